//! Running a scene for a duration under a trajectory and summarising it: real-time factor,
//! tracking RMS / max per joint, loop-closure error, RCM error.

use crate::camera::{write_frame_files, StereoCamera};
use crate::error::{Result, SimError};
use crate::recording::{RecordOptions, Recorder};
use crate::sim::{Sim, SimOptions};
use crate::trajectory::Trajectory;
use crate::Scene;
use crate::run_tally::{RcmWatch, Tally};
pub use crate::run_tally::WindowSummary;
use serde::Serialize;
use std::time::Instant;

/// Which reference the arms follow.
#[derive(Debug, Clone, PartialEq)]
pub enum TrajectoryKind {
    /// The paper's tracking test ([`Trajectory::tracking_test`]).
    Sine,
    /// Hold home.
    Hold,
    /// Recorded joint trajectories for some arms; the others hold home.
    Replay(Replay),
}

/// Recorded joint trajectories replayed as setpoints. Each arm starts at its first sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Replay {
    /// Where they came from (a file), for the summary.
    pub source: String,
    /// Arm name and its [`Trajectory::Samples`].
    pub arms: Vec<(String, Trajectory)>,
}

impl TrajectoryKind {
    /// `sine`, `hold` or `replay:SOURCE`.
    pub fn label(&self) -> String {
        match self {
            TrajectoryKind::Sine => "sine".into(),
            TrajectoryKind::Hold => "hold".into(),
            TrajectoryKind::Replay(r) => format!("replay:{}", r.source),
        }
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Simulated time (s).
    pub duration: f64,
    pub trajectory: TrajectoryKind,
    pub sim: SimOptions,
}

/// Tracking of one joint over a run.
#[derive(Debug, Clone, Serialize)]
pub struct JointSummary {
    pub arm: String,
    pub joint: String,
    /// `rad` or `m`
    pub unit: &'static str,
    pub rms_error: f64,
    pub max_error: f64,
    /// Largest |effort| applied (N·m or N).
    pub max_effort: f64,
}

/// Summary of a run (SI units).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    pub scene: String,
    pub trajectory: String,
    /// s
    pub duration: f64,
    pub dt: f64,
    pub steps: u64,
    /// The physics engine that ran.
    pub engine: crate::sim::Engine,
    pub solver: crate::scene::SolverSettings,
    /// Gauss-Seidel sweeps per substep of each arm group (rapier world), which override
    /// `solver.pgs_iterations` for groups whose arms ask for more.
    pub group_pgs_iterations: Vec<usize>,
    pub loops: crate::sim::LoopMode,
    pub closing_links: crate::sim::ClosingLinks,
    /// s of wall time
    pub wall_time: f64,
    /// simulated time / wall time
    pub real_time_factor: f64,
    pub joints: Vec<JointSummary>,
    /// Largest loop-closure gap over the run (m).
    pub max_closure_error: f64,
    /// When that gap occurred (s).
    pub max_closure_time: f64,
    /// Largest gap over the last tenth of the run (m): equal to the max when nothing drifts.
    pub final_closure_error: f64,
    /// Largest distance of an insertion axis from its arm's kinematic RCM (m).
    pub max_rcm_error: f64,
    /// The run in ten equal windows of simulated time, each with its largest loop-closure gap
    /// and RCM distance: the first against the last says whether anything drifts over a long run.
    pub windows: Vec<WindowSummary>,
    /// False if any state went non-finite.
    pub finite: bool,
    /// Amplitudes scaled to the joint limits, and other remarks.
    pub notes: Vec<String>,
    /// The scene's camera, if it has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraSummary>,
}

/// What the camera cost in a run.
#[derive(Debug, Clone, Serialize)]
pub struct CameraSummary {
    /// Stereo frames rendered.
    pub frames: u64,
    /// Hz
    pub rate_hz: f64,
    /// Wall time spent rendering both eyes (s), included in `wall_time`.
    pub render_time: f64,
    /// Mean wall time per stereo frame (s).
    pub time_per_frame: f64,
}

