//! Command-line flags (clap). Raw flags only: `commands` validates and converts them.

use clap::{Parser, Subcommand};

/// Closed-loop models of the da Vinci Research Kit manipulators.
///
/// MODEL is a built-in name (psm, ecm, suj-psm1, suj-psm2, suj-psm3, suj-ecm, cart, mtml, mtmr,
/// psm-serial, ecm-serial) or a path to a model file (.toml), a dVRK JSON file or a URDF.
/// Units: m, rad.
#[derive(Debug, Parser)]
#[command(name = "dvrk", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// List, show and check models.
    Model {
        #[command(subcommand)]
        command: crate::commands::model::ModelCommand,
    },
    /// Forward kinematics of every frame (one configuration) or of one frame (a CSV of many).
    Fk(crate::commands::fk::FkArgs),
    /// Inverse kinematics of the tool tip.
    Ik(crate::commands::ik::IkArgs),
    /// Write a model as URDF (tree + mimic joints) or SDF (with the loop-closing joints), or a
    /// scene or model as MJCF for MuJoCo (inertias, loop closures, cables, damping, limits, motors).
    Export(crate::commands::export::ExportArgs),
    /// Headless dynamic simulation of a scene (rapier): the project's main job.
    Sim(crate::commands::sim::SimArgs),
    /// A scene as a live twin on ROS 2 in real time: the dVRK's CRTK topics published, its
    /// commands (servo_jp, servo_jf) taken.
    Serve(crate::commands::serve::ServeArgs),
    /// Motion-capture calibration: pivot (RCM), joint axes, model update.
    Calib {
        #[command(subcommand)]
        command: crate::commands::calib::CalibCommand,
    },
    /// Dynamic identification: inertial parameters (physically consistent) and friction, offsets,
    /// motor inertia and springs from a joint recording with efforts.
    Identify(crate::commands::identify::IdentifyArgs),
    /// Gravity compensation from a model (an identified one): the efforts that hold the arm
    /// still at a configuration; with a recording, against its efforts where it moves slowest.
    Gc(crate::commands::gc::GcArgs),
    /// A recorded MTM (MCAP or ROS 1 bag) driving a simulated PSM through the console's follow
    /// mode (scaled relative translation, absolute orientation, alignment, clutch, gripper -> jaw).
    Teleop(crate::commands::teleop::TeleopArgs),
    /// Which physical effect does the model lack? A recording's efforts against the model's:
    /// ranked candidates with evidence, a verdict, the model with the named effect.
    Discrepancy(crate::commands::discrepancy::DiscrepancyArgs),
    /// Synthetic recordings for tests and demos.
    Synth {
        #[command(subcommand)]
        command: crate::commands::synth::SynthCommand,
    },
}

