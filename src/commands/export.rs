//! `dvrk export urdf|sdf`.

use crate::cli::{ExportArgs, ExportFormat};
use anyhow::Result;

pub fn run(args: &ExportArgs) -> Result<()> {
    let m = super::load(&args.model)?;
    let text = match args.format {
        ExportFormat::Urdf => {
            if args.q.is_some() {
                anyhow::bail!("--q: a URDF holds no configuration (it applies to sdf only)");
            }
            dvrk_kin::urdf::export_urdf(&m)?
        }
        ExportFormat::Sdf => {
            let q = super::q_arg(&m, "--q", args.q.as_deref())?;
            dvrk_kin::sdf::export_sdf(&m, &q)?
        }
    };
    crate::io::write_atomic(&args.output, text.as_bytes())
}
