//! `dvrk discrepancy`: which physical effect does the model lack? The recording's efforts
//! against the model's (dvrk-calib's discrepancy workflow), a JSON report, optionally the model
//! with the named effect added and a before/after plot.

use crate::outln;
use anyhow::{bail, Context, Result};
use clap::Args;
use dvrk_calib::discrepancy::Options;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct DiscrepancyArgs {
    /// The current model (built-in name or .toml file).
    #[arg(long)]
    pub model: String,
    /// Joint recording with setpoints and efforts.
    #[arg(long)]
    pub recording: PathBuf,
    /// auto (told from the file), mcap or bag (the dVRK's /<ARM>/setpoint_js and
    /// /<ARM>/measured_js with efforts, the jaw on /<ARM>/jaw/..., or every joint on one topic),
    /// wpi-csv (the WPI dynamics recordings: no setpoints, tool channels in actuator space) or
    /// csv (header time,q1..qN,tau1..tauN[,setpoint1..setpointN]: s, rad or m, N·m or N; without
    /// setpoints the encoders stand in for them).
    #[arg(long, default_value = "auto")]
    pub format: String,
    #[arg(long, default_value = "PSM1")]
    pub arm: String,
    /// A tracked marker body: its MCAP pose topic (geometry_msgs/PoseStamped, TF child frame or
    /// Foxglove pose), or with --format csv the NAME of its pose columns NAME.x .. NAME.qw. The
    /// kinematic channel, its evidence joined to the torque channel's.
    #[arg(long, requires = "marker_link")]
    pub marker_topic: Option<String>,
    /// The link the marker is fixed on: frame name, or the paper's frame number (PSM, ECM).
    #[arg(long, requires = "marker_topic")]
    pub marker_link: Option<String>,
    /// Write the report (JSON) here.
    #[arg(long)]
    pub report: PathBuf,
    /// Residual before and after against time, velocity, load and position, per moving joint
    /// (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the model with the named effect added (as [[effects]]) here.
    #[arg(short = 'o', long)]
    pub output: Option<PathBuf>,
    /// Skip the tracking channel's replay through the simulator (faster).
    #[arg(long)]
    pub no_tracking: bool,
    /// Prior standard deviation of the model's inertias, relative: ROT (rotational inertia) or
    /// ROT,MASS (mass and first moments too); they are refitted within it next to every candidate.
    #[arg(long, value_name = "ROT[,MASS]")]
    pub inertia_prior: Option<String>,
    /// Rounds of name-add-rerun (1: a single analysis).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=20))]
    pub max_rounds: u32,
}

/// The model file's text with `effects` appended as `[[effects]]` tables.
fn model_text_with(model: &str, effects: &[dvrk_kin::effects::EffectSpec]) -> Result<String> {
    let text = match dvrk_kin::load::builtin_text(model) {
        Some(t) => t.to_string(),
        None if model.ends_with(".toml") => dvrk_kin::load::read_text(std::path::Path::new(model))?,
        None => bail!("-o: {model} is not a TOML model; the named effect can only be appended to a .toml model file"),
    };
    #[derive(serde::Serialize)]
    struct Effects<'a> {
        effects: &'a [dvrk_kin::effects::EffectSpec],
    }
    let table = toml::to_string(&Effects { effects })?;
    Ok(format!("{}\n# Added by dvrk discrepancy\n{table}", text.trim_end()))
}

