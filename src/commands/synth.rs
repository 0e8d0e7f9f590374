//! `dvrk synth`: synthetic recordings for tests and demos. `synth mocap` writes what a real
//! tracker would record of a robot model: three-marker rigid bodies on the PSM links of the
//! paper's Figure 5, marker noise, occlusions, a tracker frame the fits do not know.

use crate::outln;
use anyhow::{anyhow, bail, Result};
use clap::{Args, Subcommand};
use dvrk_sim::recording::McapLayout;
use dvrk_calib::mocap::synth::{Scenario, SynthMotion, SynthOptions};
use serde_json::json;
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum SynthCommand {
    /// A synthetic motion-capture recording (.mcap or plain .csv).
    Mocap(MocapArgs),
    /// A joint recording (.mcap: /<ARM>/setpoint_js, /<ARM>/measured_js with efforts, and a
    /// tracked marker's poses with --marker-link; or .csv: time,q1..qN,tau1..tauN,
    /// setpoint1..setpointN) of an arm with one or two hidden physical effects (or none), and the
    /// answer in a separate JSON file.
    HiddenEffect(HiddenEffectArgs),
}

#[derive(Debug, Args)]
pub struct HiddenEffectArgs {
    /// The arm's scene (built-in: psm); its first arm is simulated.
    #[arg(long, default_value = "psm")]
    pub model: String,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// none, random, random-pair, an effect (coulomb_friction, viscous_friction, spring,
    /// joint_compliance, backlash, latency, joint_offset, payload_mass, coupling_error;
    /// counterweight_error and the wrist's actuator_coulomb_friction, actuator_viscous_friction
    /// by name only; with --marker-link also link_length, clock_offset (the tracker's clock 5-30
    /// ms off either way) and motion_play (0.2-0.6 deg of play by motion direction on the outer
    /// yaw or pitch)) or two joined by `+`.
    #[arg(long, default_value = "random")]
    pub effect: String,
    /// Effort noise per joint (N·m, N), comma-separated; about 1% of each joint's effort when absent.
    #[arg(long)]
    pub noise: Option<String>,
    /// Encoder noise (rad, m).
    #[arg(long, default_value_t = dvrk_calib::discrepancy::generate::POSITION_NOISE)]
    pub position_noise: f64,
    /// Set the noise of each effect's joint so the effect's RMS is this many times it.
    #[arg(long)]
    pub enr: Option<f64>,
    /// Recorded time (s).
    #[arg(long, default_value_t = 30.0)]
    pub duration: f64,
    /// Add a tracker (100 Hz, 0.1 mm, 1 mrad; placed at random) following a marker on this link
    /// (frame name or the paper's number): the kinematic channel, on the pose topic the answer
    /// names (in a CSV: pose columns NAME.x .. NAME.qw, NAME the topic's body name).
    #[arg(long)]
    pub marker_link: Option<String>,
    /// Where a hidden payload sits: `any` (a moving body drawn by the seed, near its centre of
    /// mass) or a frame name; default the tool's yaw link.
    #[arg(long)]
    pub payload_link: Option<String>,
    /// The truth's physics engine: rapier (shares no dynamics code with the analysis) or reduced
    /// (dvrk-kin's forward dynamics, about 16x faster; the answer says `truth_engine`).
    #[arg(long, value_parser = ["rapier", "reduced"], default_value = "rapier")]
    pub engine: String,
    /// Output recording: .mcap or .csv (`dvrk discrepancy --format csv`), written whole or not at
    /// all.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The answer (JSON): `effects`, each with its joint or link, parameters, effect-to-noise ratio.
    #[arg(long)]
    pub answer: PathBuf,
}

