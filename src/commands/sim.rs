//! `dvrk sim`: run a scene headless for a duration under a trajectory and print a summary
//! (real-time factor, tracking RMS / max per joint, loop-closure and RCM errors).

use anyhow::{bail, Context, Result};
use clap::Args;
use dvrk_sim::run::TrajectoryKind;
use dvrk_sim::{Colliders, Engine, LoopMode, Outputs, RunOptions, Scene, SimOptions};


/// The default scene: the whole cart (SUJ held, PSMs on the tracking test, ECM holding).
const DEFAULT_SCENE: &str = "full";
/// Default simulated time (s): one period of the 0.1 Hz tracking sine; the full scene runs at a
/// real-time factor of ~70 on the reduced engine (~3 on rapier; criterion bench
/// `rtf/full_1s_sine_reduced`), so a fraction of a second of wall time.
const DEFAULT_DURATION: f64 = 10.0;

#[derive(Debug, Args)]
pub struct SimArgs {
    /// Built-in scene (full, full-camera, 3psm, 2psm-ecm, psm, ecm) or a scene file (.toml).
    #[arg(long, default_value = DEFAULT_SCENE)]
    pub scene: String,
    /// Simulated time (s).
    #[arg(long, default_value_t = DEFAULT_DURATION)]
    pub duration: f64,
    /// Record the run as MCAP (ROS 2 CDR on the dVRK's CRTK topics, Foxglove transforms).
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
    /// Recording rate (Hz of simulated time), with --out or --live: one sample every whole number
    /// of time steps (another rate is refused, naming the two on either side).
    #[arg(long, default_value_t = dvrk_sim::RecordOptions::DEFAULT_RATE)]
    pub rate: f64,
    /// sine (the paper's section 4.3 tracking test), hold (home), or replay:FILE (the joint
    /// setpoints of a recording: an MCAP's /<ARM>/setpoint_js, else /<ARM>/measured_js, for each
    /// arm; or a plain CSV with time,q1..qN for the scene's one tracked arm). Replayed arms start
    /// on their first sample; the others hold home.
    #[arg(long, default_value = "sine")]
    pub trajectory: String,
    /// Use another model for an arm: ARM=MODEL (a built-in name or a model file, e.g. the
    /// output of `dvrk calib apply`), keeping the arm's mount, inertials and gains. Repeatable.
    #[arg(long, value_name = "ARM=MODEL")]
    pub model: Vec<String>,
    /// Close the loops with impulse joints (default) or follow the passive joints by coupling.
    #[arg(long, default_value = "impulse-joints", value_parser = ["impulse-joints", "dof-coupling"])]
    pub loops: String,
    /// Solver iterations (substeps) per step; the scene's value when absent.
    #[arg(long)]
    pub solver_iterations: Option<usize>,
    /// Step the independent arm groups (each arm on the cart with what it carries) on separate
    /// threads; results are the same as the sequential run (rapier; the reduced engine's steps
    /// are too small a task for threads and ignore it).
    #[arg(long)]
    pub parallel: bool,
    /// Draw the tracking of the tracked joints (the PSMs on the sine) as a PNG or SVG like the
    /// paper's Figure 10: per joint, commanded vs measured position (left) and the error (right).
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// Sampling rate of --plot (Hz of simulated time).
    #[arg(long, default_value_t = 50.0)]
    pub plot_rate: f64,
    /// Write each camera frame of a scene with a camera (full-camera) as PNG files in this directory:
    /// left_000001.png, right_000001.png (colour) and left_depth_000001.png, right_depth_000001.png
    /// (16-bit depth in mm).
    #[arg(long)]
    pub frames_dir: Option<std::path::PathBuf>,
    /// Physics engine: reduced (forward dynamics in the actuated joints, loops exact; 10x
    /// rapier's speed) or rapier (the multibody with impulse-closed loops; contacts). When
    /// absent: the scene file's `engine`, else rapier with --contacts, --loops or
    /// --solver-iterations (its options), else reduced.
    #[arg(long, value_parser = ["rapier", "reduced"])]
    pub engine: Option<String>,
    /// Let the link geometry of different arms in one rapier world touch (contacts are off by
    /// default, as in the paper).
    #[arg(long)]
    pub contacts: bool,
    /// Serve the running simulation live over the Foxglove WebSocket protocol (Foxglove,
    /// Lichtblick: open a connection to ws://HOST:PORT): the recording's topics (CRTK joint
    /// states, poses, /tf) sampled at --rate. HOST:PORT, PORT or HOST; 127.0.0.1:8765 when given
    /// no value. Pair it with --realtime and a long --duration to watch; Ctrl-C stops cleanly.
    #[arg(long, value_name = "HOST:PORT", num_args = 0..=1, default_missing_value = "")]
    pub live: Option<String>,
    /// Pace the simulation to wall-clock time (1: real time; 0.5: half speed); without it the
    /// simulation runs as fast as it can and the live view samples it.
    #[arg(long, value_name = "FACTOR", num_args = 0..=1, default_missing_value = "1")]
    pub realtime: Option<f64>,
    /// Brake the setup joints: each arm a setup-joint arm carries is held on a fixed base where
    /// the setup joints put it (as the cart's brakes hold them), not on six position drives;
    /// about twice as fast on the full cart (docs/engines.md). The scene file's
    /// `brake_setup_joints = true` does the same.
    #[arg(long)]
    pub brake_suj: bool,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// The engine a run uses: the flag's, the scene file's, rapier when a rapier option is given,
/// else the reduced engine (the fastest that holds the scene's physics: the cross-checks of
/// `crates/dvrk-sim/tests/sim/reduced.rs`).
fn engine(args: &SimArgs, scene: &Scene) -> Engine {
    match (args.engine.as_deref(), scene.engine) {
        // (clap takes only the engines' names.)
        (Some(name), _) => Engine::from_name(name).unwrap_or_default(),
        (None, Some(e)) => e,
        (None, None) if args.contacts || args.loops != "impulse-joints" || args.solver_iterations.is_some() => Engine::Rapier,
        (None, None) => Engine::Reduced,
    }
}

/// Start the Foxglove live view `--live` asks for (`HOST:PORT`, `PORT`, or empty: the default)
/// and say where, on stderr (stdout stays the summary: --json scripts read it).
pub fn start_live(address: &str, scene: &str) -> Result<dvrk_sim::Live> {
    let options = dvrk_sim::LiveOptions::parse(address).map_err(anyhow::Error::msg)?;
    let live = dvrk_sim::Live::serve(&options, &format!("dvrk-twin {scene}"))?;
    eprintln!("live: serving {} (Foxglove WebSocket protocol): open it in Foxglove or Lichtblick; Ctrl-C stops", live.url());
    Ok(live)
}

/// Load `--scene` (its error names the file and field: one line, the flag in front) and print
/// what loading noted on stderr.
pub fn load_scene(scene: &str) -> Result<Scene> {
    let scene = Scene::load(scene).map_err(|e| anyhow::anyhow!("--scene: {e}"))?;
    for n in &scene.notes {
        eprintln!("note: {n}");
    }
    Ok(scene)
}

pub fn run(args: &SimArgs) -> Result<()> {
    if !(args.duration.is_finite() && args.duration > 0.0) {
        bail!("--duration {}: must be a positive number of seconds", args.duration);
    }
    if let Some(n) = args.solver_iterations {
        if n == 0 || n > 1000 {
            bail!("--solver-iterations {n}: must be in 1..=1000");
        }
    }
    // Outputs are checked before any work: none is an input or another output, each in an
    // existing directory.
    let replay = args.trajectory.strip_prefix("replay:").map(std::path::Path::new);
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("--scene", std::path::Path::new(&args.scene))];
    inputs.extend(replay.map(|p| ("--trajectory replay:", p)));
    inputs.extend(args.model.iter().filter_map(|m| m.split_once('=')).map(|(_, f)| ("--model", std::path::Path::new(f))));
    crate::io::check_outputs(&inputs, &[("--out", args.out.as_deref()), ("--plot", args.plot.as_deref())])?;
    if !(args.rate.is_finite() && args.rate > 0.0) {
        bail!("--rate {}: must be a positive number of samples per second", args.rate);
    }
    if !(args.plot_rate.is_finite() && args.plot_rate > 0.0) {
        bail!("--plot-rate {}: must be a positive number of samples per second", args.plot_rate);
    }
    crate::io::check_plot(args.plot.as_deref())?;
    // The trajectory's kind now; a replay's file is read against the scene below.
    enum TrajectoryArg<'a> {
        Kind(TrajectoryKind),
        Replay(&'a std::path::Path),
    }
    let trajectory_arg = match (args.trajectory.as_str(), replay) {
        ("sine", _) => TrajectoryArg::Kind(TrajectoryKind::Sine),
        ("hold", _) => TrajectoryArg::Kind(TrajectoryKind::Hold),
        (_, Some(path)) => TrajectoryArg::Replay(path),
        (t, None) => bail!("--trajectory {t}: unknown (valid: sine, hold, replay:FILE)"),
    };
    let mut scene = load_scene(&args.scene)?;
    if args.brake_suj && scene.brake_setup_joints() == 0 {
        bail!("--brake-suj: scene `{}` has no setup joints carrying an arm", scene.name);
    }
    for m in &args.model {
        let Some((arm, file)) = m.split_once('=') else { bail!("--model {m}: expected ARM=MODEL (a built-in model or a file), e.g. PSM1=my-psm.toml") };
        let a = scene.arm_index(arm).with_context(|| format!("--model {m}"))?;
        let model = dvrk_kin::load(file, None).with_context(|| format!("--model {m}"))?;
        scene.set_model(a, model).with_context(|| format!("--model {m}"))?;
    }
    let trajectory = match trajectory_arg {
        TrajectoryArg::Kind(kind) => kind,
        TrajectoryArg::Replay(path) => TrajectoryKind::Replay(dvrk_calib::replay::read_replay(path, &scene).map_err(|e| anyhow::anyhow!("--trajectory {}: {e}", args.trajectory))?),
    };
    let loops = if args.loops == "dof-coupling" { LoopMode::DofCoupling } else { LoopMode::ImpulseJoints };
    let options = RunOptions {
        duration: args.duration,
        trajectory,
        sim: SimOptions {
            loops,
            solver_iterations: args.solver_iterations,
            parallel: args.parallel,
            colliders: if args.contacts { Colliders::Contacts } else { Colliders::NoContacts },
            engine: Some(engine(args, &scene)),
            ..Default::default()
        },
    };
    let record = args.out.as_ref().map(|p| dvrk_sim::RecordOptions { path: p.clone(), rate: args.rate });
    let trace_rate = args.plot.as_ref().map(|_| args.plot_rate);
    if let Some(d) = &args.frames_dir {
        if scene.camera.is_none() {
            bail!("--frames-dir {}: scene {} has no camera (full-camera has one)", d.display(), args.scene);
        }
        // The directory itself is made if absent, never its parents.
        if !d.is_dir() {
            std::fs::create_dir(d).with_context(|| format!("--frames-dir {}: cannot create it (its parent must exist)", d.display()))?;
        }
    }
    // A long run stops cleanly on SIGINT/SIGTERM: its recording holds what ran.
    let stop = crate::signals::stop_flag();
    if let Some(f) = args.realtime {
        if !(f.is_finite() && f > 0.0) {
            bail!("--realtime {f}: must be a positive factor of wall-clock time (1: real time)");
        }
    }
    let live = args.live.as_deref().map(|a| start_live(a, &args.scene)).transpose()?.map(|l| std::sync::Mutex::new(Some(l)));
    let outputs = Outputs { record: record.as_ref(), trace_rate, frames_dir: args.frames_dir.as_deref(), stop: Some(stop), live: live.as_ref(), realtime: args.realtime };
    // Simulated time and the real-time factor so far (`--json`: nothing drawn).
    let started = std::time::Instant::now();
    let bar = crate::progress::Progress::bar(1000, "{bar:40} {percent:>3}% {msg}", crate::progress::Progress::wanted(args.json));
    let run = dvrk_sim::run_staged(&scene, &options, &outputs, |f| {
        bar.set_position((f * 1000.0) as u64);
        let simulated = f * args.duration;
        bar.set_message(format!("{simulated:.1} of {:.1} s simulated, {:.0}x real time", args.duration, simulated / started.elapsed().as_secs_f64().max(1e-9)));
    })?;
    bar.finish();
    let (summary, trace) = (run.summary, run.trace);
    if stop.load(std::sync::atomic::Ordering::SeqCst) {
        eprintln!("stopped by a signal after {:.3} s of simulated time: the outputs hold the run up to then", summary.duration);
    }
    // A run that went non-finite replaces no output; otherwise every output is committed together.
    if !summary.finite {
        if args.json {
            println!("{}", serde_json::to_string(&summary)?);
        }
        bail!("the simulation went non-finite (at most {:.6e} m loop-closure gap, at {:.3} s); no output was written", summary.max_closure_error, summary.max_closure_time);
    }
    let mut staged: Vec<dvrk_kin::atomic::Staged> = run.recording.into_iter().collect();
    if let (Some(p), Some(trace)) = (&args.plot, &trace) {
        let title = format!("{} {}: commanded blue, measured orange, error green", summary.scene, summary.trajectory);
        let image = trace.figure(&title);
        staged.push(crate::io::stage(p, &image.encode(p)?).with_context(|| format!("--plot {}", p.display()))?);
    }
    dvrk_kin::atomic::commit_all(staged)?;
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
        return Ok(());
    }
    println!(
        "scene {} ({}), trajectory {}, {:.1} s simulated in {:.2} s: real-time factor {:.1}",
        summary.scene, scene.title, summary.trajectory, summary.duration, summary.wall_time, summary.real_time_factor
    );
    match summary.engine {
        Engine::Rapier => println!("engine rapier, dt {} s, {} solver iterations, loops: {:?}", summary.dt, summary.solver.iterations, summary.loops),
        Engine::Reduced => println!("engine reduced (loops exact), dt {} s", summary.dt),
    }
    println!("{:>8} {:<20} {:>12} {:>12} {:>12}", "arm", "joint", "rms error", "max error", "max effort");
    for j in &summary.joints {
        println!("{:>8} {:<20} {:>10.3e} {:<3} {:>8.3e} {:<3} {:>10.3}", j.arm, j.joint, j.rms_error, j.unit, j.max_error, j.unit, j.max_effort);
    }
    println!(
        "loop closure: max {:.3e} m, last 10% {:.3e} m; RCM: max {:.3e} m",
        summary.max_closure_error, summary.final_closure_error, summary.max_rcm_error
    );
    if let Some(c) = &summary.camera {
        println!(
            "camera: {} stereo frames at {} Hz, {:.1} ms per frame (both eyes), {:.2} s of the wall time",
            c.frames,
            c.rate_hz,
            c.time_per_frame * 1e3,
            c.render_time
        );
    }
    if let Some(d) = &args.frames_dir {
        println!("wrote the camera frames to {}", d.display());
    }
    if let Some(p) = &args.plot {
        println!("plotted {}", p.display());
    }
    if let Some(p) = &args.out {
        println!("recorded {} at {} Hz", p.display(), args.rate);
    }
    for n in &summary.notes {
        println!("note: {n}");
    }
    Ok(())
}
