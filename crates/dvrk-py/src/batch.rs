//! Python bindings of `dvrk_sim::BatchSim`: `dvrk_twin.BatchSim`, many copies of a scene stepped
//! in parallel without the GIL. The state and command arrays are numpy arrays this object owns
//! (`(n, nq)`, float64): `step` reads the commands from them and writes the states into them in
//! place, so a policy writes `batch.target[:] = ...` and reads `batch.q` with no copy of its own.

use crate::errors::{Error, Result};
use dvrk_sim::{Gains, Scene};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Many independent copies of a scene stepped together on a thread pool, the GIL released while
/// they step (units: m, rad, s, N, N·m). Reduced engine by default.
#[pyclass(module = "dvrk_twin", name = "BatchSim", unsendable)]
pub struct PyBatchSim {
    batch: dvrk_sim::BatchSim,
    names: Vec<String>,
    q: Py<PyArray2<f64>>,
    qd: Py<PyArray2<f64>>,
    effort: Py<PyArray2<f64>>,
    target: Py<PyArray2<f64>>,
    target_velocity: Py<PyArray2<f64>>,
    effort_command: Py<PyArray2<f64>>,
}

fn array(py: Python<'_>, flat: &[f64], n: usize, nq: usize) -> Result<Py<PyArray2<f64>>> {
    let a = numpy::PyArray1::from_slice(py, flat).reshape([n, nq]).map_err(|e| Error::Input(e.to_string()))?;
    Ok(a.unbind())
}

/// `src` (an `(n, nq)` array the user may have replaced the contents of) into `dst`.
fn copy_in(py: Python<'_>, name: &str, src: &Py<PyArray2<f64>>, dst: &mut [f64]) -> Result<()> {
    let a = src.bind(py).readonly();
    let s = a.as_slice().map_err(|_| Error::Input(format!("{name}: not a contiguous array")))?;
    dst.copy_from_slice(s);
    Ok(())
}

fn copy_out(py: Python<'_>, src: &[f64], dst: &Py<PyArray2<f64>>) -> Result<()> {
    let mut a = dst.bind(py).readwrite();
    let d = a.as_slice_mut().map_err(|_| Error::Input("state array: not contiguous".into()))?;
    d.copy_from_slice(src);
    Ok(())
}

/// `value` (anything numpy takes as an `(n, nq)` float array, or broadcasts to it) into `dst`.
fn assign(py: Python<'_>, name: &str, dst: &Py<PyArray2<f64>>, value: &Bound<'_, PyAny>) -> Result<()> {
    dst.bind(py).call_method1("__setitem__", (py.Ellipsis(), value)).map_err(|e| Error::Input(format!("{name}: {e}")))?;
    Ok(())
}

impl PyBatchSim {
    fn copy(&self, c: usize) -> Result<usize> {
        if c < self.batch.n() {
            Ok(c)
        } else {
            Err(Error::Input(format!("copy {c}: the batch has {} copies", self.batch.n())))
        }
    }

    fn joint(&self, j: crate::sim::JointArg) -> Result<usize> {
        crate::sim::joint_index(&self.names, j)
    }

    /// The state arrays from the batch's.
    fn publish(&self, py: Python<'_>) -> Result<()> {
        copy_out(py, self.batch.q(), &self.q)?;
        copy_out(py, self.batch.qd(), &self.qd)?;
        copy_out(py, self.batch.effort(), &self.effort)
    }

    /// Copy `c`'s commands in the arrays from the batch's (after a reset: hold).
    fn commands_of(&mut self, py: Python<'_>, c: usize) -> Result<()> {
        let nq = self.batch.nq();
        let r = c * nq..(c + 1) * nq;
        for (src, dst) in [
            (self.batch.target_mut()[r.clone()].to_vec(), &self.target),
            (self.batch.target_velocity_mut()[r.clone()].to_vec(), &self.target_velocity),
            (self.batch.effort_command_mut()[r.clone()].to_vec(), &self.effort_command),
        ] {
            let mut a = dst.bind(py).readwrite();
            let d = a.as_slice_mut().map_err(|_| Error::Input("command array: not contiguous".into()))?;
            d[r.clone()].copy_from_slice(&src);
        }
        Ok(())
    }
}

/// A frame: its name or its index as the model file numbers it.
#[derive(FromPyObject)]
pub enum FrameArg {
    Index(i64),
    Name(String),
}

