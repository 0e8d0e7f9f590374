//! `dvrk calib`: motion-capture calibration (issue 4; not built yet).

use anyhow::{bail, Result};
use clap::Subcommand;

#[derive(Debug, Subcommand)]
pub enum CalibCommand {
    /// Pivot calibration of the RCM (not built yet).
    Pivot,
}

pub fn run(_c: &CalibCommand) -> Result<()> {
    bail!("dvrk calib is not built yet")
}