/// Files a run writes besides its summary.
#[derive(Debug, Clone, Default)]
pub struct Outputs<'a> {
    /// Record the run as MCAP.
    pub record: Option<&'a RecordOptions>,
    /// Sample the tracked joints at this rate (Hz) for [`Trace`].
    pub trace_rate: Option<f64>,
    /// Write each camera frame as PNG files here ([`crate::camera::write_frame_files`]).
    pub frames_dir: Option<&'a std::path::Path>,
    /// Stop early once this is set (a SIGINT handler's flag): the run ends after the step under
    /// way, and its summary (with a note) and recording cover the time that ran.
    pub stop: Option<&'a std::sync::atomic::AtomicBool>,
    /// Serve the run live on this view (started by the caller, so it can say where before the
    /// run begins; the run takes it and stops it at the end), at the recording's rate.
    pub live: Option<&'a std::sync::Mutex<Option<crate::live::Live>>>,
    /// Pace the simulation to this many times wall-clock time (1: real time); as fast as it can
    /// when absent.
    pub realtime: Option<f64>,
}

/// A finished run: its summary, its trace, and its recording complete but not yet moved over its
/// destination ([`dvrk_kin::atomic::Staged`]: commit it with the command's other outputs).
#[derive(Debug)]
pub struct Run {
    pub summary: Summary,
    pub trace: Option<Trace>,
    pub recording: Option<dvrk_kin::atomic::Staged>,
}

/// Commanded and measured positions of the tracked joints sampled over a run (for Figure 10).
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Sample times (s).
    pub t: Vec<f64>,
    pub joints: Vec<TraceJoint>,
}

/// One joint of a [`Trace`].
#[derive(Debug, Clone)]
pub struct TraceJoint {
    pub arm: String,
    pub joint: String,
    /// `rad` or `m`
    pub unit: &'static str,
    /// Index in the simulation's joint vector.
    pub index: usize,
    pub commanded: Vec<f64>,
    pub measured: Vec<f64>,
}

impl Trace {
    /// The paper's Figure 10: per joint, commanded (blue) and measured (orange) position on the
    /// left, the error (measured - commanded, green) on the right.
    pub fn figure(&self, title: &str) -> crate::plot::Figure {
        use crate::plot::{Figure, Line, Panel, BLUE, GREEN, ORANGE};
        let series = |v: &[f64]| self.t.iter().copied().zip(v.iter().copied()).collect::<Vec<_>>();
        let mut panels = Vec::with_capacity(2 * self.joints.len());
        for j in &self.joints {
            let name = format!("{} {}", j.arm, j.joint);
            panels.push(Panel {
                title: format!("{name} position"),
                x_label: "time (s)".into(),
                y_label: format!("position ({})", j.unit),
                points: vec![],
                marks: vec![],
                equal: false,
                lines: vec![Line { points: series(&j.commanded), color: BLUE, width: 3, label: "commanded".into() }, Line { points: series(&j.measured), color: ORANGE, width: 1, label: "measured".into() }],
                scatter: vec![],
            });
            let err: Vec<f64> = j.measured.iter().zip(&j.commanded).map(|(m, c)| m - c).collect();
            panels.push(Panel {
                title: format!("{name} error"),
                x_label: "time (s)".into(),
                y_label: format!("error ({})", j.unit),
                points: vec![],
                marks: vec![],
                equal: false,
                lines: vec![Line { points: series(&err), color: GREEN, width: 1, label: "measured - commanded".into() }],
                scatter: vec![],
            });
        }
        Figure { title: title.into(), panels, columns: 2, panel_size: (480, 200) }
    }
}

/// Run `scene` as `options` say; `progress` is called with the fraction done every 1%.
pub fn run(scene: &Scene, options: &RunOptions, progress: impl FnMut(f64)) -> Result<Summary> {
    run_recorded(scene, options, None, progress)
}

