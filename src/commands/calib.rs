//! `dvrk calib`: motion-capture calibration: the RCM by pivot calibration (paper eq. 3-5), the
//! joint axes and Table 6 distances (section 2.4), and a model file for one robot.

use crate::outln;
use anyhow::{anyhow, bail, Result};
use clap::{Args, Subcommand};
use dvrk_calib::mocap::axis_distances::AxesReport;
use dvrk_calib::mocap::psm_dh::{psm_dh, PsmDh, PSM_AXES};
use dvrk_calib::{calibrate_axes, pivot_calibration, read_recording, AxesConfig, AxesOptions, McapOptions, PivotMethod, PivotOptions};
use std::path::{Path, PathBuf};

#[derive(Debug, Subcommand)]
pub enum CalibCommand {
    /// Pivot calibration of the RCM (eq. 3-5): markers on link 8 while q1 and q2 move.
    Pivot(PivotArgs),
    /// Joint axes between marker clusters and the Table 6 axis distances (section 2.4).
    Axes(AxesArgs),
    /// Write a model file for one robot from an axes result (`calib axes --json`).
    Apply(ApplyArgs),
}

#[derive(Debug, Args)]
pub struct PivotArgs {
    /// Recording: .mcap (ROS 2 / Foxglove), Motive .csv export or plain .csv.
    #[arg(long)]
    pub recording: PathBuf,
    /// The pivoting rigid body: topic, TF child frame or rigid-body name (default: the only one).
    #[arg(long)]
    pub topic: Option<String>,
    /// one-step (the paper's eq. 4), two-step or sphere.
    #[arg(long, default_value = "one-step")]
    pub method: String,
    /// Fit the rigid body's poses from its raw markers (Motive or plain CSV with marker columns).
    #[arg(long)]
    pub from_markers: bool,
    /// Print the result as one JSON object (m, in the recording's frames).
    #[arg(long)]
    pub json: bool,
    /// Also write the RCM point cloud (Figure 9) as an image (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct AxesArgs {
    /// Recording: .mcap, Motive .csv export or plain .csv.
    #[arg(long)]
    pub recording: PathBuf,
    /// Which rigid body sits on which link and which links share an axis (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// sara or gamage-lasenby (default: the configuration's, else sara).
    #[arg(long)]
    pub method: Option<String>,
    /// Fit poses from raw markers even where the recording has rigid-body poses.
    #[arg(long)]
    pub from_markers: bool,
    /// The JointState topic that tells joint zero (default: the first one in the recording).
    #[arg(long)]
    pub joint_topic: Option<String>,
    /// Print the result as one JSON object (the input of `calib apply`).
    #[arg(long)]
    pub json: bool,
    /// Also write the JSON result to this file (whole or not at all).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Also write the axis residuals as an image (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct ApplyArgs {
    /// An axes result (`dvrk calib axes --json`).
    #[arg(long)]
    pub axes: PathBuf,
    /// The model to update (built-in name or file; a PSM layout).
    #[arg(long, default_value = "psm")]
    pub model: String,
    /// Output model file (TOML), written whole or not at all.
    #[arg(short, long)]
    pub output: PathBuf,
}

pub fn run(c: &CalibCommand) -> Result<()> {
    match c {
        CalibCommand::Pivot(a) => pivot(a),
        CalibCommand::Axes(a) => axes(a),
        CalibCommand::Apply(a) => apply(a),
    }
}

