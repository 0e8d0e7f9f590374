//! Python bindings of `dvrk-sim`: `dvrk_twin.Sim` (a running scene) and `dvrk_twin.run_scene`.
//! Conversions only; the simulator knows nothing of Python.

use crate::errors::{Error, Result};
use dvrk_sim::run::TrajectoryKind;
use dvrk_sim::{Gains, LoopMode, Mode, RunOptions, Scene, SimOptions};
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;

/// A joint of a scene: its index in the scene's joint vector, or its name `ARM/joint`.
#[derive(FromPyObject)]
pub enum JointArg {
    Index(usize),
    Name(String),
}

fn options(loops: &str, solver_iterations: Option<usize>, engine: Option<&str>) -> Result<SimOptions> {
    let mut o = SimOptions::default();
    o.engine = match engine {
        None => None,
        Some("rapier") => Some(dvrk_sim::Engine::Rapier),
        Some("reduced") => Some(dvrk_sim::Engine::Reduced),
        Some(other) => return Err(Error::Input(format!("engine = `{other}`: expected `rapier` or `reduced`"))),
    };
    o.loops = match loops {
        "impulse" => LoopMode::ImpulseJoints,
        "coupling" => LoopMode::DofCoupling,
        other => return Err(Error::Input(format!("loops = `{other}`: expected `impulse` or `coupling`"))),
    };
    if let Some(n) = solver_iterations {
        if n == 0 {
            return Err(Error::Input("solver_iterations = 0: must be at least 1".into()));
        }
        o.solver_iterations = Some(n);
    }
    Ok(o)
}

/// A running dynamic simulation of a scene (rapier, f64). Units: m, rad, s, N, N·m.
#[pyclass(module = "dvrk_twin", name = "Sim", unsendable)]
pub struct PySim {
    sim: dvrk_sim::Sim,
    names: Vec<String>,
    /// The live view ([`PySim::serve`]) and the steps taken since it started.
    live: Option<(dvrk_sim::Recorder, u64)>,
}

/// The scene joint `j` names among `names` (`ARM/joint`, scene order).
pub(crate) fn joint_index(names: &[String], j: JointArg) -> Result<usize> {
    match j {
        JointArg::Index(i) if i < names.len() => Ok(i),
        JointArg::Index(i) => Err(Error::Input(format!("joint index {i}: the scene has {} joints", names.len()))),
        JointArg::Name(n) => names.iter().position(|x| *x == n).ok_or_else(|| Error::Input(format!("unknown joint `{n}`; valid: {}", names.join(", ")))),
    }
}

/// A scene's joint names, `ARM/joint`, in the order of its joint vector.
pub(crate) fn joint_names(sim: &dvrk_sim::Sim) -> Vec<String> {
    sim.arms.iter().flat_map(|a| a.model.joints.iter().map(move |j| format!("{}/{}", a.name, j.name))).collect()
}

/// A drive mode by its Python name.
pub(crate) fn mode(name: &str) -> Result<Mode> {
    match name {
        "pid" => Ok(Mode::Pid),
        "position" => Ok(Mode::Position),
        "effort" => Ok(Mode::Effort),
        other => Err(Error::Input(format!("mode = `{other}`: expected pid, position or effort"))),
    }
}

impl PySim {
    fn joint(&self, j: JointArg) -> Result<usize> {
        joint_index(&self.names, j)
    }
}

#[pymethods]
impl PySim {
    /// Build a scene (built-in name such as "psm", "ecm", or a scene file) ready to step.
    /// `loops`: "impulse" (loop-closing impulse joints) or "coupling" (loop-free, URDF-mimic way).
    /// `engine`: "rapier" or "reduced" (forward dynamics in the actuated joints, loops exact, no
    /// contacts); the scene's when None.
    #[staticmethod]
    #[pyo3(signature = (scene, loops="impulse", solver_iterations=None, engine=None))]
    fn from_scene(scene: &str, loops: &str, solver_iterations: Option<usize>, engine: Option<&str>) -> Result<Self> {
        let s = Scene::load(scene)?;
        let sim = dvrk_sim::Sim::new(&s, &options(loops, solver_iterations, engine)?)?;
        let names = joint_names(&sim);
        Ok(PySim { sim, names, live: None })
    }

    /// Joint names `ARM/joint`, in the order of `q`.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// Number of joints of the scene.
    #[getter]
    fn nq(&self) -> usize {
        self.sim.nq()
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.sim.time
    }