#[pymethods]
impl PyBatchSim {
    /// `n` copies of a scene (built-in name or scene file), each at the scene's start holding
    /// it, stepped on `threads` threads (0: one per core). `engine`: "reduced" (default) or
    /// "rapier".
    #[staticmethod]
    #[pyo3(signature = (scene, n, engine="reduced", threads=0))]
    fn from_scene(py: Python<'_>, scene: &str, n: usize, engine: &str, threads: usize) -> Result<Self> {
        let s = Scene::load(scene)?;
        let mut o = dvrk_sim::SimOptions::default();
        o.engine = Some(dvrk_sim::Engine::from_name(engine).ok_or_else(|| Error::Input(format!("engine = `{engine}`: expected `reduced` or `rapier`")))?);
        let batch = py.detach(|| dvrk_sim::BatchSim::new(&s, n, &o, threads))?;
        let names = crate::sim::joint_names(batch.sim(0)?);
        let nq = batch.nq();
        let mut me = PyBatchSim {
            q: array(py, batch.q(), n, nq)?,
            qd: array(py, batch.qd(), n, nq)?,
            effort: array(py, batch.effort(), n, nq)?,
            target: array(py, batch.q(), n, nq)?,
            target_velocity: array(py, &vec![0.0; n * nq], n, nq)?,
            effort_command: array(py, &vec![0.0; n * nq], n, nq)?,
            batch,
            names,
        };
        for c in 0..n {
            me.commands_of(py, c)?;
        }
        Ok(me)
    }

    /// Number of copies.
    #[getter]
    fn n(&self) -> usize {
        self.batch.n()
    }

    /// Joints per copy.
    #[getter]
    fn nq(&self) -> usize {
        self.batch.nq()
    }

