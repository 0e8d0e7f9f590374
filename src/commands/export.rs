//! `dvrk export urdf|sdf|mjcf`.

use clap::{Args, ValueEnum};
use std::path::PathBuf;
use anyhow::Result;

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
    pub model: super::ModelArgs,
    /// Output file (written whole or not at all).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Configuration the SDF link poses are written at (default: home).
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
    /// urdf: each body's inertial (the model file's [[inertials]], else the built-in ones) on its
    /// first frame's link, for URDF dynamics libraries (Pinocchio with mimic joints).
    #[arg(long)]
    pub inertials: bool,
}

pub fn run(args: &ExportArgs) -> Result<()> {
    let mut inputs = vec![("MODEL", std::path::Path::new(&args.model.model))];
    inputs.extend(args.model.tool.as_deref().map(|t| ("--tool", t)));
    crate::io::check_outputs(&inputs, &[("-o", Some(&args.output))])?;
    // The flags a format does not take are refused before anything is loaded.
    match args.format {
        ExportFormat::Urdf if args.q.is_some() => anyhow::bail!("--q: a URDF holds no configuration (it applies to sdf only)"),
        ExportFormat::Mjcf if args.q.is_some() => anyhow::bail!("--q: an MJCF export starts at the scene's home configuration (it applies to sdf only)"),
        ExportFormat::Mjcf if args.model.tool.is_some() => anyhow::bail!("--tool: not supported by mjcf (the scene's models are exported as they are)"),
        ExportFormat::Sdf | ExportFormat::Mjcf if args.inertials => anyhow::bail!("--inertials: applies to urdf only (mjcf always carries them)"),
        _ => {}
    }
    let text = match args.format {
        ExportFormat::Urdf if args.inertials => {
            let m = super::load(&args.model)?;
            let inertias = dvrk_sim::scene::model_inertias(&m).map_err(|e| anyhow::anyhow!("--inertials: {e}"))?;
            let inertias = dvrk_kin::effects::effect_inertias(&m, &m.effects, &inertias)?;
            dvrk_kin::urdf::export_urdf_with_inertials(&m, Some(&inertias))?
        }
        ExportFormat::Urdf => dvrk_kin::urdf::export_urdf(&super::load(&args.model)?)?,
        ExportFormat::Sdf => {
            let m = super::load(&args.model)?;
            let q = super::q_arg(&m, "--q", args.q.as_deref())?;
            dvrk_kin::sdf::export_sdf(&m, &q)?
        }
        ExportFormat::Mjcf => {
            let text = dvrk_sim::mjcf::export_named(&args.model.model)?;
            for line in text.lines().filter_map(|l| l.trim().strip_prefix("<!-- not exported: ")) {
                eprintln!("note: {}", line.trim_end_matches(" -->"));
            }
            text
        }
    };
    Ok(dvrk_kin::atomic::write_atomic(&args.output, text.as_bytes())?)
}