#[derive(Debug, Args)]
pub struct MocapArgs {
    /// The robot: built-in name or model file (a PSM layout: frames 2, 3, 4, 6, 7, 8).
    #[arg(long, default_value = "psm")]
    pub model: String,
    /// q1q2-sweep (pivot: q1 and q2 in a Lissajous sweep) or q2-sweep (axes: q2 alone, q1 = 0).
    #[arg(long, default_value = "q1q2-sweep")]
    pub motion: String,
    /// Marker noise, standard deviation per coordinate (mm).
    #[arg(long, default_value_t = 0.1)]
    pub noise_mm: f64,
    /// Frame rate (Hz).
    #[arg(long, default_value_t = 120.0)]
    pub rate: f64,
    /// Length (s).
    #[arg(long, default_value_t = 20.0)]
    pub duration: f64,
    /// Sweep amplitudes of q1 and q2 (rad), comma-separated.
    #[arg(long, default_value = "0.6,0.8")]
    pub amplitude: String,
    /// Probability that a marker is hidden in a frame.
    #[arg(long, default_value_t = 0.01)]
    pub occlusion: f64,
    /// Probability that a body's frame has a ghost marker 5 mm off.
    #[arg(long, default_value_t = 0.0)]
    pub outliers: f64,
    /// Seed of the noise, occlusions and outliers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// MCAP layout: pose-stamped (/mocap/NAME/pose), tf (/tf), foxglove (foxglove.PoseInFrame in
    /// protobuf on /mocap/NAME/pose) or foxglove-json (the same in JSON).
    #[arg(long, default_value = "pose-stamped")]
    pub layout: String,
    /// Topic of the joint states (sensor_msgs/msg/JointState).
    #[arg(long, default_value = "/PSM1/measured_js")]
    pub joint_topic: String,
    /// Output: .mcap or .csv (plain CSV, with the raw markers), written whole or not at all.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the matching axes configuration (for `calib axes --config`).
    #[arg(long)]
    pub config_out: Option<PathBuf>,
    /// Also write the ground truth (tracker frame, RCM, clusters) as JSON.
    #[arg(long)]
    pub truth: Option<PathBuf>,
}

pub fn run(c: &SynthCommand) -> Result<()> {
    match c {
        SynthCommand::Mocap(a) => mocap(a),
        SynthCommand::HiddenEffect(a) => hidden_effect(a),
    }
}

fn hidden_effect(a: &HiddenEffectArgs) -> Result<()> {
    use dvrk_calib::discrepancy::{hidden_effect, Hidden, HiddenOptions};
    use dvrk_sim::recording;
    let hidden: Hidden = a.effect.parse().map_err(|e| anyhow!("--effect: {e}"))?;
    let effort_noise = a.noise.as_deref().map(|t| crate::io::parse_list("--noise", t)).transpose()?;
    let ext = a.output.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext != "mcap" && ext != "csv" {
        bail!("-o {}: the recording is written as MCAP (.mcap) or plain CSV (.csv)", a.output.display());
    }
    crate::io::check_outputs(&[("--model", std::path::Path::new(&a.model))], &[("-o", Some(&a.output)), ("--answer", Some(&a.answer))])?;
    let marker = a.marker_link.clone().map(|link| dvrk_calib::discrepancy::generate::MarkerOptions { link, ..Default::default() });
    let o = HiddenOptions { hidden, seed: a.seed, duration: a.duration, effort_noise, position_noise: a.position_noise, enr: a.enr, marker, payload_link: a.payload_link.clone(), engine: dvrk_sim::Engine::from_name(&a.engine).unwrap_or_default(), ..Default::default() };
    let spinner = crate::progress::Progress::spinner(&format!("simulating the truth: {} s at 0.125 ms steps", a.duration), crate::progress::Progress::wanted(false));
    let h = hidden_effect(&a.model, &o)?;
    spinner.finish();
    let bytes = match ext.as_str() {
        "csv" => dvrk_sim::recording::write_joint_log_csv(&h.log).into_bytes(),
        _ => recording::write_joint_log_mcap(&h.log, &dvrk_sim::Scene::load(&a.model)?.arms[0].name)?,
    };
    let staged = vec![crate::io::stage(&a.output, &bytes)?, crate::io::stage(&a.answer, format!("{}\n", serde_json::to_string_pretty(&h.answer)?).as_bytes())?];
    dvrk_kin::atomic::commit_all(staged)?;
    let what = match h.answer.effects.is_empty() {
        true => "no effect".to_string(),
        false => h.answer.effects.iter().map(|e| format!("{} (ENR {:.1})", e.spec.name, e.enr)).collect::<Vec<_>>().join(" and "),
    };
    outln!("wrote {} ({} samples, {:.0} s) with {what} hidden; answer in {}", a.output.display(), h.log.len(), a.duration, a.answer.display());
    Ok(())
}

