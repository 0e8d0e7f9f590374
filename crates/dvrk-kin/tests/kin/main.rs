//! Integration tests of dvrk-kin: one binary, one module per concern. What a signal handler does
//! with staged outputs is its own binary (`tests/staged_files.rs`: the registry is process-wide).
//!
//! - `dynamics`: rigid-body dynamics against closed forms and independent computations.
//! - `effects`: the `[[effects]]` section, its checks, and the friction / spring efforts.
//! - `interchange`: URDF and SDF export and import.
//! - `check`: `dvrk model check` on models no robot has.

mod check;
mod dynamics;
mod effects;
mod interchange;
