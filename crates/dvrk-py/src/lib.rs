//! Python bindings of `dvrk-kin`: the native module `dvrk_twin._dvrk_twin`, re-exported by the
//! package `dvrk_twin` (python/dvrk_twin/__init__.py, stubs in _dvrk_twin.pyi).
//!
//! A thin layer: [`PyModel`] wraps a [`Model`]; every method converts its arguments, calls the
//! Rust API and converts the result. All conversions live here; `dvrk-kin` knows nothing of
//! Python. Errors go through the one mapping in [`errors`]. Batches of configurations release the
//! GIL and reuse one [`Data`] workspace (no allocation per configuration).
//!
//! Units: m, rad everywhere; poses are 4x4 homogeneous matrices (rotation, translation in m).

mod batch;
mod calib;
mod dynamics;
mod errors;
mod sim;

use dvrk_kin::check::check_model;
use dvrk_kin::rcm::pivot_residual;
use dvrk_kin::{
    compute_frame_placements, forward_kinematics, frame_jacobian, inverse_kinematics,
    max_closure_residual, Data, FrameRef, IkOptions, JointType, KinError, Model, Pose,
};
use errors::{exceptions, Error, Result};
use nalgebra::{Matrix3, Matrix6xX, Rotation3, Translation3};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArrayDyn, PyArrayLikeDyn};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::path::PathBuf;

/// A frame given by its number in the paper (int) or by its name (str).
#[derive(FromPyObject)]
enum FrameArg {
    Number(i64),
    Name(String),
}

/// Joint configurations from a (nq,) or (N, nq) array, copied row-major and checked for size and
/// finiteness (not for the joint limits).
struct Configs {
    q: Vec<f64>,
    n: usize,
    nq: usize,
    batch: bool,
}

impl Configs {
    fn row(&self, i: usize) -> &[f64] {
        &self.q[i * self.nq..(i + 1) * self.nq]
    }
}

fn shape_str(s: &[usize]) -> String {
    match s {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            s.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

fn configs(
    model: &Model,
    q: &PyArrayLikeDyn<'_, f64, AllowTypeChange>,
    name: &str,
    allow_batch: bool,
) -> Result<Configs> {
    let v = q.as_array();
    let nq = model.nq();
    let (n, m, batch) = match v.shape() {
        [m] => (1, *m, false),
        [n, m] if allow_batch => (*n, *m, true),
        s => {
            let want = if allow_batch {
                format!("(nq,) = ({nq},) or (N, nq) = (N, {nq})")
            } else {
                format!("(nq,) = ({nq},)")
            };
            return Err(Error::Input(format!(
                "{name} must have shape {want}, got shape {}",
                shape_str(s)
            )));
        }
    };
    if m != nq {
        return Err(KinError::Size {
            what: format!("{name} of model {}", model.name),
            expected: nq,
            got: m,
        }
        .into());
    }
    // Logical (row-major) order, whatever the strides of the input.
    let c = Configs {
        q: v.iter().copied().collect(),
        n,
        nq,
        batch,
    };
    for i in 0..n {
        model.check_q_size(c.row(i)).map_err(|e| match batch {
            true => Error::Input(format!("{name}[{i}]: {e}")),
            false => e.into(),
        })?;
    }
    Ok(c)
}

/// Write `p` as a row-major 4x4 homogeneous matrix.
#[inline]
fn write_pose(p: &Pose, out: &mut [f64]) {
    let r = p.rotation.matrix();
    let t = &p.translation.vector;
    for i in 0..3 {
        out[4 * i] = r[(i, 0)];
        out[4 * i + 1] = r[(i, 1)];
        out[4 * i + 2] = r[(i, 2)];
        out[4 * i + 3] = t[i];
    }
    out[12..16].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
}

fn to_array<'py>(
    py: Python<'py>,
    shape: &[usize],
    data: Vec<f64>,
) -> Result<Bound<'py, PyArrayDyn<f64>>> {
    let a = ArrayD::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

fn pose_array<'py>(py: Python<'py>, p: &Pose) -> Result<Bound<'py, PyArrayDyn<f64>>> {
    let mut out = vec![0.0; 16];
    write_pose(p, &mut out);
    to_array(py, &[4, 4], out)
}

