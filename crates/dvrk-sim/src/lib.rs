//! # dvrk-sim
//!
//! Headless dynamic simulation of the dvrk-kin closed-loop models (f64) on two engines: the
//! reduced one ([`reduced`]: forward dynamics in the actuated joints, loops exact by
//! construction) and rapier's (one rigid body per dvrk-kin body, the frame tree as a
//! multibody, loops closed by impulse joints; contacts). Both share per-joint PID / position /
//! effort actuators with the paper's gains (Table 8), joint damping 0.1, a reflected drive
//! inertia (armature) on the light wrist joints and the effects of the vocabulary.
//!
//! ```no_run
//! let scene = dvrk_sim::Scene::load("psm").unwrap();
//! let mut sim = dvrk_sim::Sim::new(&scene, &Default::default()).unwrap();
//! for _ in 0..1000 { sim.step(); }
//! assert!(sim.closure_error() < 1e-3); // m
//! ```
//!
//! Units: m, rad, s, kg, N, N·m.

pub mod batch;
pub mod camera;
pub mod control;
pub mod effects;
mod error;
pub mod geometry;
pub mod inertials;
pub mod joint_move;
pub mod live;
pub mod mjcf;
pub mod pace;
pub mod pivot;
pub mod plot;
pub mod recipe;
pub mod recording;
pub mod reduced;
pub mod ros2;
pub mod run;
mod run_tally;
pub mod scene;
mod command_mode;
pub mod serve;
pub mod serve_cp;
pub mod serve_teleop;
pub mod sim;
mod arm_state;
mod options;
mod rapier_build;
mod rapier_world;
pub mod teleop;
pub mod teleop_replay;
pub mod trajectory;
pub mod warnings;

pub use batch::BatchSim;
pub use control::{Actuator, Gains, Mode};
pub use error::{Result, SimError};
pub use live::{Live, LiveOptions};
pub use mjcf::export_mjcf;
pub use recording::{RecordOptions, Recorder};
pub use run::{run, run_recorded, run_staged, run_traced, run_with, CameraSummary, Outputs, Run, RunOptions, Summary, Trace, WindowSummary};
pub use scene::{Scene, SolverSettings};
pub use sim::{ClosingLinks, Colliders, Coriolis, Engine, LoopMode, Sim, SimOptions};
pub use dvrk_kin;
