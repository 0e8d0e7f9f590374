//! `dvrk serve`: a scene as a live twin on ROS 2, in real time: the dVRK console's topics out,
//! its commands in (`dvrk_sim::serve`).

use anyhow::{bail, Context, Result};
use clap::Args;
use dvrk_sim::ros2::Ros2Options;
use dvrk_sim::serve::ServeOptions;
use dvrk_sim::{Engine, SimOptions};

#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Built-in scene (psm, ecm, full, ...) or a scene file (.toml).
    #[arg(long, default_value = "psm")]
    pub scene: String,
    /// DDS domain (0..=232); default: ROS_DOMAIN_ID, else 0.
    #[arg(long)]
    pub domain: Option<u16>,
    /// Messages per second on every topic (Hz): one every whole number of time steps (1000, 500,
    /// 333.333, 250, 200, ... at 1 ms steps); another rate is refused.
    #[arg(long, default_value_t = 200.0)]
    pub rate: f64,
    /// Physics engine: reduced (default) or rapier.
    #[arg(long, default_value = "reduced")]
    pub engine: String,
    /// Also record the run as MCAP (the same topics, and Foxglove's /tf and /scene).
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Simulated seconds to serve; until Ctrl-C when absent.
    #[arg(long)]
    pub duration: Option<f64>,
    /// An interface address to serve on besides loopback (repeatable). Without it nothing
    /// leaves this machine.
    #[arg(long = "network")]
    pub networks: Vec<std::net::IpAddr>,
    /// Add the model's gravity torque to every arm's controller (PID and servo_jf efforts), as
    /// the dVRK's gravity compensation does.
    #[arg(long)]
    pub gravity_compensation: bool,
    /// Also serve the run to Foxglove or Lichtblick (WebSocket), on HOST:PORT (127.0.0.1:8765
    /// by default): the same pacing loop feeds both.
    #[arg(long, num_args = 0..=1, default_missing_value = "")]
    pub live: Option<String>,
    /// Teleoperation: this MTM's topics on ROS 2 (/MTM/measured_cp, /MTM/gripper/measured_js and
    /// the clutch pedal), as a dVRK console publishes them, drive a PSM of the scene through the
    /// console's follow mode.
    #[arg(long, value_name = "MTM")]
    pub teleop: Option<String>,
    /// The PSM that follows (--teleop); the scene's first PSM when absent.
    #[arg(long, requires = "teleop")]
    pub teleop_psm: Option<String>,
    /// The ECM whose camera frame the motion is in (--teleop): the scene's ECM when absent,
    /// `none` for the PSM's own measured_cp frame.
    #[arg(long, requires = "teleop")]
    pub teleop_ecm: Option<String>,
    /// refuse: follow only once aligned within 5 deg (the console's default); offset: keep the
    /// orientation difference at follow start.
    #[arg(long, default_value = "refuse", value_parser = ["refuse", "offset"], requires = "teleop")]
    pub align: String,
    /// PSM translation per MTM translation (--teleop).
    #[arg(long, default_value_t = 0.2, requires = "teleop")]
    pub scale: f64,
    /// The clutch pedal's topic (sensor_msgs/Joy).
    #[arg(long, default_value = "/footpedals/clutch", requires = "teleop")]
    pub clutch_topic: String,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &ServeArgs) -> Result<()> {
    let engine = match args.engine.as_str() {
        "reduced" => Engine::Reduced,
        "rapier" => Engine::Rapier,
        e => bail!("--engine {e}: unknown (valid: reduced, rapier)"),
    };
    crate::io::check_outputs(&[("--scene", std::path::Path::new(&args.scene))], &[("--out", args.out.as_deref())])?;
    let domain = match args.domain {
        Some(d) => d,
        None => Ros2Options::domain_from_env()?,
    };
    if domain > Ros2Options::MAX_DOMAIN {
        bail!("--domain {domain}: must be in 0..={}", Ros2Options::MAX_DOMAIN);
    }
    // Every flag is checked: now the scene.
    let scene = super::sim::load_scene(&args.scene)?;
    let teleop = match &args.teleop {
        Some(mtm) => {
            if !(args.scale.is_finite() && args.scale > 0.0) {
                bail!("--scale {}: must be a positive number", args.scale);
            }
            let kind = |k: &str| super::first_arm_of(&scene, k).map(|a| scene.arms[a].name.clone());
            let psm = match &args.teleop_psm {
                Some(p) => p.clone(),
                None => kind("psm").with_context(|| format!("--teleop: scene {} has no PSM to drive", args.scene))?,
            };
            let ecm = match args.teleop_ecm.as_deref() {
                Some("none") => None,
                Some(e) => Some(e.to_string()),
                None => kind("ecm"),
            };
            let config = dvrk_sim::teleop::TeleopConfig {
                scale: args.scale,
                align: if args.align == "offset" { dvrk_sim::teleop::Align::Offset } else { dvrk_sim::teleop::Align::Refuse },
                ..Default::default()
            };
            Some(dvrk_sim::serve_teleop::ServeTeleop { mtm: mtm.clone(), psm, ecm, clutch_topic: args.clutch_topic.clone(), config })
        }
        None => None,
    };
    let options = ServeOptions {
        duration: args.duration,
        rate: args.rate,
        ros2: Ros2Options { domain, networks: args.networks.clone(), node: "dvrk_twin".into() },
        record: args.out.as_ref().map(|p| dvrk_sim::RecordOptions { path: p.clone(), rate: args.rate }),
        gravity_compensation: args.gravity_compensation,
        teleop,
    };
    let stop = crate::signals::stop_flag();
    let sim_options = SimOptions { engine: Some(engine), ..Default::default() };
    let live = args.live.as_deref().map(|a| super::sim::start_live(a, &args.scene)).transpose()?;
    let (summary, staged) = dvrk_sim::serve::serve(&scene, &sim_options, &options, stop, live, |node| {
        let arms: Vec<&str> = scene.arms.iter().map(|a| a.name.as_str()).collect();
        eprintln!("serving {} on ROS 2 domain {} ({}), {} Hz; Ctrl-C stops", arms.join(", "), node.domain(), if args.networks.is_empty() { "loopback only" } else { "loopback and --network" }, args.rate);
    })?;
    if let (Some(staged), Some(out)) = (staged, &args.out) {
        staged.commit().with_context(|| format!("--out {}", out.display()))?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "served {:.3} s in {:.3} s of wall time: {} steps, {} messages per topic, {} commands applied, {} refused; worst lag {:.2} ms; warning lines dropped: {} on stderr, {} on /rosout",
            summary.simulated,
            summary.wall,
            summary.steps,
            summary.samples,
            summary.commands,
            summary.refused,
            summary.worst_lag * 1e3,
            summary.stderr_dropped,
            summary.rosout_dropped
        );
        if let Some(t) = &summary.teleop {
            println!(
                "teleoperation of {} in {}: {} MTM poses, following {:.2} s, clutched {:.2} s ({} presses), waiting for alignment {:.2} s; IK misses {}",
                t.psm, t.camera_frame, t.samples, t.following_s, t.clutched_s, t.clutch_presses, t.misaligned_s, t.ik_misses
            );
        }
    }
    Ok(())
}