/// A pose from a row-major 4x4 homogeneous matrix given by the user: finite, last row
/// [0, 0, 0, 1], rotation part orthonormal with determinant +1 to 1e-6. A rotation that is
/// orthonormal to 1e-12 is taken as given (an `fk` result round-trips exactly); a less accurate
/// one (4 printed digits) is replaced by the nearest rotation (polar decomposition).
fn pose_from_matrix(m: &[[f64; 4]; 4], what: &str) -> Result<Pose> {
    if let Some((i, j)) = (0..16)
        .map(|k| (k / 4, k % 4))
        .find(|&(i, j)| !m[i][j].is_finite())
    {
        return Err(Error::Input(format!(
            "{what}[{i}, {j}] = {}: not finite",
            m[i][j]
        )));
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(Error::Input(format!(
            "{what}: last row must be [0, 0, 0, 1], got {:?}",
            m[3]
        )));
    }
    let r = Matrix3::from_fn(|i, j| m[i][j]);
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > 1e-6 || r.determinant() <= 0.0 {
        return Err(Error::Input(format!(
            "{what}: rotation part is not a rotation (|R^T R - I| = {err:.3e}, det = {:.6})",
            r.determinant()
        )));
    }
    let r = if err <= 1e-12 {
        r
    } else {
        let svd = r.try_svd(true, true, f64::EPSILON, 100).ok_or_else(|| {
            Error::Input(format!("{what}: cannot orthonormalise the rotation part"))
        })?;
        let (u, vt) = (svd.u.expect("computed"), svd.v_t.expect("computed"));
        u * vt
    };
    Ok(Pose::from_parts(
        Translation3::new(m[0][3], m[1][3], m[2][3]),
        Rotation3::from_matrix_unchecked(r),
    ))
}

/// A kinematic model of a dVRK manipulator, a composed system (the cart), or any model file:
/// a tree of frames driven by the actuated joints `q`, with loop closures and an RCM.
///
/// Units: lengths in m, angles in rad. `q` holds one value per actuated joint (rad for revolute,
/// m for prismatic joints), in the order of `joint_names`. Frames are addressed by their number in
/// the paper (int, see `frame_indices`) or by name (str, see `frame_names`); arrays indexed by
/// frame (the result of `fk`) are in the order of `frame_names` ("positions").
#[pyclass(module = "dvrk_twin", name = "Model", frozen)]
struct PyModel {
    model: Model,
    /// Its dynamics, built at the first dynamics call ([`dynamics::dynamics_of`]).
    dynamics: std::sync::OnceLock<dvrk_kin::DynamicsModel>,
}

