//! `dvrk discrepancy`: which physical effect does the model lack? The recording's efforts
//! against the model's (dvrk-calib's discrepancy workflow), a JSON report, optionally the model
//! with the named effect added and a before/after plot.

use crate::outln;
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use dvrk_calib::discrepancy::{discrepancy, joint_log, Options};
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct DiscrepancyArgs {
    /// The current model (built-in name or .toml file).
    #[arg(long)]
    pub model: String,
    /// Joint recording with setpoints and efforts.
    #[arg(long)]
    pub recording: PathBuf,
    /// mcap (/<ARM>/setpoint_js and /<ARM>/measured_js with efforts); wpi-csv and csv are not
    /// read yet.
    #[arg(long, default_value = "mcap")]
    pub format: String,
    #[arg(long, default_value = "PSM1")]
    pub arm: String,
    /// Tracker topic for the kinematic channel (not analysed yet).
    #[arg(long, requires = "marker_link")]
    pub marker_topic: Option<String>,
    /// Frame name or paper frame number the marker is on.
    #[arg(long, requires = "marker_topic")]
    pub marker_link: Option<String>,
    /// Write the report (JSON) here.
    #[arg(long)]
    pub report: PathBuf,
    /// Residual before and after (PNG).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the model with the named effect added (as [[effects]]) here.
    #[arg(short = 'o', long)]
    pub output: Option<PathBuf>,
    /// Skip the tracking channel's replay through the simulator (faster).
    #[arg(long)]
    pub no_tracking: bool,
}

/// The model file's text with `effect` appended as an `[[effects]]` table.
fn model_text_with(model: &str, effect: &dvrk_kin::effects::EffectSpec) -> Result<String> {
    let text = match dvrk_kin::load::builtin_text(model) {
        Some(t) => t.to_string(),
        None if model.ends_with(".toml") => std::fs::read_to_string(model).with_context(|| format!("{model}: cannot read"))?,
        None => bail!("-o: {model} is not a TOML model; the named effect can only be appended to a .toml model file"),
    };
    #[derive(serde::Serialize)]
    struct Effects<'a> {
        effects: [&'a dvrk_kin::effects::EffectSpec; 1],
    }
    let table = toml::to_string(&Effects { effects: [effect] })?;
    Ok(format!("{}\n# Added by dvrk discrepancy\n{table}", text.trim_end()))
}

pub fn run(a: &DiscrepancyArgs) -> Result<()> {
    if a.marker_topic.is_some() {
        bail!("--marker-topic: the kinematic channel is not implemented yet (torque and tracking channels only)");
    }
    let log = match a.format.as_str() {
        "mcap" => joint_log::read_mcap(&a.recording, &a.arm)?,
        "wpi-csv" | "csv" => bail!("--format {}: not read by dvrk discrepancy yet (use an MCAP with /{}/setpoint_js and /{}/measured_js)", a.format, a.arm, a.arm),
        other => bail!("--format: `{other}` is not a format; valid: mcap, wpi-csv, csv"),
    };
    let model = dvrk_kin::load(&a.model, None)?;
    let scene = dvrk_calib::discrepancy::scene_for_arm(&a.arm).map_err(|e| anyhow!("--arm {}: {e}", a.arm))?;
    let options = Options { tracking: !a.no_tracking, ..Default::default() };
    let out = discrepancy(&model, &scene, &a.arm, &log, &options).map_err(|e| anyhow!("{}: {e}", a.recording.display()))?;
    let r = &out.report;
    crate::io::write_atomic(&a.report, format!("{}\n", serde_json::to_string_pretty(r)?).as_bytes())?;
    if let (Some(path), Some(effect)) = (&a.output, &out.named) {
        let text = model_text_with(&a.model, effect)?;
        // Check it loads before writing it.
        dvrk_kin::load::load_toml_text(&text, path, None, None).with_context(|| format!("{}: the updated model does not load", path.display()))?;
        crate::io::write_atomic(path, text.as_bytes())?;
    }
    if a.plot.is_some() {
        bail!("--plot: not drawn yet (the report holds the numbers)");
    }
    let named = r.effects.iter().map(|e| format!("{} {}", e.name, e.joint.clone().or(e.link.clone()).unwrap_or_default())).collect::<Vec<_>>().join(", ");
    outln!(
        "{}: {}{} (torque residual {:.2} -> {:.2} of the noise floor on held-out data); report in {}",
        a.recording.display(),
        r.verdict,
        if named.is_empty() { String::new() } else { format!(": {named}") },
        r.rms_heldout_before,
        r.rms_heldout_after,
        a.report.display()
    );
    Ok(())
}
