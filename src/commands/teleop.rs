//! `dvrk teleop`: a recorded MTM (MCAP or ROS 1 bag) driving a simulated PSM through the
//! console's follow mode (dvrk_sim::teleop, dvrk_sim::teleop_replay), the run recorded as the
//! dVRK publishes it.

use anyhow::{bail, Context, Result};
use clap::Args;
use dvrk_sim::teleop::{Align, TeleopConfig};
use dvrk_sim::teleop_replay::{camera_frame, plan, MtmMotion};
use dvrk_sim::{Engine, Outputs, RunOptions, SimOptions};
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct TeleopArgs {
    /// The MTM's recording (MCAP or ROS 1 bag): /MTMR/measured_cp, /MTMR/gripper/measured_js,
    /// /footpedals/clutch (the dVRK 1.x names under /dvrk are read too).
    #[arg(long)]
    pub mtm: PathBuf,
    /// The MTM in the recording (MTML, MTMR); the only one it holds when absent.
    #[arg(long)]
    pub arm: Option<String>,
    /// Scene (built-in name or file) with the PSM to drive.
    #[arg(long, default_value = "psm")]
    pub scene: String,
    /// The PSM to drive; the scene's first PSM when absent.
    #[arg(long)]
    pub psm: Option<String>,
    /// The ECM whose camera frame the motion is in: the scene's ECM when absent, `none` for the
    /// PSM's own measured_cp frame.
    #[arg(long)]
    pub ecm: Option<String>,
    /// refuse: follow only once the MTM's orientation is within the start tolerance of the PSM's
    /// (the console's default); offset: keep the difference at follow start (its alignment offset).
    #[arg(long, default_value = "refuse", value_parser = ["refuse", "offset"])]
    pub align: String,
    /// PSM translation per MTM translation.
    #[arg(long, default_value_t = 0.2)]
    pub scale: f64,
    /// Largest orientation difference at which following starts (deg).
    #[arg(long, default_value_t = 5.0)]
    pub start_tolerance: f64,
    /// Simulated time (s); the recording's duration when absent.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Record the run here (MCAP, the dVRK's CRTK topics).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Recording rate (Hz).
    #[arg(long, default_value_t = dvrk_sim::RecordOptions::DEFAULT_RATE)]
    pub rate: f64,
    /// Also serve the run to Foxglove or Lichtblick (WebSocket) on HOST:PORT (127.0.0.1:8765 by
    /// default), paced to real time unless --realtime says otherwise.
    #[arg(long, num_args = 0..=1, default_missing_value = "")]
    pub live: Option<String>,
    /// Pace the run to this many times wall-clock time (1: as recorded).
    #[arg(long)]
    pub realtime: Option<f64>,
    /// Print the result as one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &TeleopArgs) -> Result<()> {
    crate::io::check_outputs(&[("--mtm", args.mtm.as_path()), ("--scene", std::path::Path::new(&args.scene))], &[("--out", args.out.as_deref())])?;
    if !(args.scale.is_finite() && args.scale > 0.0) {
        bail!("--scale {}: must be a positive number", args.scale);
    }
    if !(args.start_tolerance.is_finite() && args.start_tolerance > 0.0 && args.start_tolerance <= 180.0) {
        bail!("--start-tolerance {}: must be in (0, 180] deg", args.start_tolerance);
    }
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate {}: must be a positive number of samples per second", args.rate);
    }
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration {d}: must be a positive number of seconds");
        }
    }
    let scene = crate::commands::sim::load_scene(&args.scene)?;
    let psm = match &args.psm {
        Some(name) => scene.arm_index(name).with_context(|| format!("--psm {name}"))?,
        None => super::first_arm_of(&scene, "psm").with_context(|| format!("--scene {}: no PSM to drive", args.scene))?,
    };
    let ecm = match args.ecm.as_deref() {
        Some("none") => None,
        Some(name) => Some(scene.arm_index(name).with_context(|| format!("--ecm {name}"))?),
        None => super::first_arm_of(&scene, "ecm"),
    };
    let log = dvrk_sim::recording::read_mtm(&args.mtm, args.arm.as_deref()).map_err(|e| anyhow::anyhow!("--mtm: {e}"))?;
    let notes: Vec<String> = log.notes.iter().map(|n| format!("{}: {n}", args.mtm.display())).collect();
    if !args.json {
        for n in &notes {
            eprintln!("note: {n}");
        }
    }
    let config = TeleopConfig {
        scale: args.scale,
        start_tolerance_rad: args.start_tolerance.to_radians(),
        align: if args.align == "offset" { Align::Offset } else { Align::Refuse },
        ..TeleopConfig::default()
    };
    let (camera, camera_name) = camera_frame(&scene, psm, ecm)?;
    let motion = MtmMotion { t: &log.t, poses: &log.poses, gripper: log.gripper.as_deref(), clutch: &log.clutch };
    let follow = plan(&scene, psm, &camera, &camera_name, &motion, &config)?;
    let r = &follow.report;
    let psm_name = &scene.arms[psm].name;
    if r.following_from.is_none() {
        if r.clutched_s > 0.0 && r.misaligned_s == 0.0 {
            bail!("--mtm {}: the clutch is pressed throughout; {psm_name} never follows", args.mtm.display());
        }
        bail!(
            "--mtm {}: {}'s orientation never comes within {} deg of {psm_name}'s (at the start {:.1} deg, closest {:.1} deg at {:.2} s): the console does not follow until aligned; --align offset keeps the difference",
            args.mtm.display(),
            log.arm,
            args.start_tolerance,
            r.misalignment_at_start_deg,
            r.closest_alignment_deg,
            r.closest_alignment_at
        );
    }
    let duration = args.duration.unwrap_or(log.duration().max(scene.dt));
    let options = RunOptions {
        duration,
        trajectory: dvrk_sim::run::TrajectoryKind::Replay(dvrk_sim::run::Replay { source: args.mtm.display().to_string(), arms: vec![(psm_name.clone(), follow.trajectory.clone())] }),
        sim: SimOptions { engine: Some(scene.engine.unwrap_or(Engine::Reduced)), ..Default::default() },
    };
    let record = args.out.as_ref().map(|p| dvrk_sim::RecordOptions { path: p.clone(), rate: args.rate });
    if let Some(f) = args.realtime {
        if !(f.is_finite() && f > 0.0) {
            bail!("--realtime {f}: must be a positive factor of wall-clock time (1: as recorded)");
        }
    }
    let stop = crate::signals::stop_flag();
    let live = args.live.as_deref().map(|a| crate::commands::sim::start_live(a, &args.scene)).transpose()?.map(|l| std::sync::Mutex::new(Some(l)));
    // A live view is watched as it happens: real time unless asked otherwise.
    let realtime = args.realtime.or(live.as_ref().map(|_| 1.0));
    let outputs = Outputs { record: record.as_ref(), stop: Some(stop), live: live.as_ref(), realtime, ..Default::default() };
    let run = dvrk_sim::run_staged(&scene, &options, &outputs, |_| {})?;
    if !run.summary.finite {
        bail!("the simulation went non-finite; no output was written");
    }
    dvrk_kin::atomic::commit_all(run.recording.into_iter().collect())?;
    let summary = run.summary;
    if args.json {
        let mtm = serde_json::json!({
            "file": args.mtm.display().to_string(),
            "arm": log.arm,
            "topics": { "pose": log.topics.pose, "gripper": log.topics.gripper, "clutch": log.topics.clutch },
            "frame_id": log.frame_id,
            "samples": log.len(),
            "duration": log.duration(),
            "notes": log.notes,
        });
        crate::outln!("{}", serde_json::json!({ "mtm": mtm, "follow": follow.report, "run": summary }));
        return Ok(());
    }
    let r = &follow.report;
    crate::outln!("{} ({} samples over {:.2} s from {}) -> {psm_name} of scene {}, in {}", log.arm, log.len(), log.duration(), log.topics.pose, summary.scene, r.camera_frame);
    crate::outln!(
        "following from {:.2} s: {:.2} s following, {:.2} s clutched ({} presses), {:.2} s waiting for alignment (at the start {:.1} deg off)",
        r.following_from.unwrap_or(f64::NAN),
        r.following_s,
        r.clutched_s,
        r.clutch_presses,
        r.misaligned_s,
        r.misalignment_at_start_deg
    );
    crate::outln!("commanded tip path {:.4} m; jaw {}; IK misses {}{}", r.tip_path_m, r.jaw_range.map_or("held (no gripper)".into(), |j| format!("{:.3}..{:.3} rad", j[0], j[1])), r.ik_misses, r.first_ik_miss.as_ref().map_or(String::new(), |m| format!(" (first {m})")));
    crate::outln!("simulated {:.2} s in {:.2} s (real-time factor {:.1})", summary.duration, summary.wall_time, summary.real_time_factor);
    for j in summary.joints.iter().filter(|j| &j.arm == psm_name) {
        crate::outln!("  {:<20} tracking rms {:.3e} {}, max {:.3e}", j.joint, j.rms_error, j.unit, j.max_error);
    }
    if let Some(p) = &args.out {
        crate::outln!("recorded {} at {} Hz", p.display(), args.rate);
    }
    for n in summary.notes.iter() {
        crate::outln!("note: {n}");
    }
    Ok(())
}
