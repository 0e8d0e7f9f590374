//! Command-line flags (clap). Raw flags only: `commands` validates and converts them.

use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

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
        command: ModelCommand,
    },
    /// Forward kinematics of every frame (one configuration) or of one frame (a CSV of many).
    Fk(FkArgs),
    /// Inverse kinematics of the tool tip.
    Ik(IkArgs),
    /// Write a model as URDF (tree + mimic joints) or SDF (with the loop-closing joints), or a
    /// scene or model as MJCF for MuJoCo (inertias, loop closures, cables, damping, limits, motors).
    Export(ExportArgs),
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
    /// Which physical effect does the model lack? A recording's efforts against the model's:
    /// ranked candidates with evidence, a verdict, the model with the named effect.
    Discrepancy(crate::commands::discrepancy::DiscrepancyArgs),
    /// Synthetic recordings for tests and demos.
    Synth {
        #[command(subcommand)]
        command: crate::commands::synth::SynthCommand,
    },
}

#[derive(Debug, Subcommand)]
pub enum ModelCommand {
    /// List the built-in models.
    List,
    /// Print a model's DH table, joints, bodies and closures, as the paper prints them.
    Show(ModelArgs),
    /// Closure residual, RCM, closure conditioning over the joint range, serial equivalence.
    Check(CheckArgs),
}

/// A model and an optional tool.
#[derive(Debug, Args)]
pub struct ModelArgs {
    /// Built-in name or file.
    pub model: String,
    /// dVRK tool file (JSON) for models with a tool (psm, psm-serial, PSM.json).
    #[arg(long)]
    pub tool: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Configurations sampled over the joint range.
    #[arg(long, default_value_t = 10_000)]
    pub samples: usize,
}

#[derive(Debug, Args)]
pub struct FkArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Joint positions, comma-separated (rad, m); the model's home when absent.
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
    /// Print every frame as JSON.
    #[arg(long)]
    pub json: bool,
    /// `--q` holds actuator positions (encoders), mapped to joints by the model's coupling.
    #[arg(long)]
    pub actuators: bool,
    /// CSV of measured configurations: a header with a column per joint, `qK` or the joint's name
    /// (`outer_yaw`, ...); other columns are ignored. Joints the output frame does not depend on
    /// (a PSM's jaw for the tool tip) may be left out: they are held at their home. Rows past the
    /// model's joint limits are evaluated as measured and counted on stderr.
    #[arg(long, requires = "output")]
    pub input: Option<PathBuf>,
    /// CSV of poses x,y,z,qx,qy,qz,qw (m) of `--frame`, one row per input row.
    #[arg(long, requires = "input")]
    pub output: Option<PathBuf>,
    /// Frame name or paper frame number for `--output` (default: the tool tip).
    #[arg(long)]
    pub frame: Option<String>,
    /// With `--input`: refuse a row outside the model's joint limits instead of counting it.
    #[arg(long, requires = "input")]
    pub strict: bool,
}

#[derive(Debug, Args)]
pub struct IkArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Target pose of the tip in the model's base frame: x,y,z (m), qx,qy,qz,qw.
    #[arg(long, allow_hyphen_values = true)]
    pub pose: String,
    /// Start configuration, comma-separated (default: home).
    #[arg(long, allow_hyphen_values = true)]
    pub seed: Option<String>,
    /// Frame to place (default: the tool tip).
    #[arg(long)]
    pub frame: Option<String>,
    /// Print the solution as JSON.
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ExportFormat {
    Urdf,
    Sdf,
    /// MuJoCo XML of a scene (built-in name or scene file) or of a model with its built-in
    /// inertials and gains.
    Mjcf,
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// urdf, sdf or mjcf.
    pub format: ExportFormat,
    /// MODEL (urdf, sdf); for mjcf a scene (psm, ecm, 2psm-ecm, 3psm, full, or a scene file),
    /// else a model.
    #[command(flatten)]
    pub model: ModelArgs,
    /// Output file (written whole or not at all).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Configuration the SDF link poses are written at (default: home).
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
}