impl PyModel {
    /// `what` at every configuration of `q` (with `qd`, `qdd` of the same shape where given),
    /// without the GIL for a batch: shape (N, *tail) for a batch, `tail` for one configuration.
    fn dynamics_call<'py>(
        &self,
        py: Python<'py>,
        what: dynamics::Quantity,
        tail: &[usize],
        q: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        rates: [Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>; 2],
    ) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let m = &self.model;
        let c = configs(m, &q, "q", true)?;
        drop(q);
        let [qd, qdd] = rates;
        let rate = |a: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>, name: &str| -> Result<Vec<f64>> {
            let Some(a) = a else { return Ok(vec![0.0; c.q.len()]) };
            let v = a.as_array();
            let want: Vec<usize> = if c.batch { vec![c.n, c.nq] } else { vec![c.nq] };
            if v.shape() != want.as_slice() {
                return Err(Error::Input(format!("{name} must have the shape of q, {}, got {}", shape_str(&want), shape_str(v.shape()))));
            }
            let x: Vec<f64> = v.iter().copied().collect();
            if let Some(i) = x.iter().position(|x| !x.is_finite()) {
                return Err(Error::Input(format!("{name}[{i}] = {}: must be finite", x[i])));
            }
            Ok(x)
        };
        let (qd, qdd) = (rate(qd, "qd")?, rate(qdd, "qdd")?);
        let dm = self.dynamics()?;
        let run = || dynamics::evaluate(m, dm, what, c.n, &c.q, &qd, &qdd);
        let out = if c.batch { py.detach(run)? } else { run()? };
        let mut shape = Vec::with_capacity(1 + tail.len());
        if c.batch {
            shape.push(c.n);
        }
        shape.extend_from_slice(tail);
        to_array(py, &shape, out)
    }

    /// The model's dynamics, built at the first call ([`dynamics::dynamics_of`]).
    fn dynamics(&self) -> Result<&dvrk_kin::DynamicsModel> {
        if let Some(dm) = self.dynamics.get() {
            return Ok(dm);
        }
        let dm = dynamics::dynamics_of(&self.model)?;
        Ok(self.dynamics.get_or_init(|| dm))
    }

    fn frame_pos(&self, f: FrameArg) -> Result<usize> {
        let r = match f {
            FrameArg::Number(i) => FrameRef::Index(i),
            FrameArg::Name(s) => FrameRef::Name(s),
        };
        Ok(self.model.frame_id(&r)?)
    }
}

#[pymethods]
impl PyModel {
    /// Load a model by built-in name (see `builtin_models()`) or from a file: a `.toml` model or
    /// system file, a dVRK arm `.json` (serial chain), or a `.urdf`. `tool` is a dVRK tool `.json`
    /// that replaces the tool figures (tool length, jaw offset, wrist limits) of a model that
    /// carries a tool (the PSM).
    ///
    /// Raises ModelNotFoundError (a FileNotFoundError and ValueError) for an unknown name or a
    /// missing file, listing the valid names; ModelError (a ValueError) for an invalid file,
    /// naming the file, the field and the value.
    #[staticmethod]
    #[pyo3(signature = (name_or_path, tool=None))]
    fn load(py: Python<'_>, name_or_path: PathBuf, tool: Option<PathBuf>) -> Result<Self> {
        let name = name_or_path
            .to_str()
            .ok_or_else(|| {
                Error::Input(format!(
                    "model path {} is not valid UTF-8",
                    name_or_path.display()
                ))
            })?
            .to_string();
        let model = py.detach(|| dvrk_kin::load(&name, tool.as_deref()))?;
        Ok(PyModel { model, dynamics: std::sync::OnceLock::new() })
    }

    /// Model name (str).
    #[getter]
    fn name(&self) -> &str {
        &self.model.name
    }

    /// One-line description of the model (str).
    #[getter]
    fn title(&self) -> &str {
        &self.model.title
    }

    /// Number of actuated joints: the length of `q` (int).
    #[getter]
    fn nq(&self) -> usize {
        self.model.nq()
    }

    /// Number of frames (int): the length of `frame_names` and of the first axis of `fk(q)`.
    #[getter]
    fn nframes(&self) -> usize {
        self.model.frames.len()
    }