/// [`run`], recording the run as MCAP when `record` is given (see [`crate::recording::writer`]).
pub fn run_recorded(scene: &Scene, options: &RunOptions, record: Option<&RecordOptions>, progress: impl FnMut(f64)) -> Result<Summary> {
    run_traced(scene, options, record, None, progress).map(|(s, _)| s)
}

/// [`run_recorded`], also sampling the commanded and measured positions of the tracked joints
/// (those of arms on the sine; every joint when none is) at `trace_rate` Hz of simulated time
/// when given, into buffers allocated before the run.
pub fn run_traced(
    scene: &Scene,
    options: &RunOptions,
    record: Option<&RecordOptions>,
    trace_rate: Option<f64>,
    progress: impl FnMut(f64),
) -> Result<(Summary, Option<Trace>)> {
    run_with(scene, options, &Outputs { record, trace_rate, ..Default::default() }, progress)
}

/// [`run_traced`] with every output; the scene's camera (if any) renders at its own rate inside
/// the loop whether or not its frames are written. The recording is moved over its destination
/// only when the run stayed finite (a failed run replaces nothing).
pub fn run_with(scene: &Scene, options: &RunOptions, outputs: &Outputs, progress: impl FnMut(f64)) -> Result<(Summary, Option<Trace>)> {
    let run = run_staged(scene, options, outputs, progress)?;
    if let Some(r) = run.recording.filter(|_| run.summary.finite) {
        let path = r.target().display().to_string();
        r.commit().map_err(|e| SimError::Io { path, source: std::io::Error::other(e.to_string()) })?;
    }
    Ok((run.summary, run.trace))
}