    /// Time step (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.batch.dt()
    }

    /// Worker threads.
    #[getter]
    fn threads(&self) -> usize {
        self.batch.threads()
    }

    /// Joint names `ARM/joint`, the columns of the arrays.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.names.clone()
    }

    /// Joint limits (rad, m), shape (nq, 2): lower, upper.
    #[getter]
    fn joint_limits<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyArray2<f64>>> {
        let sim = self.batch.sim(0)?;
        let flat: Vec<f64> = sim.arms.iter().flat_map(|a| a.model.joints.iter().flat_map(|j| [j.lower, j.upper])).collect();
        Ok(array(py, &flat, self.batch.nq(), 2)?.into_bound(py))
    }

    /// Effort limits (N·m, N) of the drives, shape (nq,): where effort commands are clamped.
    #[getter]
    fn effort_limits(&self) -> Result<Vec<f64>> {
        Ok(self.batch.sim(0)?.arms.iter().flat_map(|a| a.model.joints.iter().map(|j| j.effort_limit)).collect())
    }

    /// Each copy's simulated time (s), shape (n,).
    #[getter]
    fn time(&self) -> Vec<f64> {
        (0..self.batch.n()).map(|c| self.batch.sim(c).map(|s| s.time).unwrap_or(f64::NAN)).collect()
    }

    /// Measured joint positions (rad, m), (n, nq); updated in place by `step`.
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.q.bind(py).clone()
    }

    /// Measured joint velocities (rad/s, m/s), (n, nq); updated in place by `step`.
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.qd.bind(py).clone()
    }

    /// Efforts the drives applied at the last step (N·m, N), (n, nq); updated in place.
    #[getter]
    fn effort<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.effort.bind(py).clone()
    }

    /// Position targets (rad, m), (n, nq), read by `step` (PID and position modes; clamped to
    /// the limits). Write into it, or assign anything that broadcasts to (n, nq).
    #[getter]
    fn target<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.target.bind(py).clone()
    }

    #[setter(target)]
    fn set_target_array(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> Result<()> {
        assign(py, "target", &self.target, value)
    }

    /// Velocity feed-forward of the targets (rad/s, m/s), (n, nq).
    #[getter]
    fn target_velocity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.target_velocity.bind(py).clone()
    }

    #[setter(target_velocity)]
    fn set_target_velocity_array(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> Result<()> {
        assign(py, "target_velocity", &self.target_velocity, value)
    }

    /// Effort commands of joints in effort mode (N·m, N), (n, nq); clamped at the effort limits.
    #[getter]
    fn effort_command<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.effort_command.bind(py).clone()
    }

    #[setter(effort_command)]
    fn set_effort_command_array(&self, py: Python<'_>, value: &Bound<'_, PyAny>) -> Result<()> {
        assign(py, "effort_command", &self.effort_command, value)
    }

    /// Advance every copy `k` steps of `dt` with the command arrays, in parallel and without
    /// the GIL; then `q`, `qd`, `effort` hold the result. A non-finite command raises before
    /// any copy moves; a copy whose state diverges raises naming it.
    #[pyo3(signature = (k=1))]
    fn step(&mut self, py: Python<'_>, k: usize) -> Result<()> {
        copy_in(py, "target", &self.target, self.batch.target_mut())?;
        copy_in(py, "target_velocity", &self.target_velocity, self.batch.target_velocity_mut())?;
        copy_in(py, "effort_command", &self.effort_command, self.batch.effort_command_mut())?;
        let batch = &mut self.batch;
        let result = py.detach(|| batch.step(k));
        self.publish(py)?;
        Ok(result?)
    }

    /// Rebuild copies at a start: `copies` one index or a list (None: all), `q` the start
    /// positions (rad, m) per copy, shape (nq,) for all or (len(copies), nq), None: the scene's.
    /// The copies' targets then hold their start and their efforts are zero.
    #[pyo3(signature = (copies=None, q=None))]
    fn reset(&mut self, py: Python<'_>, copies: Option<&Bound<'_, PyAny>>, q: Option<numpy::PyReadonlyArrayDyn<'_, f64>>) -> Result<()> {
        let list: Vec<usize> = match copies {
            None => (0..self.batch.n()).collect(),
            Some(c) => match c.extract::<usize>() {
                Ok(one) => vec![one],
                Err(_) => c.extract::<Vec<usize>>().map_err(|_| Error::Input("copies: expected an index or a list of indices".into()))?,
            },
        };
        let nq = self.batch.nq();
        let starts: Option<Vec<Vec<f64>>> = match &q {
            None => None,
            Some(a) => {
                let shape = a.shape().to_vec();
                let data = a.as_slice().map_err(|_| Error::Input("q: not a contiguous array".into()))?;
                match shape.as_slice() {
                    [m] if *m == nq => Some(vec![data.to_vec(); list.len()]),
                    [r, m] if *r == list.len() && *m == nq => Some(data.chunks(nq).map(|c| c.to_vec()).collect()),
                    _ => return Err(Error::Input(format!("q: shape {shape:?}; expected ({nq},) or ({}, {nq})", list.len()))),
                }
            }
        };
        for (i, &c) in list.iter().enumerate() {
            self.copy(c)?;
            self.batch.reset(c, starts.as_ref().map(|s| s[i].as_slice()))?;
            self.commands_of(py, c)?;
        }
        self.publish(py)
    }

    /// Give copy `copy`'s arm `arm` a model file (payloads, friction, a calibrated or
    /// identified model: its `[[effects]]`, `[[inertials]]`, `[drive]`) and rebuild the copy at
    /// its start.
    #[pyo3(signature = (copy, path, arm=0))]
    fn set_model(&mut self, py: Python<'_>, copy: usize, path: std::path::PathBuf, arm: usize) -> Result<()> {
        self.copy(copy)?;
        let name = path.to_string_lossy().into_owned();
        let model = dvrk_sim::dvrk_kin::load(&name, None)?;
        self.batch.set_model(copy, arm, model)?;
        self.commands_of(py, copy)?;
        self.publish(py)
    }

    /// PID gains of one copy's joint: kp (N·m/rad, N/m), ki, kd.
    fn set_gains(&mut self, copy: usize, joint: crate::sim::JointArg, kp: f64, ki: f64, kd: f64) -> Result<()> {
        let (c, j) = (self.copy(copy)?, self.joint(joint)?);
        Ok(self.batch.set_gains(c, j, Gains { kp, ki, kd })?)
    }

    /// Control mode of one copy's joint, or of every copy's when `copy` is None: "pid",
    /// "position" or "effort" (which reads `effort_command`).
    #[pyo3(signature = (joint, mode, copy=None))]
    fn set_mode(&mut self, joint: crate::sim::JointArg, mode: &str, copy: Option<usize>) -> Result<()> {
        let mode = crate::sim::mode(mode)?;
        let j = self.joint(joint)?;
        let copies: Vec<usize> = match copy {
            Some(c) => vec![self.copy(c)?],
            None => (0..self.batch.n()).collect(),
        };
        for c in copies {
            self.batch.set_mode(c, j, mode)?;
        }
        Ok(())
    }

    /// World poses (4x4, m) of a frame (name, or index as in the model file; None: `tool_tip`)
    /// of arm `arm` in every copy, shape (n, 4, 4): the simulated links'.
    #[pyo3(signature = (frame=None, arm=0))]
    fn frame_poses<'py>(&self, py: Python<'py>, frame: Option<FrameArg>, arm: usize) -> Result<Bound<'py, numpy::PyArray3<f64>>> {
        let sim = self.batch.sim(0)?;
        let model = &sim.arms.get(arm).ok_or_else(|| Error::Input(format!("arm {arm}: the scene has {} arms", sim.arms.len())))?.model;
        let r = match frame {
            Some(FrameArg::Index(i)) => dvrk_sim::dvrk_kin::FrameRef::Index(i),
            Some(FrameArg::Name(n)) => dvrk_sim::dvrk_kin::FrameRef::Name(n),
            None => dvrk_sim::dvrk_kin::FrameRef::Name("tool_tip".into()),
        };
        let f = model.frame_id(&r)?;
        let n = self.batch.n();
        let mut out = vec![0.0; n * 16];
        self.batch.frame_poses(arm, f, &mut out)?;
        numpy::PyArray1::from_vec(py, out).reshape([n, 4, 4]).map_err(|e| Error::Input(e.to_string()))
    }

    fn __repr__(&self) -> String {
        format!("BatchSim(n={}, nq={}, engine={:?}, threads={})", self.batch.n(), self.batch.nq(), self.batch.engine(), self.batch.threads())
    }
}