    /// Names of the actuated joints, in the order of `q` (list[str]).
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.model.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// Kind of each joint: "revolute" (q in rad) or "prismatic" (q in m) (list[str]).
    #[getter]
    fn joint_types(&self) -> Vec<&'static str> {
        self.model
            .joints
            .iter()
            .map(|j| match j.kind {
                JointType::Revolute => "revolute",
                JointType::Prismatic => "prismatic",
            })
            .collect()
    }

    /// Joint limits, shape (nq, 2): lower, upper per joint (rad or m).
    #[getter]
    fn joint_limits<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let v = self
            .model
            .joints
            .iter()
            .flat_map(|j| [j.lower, j.upper])
            .collect();
        to_array(py, &[self.model.nq(), 2], v)
    }

    /// Home configuration, shape (nq,) (rad or m).
    #[getter]
    fn home<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.model.home())
    }

    /// Frame names, in frame-position order (list[str]).
    #[getter]
    fn frame_names(&self) -> Vec<String> {
        self.model.frames.iter().map(|f| f.name.clone()).collect()
    }

    /// The paper's frame number of each frame position (list[int]); a running number for models
    /// without one. Pass one of these (or a name) as `frame=` to `fk`, `jacobian` and `ik`.
    #[getter]
    fn frame_indices(&self) -> Vec<i64> {
        self.model.frames.iter().map(|f| f.index).collect()
    }

    /// Parent of each frame as a frame position, None for a child of the base (list[int | None]).
    /// Parents come before their children.
    #[getter]
    fn frame_parents(&self) -> Vec<Option<usize>> {
        self.model.frames.iter().map(|f| f.parent).collect()
    }

    /// Position of the tool-tip frame (int; the default frame of `jacobian` and `ik`).
    #[getter]
    fn tip(&self) -> usize {
        self.model.tip
    }

    /// Pose of the model's base frame in the world, shape (4, 4) (m). `fk` poses are in the world.
    #[getter]
    fn base<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        pose_array(py, &self.model.base)
    }

    /// Remote centre of motion in the model's base frame, shape (3,) (m), or None for a model
    /// without one.
    #[getter]
    fn rcm<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.model
            .rcm
            .as_ref()
            .map(|r| PyArray1::from_slice(py, r.point.as_slice()))
    }

    /// Rigid bodies: list of (name, [frame positions]) (frames that never move relative to
    /// each other form one body).
    #[getter]
    fn bodies(&self) -> Vec<(String, Vec<usize>)> {
        self.model
            .bodies
            .iter()
            .map(|b| (b.name.clone(), b.frames.clone()))
            .collect()
    }

    /// Loop closures: list of (name, frame, point, partner, partner_point): the point (shape
    /// (3,), m) given in frame position `frame` coincides with `partner_point` in `partner` for
    /// every q.
    #[allow(clippy::type_complexity)]
    #[getter]
    fn closures<'py>(
        &self,
        py: Python<'py>,
    ) -> Vec<(
        String,
        usize,
        Bound<'py, PyArray1<f64>>,
        usize,
        Bound<'py, PyArray1<f64>>,
    )> {
        self.model
            .closures
            .iter()
            .map(|c| {
                (
                    c.name.clone(),
                    c.frame,
                    PyArray1::from_slice(py, c.point.as_slice()),
                    c.partner,
                    PyArray1::from_slice(py, c.partner_point.as_slice()),
                )
            })
            .collect()
    }

    /// Position of a frame given by paper number (int) or name (str) (int). Raises InputError
    /// (a ValueError) listing the frame names for an unknown frame.
    fn frame_position(&self, frame: FrameArg) -> Result<usize> {
        self.frame_pos(frame)
    }

    /// The drive efforts (N·m, N) for joint positions `q` (rad, m), velocities `qd` and
    /// accelerations `qdd` ((nq,) or (N, nq) each; zero when None): inverse dynamics with the
    /// model's inertials (the file's `[[inertials]]`, else the built-in ones) and its payloads,
    /// gravity (0, 0, -9.81) m/s^2 in the model's world, and with `effects` its friction, springs
    /// and motor inertias (presliding at its sliding limit). Shape of `q`. Batches release the GIL.
    #[pyo3(signature = (q, qd=None, qdd=None, effects=true))]
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        qd: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
        qdd: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
        effects: bool,
    ) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let nq = self.model.nq();
        self.dynamics_call(py, dynamics::Quantity::InverseDynamics { effects }, &[nq], q, [qd, qdd])
    }

    /// The joint-space inertia matrix M(q) (kg m^2, kg; nq x nq, or N x nq x nq), with the
    /// motors' reflected inertia when `effects`.
    #[pyo3(signature = (q, effects=true))]
    fn mass_matrix<'py>(&self, py: Python<'py>, q: PyArrayLikeDyn<'py, f64, AllowTypeChange>, effects: bool) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let nq = self.model.nq();
        self.dynamics_call(py, dynamics::Quantity::MassMatrix { effects }, &[nq, nq], q, [None, None])
    }

    /// The gravity torque g(q) (N·m, N): the efforts that hold the arm still at `q`.
    fn gravity<'py>(&self, py: Python<'py>, q: PyArrayLikeDyn<'py, f64, AllowTypeChange>) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let nq = self.model.nq();
        self.dynamics_call(py, dynamics::Quantity::Gravity, &[nq], q, [None, None])
    }

    /// The inertial-parameter regressor Y(q, qd, qdd) (nq x 10 nbodies, or N x ...): the rigid
    /// bodies' inverse dynamics are `Y @ inertial_parameters`, per body (m, m cx, m cy, m cz,
    /// Ixx, Ixy, Ixz, Iyy, Iyz, Izz) about its first frame's origin, in `bodies` order.
    #[pyo3(signature = (q, qd=None, qdd=None))]
    fn regressor<'py>(
        &self,
        py: Python<'py>,
        q: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        qd: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
        qdd: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
    ) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let cols = dvrk_kin::dynamics::PARAMETERS_PER_BODY * self.model.bodies.len();
        let nq = self.model.nq();
        self.dynamics_call(py, dynamics::Quantity::Regressor, &[nq, cols], q, [qd, qdd])
    }

    /// The model as URDF text (the frame tree with mimic joints for the passive frames, the
    /// loops in a comment; `dvrk export urdf`); with `inertials` each body's mass, centre of mass
    /// and inertia (the dynamics' own, payloads applied) on its first frame's link, so that a
    /// URDF dynamics library with mimic joints computes the closed-loop dynamics.
    #[pyo3(signature = (inertials=false))]
    fn export_urdf(&self, inertials: bool) -> Result<String> {
        if !inertials {
            return Ok(dvrk_kin::urdf::export_urdf(&self.model)?);
        }
        Ok(dvrk_kin::urdf::export_urdf_with_inertials(&self.model, Some(self.dynamics()?.inertias()))?)
    }

    /// The inertial parameters the dynamics use (10 per body, the regressor's columns), with
    /// the payload and counterweight effects applied.
    fn inertial_parameters<'py>(&self, py: Python<'py>) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let p = self.dynamics()?.parameters();
        to_array(py, &[p.len()], p)
    }

    /// Forward kinematics: world poses (4x4 homogeneous, translation in m) at joint positions q
    /// (rad / m; size and finiteness are checked, joint limits are not).
    ///
    /// q of shape (nq,) gives (nframes, 4, 4) (every frame, in `frame_names` order) or, with
    /// `frame` (paper number or name), (4, 4). q of shape (N, nq) gives (N, nframes, 4, 4) or
    /// (N, 4, 4); a batch runs without the GIL.
    #[pyo3(signature = (q, frame=None))]
    fn fk<'py>(
        &self,
        py: Python<'py>,
        q: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        frame: Option<FrameArg>,
    ) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let m = &self.model;
        let frame = frame.map(|f| self.frame_pos(f)).transpose()?;
        let c = configs(m, &q, "q", true)?;
        drop(q);
        let nf = m.frames.len();
        let per = if frame.is_some() { 16 } else { 16 * nf };
        let run = || {
            let mut data = Data::new(m);
            let mut out = vec![0.0; c.n * per];
            for i in 0..c.n {
                compute_frame_placements(m, &mut data, c.row(i));
                let o = &mut out[i * per..(i + 1) * per];
                match frame {
                    Some(f) => write_pose(&data.frames[f], o),
                    None => {
                        for (k, p) in data.frames.iter().enumerate() {
                            write_pose(p, &mut o[16 * k..16 * (k + 1)]);
                        }
                    }
                }
            }
            out
        };
        let out = if c.batch { py.detach(run) } else { run() };
        let mut shape = Vec::with_capacity(4);
        if c.batch {
            shape.push(c.n);
        }
        if frame.is_none() {
            shape.push(nf);
        }
        shape.extend([4, 4]);
        to_array(py, &shape, out)
    }

    /// Geometric Jacobian of a frame (default: the tip) at q (rad / m): shape (6, nq); rows 0-2
    /// the linear velocity of the frame origin (m/s per rad/s or per m/s), rows 3-5 the angular
    /// velocity (rad/s per rad/s), both in world axes. q of shape (N, nq) gives (N, 6, nq),
    /// computed without the GIL.
    #[pyo3(signature = (q, frame=None))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        frame: Option<FrameArg>,
    ) -> Result<Bound<'py, PyArrayDyn<f64>>> {
        let m = &self.model;
        let f = match frame {
            Some(f) => self.frame_pos(f)?,
            None => m.tip,
        };
        let c = configs(m, &q, "q", true)?;
        drop(q);
        let nq = m.nq();
        let per = 6 * nq;
        let run = || -> std::result::Result<Vec<f64>, KinError> {
            let mut data = Data::new(m);
            let mut jac = Matrix6xX::zeros(nq);
            let mut out = vec![0.0; c.n * per];
            for i in 0..c.n {
                compute_frame_placements(m, &mut data, c.row(i));
                frame_jacobian(m, &data, f, &mut jac)?;
                let o = &mut out[i * per..(i + 1) * per];
                for r in 0..6 {
                    for k in 0..nq {
                        o[r * nq + k] = jac[(r, k)];
                    }
                }
            }
            Ok(out)
        };
        let out = if c.batch { py.detach(run)? } else { run()? };
        let shape: Vec<usize> = if c.batch {
            vec![c.n, 6, nq]
        } else {
            vec![6, nq]
        };
        to_array(py, &shape, out)
    }

    /// Inverse kinematics: joint positions q, shape (nq,) (rad / m), that put `frame` (default:
    /// the tip) at `pose` (4x4 homogeneous, world frame, translation in m), within the joint
    /// limits. Newton steps from `seed` (default: home), then from spread starts. Arms with six
    /// or more joints moving the frame reach the full pose (1e-9 m, 1e-9 rad); arms with fewer
    /// (the ECM) reach the position exactly and the orientation as well as they can.
    ///
    /// Raises IkError (a ValueError) when the target is out of reach (with the closest approach
    /// in mm and deg) or reached only outside the joint limits; InputError for a pose that is not
    /// 4x4, not finite or not a rigid transform. Runs without the GIL.
    #[pyo3(signature = (pose, seed=None, frame=None))]
    fn ik<'py>(
        &self,
        py: Python<'py>,
        pose: PyArrayLikeDyn<'py, f64, AllowTypeChange>,
        seed: Option<PyArrayLikeDyn<'py, f64, AllowTypeChange>>,
        frame: Option<FrameArg>,
    ) -> Result<Bound<'py, PyArray1<f64>>> {
        let m = &self.model;
        let frame = frame.map(|f| self.frame_pos(f)).transpose()?;
        let p = pose.as_array();
        if p.shape() != [4, 4] {
            return Err(Error::Input(format!(
                "wrong argument shape for pose: expected (4, 4), got {}",
                shape_str(p.shape())
            )));
        }
        let rows: [[f64; 4]; 4] = std::array::from_fn(|i| std::array::from_fn(|j| p[[i, j]]));
        drop(pose);
        let target = pose_from_matrix(&rows, "pose")?;
        let seed = match seed {
            Some(s) => configs(m, &s, "seed", false)?.q,
            None => m.home(),
        };
        let opts = IkOptions {
            frame,
            ..IkOptions::default()
        };
        let sol = py.detach(|| inverse_kinematics(m, &target, &seed, &opts))?;
        Ok(PyArray1::from_vec(py, sol.q))
    }

    /// Largest loop-closure gap at q (m): the distance between the two points of each closure,
    /// which coincide for a consistent mechanism (0.0 for a model without closures). q of shape
    /// (nq,) (rad / m).
    fn closure_residual(&self, q: PyArrayLikeDyn<'_, f64, AllowTypeChange>) -> Result<f64> {
        let c = configs(&self.model, &q, "q", false)?;
        let mut data = Data::new(&self.model);
        forward_kinematics(&self.model, &mut data, c.row(0))?;
        Ok(max_closure_residual(&self.model, &data))
    }

    /// Distance from the RCM to the insertion axis at q (m), or None for a model without an
    /// RCM. q of shape (nq,) (rad / m).
    fn pivot_residual(&self, q: PyArrayLikeDyn<'_, f64, AllowTypeChange>) -> Result<Option<f64>> {
        let c = configs(&self.model, &q, "q", false)?;
        let mut data = Data::new(&self.model);
        forward_kinematics(&self.model, &mut data, c.row(0))?;
        Ok(pivot_residual(&self.model, &data))
    }

    /// The figures of `dvrk model check` over `samples` configurations spread over the joint
    /// range, as a dict: max_closure_residual_m (m), rcm ([x, y, z] in m, base frame),
    /// max_pivot_residual_m (m), conditioning (sigma_min_* in m/rad), serial_equivalence
    /// (max_position_error_m, max_orientation_error_rad), ok (bool), problems (list[str]).
    /// Figures that do not apply are None. Runs without the GIL.
    #[pyo3(signature = (samples=2000))]
    fn check<'py>(&self, py: Python<'py>, samples: usize) -> Result<Bound<'py, PyAny>> {
        let report = py.detach(|| check_model(&self.model, samples))?;
        let text =
            serde_json::to_string(&report).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        Ok(py.import("json")?.call_method1("loads", (text,))?)
    }

    fn __repr__(&self) -> String {
        let m = &self.model;
        format!(
            "<dvrk_twin.Model '{}': {} joints, {} frames, tip {}>",
            m.name,
            m.nq(),
            m.frames.len(),
            m.frames.get(m.tip).map_or("-", |f| f.name.as_str())
        )
    }
}