/// [`run_with`], the recording left staged for the caller to commit with its other outputs.
pub fn run_staged(scene: &Scene, options: &RunOptions, outputs: &Outputs, mut progress: impl FnMut(f64)) -> Result<Run> {
    check(scene, options, outputs)?;
    let (started, replayed) = start_on_replay(scene, &options.trajectory)?;
    let scene = started.as_ref().unwrap_or(scene);
    let mut sim = Sim::new(scene, &options.sim)?;
    let live = outputs.live.and_then(|m| m.lock().ok()?.take());
    let mut recorder = match (outputs.record, live) {
        (None, None) => None,
        (record, live) => Some(Recorder::open(&sim, record, live, record.map_or(RecordOptions::DEFAULT_RATE, |r| r.rate))?),
    };
    let mut camera = scene.camera.as_ref().map(|c| StereoCamera::new(c, &sim, &scene.file)).transpose()?;
    if let Some(c) = camera.as_mut() {
        c.parallel = options.sim.parallel;
    }
    if let (Some(r), Some(_)) = (recorder.as_mut(), camera.as_ref()) {
        r.add_camera()?;
    }
    let (mut png, mut scratch) = (Vec::new(), Vec::new());
    let (trajectories, mut notes) = references(&sim, &options.trajectory, &replayed);
    let rcm = RcmWatch::new(&sim);
    let n = sim.nq();
    let steps = (options.duration / sim.dt).round().max(1.0) as u64;
    let (mut qr, mut qdr) = (vec![0.0; n], vec![0.0; n]);
    let mut tally = Tally::new(n, steps, sim.dt);
    let every = (steps / 100).max(1);
    let mut trace = outputs.trace_rate.map(|rate| Trace::for_run(&sim, &trajectories, rate, steps));
    let start = Instant::now();
    let mut pacer = outputs.realtime.map(crate::pace::Pacer::new);
    let mut done = steps;
    for s in 0..steps {
        let t = (s + 1) as f64 * sim.dt;
        for (a, traj) in trajectories.iter().enumerate() {
            let off = sim.arms[a].q_offset;
            let nk = sim.arms[a].model.nq();
            traj.sample(t, &mut qr[off..off + nk], &mut qdr[off..off + nk]);
        }
        for i in 0..n {
            sim.set_target(i, qr[i], qdr[i])?;
        }
        sim.step();
        if let Some(r) = recorder.as_mut() {
            r.after_step(&sim, s + 1)?;
        }
        if let Some(cam) = camera.as_mut() {
            if cam.after_step(&sim) {
                if let Some(r) = recorder.as_mut() {
                    r.write_camera(&sim, cam)?;
                }
                if let Some(d) = outputs.frames_dir {
                    write_frame_files(cam, d, &mut png, &mut scratch)?;
                }
            }
        }
        tally.after_step(&sim, s, t, &rcm)?;
        if let Some((stride, tr)) = trace.as_mut() {
            if s % *stride == 0 || s + 1 == steps {
                tr.sample(&sim, t)?;
            }
        }
        if s % every == 0 {
            progress(s as f64 / steps as f64);
        }
        if let Some(p) = pacer.as_mut() {
            p.wait(t);
        }
        if outputs.stop.is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed)) && s + 1 < steps {
            done = s + 1;
            notes.push(format!("stopped at {:.3} s of the {:.3} s asked for; the summary and the recording cover what ran", done as f64 * sim.dt, steps as f64 * sim.dt));
            break;
        }
    }
    let wall = start.elapsed().as_secs_f64();
    let recording = recorder.map(|r| r.finish_staged()).transpose()?.flatten();
    progress(1.0);
    let mut joints = Vec::with_capacity(n);
    for arm in &sim.arms {
        for (k, j) in arm.model.joints.iter().enumerate() {
            let i = arm.q_offset + k;
            joints.push(JointSummary {
                arm: arm.name.clone(),
                joint: j.name.clone(),
                unit: j.unit(),
                rms_error: (tally.sum_sq[i] / done as f64).sqrt(),
                max_error: tally.max_err[i],
                max_effort: tally.max_eff[i],
            });
        }
    }
    let simulated = done as f64 * sim.dt;
    let summary = Summary {
        scene: scene.name.clone(),
        trajectory: options.trajectory.label(),
        duration: simulated,
        dt: sim.dt,
        steps: done,
        engine: sim.engine(),
        solver: scene.solver_settings(&options.sim),
        group_pgs_iterations: sim.group_pgs_iterations(),
        loops: options.sim.loops,
        closing_links: options.sim.closing_links,
        wall_time: wall,
        real_time_factor: simulated / wall.max(1e-12),
        joints,
        max_closure_error: tally.max_closure,
        max_closure_time: tally.max_closure_time,
        final_closure_error: tally.final_closure,
        max_rcm_error: tally.max_rcm,
        windows: tally.windows_reached(done, sim.dt),
        finite: tally.finite,
        notes,
        camera: camera.map(|c| CameraSummary {
            frames: c.frames,
            rate_hz: c.params.rate_hz,
            render_time: c.render_seconds,
            time_per_frame: c.render_seconds / c.frames.max(1) as f64,
        }),
    };
    Ok(Run { summary, trace: trace.map(|(_, t)| t), recording })
}

/// The run's options and outputs checked before the scene is built.
fn check(scene: &Scene, options: &RunOptions, outputs: &Outputs) -> Result<()> {
    if let Some(d) = outputs.frames_dir {
        if scene.camera.is_none() {
            return Err(SimError::field(&scene.file, "camera", format!("--frames-dir {}: the scene has no camera", d.display())));
        }
        if !d.is_dir() {
            return Err(SimError::Io { path: d.display().to_string(), source: std::io::Error::new(std::io::ErrorKind::NotFound, "not a directory") });
        }
    }
    if let Some(r) = outputs.trace_rate {
        if !(r.is_finite() && r > 0.0) {
            return Err(SimError::value("trace rate (Hz)", r, "must be a positive finite number"));
        }
        // The trace is kept in memory (two numbers per traced joint and sample): bounded before
        // anything is allocated.
        if options.duration * r > 1e7 {
            return Err(SimError::value("traced samples (duration x plot rate)", options.duration * r, "at most 1e7 are kept in memory for the plot; lower the plot rate"));
        }
    }
    if !(options.duration.is_finite() && options.duration > 0.0) {
        return Err(SimError::value("duration (s)", options.duration, "must be a positive finite number"));
    }
    if let Some(f) = outputs.realtime {
        if !(f.is_finite() && f > 0.0) {
            return Err(SimError::value("real-time factor (--realtime)", f, "must be a positive finite number"));
        }
    }
    Ok(())
}