    /// Time step (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.sim.dt
    }

    /// Measured joint positions (rad, m), shape (nq,).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.sim.q().to_vec().into_pyarray(py)
    }

    /// Measured joint velocities (rad/s, m/s), shape (nq,).
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.sim.qd().to_vec().into_pyarray(py)
    }

    /// Largest loop-closure gap now (m).
    #[getter]
    fn closure_error(&self) -> f64 {
        self.sim.closure_error()
    }

    /// Advance `n` steps of `dt`. Raises `DvrkError` at the first step whose state is not
    /// finite (a NaN state is never returned as if it were a result).
    #[pyo3(signature = (n=1))]
    fn step(&mut self, n: usize) -> Result<()> {
        for _ in 0..n {
            self.sim.step();
            self.sim.check_finite()?;
            if let Some((recorder, steps)) = self.live.as_mut() {
                *steps += 1;
                recorder.after_step(&self.sim, *steps)?;
            }
        }
        Ok(())
    }

    /// Serve this simulation live over the Foxglove WebSocket protocol (Foxglove, Lichtblick):
    /// the topics `dvrk sim --out` records (CRTK joint states, poses, /tf, the link geometry on
    /// /scene), sampled every `1 / rate` s of simulated time as `step` advances it. `port` 0
    /// picks a free one. Returns the address, `ws://HOST:PORT`. Serving again replaces the view.
    #[pyo3(signature = (host="127.0.0.1", port=8765, rate=100.0))]
    fn serve(&mut self, host: &str, port: u16, rate: f64) -> Result<String> {
        self.stop_serving()?;
        let live = dvrk_sim::Live::serve(&dvrk_sim::LiveOptions { host: host.into(), port }, &format!("dvrk-twin {}", self.sim.scene_name))?;
        let url = live.url();
        self.live = Some((dvrk_sim::Recorder::open(&self.sim, None, Some(live), rate)?, 0));
        Ok(url)
    }

    /// Stop the live view (closes the connections); nothing happens when not serving.
    fn stop_serving(&mut self) -> Result<()> {
        if let Some((recorder, _)) = self.live.take() {
            recorder.finish_staged()?;
        }
        Ok(())
    }

    /// The live view's address, `ws://HOST:PORT`, or None.
    #[getter]
    fn live_url(&self) -> Option<String> {
        self.live.as_ref().and_then(|(r, _)| r.live().map(|l| l.url()))
    }

    /// Control mode of a joint: "pid", "position" or "effort".
    fn set_mode(&mut self, joint: JointArg, mode: &str) -> Result<()> {
        let mode = self::mode(mode)?;
        let i = self.joint(joint)?;
        Ok(self.sim.set_mode(i, mode)?)
    }

    /// Position target (rad, m) and velocity feed-forward (rad/s, m/s) of a joint.
    #[pyo3(signature = (joint, position, velocity=0.0))]
    fn set_target(&mut self, joint: JointArg, position: f64, velocity: f64) -> Result<()> {
        let i = self.joint(joint)?;
        Ok(self.sim.set_target(i, position, velocity)?)
    }

    /// Open-loop effort (N·m, N) of a joint in effort mode (clamped at its effort limit).
    fn set_effort(&mut self, joint: JointArg, effort: f64) -> Result<()> {
        let i = self.joint(joint)?;
        Ok(self.sim.set_effort(i, effort)?)
    }

    /// PID gains of a joint: kp (N·m/rad, N/m), ki, kd.
    fn set_gains(&mut self, joint: JointArg, kp: f64, ki: f64, kd: f64) -> Result<()> {
        let i = self.joint(joint)?;
        Ok(self.sim.set_gains(i, Gains { kp, ki, kd })?)
    }

    /// Effort applied at the last step (N·m, N).
    fn effort(&self, joint: JointArg) -> Result<f64> {
        let i = self.joint(joint)?;
        Ok(self.sim.effort(i)?)
    }

    fn __repr__(&self) -> String {
        format!("Sim(scene={:?}, nq={}, time={:.3} s)", self.sim.scene_name, self.sim.nq(), self.sim.time)
    }
}