/// Names of the built-in models accepted by `Model.load` (list[str]).
#[pyfunction]
fn builtin_models() -> Vec<&'static str> {
    dvrk_kin::builtin_names().collect()
}

/// Kinematics of the da Vinci Research Kit manipulators (native part of `dvrk_twin`).
#[pymodule]
fn _dvrk_twin(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<PyModel>()?;
    m.add_function(wrap_pyfunction!(builtin_models, m)?)?;
    m.add_class::<sim::PySim>()?;
    m.add_class::<batch::PyBatchSim>()?;
    m.add_function(wrap_pyfunction!(sim::run_scene, m)?)?;
    m.add_function(wrap_pyfunction!(sim::serve, m)?)?;
    m.add_function(wrap_pyfunction!(sim::builtin_scenes, m)?)?;
    m.add_function(wrap_pyfunction!(sim::export_mjcf, m)?)?;
    m.add_function(wrap_pyfunction!(calib::pivot, m)?)?;
    m.add_function(wrap_pyfunction!(calib::axis, m)?)?;
    m.add_function(wrap_pyfunction!(calib::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(calib::identify, m)?)?;
    m.add_function(wrap_pyfunction!(calib::discrepancy, m)?)?;
    m.add_function(wrap_pyfunction!(calib::synth_hidden_effect, m)?)?;
    let ex = exceptions(py)?;
    m.add("DvrkError", ex.base.bind(py))?;
    m.add("ModelError", ex.model.bind(py))?;
    m.add("ModelNotFoundError", ex.not_found.bind(py))?;
    m.add("InputError", ex.input.bind(py))?;
    m.add("IkError", ex.ik.bind(py))?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
