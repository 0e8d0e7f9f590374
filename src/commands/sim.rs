//! `dvrk sim`: headless simulation (issue 3; not built yet).

use anyhow::{bail, Result};
use clap::Args;

#[derive(Debug, Args)]
pub struct SimArgs {}

pub fn run(_args: &SimArgs) -> Result<()> {
    bail!("dvrk sim is not built yet")
}