pub fn run(a: &DiscrepancyArgs) -> Result<()> {
    crate::io::check_plot(a.plot.as_deref())?;
    let model_path = std::path::Path::new(&a.model);
    crate::io::check_outputs(
        &[("--recording", &a.recording), ("--model", model_path)],
        &[("--report", Some(&a.report)), ("-o", a.output.as_deref()), ("--plot", a.plot.as_deref())],
    )?;
    let mut options = Options { tracking: !a.no_tracking, ..Default::default() };
    if let Some(text) = &a.inertia_prior {
        let v: Vec<f64> =
            text.split(',').map(|x| x.trim().parse::<f64>()).collect::<std::result::Result<_, _>>().map_err(|_| anyhow::anyhow!("--inertia-prior {text}: expected ROT or ROT,MASS (numbers >= 0)"))?;
        if v.is_empty() || v.len() > 2 || v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
            bail!("--inertia-prior {text}: expected ROT or ROT,MASS (finite numbers >= 0)");
        }
        options.inertia_prior = dvrk_calib::discrepancy::InertiaPrior::relative(v[0], v.get(1).copied().unwrap_or(options.inertia_prior.mass));
    }
    let model = dvrk_kin::load(&a.model, None)?;
    let marker = a.marker_topic.as_ref().zip(a.marker_link.as_ref()).map(|(topic, link)| dvrk_calib::discrepancy::from_file::MarkerSource { topic: topic.clone(), link: link.clone() });
    let spinner = crate::progress::Progress::spinner("", crate::progress::Progress::wanted(false));
    let out = dvrk_calib::discrepancy::from_file::run_with(&a.recording, &a.format, &model, &a.arm, marker.as_ref(), &options, a.max_rounds as usize, &mut |stage| spinner.set_message(stage))?;
    spinner.finish();
    let r = &out.report;
    // Drawn before anything is written: a failure leaves no partial set of outputs.
    let image = match &a.plot {
        Some(p) => Some(dvrk_calib::discrepancy::plot::figure(&out.residuals, &a.recording.display().to_string())?.encode(p)?),
        None => None,
    };
    // Every output staged, then all committed together.
    let mut staged = vec![crate::io::stage(&a.report, format!("{}\n", serde_json::to_string_pretty(r)?).as_bytes())?];
    if let Some(path) = &a.output {
        if !out.named.is_empty() {
            let text = model_text_with(&a.model, &out.named)?;
            // Check it loads before writing it.
            dvrk_kin::load::load_toml_text(&text, path, None, None).with_context(|| format!("{}: the updated model does not load", path.display()))?;
            staged.push(crate::io::stage(path, text.as_bytes())?);
        }
    }
    if let (Some(p), Some(image)) = (&a.plot, &image) {
        staged.push(crate::io::stage(p, image).with_context(|| format!("--plot {}", p.display()))?);
    }
    dvrk_kin::atomic::commit_all(staged)?;
    let named = r.effects.iter().map(|e| e.label()).collect::<Vec<_>>().join(", ");
    outln!("{}: {}{}; report in {}", a.recording.display(), r.verdict, if named.is_empty() { String::new() } else { format!(": {named}") }, a.report.display());
    // Per joint in its own unit: what is left, and how much of the joint's effort was explained.
    for j in &r.joints {
        outln!(
            "  {:<20} residual {:.4} -> {:.4} {} ({:.0}% of its effort explained; {:.4} {} held out -> {:.4}); {}",
            j.joint,
            j.band_rms_before,
            j.band_rms_after,
            j.unit,
            100.0 * j.share_explained,
            j.band_rms_heldout_before,
            j.unit,
            j.band_rms_heldout_after,
            j.unexplained
        );
    }
    // The tracked marker: its pose residual over the tracker's noise (the only figures of a
    // recording without efforts).
    if let Some(k) = &r.kinematic {
        outln!(
            "  marker on {:<10} residual {:.2} -> {:.2} of the tracker's noise ({:.2e} m, {:.2e} rad; held out {:.2} -> {:.2})",
            k.link,
            k.rms_before,
            k.rms_after,
            k.noise_position,
            k.noise_rotation,
            k.rms_heldout_before,
            k.rms_heldout_after
        );
    }
    for p in r.effects.iter().filter_map(|e| e.payload.as_ref().map(|p| (e, p))) {
        let (e, p) = p;
        outln!(
            "  {}: {:.3} kg [{:.3}, {:.3}] at ({:.3}, {:.3}, {:.3}) m; first moment about the pivot {:.4} kg m [{:.4}, {:.4}]{}{}",
            e.label(),
            p.mass,
            p.mass_ci95[0],
            p.mass_ci95[1],
            p.position[0],
            p.position[1],
            p.position[2],
            p.first_moment,
            p.first_moment_ci95[0],
            p.first_moment_ci95[1],
            if p.cannot_fix.is_empty() { String::new() } else { format!("; cannot fix: {}", p.cannot_fix.join("; ")) },
            if p.equivalent.is_empty() { String::new() } else { format!("; as well explained on: {}", p.equivalent.iter().map(|q| q.link.as_str()).collect::<Vec<_>>().join(", ")) }
        );
    }
    Ok(())
}