fn pivot(a: &PivotArgs) -> Result<()> {
    crate::io::check_outputs(&[("--recording", &a.recording)], &[("--plot", a.plot.as_deref())])?;
    crate::io::check_plot(a.plot.as_deref())?;
    let method: PivotMethod = a.method.parse().map_err(|e| anyhow!("--method: {e}"))?;
    // All topics are read so that `--topic` may be a short name (`end` for /mocap/end/pose).
    let spinner = crate::progress::Progress::spinner("reading the recording", crate::progress::Progress::wanted(a.json));
    let rec = read_recording(&a.recording, &McapOptions::default())?;
    spinner.set_message("fitting the pivot");
    let name = match &a.topic {
        Some(t) => t.clone(),
        None => {
            let mut names = rec.body_names();
            names.extend(rec.markers.iter().map(|m| m.body.clone()).filter(|b| !names.contains(b)).collect::<Vec<_>>());
            match names.as_slice() {
                [one] => one.clone(),
                [] => bail!("{}: no rigid body in the recording", a.recording.display()),
                many => bail!("{}: --topic: the recording has {} rigid bodies; name one of {}", a.recording.display(), many.len(), many.join(", ")),
            }
        }
    };
    let track = rec.poses(&name, None, a.from_markers).map_err(|e| anyhow!("{}: {e}", a.recording.display()))?;
    let fit = pivot_calibration(&track.poses, &PivotOptions { method, ..Default::default() })
        .map_err(|e| anyhow!("{}: rigid body `{}`: {e}", a.recording.display(), track.name))?;
    spinner.finish();
    let mut warnings: Vec<String> = rec.warnings.clone();
    if track.occluded > 0 || track.outliers > 0 {
        warnings.push(format!("rigid body `{}`: {} occluded and {} outlier frame(s) dropped before the fit", track.name, track.occluded, track.outliers));
    }
    warnings.extend(fit.warnings.iter().cloned());
    if let Some(p) = &a.plot {
        let cloud = fit.cloud(&track.poses);
        let image = dvrk_calib::plot::cloud(&cloud, &fit.pivot, &format!("RCM point cloud: {} ({})", track.name, method.name()))?;
        dvrk_kin::atomic::write_atomic(p, &image.encode(p)?)?;
    }
    if a.json {
        let mut v = dvrk_calib::mocap::report_json::pivot_json(&fit);
        v["warnings"] = serde_json::json!(warnings);
        outln!("{}", serde_json::to_string(&v)?);
        return Ok(());
    }
    let mm = |v: &nalgebra::Vector3<f64>| format!("({:9.3}, {:9.3}, {:9.3}) mm", v.x * 1e3, v.y * 1e3, v.z * 1e3);
    let std = |s: [f64; 3]| format!("({:.3}, {:.3}, {:.3}) mm", s[0] * 1e3, s[1] * 1e3, s[2] * 1e3);
    outln!("pivot calibration of `{}` in {} ({}, {} samples, {} outliers dropped)", track.name, a.recording.display(), method.name(), fit.samples, fit.outliers);
    outln!("  pivot (b_post, tracker frame) {}  std {}", mm(&fit.pivot), std(fit.pivot_std()));
    outln!("  tip   (b_tip, marker frame)   {}  std {}", mm(&fit.tip), std(fit.tip_std()));
    let r = fit.rms_per_axis;
    outln!("  RMS per axis (paper eq. 5, Table 7): ({:.3}, {:.3}, {:.3}) mm", r[0] * 1e3, r[1] * 1e3, r[2] * 1e3);
    outln!("  RMS over all components: {:.3} mm; RMS distance from the pivot: {:.3} mm", fit.rms * 1e3, fit.rms_distance * 1e3);
    let d = fit.motion.ranges_deg();
    outln!("  motion range of the marker frame: {:.1} deg, {:.1} deg, {:.1} deg", d[0], d[1], d[2]);
    for w in &warnings {
        outln!("warning: {w}");
    }
    Ok(())
}

fn axes(a: &AxesArgs) -> Result<()> {
    crate::io::check_outputs(&[("--recording", &a.recording), ("--config", &a.config)], &[("-o", a.output.as_deref()), ("--plot", a.plot.as_deref())])?;
    crate::io::check_plot(a.plot.as_deref())?;
    let text = dvrk_kin::load::read_text(&a.config)?;
    let cfg = AxesConfig::from_toml(&text, &a.config)?;
    let method = a.method.as_deref().map(str::parse).transpose().map_err(|e| anyhow!("--method: {e}"))?;
    let spinner = crate::progress::Progress::spinner("reading the recording", crate::progress::Progress::wanted(a.json));
    let rec = read_recording(&a.recording, &McapOptions { topics: Vec::new(), joint_topic: a.joint_topic.clone() })?;
    spinner.set_message("fitting the axes");
    let report = calibrate_axes(&rec, &cfg, &AxesOptions { method, from_markers: a.from_markers }).map_err(|e| anyhow!("{}: {e}", a.recording.display()))?;
    spinner.finish();
    let has_psm = PSM_AXES.iter().all(|n| report.axis(n).is_some());
    let dh = if has_psm { Some(psm_dh(&report).map_err(|e| anyhow!("{}: {e}", a.recording.display()))?) } else { None };
    let v = dvrk_calib::mocap::report_json::axes_json(&report, dh.as_ref());
    let text = serde_json::to_string_pretty(&v)?;
    let mut staged = Vec::new();
    if let Some(o) = &a.output {
        staged.push(crate::io::stage(o, format!("{text}\n").as_bytes())?);
    }
    if let Some(p) = &a.plot {
        let image = dvrk_calib::plot::axis_residuals(&report)?;
        staged.push(crate::io::stage(p, &image.encode(p)?)?);
    }
    dvrk_kin::atomic::commit_all(staged)?;
    if a.json {
        outln!("{text}");
        return Ok(());
    }
    print_axes(&report, dh.as_ref(), &a.recording);
    Ok(())
}

