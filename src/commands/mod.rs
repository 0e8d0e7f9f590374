//! One module per subcommand; each turns validated flags into library calls and output.

pub mod calib;
pub mod discrepancy;
pub mod export;
pub mod fk;
pub mod gc;
pub mod identify;
pub mod ik;
pub mod model;
pub mod serve;
pub mod sim;
pub mod synth;
pub mod teleop;

use crate::cli::{Cli, Command};
use model::ModelCommand;
use anyhow::Result;
use dvrk_kin::{FrameRef, Model};

/// A model and an optional tool.
#[derive(Debug, clap::Args)]
pub struct ModelArgs {
    /// Built-in name or file.
    pub model: String,
    /// dVRK tool file (JSON) for models with a tool (psm, psm-serial, PSM.json).
    #[arg(long)]
    pub tool: Option<std::path::PathBuf>,
}

/// Run a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Model { command } => match command {
            ModelCommand::List => model::list(),
            ModelCommand::Show(a) => model::show(&a),
            ModelCommand::Check(a) => model::check(&a),
        },
        Command::Fk(a) => fk::run(&a),
        Command::Ik(a) => ik::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Sim(a) => sim::run(&a),
        Command::Serve(a) => serve::run(&a),
        Command::Calib { command } => calib::run(&command),
        Command::Synth { command } => synth::run(&command),
        Command::Identify(a) => identify::run(&a),
        Command::Gc(a) => gc::run(&a),
        Command::Teleop(a) => teleop::run(&a),
        Command::Discrepancy(a) => discrepancy::run(&a),
    }
}

/// Load the model a command names.
pub fn load(args: &ModelArgs) -> Result<Model> {
    Ok(dvrk_kin::load(&args.model, args.tool.as_deref())?)
}

/// A frame given on the command line: a paper frame number or a name.
pub fn frame_arg(model: &Model, flag: &str, text: &str) -> Result<usize> {
    let r = match text.parse::<i64>() {
        Ok(i) => FrameRef::Index(i),
        Err(_) => FrameRef::Name(text.to_string()),
    };
    model.frame_id(&r).map_err(|e| anyhow::anyhow!("{flag}: {e}"))
}

/// `q` from `--q` (checked against the model's size and limits), or the home configuration.
pub fn q_arg(model: &Model, flag: &str, text: Option<&str>) -> Result<Vec<f64>> {
    let Some(text) = text else { return Ok(model.home()) };
    let q = crate::io::parse_list(flag, text)?;
    model.check_q(&q).map_err(|e| anyhow::anyhow!("{flag}: {e}"))?;
    Ok(q)
}

/// The scene's first arm of `kind` (`psm`, `ecm`): its model's name or its own starts so
/// (`psm-wpi.toml`, `PSM2`), for a command that picks one when not told.
pub fn first_arm_of(scene: &dvrk_sim::Scene, kind: &str) -> Option<usize> {
    scene.arms.iter().position(|a| a.model.name.starts_with(kind) || a.name.starts_with(&kind.to_uppercase()))
}