/// Run a scene for `duration` s under a trajectory ("sine": the paper's tracking test, or
/// "hold") without the GIL, and return the summary as a dict (real-time factor, per-joint
/// tracking RMS/max, loop-closure and RCM errors, in SI units) — the same figures as
/// `dvrk sim --json`.
#[pyfunction]
#[pyo3(signature = (scene, duration, trajectory="sine", loops="impulse", solver_iterations=None, engine=None))]
pub fn run_scene<'py>(
    py: Python<'py>,
    scene: &str,
    duration: f64,
    trajectory: &str,
    loops: &str,
    solver_iterations: Option<usize>,
    engine: Option<&str>,
) -> Result<Bound<'py, PyAny>> {
    let trajectory = match trajectory {
        "sine" => TrajectoryKind::Sine,
        "hold" => TrajectoryKind::Hold,
        other => return Err(Error::Input(format!("trajectory = `{other}`: expected sine or hold"))),
    };
    let s = Scene::load(scene)?;
    let opts = RunOptions { duration, trajectory, sim: options(loops, solver_iterations, engine)? };
    let summary = py.detach(|| dvrk_sim::run(&s, &opts, |_| {}))?;
    if !summary.finite {
        let message = format!("scene {scene}: largest loop-closure gap {:.6e} m at {:.6e} s (`dvrk sim` exits 1 alike)", summary.max_closure_error, summary.max_closure_time);
        return Err(dvrk_sim::SimError::Diverged { time: summary.max_closure_time, message }.into());
    }
    let text = serde_json::to_string(&summary).map_err(|e| Error::Input(e.to_string()))?;
    Ok(py.import("json")?.call_method1("loads", (text,))?)
}

/// The MJCF (MuJoCo XML) text of a scene (built-in name or scene file) or of a model with its
/// built-in inertials and gains — what `dvrk export mjcf` writes.
#[pyfunction]
pub fn export_mjcf(name_or_path: &str) -> Result<String> {
    Ok(dvrk_sim::mjcf::export_named(name_or_path)?)
}

/// Names of the built-in scenes.
#[pyfunction]
pub fn builtin_scenes() -> Vec<&'static str> {
    dvrk_sim::scene::builtin_scenes()
}

/// Serve a scene as a live twin on ROS 2 in real time (what `dvrk serve` does): the dVRK's
/// CRTK topics published at `rate` Hz, `servo_jp`/`servo_jf` taken, on DDS domain `domain`
/// (`ROS_DOMAIN_ID`, else 0, when None), loopback only unless `networks` names interface
/// addresses; `gravity_compensation` adds the model's gravity torque to every controller. Blocks for `duration` simulated seconds, or until Ctrl-C (KeyboardInterrupt stops
/// the twin cleanly, finishes `out`, and is raised again). Returns the summary as a dict.
#[pyfunction]
#[pyo3(signature = (scene="psm", domain=None, rate=200.0, duration=None, engine="reduced", out=None, networks=Vec::new(), gravity_compensation=false))]
#[allow(clippy::too_many_arguments)]
pub fn serve<'py>(
    py: Python<'py>,
    scene: &str,
    domain: Option<u16>,
    rate: f64,
    duration: Option<f64>,
    engine: &str,
    out: Option<std::path::PathBuf>,
    networks: Vec<String>,
    gravity_compensation: bool,
) -> Result<Bound<'py, PyAny>> {
    use dvrk_sim::ros2::Ros2Options;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    let s = Scene::load(scene)?;
    let sim_options = options("impulse", None, Some(engine))?;
    let domain = match domain {
        Some(d) => d,
        None => Ros2Options::domain_from_env()?,
    };
    let mut nets = Vec::new();
    for n in &networks {
        nets.push(n.parse::<std::net::IpAddr>().map_err(|_| Error::Input(format!("networks: `{n}` is not an IP address")))?);
    }
    let serve_options = dvrk_sim::serve::ServeOptions {
        duration,
        rate,
        ros2: Ros2Options { domain, networks: nets, node: "dvrk_twin".into() },
        record: out.clone().map(|path| dvrk_sim::RecordOptions { path, rate }),
        gravity_compensation,
        teleop: None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let worker = std::thread::spawn(move || dvrk_sim::serve::serve(&s, &sim_options, &serve_options, &flag, None, |_| {}));
    // Wait without the GIL, waking to let Python see Ctrl-C.
    let mut interrupted = None;
    while !worker.is_finished() {
        py.detach(|| std::thread::sleep(std::time::Duration::from_millis(50)));
        if let Err(e) = py.check_signals() {
            stop.store(true, Ordering::Relaxed);
            interrupted = Some(e);
        }
    }
    let (summary, staged) = worker.join().map_err(|_| Error::Input("the twin's thread panicked".into()))??;
    if let Some(staged) = staged {
        staged.commit().map_err(|e| Error::Input(format!("out: {e}")))?;
    }
    if let Some(e) = interrupted {
        return Err(e.into());
    }
    let text = serde_json::to_string(&summary).map_err(|e| Error::Input(e.to_string()))?;
    Ok(py.import("json")?.call_method1("loads", (text,))?)
}