fn print_axes(r: &AxesReport, dh: Option<&PsmDh>, path: &Path) {
    outln!("axes of {} ({}, {} axes)", path.display(), r.method.name(), r.axes.len());
    if let (Some(t), Some(q)) = (r.reference_time, &r.reference_q) {
        outln!("  tracker-frame axes at t = {t:.3} s, q1 = {:.4} rad, q2 = {:.4} rad", q.first().copied().unwrap_or(f64::NAN), q.get(1).copied().unwrap_or(f64::NAN));
    } else if let Some(t) = r.reference_time {
        outln!("  tracker-frame axes at t = {t:.3} s");
    }
    outln!("  {:<5} {:<8} {:<8} {:>8} {:>10} {:>10} {:>9} {:>8}", "axis", "ref", "moving", "samples", "range deg", "std mm", "rms mm", "outliers");
    for a in &r.axes {
        outln!(
            "  {:<5} {:<8} {:<8} {:>8} {:>10.1} {:>10.4} {:>9.4} {:>8}",
            a.name,
            a.reference,
            a.moving,
            a.fit.samples,
            a.fit.motion.ranges[0].to_degrees(),
            a.fit.point_std() * 1e3,
            a.fit.rms * 1e3,
            a.fit.outliers
        );
    }
    outln!("  distances (m), normal to the axes:");
    for d in &r.distances {
        outln!("    {:>3}-{:<3} {:.5} +- {:.5}  (in {})", d.a, d.b, d.distance, d.std, d.frame);
    }
    if let Some(d) = dh {
        outln!("  PSM DH lengths: 3-4 {:.5} m, a6 {:.5} m, a7 {:.5} m, a8 {:.5} m; beta2 - beta1 {:.5} rad", d.l34.value, d.a6.value, d.a7.value, d.a8.value, d.beta_difference.value);
        for (k, v) in d.mismatch {
            outln!("    parallelogram {k}: {:.3} mm", v * 1e3);
        }
    }
    for w in &r.warnings {
        outln!("warning: {w}");
    }
}

fn apply(a: &ApplyArgs) -> Result<()> {
    crate::io::check_outputs(&[("--axes", &a.axes), ("--model", std::path::Path::new(&a.model))], &[("-o", Some(&a.output))])?;
    let text = dvrk_kin::load::read_text(&a.axes)?;
    let update = dvrk_calib::mocap::report_json::psm_update_from_json(&text, &a.axes)?;
    let model = dvrk_kin::load(&a.model, None)?;
    let name = a.output.file_stem().and_then(|s| s.to_str()).unwrap_or("psm-calibrated").to_string();
    let applied = dvrk_calib::mocap::apply::apply_psm(&model.spec, &update, &name).map_err(|e| anyhow!("--model {}: {e}", a.model))?;
    let toml = applied.spec.to_toml()?;
    let header = format!("# {name}: {} calibrated by `dvrk calib apply --axes {}`.\n# Units: m, rad.\n", a.model, a.axes.display());
    dvrk_kin::atomic::write_atomic(&a.output, format!("{header}{toml}").as_bytes())?;
    outln!("wrote {} ({})", a.output.display(), name);
    for c in &applied.changes {
        outln!("  {:<32} {:>12.6} -> {:>12.6}", c.what, c.old, c.new);
    }
    let (old, new) = (model.rcm.as_ref().map(|r| r.point), applied.model.rcm.as_ref().map(|r| r.point));
    if let (Some(o), Some(n)) = (old, new) {
        outln!("  RCM in the base frame moved by {:.3} mm: ({:.4}, {:.4}, {:.4}) m", (n - o).norm() * 1e3, n.x, n.y, n.z);
    }
    Ok(())
}
