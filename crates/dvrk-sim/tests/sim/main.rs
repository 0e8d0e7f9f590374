//! Integration tests of dvrk-sim: one binary, one module per concern (run in release:
//! `cargo test --release -p dvrk-sim-tests`). The allocation count is its own binary
//! (`tests/reduced_alloc.rs`: a process-wide counting allocator).
//!
//! - `sim`: the engine's commands, limits, gains and loop modes.
//! - `batch`: many copies stepped in parallel, each as a lone sim.
//! - `endurance`: a million steps of random commands.
//! - `reduced`: the reduced-coordinate engine against rapier on the same scenes.
//! - `energy`: energy conserved with the actuators and damping off.
//! - `dynamics_crosscheck`: steady PID efforts against dvrk-kin's Newton-Euler gravity torques.
//! - `effects`: each effect of the vocabulary's signature, on both engines.
//! - `scenes`: the multi-arm scenes of Table 9 build, run and stand where the cart puts them.
//! - `inertials`: the inertials files against the paper's SDF figures.
//! - `camera`: the stereo camera against the analytic pinhole; the link geometry.
//! - `recording`: MCAP recordings read back by the mcap crate and by Python's packages.
//! - `mjcf`: the MJCF export.
//! - `plot`: the tracking PNG of a run.

mod batch;
mod camera;
mod dynamics_crosscheck;
mod effects;
mod endurance;
mod energy;
mod inertials;
mod mjcf;
mod mtm;
mod plot;
mod recording;
mod reduced;
mod scenes;
mod sim;
mod teleop;
