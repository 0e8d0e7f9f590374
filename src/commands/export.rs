//! `dvrk export urdf|sdf|mjcf`.

use crate::cli::{ExportArgs, ExportFormat};
use anyhow::Result;

pub fn run(args: &ExportArgs) -> Result<()> {
    let mut inputs = vec![("MODEL", std::path::Path::new(&args.model.model))];
    inputs.extend(args.model.tool.as_deref().map(|t| ("--tool", t)));
    crate::io::check_outputs(&inputs, &[("-o", Some(&args.output))])?;
    let text = match args.format {
        ExportFormat::Urdf => {
            if args.q.is_some() {
                anyhow::bail!("--q: a URDF holds no configuration (it applies to sdf only)");
            }
            dvrk_kin::urdf::export_urdf(&super::load(&args.model)?)?
        }
        ExportFormat::Sdf => {
            let m = super::load(&args.model)?;
            let q = super::q_arg(&m, "--q", args.q.as_deref())?;
            dvrk_kin::sdf::export_sdf(&m, &q)?
        }
        ExportFormat::Mjcf => {
            if args.q.is_some() {
                anyhow::bail!("--q: an MJCF export starts at the scene's home configuration (it applies to sdf only)");
            }
            if args.model.tool.is_some() {
                anyhow::bail!("--tool: not supported by mjcf (the scene's models are exported as they are)");
            }
            dvrk_sim::mjcf::export_named(&args.model.model)?
        }
    };
    crate::io::write_atomic(&args.output, text.as_bytes())
}
