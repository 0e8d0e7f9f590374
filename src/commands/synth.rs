//! `dvrk synth`: synthetic recordings (issue 4; not built yet).

use anyhow::{bail, Result};
use clap::Subcommand;

#[derive(Debug, Subcommand)]
pub enum SynthCommand {
    /// A synthetic motion-capture recording (not built yet).
    Mocap,
}

pub fn run(_c: &SynthCommand) -> Result<()> {
    bail!("dvrk synth is not built yet")
}