fn mocap(a: &MocapArgs) -> Result<()> {
    crate::io::check_outputs(
        &[("--model", std::path::Path::new(&a.model))],
        &[("-o", Some(&a.output)), ("--config-out", a.config_out.as_deref()), ("--truth", a.truth.as_deref())],
    )?;
    let motion: SynthMotion = a.motion.parse().map_err(|e| anyhow!("--motion: {e}"))?;
    let amp = crate::io::parse_list("--amplitude", &a.amplitude)?;
    let [a1, a2] = amp.as_slice() else { bail!("--amplitude: give two values (q1, q2 in rad), got {}", amp.len()) };
    // (1e308 mm was taken: every marker then fell outside any cluster and the run wrote 0 poses.)
    if !(a.noise_mm.is_finite() && (0.0..=100.0).contains(&a.noise_mm)) {
        bail!("--noise-mm: {} must be in [0, 100] mm (a tracker's noise is a fraction of a millimetre)", dvrk_kin::fmt_number(a.noise_mm));
    }
    let layout = match a.layout.as_str() {
        "pose-stamped" => McapLayout::PoseStamped,
        "tf" => McapLayout::Tf,
        "foxglove-json" => McapLayout::FoxgloveJson,
        "foxglove" => McapLayout::Foxglove,
        other => bail!("--layout: `{other}` is not a layout; valid: pose-stamped, tf, foxglove, foxglove-json"),
    };
    let ext = a.output.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if ext != "mcap" && ext != "csv" {
        bail!("-o {}: unknown format `.{ext}`; valid: .mcap, .csv", a.output.display());
    }
    // Every flag is checked: now the model.
    let model = dvrk_kin::load(&a.model, None)?;
    let options = SynthOptions {
        motion,
        noise: a.noise_mm * 1e-3,
        rate: a.rate,
        duration: a.duration,
        amplitude: [*a1, *a2],
        occlusion: a.occlusion,
        outliers: a.outliers,
        seed: a.seed,
        ..Default::default()
    };
    let scenario = Scenario::new(&model, &options).map_err(|e| anyhow!("synth mocap: {e}"))?;
    let spinner = crate::progress::Progress::spinner("simulating the tracker", crate::progress::Progress::wanted(false));
    let rec = scenario.record(a.seed);
    spinner.finish();
    let bytes = match ext.as_str() {
        "mcap" => dvrk_sim::recording::write_mcap_poses(&rec, layout, &a.joint_topic)?,
        _ => dvrk_sim::recording::write_plain_csv(&rec).into_bytes(),
    };
    let mut staged = vec![crate::io::stage(&a.output, &bytes)?];
    if let Some(c) = &a.config_out {
        staged.push(crate::io::stage(c, scenario.axes_config_toml().as_bytes())?);
    }
    if let Some(t) = &a.truth {
        let clusters: Vec<_> = scenario
            .clusters
            .iter()
            .map(|c| json!({"name": c.name, "link": c.link, "frame": c.frame, "offset": dvrk_kin::pose_to_rows(&c.offset), "markers": c.layout.iter().map(|m| [m.x, m.y, m.z]).collect::<Vec<_>>()}))
            .collect();
        let v = json!({
            "model": model.name,
            "motion": motion.name(),
            "tracker_from_base": dvrk_kin::pose_to_rows(&options.tracker_from_base),
            "rcm": scenario.rcm.map(|r| [r.x, r.y, r.z]),
            "clusters": clusters,
        });
        staged.push(crate::io::stage(t, format!("{}\n", serde_json::to_string_pretty(&v)?).as_bytes())?);
    }
    dvrk_kin::atomic::commit_all(staged)?;
    let frames = scenario.t.len();
    let seen: usize = rec.bodies.iter().map(|b| b.len()).sum();
    outln!(
        "wrote {}: {} rigid bodies x {frames} frames ({:.0} s at {} Hz, {}), {} poses ({} occluded), marker noise {} mm",
        a.output.display(),
        rec.bodies.len(),
        a.duration,
        a.rate,
        motion.name(),
        seen,
        rec.bodies.iter().map(|b| b.occluded).sum::<usize>(),
        a.noise_mm
    );
    Ok(())
}