/// For a replay: the scene with each replayed arm starting on its first sample (so the run does
/// not begin with a jump), and each arm's replayed trajectory (`None`: it holds home).
fn start_on_replay<'t>(scene: &Scene, trajectory: &'t TrajectoryKind) -> Result<(Option<Scene>, Vec<Option<&'t Trajectory>>)> {
    let mut replayed: Vec<Option<&Trajectory>> = vec![None; scene.arms.len()];
    let TrajectoryKind::Replay(r) = trajectory else {
        return Ok((None, replayed));
    };
    let mut s = scene.clone();
    for (name, traj) in &r.arms {
        let a = s.arm_index(name)?;
        let (mut q0, mut qd0) = (vec![0.0; s.arms[a].model.nq()], vec![0.0; s.arms[a].model.nq()]);
        if let Trajectory::Samples { q, .. } = traj {
            if q.first().map(|x| x.len()) != Some(q0.len()) {
                return Err(SimError::field(&r.source, name.as_str(), format!("samples are not {} joints long", q0.len())));
            }
        }
        traj.sample(0.0, &mut q0, &mut qd0);
        s.set_start(a, &q0)?;
        replayed[a] = Some(traj);
    }
    Ok((Some(s), replayed))
}

/// Each arm's reference under `trajectory` (`replayed`: a replay's per arm), and the notes the
/// tracking test makes (amplitudes scaled to the limits).
fn references(sim: &Sim, trajectory: &TrajectoryKind, replayed: &[Option<&Trajectory>]) -> (Vec<Trajectory>, Vec<String>) {
    let mut notes = Vec::new();
    let trajectories = sim
        .arms
        .iter()
        .enumerate()
        .map(|(i, a)| match trajectory {
            TrajectoryKind::Replay(_) => replayed[i].cloned().unwrap_or_else(|| Trajectory::Hold { q: a.model.home() }),
            TrajectoryKind::Sine if a.tracking == crate::scene::Tracking::Sine => {
                let (t, n) = Trajectory::tracking_test(&a.model);
                notes.extend(n.into_iter().map(|s| format!("{}: {s}", a.name)));
                t
            }
            _ => Trajectory::Hold { q: a.model.home() },
        })
        .collect();
    (trajectories, notes)
}

impl Trace {
    /// An empty trace of the tracked joints (those of arms on a reference other than holding;
    /// every joint when none is) for a run of `steps` steps, sampled at `rate` (Hz); with its
    /// stride in steps. Its buffers are allocated here, not in the run.
    fn for_run(sim: &Sim, trajectories: &[Trajectory], rate: f64, steps: u64) -> (u64, Trace) {
        let sine: Vec<bool> = trajectories.iter().map(|t| !matches!(t, Trajectory::Hold { .. })).collect();
        let any = sine.iter().any(|s| *s);
        let stride = ((1.0 / (rate * sim.dt)).round() as u64).max(1);
        let cap = (steps / stride + 2) as usize;
        let mut joints = Vec::new();
        for (a, arm) in sim.arms.iter().enumerate() {
            if any && !sine[a] {
                continue;
            }
            for (k, j) in arm.model.joints.iter().enumerate() {
                joints.push(TraceJoint { arm: arm.name.clone(), joint: j.name.clone(), unit: j.unit(), index: arm.q_offset + k, commanded: Vec::with_capacity(cap), measured: Vec::with_capacity(cap) });
            }
        }
        (stride, Trace { t: Vec::with_capacity(cap), joints })
    }

    /// One sample of the run at `t` (s).
    fn sample(&mut self, sim: &Sim, t: f64) -> Result<()> {
        self.t.push(t);
        for j in &mut self.joints {
            j.commanded.push(sim.actuator(j.index)?.target);
            j.measured.push(sim.q()[j.index]);
        }
        Ok(())
    }
}
