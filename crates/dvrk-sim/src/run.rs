//! Running a scene for a duration under a trajectory and summarising it: real-time factor,
//! tracking RMS / max per joint, loop-closure error, RCM error.

use crate::camera::{write_frame_files, StereoCamera};
use crate::error::{Result, SimError};
use crate::recording::{RecordOptions, Recorder};
use crate::sim::{Sim, SimOptions};
use crate::trajectory::Trajectory;
use crate::Scene;
use dvrk_kin::rcm::distance_to_axis;
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

/// One tenth of a run ([`Summary::windows`]).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct WindowSummary {
    /// s of simulated time
    pub start: f64,
    pub end: f64,
    /// Largest loop-closure gap in the window (m).
    pub max_closure_error: f64,
    /// Largest distance of an insertion axis from its arm's RCM in the window (m).
    pub max_rcm_error: f64,
}

/// Windows of a run ([`Summary::windows`]).
const WINDOWS: u64 = 10;

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
    let (record, trace_rate) = (outputs.record, outputs.trace_rate);
    if let Some(d) = outputs.frames_dir {
        if scene.camera.is_none() {
            return Err(SimError::field(&scene.file, "camera", format!("--frames-dir {}: the scene has no camera", d.display())));
        }
        if !d.is_dir() {
            return Err(SimError::Io { path: d.display().to_string(), source: std::io::Error::new(std::io::ErrorKind::NotFound, "not a directory") });
        }
    }
    if let Some(r) = trace_rate {
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
    // A replayed arm starts on its first sample, so the run does not begin with a jump.
    let mut replayed: Vec<Option<&Trajectory>> = vec![None; scene.arms.len()];
    let started;
    let scene = match &options.trajectory {
        TrajectoryKind::Replay(r) => {
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
            started = s;
            &started
        }
        _ => scene,
    };
    let mut sim = Sim::new(scene, &options.sim)?;
    if let Some(f) = outputs.realtime {
        if !(f.is_finite() && f > 0.0) {
            return Err(SimError::value("real-time factor (--realtime)", f, "must be a positive finite number"));
        }
    }
    let live = outputs.live.and_then(|m| m.lock().ok()?.take());
    let mut recorder = match (record, live) {
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
    let mut notes = Vec::new();
    let trajectories: Vec<Trajectory> = sim
        .arms
        .iter()
        .enumerate()
        .map(|(i, a)| match &options.trajectory {
            TrajectoryKind::Replay(_) => replayed[i].cloned().unwrap_or_else(|| Trajectory::Hold { q: a.model.home() }),
            TrajectoryKind::Sine if a.tracking == crate::scene::Tracking::Sine => {
                let (t, n) = Trajectory::tracking_test(&a.model);
                notes.extend(n.into_iter().map(|s| format!("{}: {s}", a.name)));
                t
            }
            _ => Trajectory::Hold { q: a.model.home() },
        })
        .collect();
    // The RCM of each arm: its insertion-axis frame's placement in its body, and the world point.
    let rcms: Vec<Option<(usize, dvrk_kin::Pose, nalgebra::Vector3<f64>)>> = sim
        .arms
        .iter()
        .map(|a| {
            let m = &a.model;
            let r = m.rcm.as_ref()?;
            let fk = m.fk(&m.home()).ok()?;
            let body = m.frames[r.frame].body;
            let rel = fk[m.bodies[body].frames[0]].inverse() * fk[r.frame];
            Some((r.frame, rel, (m.base * nalgebra::Point3::from(r.point)).coords))
        })
        .collect();
    // An arm carried by another (a PSM on its held SUJ) has its RCM fixed to the carrying body,
    // which the position-held setup joints let sag slightly: the point, in that body's frame.
    let carriers: Vec<Option<(usize, usize, nalgebra::Vector3<f64>)>> = sim
        .arms
        .iter()
        .zip(&rcms)
        .map(|(a, r)| {
            let (pa, pf) = a.parent?;
            let body = sim.arms[pa].model.frames[pf].body;
            let local = sim.body_pose(pa, body).inverse() * nalgebra::Point3::from(r.as_ref()?.2);
            Some((pa, body, local.coords))
        })
        .collect();
    let n = sim.nq();
    let steps = (options.duration / sim.dt).round().max(1.0) as u64;
    let (mut qr, mut qdr) = (vec![0.0; n], vec![0.0; n]);
    let mut sum_sq = vec![0.0; n];
    let mut max_err = vec![0.0_f64; n];
    let mut max_eff = vec![0.0_f64; n];
    let (mut max_closure, mut final_closure, mut max_rcm) = (0.0_f64, 0.0_f64, 0.0_f64);
    let mut max_closure_time = 0.0;
    let mut windows: Vec<WindowSummary> = (0..WINDOWS)
        .map(|w| WindowSummary { start: (w * steps / WINDOWS) as f64 * sim.dt, end: ((w + 1) * steps / WINDOWS) as f64 * sim.dt, max_closure_error: 0.0, max_rcm_error: 0.0 })
        .collect();
    let mut finite = true;
    let every = (steps / 100).max(1);
    let mut trace = trace_rate.map(|rate| {
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
                joints.push(TraceJoint {
                    arm: arm.name.clone(),
                    joint: j.name.clone(),
                    unit: j.unit(),
                    index: arm.q_offset + k,
                    commanded: Vec::with_capacity(cap),
                    measured: Vec::with_capacity(cap),
                });
            }
        }
        (stride, Trace { t: Vec::with_capacity(cap), joints })
    });
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
        for i in 0..n {
            let e = sim.q()[i] - sim.actuator(i)?.target;
            if !e.is_finite() {
                finite = false;
            }
            sum_sq[i] += e * e;
            max_err[i] = max_err[i].max(e.abs());
            max_eff[i] = max_eff[i].max(sim.actuator(i)?.effort.abs());
        }
        let c = sim.closure_error();
        if c > max_closure {
            max_closure = c;
            max_closure_time = t;
        }
        if s >= steps - steps / 10 {
            final_closure = final_closure.max(c);
        }
        let window = &mut windows[(s * WINDOWS / steps) as usize];
        window.max_closure_error = window.max_closure_error.max(c);
        for (a, r) in rcms.iter().enumerate() {
            if let Some((frame, rel, point)) = r {
                let pose = sim.frame_pose(a, *frame, rel);
                let point = match carriers[a] {
                    Some((pa, body, local)) => (sim.body_pose(pa, body) * nalgebra::Point3::from(local)).coords,
                    None => *point,
                };
                let d = distance_to_axis(&pose, &point);
                max_rcm = max_rcm.max(d);
                window.max_rcm_error = window.max_rcm_error.max(d);
            }
        }
        if let Some((stride, tr)) = trace.as_mut() {
            if s % *stride == 0 || s + 1 == steps {
                tr.t.push(t);
                for j in &mut tr.joints {
                    j.commanded.push(sim.actuator(j.index)?.target);
                    j.measured.push(sim.q()[j.index]);
                }
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
                rms_error: (sum_sq[i] / done as f64).sqrt(),
                max_error: max_err[i],
                max_effort: max_eff[i],
            });
        }
    }
    let simulated = done as f64 * sim.dt;
    // A run stopped early (a signal, a non-finite state) reports the windows it reached.
    windows.retain(|w| w.start < done as f64 * sim.dt);
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
        max_closure_error: max_closure,
        max_closure_time,
        final_closure_error: final_closure,
        max_rcm_error: max_rcm,
        windows,
        finite,
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
