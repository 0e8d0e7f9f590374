//! The immutable model: flat arrays of frames in depth-first order (parent before child), the
//! actuated joints, loop closures, bodies and the RCM. Built once from a [`ModelSpec`]; evaluated
//! with a reusable [`crate::Data`].

use crate::error::{KinError, Result};
use crate::expr::{parse_affine, Affine, Scope};
use crate::spec::{Convention, FrameJoint, FrameRef, JointType, ModelSpec, Value};
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};
use std::collections::BTreeMap;

/// A rigid transform (rotation matrix + translation in m).
pub type Pose = nalgebra::IsometryMatrix3<f64>;

/// An actuated joint: one coordinate of `q`.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    pub name: String,
    pub kind: JointType,
    /// rad or m
    pub lower: f64,
    /// rad or m
    pub upper: f64,
    /// N·m or N (0: unknown)
    pub effort_limit: f64,
    /// rad or m
    pub home: f64,
}

impl Joint {
    /// Unit of the position: `rad` or `m`.
    pub fn unit(&self) -> &'static str {
        match self.kind {
            JointType::Revolute => "rad",
            JointType::Prismatic => "m",
        }
    }
}

/// How a frame moves relative to its parent.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Motion {
    /// The whole local transform is constant.
    Fixed(Pose),
    /// `pre * Rz(theta(q)) * Tz(d0) * post`
    Revolute { d0: f64 },
    /// `pre * Tz(d(q)) * post` (theta folded into `pre`)
    Prismatic,
}

/// How a revolute frame's angle is evaluated: most are `+-q_k + b`, whose sine and cosine come
/// from one `sin_cos(q_k)` per evaluation by the angle-sum formulas.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Angle {
    Unit { joint: usize, sign: f64, sin_b: f64, cos_b: f64 },
    General { terms: Vec<(usize, f64)>, offset: f64 },
}

/// Sparse forms of the frames' affine maps, built once per model for the FK loop.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Eval {
    /// Per frame: the angle of a revolute frame (`None` otherwise).
    pub(crate) angle: Vec<Option<Angle>>,
    /// Per frame: the non-zero terms of `d` and its offset (prismatic frames).
    pub(crate) lin: Vec<(Vec<(usize, f64)>, f64)>,
    /// Joints whose `sin_cos` the angles use.
    pub(crate) trig_joints: Vec<usize>,
}

impl Eval {
    pub(crate) fn build(frames: &[Frame]) -> Eval {
        let mut eval = Eval::default();
        for f in frames {
            let angle = match f.motion {
                Motion::Revolute { .. } => {
                    let terms: Vec<(usize, f64)> = f.theta.joints().collect();
                    Some(match terms.as_slice() {
                        [(k, c)] if c.abs() == 1.0 => {
                            if !eval.trig_joints.contains(k) {
                                eval.trig_joints.push(*k);
                            }
                            let (sin_b, cos_b) = f.theta.offset.sin_cos();
                            Angle::Unit { joint: *k, sign: *c, sin_b, cos_b }
                        }
                        _ => Angle::General { terms, offset: f.theta.offset },
                    })
                }
                _ => None,
            };
            eval.angle.push(angle);
            eval.lin.push((f.d.joints().collect(), f.d.offset));
        }
        eval
    }
}

/// One frame of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// The paper's frame number (PSM, ECM) or a running number.
    pub index: i64,
    pub name: String,
    /// Predecessor (position in [`Model::frames`]); `None` for a child of the base.
    pub parent: Option<usize>,
    /// Rigid part (position in [`Model::bodies`]).
    pub body: usize,
    pub joint: FrameJoint,
    /// DH `a` (m) and `alpha` (rad); NaN for frames given as a transform.
    pub a: f64,
    pub alpha: f64,
    /// Joint angle as an affine map of `q` (rad).
    pub theta: Affine,
    /// Joint offset as an affine map of `q` (m).
    pub d: Affine,
    pub(crate) pre: Pose,
    pub(crate) post: Option<Pose>,
    pub(crate) motion: Motion,
}

impl Frame {
    /// True when this frame's placement relative to its parent depends on `q`.
    pub fn is_moving(&self) -> bool {
        !matches!(self.motion, Motion::Fixed(_))
    }
    /// The frame's joint variable (theta for revolute, d for prismatic), if it moves.
    pub fn variable(&self) -> Option<&Affine> {
        match self.motion {
            Motion::Fixed(_) => None,
            Motion::Revolute { .. } => Some(&self.theta),
            Motion::Prismatic => Some(&self.d),
        }
    }
    /// Constant transform before the joint motion (`Rx(alpha) Tx(a)` in modified DH).
    pub fn pre(&self) -> &Pose {
        &self.pre
    }
    /// Constant transform after the joint motion (standard DH: `Tx(a) Rx(alpha)`).
    pub fn post(&self) -> Option<&Pose> {
        self.post.as_ref()
    }
}

/// Frames that move as one rigid part.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    pub name: String,
    /// Positions in [`Model::frames`].
    pub frames: Vec<usize>,
}

/// A loop closure: `frame * point == partner * partner_point` for every `q`.
#[derive(Debug, Clone, PartialEq)]
pub struct Closure {
    pub name: String,
    pub frame: usize,
    /// m, in `frame`
    pub point: Vector3<f64>,
    pub partner: usize,
    /// m, in `partner`
    pub partner_point: Vector3<f64>,
}

/// The remote centre of motion: the fixed point the z axis of `frame` passes through.
#[derive(Debug, Clone, PartialEq)]
pub struct Rcm {
    pub frame: usize,
    /// m, in the model's base frame
    pub point: Vector3<f64>,
}

/// An immutable kinematic model.
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub title: String,
    pub joints: Vec<Joint>,
    /// Depth-first order: a frame's parent comes before it.
    pub frames: Vec<Frame>,
    pub bodies: Vec<Body>,
    pub closures: Vec<Closure>,
    pub rcm: Option<Rcm>,
    /// The tool-tip frame.
    pub tip: usize,
    /// Where the model's base frame sits in the world.
    pub base: Pose,
    /// ActuatorToJointPosition (joints x actuators), if the file gives one.
    pub coupling: Option<nalgebra::DMatrix<f64>>,
    /// The file this model was compiled from (for export, tools and calibration updates).
    pub spec: ModelSpec,
    /// Where the model was loaded from (a file), for resolving relative references.
    pub origin: Option<std::path::PathBuf>,
    /// The dVRK tool file applied to this model, if any.
    pub tool_file: Option<std::path::PathBuf>,
    /// The arms of a composed system (empty for a single model).
    pub parts: Vec<Part>,
    /// Physical effects from the file's `[[effects]]`, checked; the kinematic ones are already
    /// applied to the frames and base.
    pub effects: Vec<crate::effects::Effect>,
    /// Sparse evaluation data, built by [`Model::finalize`].
    pub(crate) eval: Eval,
}

/// One arm of a composed system (see [`crate::compose`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Part {
    /// Arm name (`PSM1`, `SUJ-ECM`...), the prefix of its frame and joint names.
    pub name: String,
    /// The model it was built from (built-in name or path).
    pub model: String,
    /// Its joints within `q`.
    pub joints: std::ops::Range<usize>,
    /// Its frames within [`Model::frames`] (the mount frame first).
    pub frames: std::ops::Range<usize>,
    /// Its RCM: `frame` indexes the system's frames, `point` is in the arm's base frame, which
    /// is the mount frame `frames.start` (m).
    pub rcm: Option<Rcm>,
}

/// Deterministic, well-spread configurations within the joint limits (golden-ratio sequence).
pub fn sample_configurations(joints: &[Joint], count: usize) -> Vec<Vec<f64>> {
    const PHI: f64 = 0.618_033_988_749_894_9;
    (0..count)
        .map(|i| {
            joints
                .iter()
                .enumerate()
                .map(|(k, j)| {
                    let u = ((i as f64 + 1.0) * PHI * (1.0 + 0.37 * k as f64) + 0.13 * k as f64).fract();
                    j.lower + (j.upper - j.lower) * u
                })
                .collect()
        })
        .collect()
}

fn rx(alpha: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::x_axis(), alpha))
}
fn rz(theta: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::z_axis(), theta))
}
fn tx(a: f64) -> Pose {
    Pose::from_parts(Translation3::new(a, 0.0, 0.0), Rotation3::identity())
}
fn tz(d: f64) -> Pose {
    Pose::from_parts(Translation3::new(0.0, 0.0, d), Rotation3::identity())
}

/// A pose from a row-major 4x4 matrix; the rotation must be orthonormal.
pub fn pose_from_rows(m: &[[f64; 4]; 4], field: &str) -> Result<Pose> {
    if m.iter().flatten().any(|x| !x.is_finite()) {
        return Err(KinError::field(field, "transform has a non-finite entry"));
    }
    let r = Matrix3::new(m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2], m[2][0], m[2][1], m[2][2]);
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > 1e-3 || r.determinant() < 0.0 {
        return Err(KinError::field(field, format!("rotation part is not a rotation (|R^T R - I| = {err:.3e})")));
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(KinError::field(field, format!("last row must be [0, 0, 0, 1], got {:?}", m[3])));
    }
    // Re-orthonormalise the 4-digit rotations of dVRK files so chained poses stay rigid.
    let rot = Rotation3::from_matrix_eps(&r, 1e-12, 100, Rotation3::identity());
    Ok(Pose::from_parts(Translation3::new(m[0][3], m[1][3], m[2][3]), rot))
}

/// A pose as a row-major 4x4 matrix.
pub fn pose_to_rows(p: &Pose) -> [[f64; 4]; 4] {
    let h = p.to_homogeneous();
    let mut out = [[0.0; 4]; 4];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = h[(i, j)];
        }
    }
    out
}

impl Model {
    /// Last step of building a model from frames: the evaluation data, then the bodies (named
    /// from `declared`, one optional name per frame).
    pub(crate) fn finalize(&mut self, declared: &[Option<String>]) -> Result<()> {
        self.eval = Eval::build(&self.frames);
        crate::bodies::assign_bodies(self, declared)
    }

    /// Number of actuated joints (the length of `q`).
    pub fn nq(&self) -> usize {
        self.joints.len()
    }

    /// Position of a frame given by number or name.
    pub fn frame_id(&self, r: &FrameRef) -> Result<usize> {
        let found = match r {
            FrameRef::Index(i) => self.frames.iter().position(|f| f.index == *i),
            FrameRef::Name(s) => self
                .frames
                .iter()
                .position(|f| f.name == *s)
                .or_else(|| s.parse::<i64>().ok().and_then(|i| self.frames.iter().position(|f| f.index == i))),
        };
        found.ok_or_else(|| KinError::unknown("frame", &r.to_string(), self.frames.iter().map(|f| f.name.clone())))
    }

    /// Position of a joint given by name.
    pub fn joint_id(&self, name: &str) -> Result<usize> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| KinError::unknown("joint", name, self.joints.iter().map(|j| j.name.clone())))
    }

    /// The joints whose values move frame `frame` (position in [`Model::frames`]) relative to the
    /// base: every joint with a coefficient in the joint variable of the frame or one of its
    /// predecessors (passive frames are affine in the actuated joints, so loops are covered).
    pub fn frame_support(&self, frame: usize) -> Vec<bool> {
        let mut moves = vec![false; self.nq()];
        let mut at = Some(frame);
        while let Some(f) = at.and_then(|i| self.frames.get(i)) {
            for (k, _) in f.variable().into_iter().flat_map(|v| v.joints()) {
                moves[k] = true;
            }
            at = f.parent;
        }
        moves
    }

    /// The home configuration.
    pub fn home(&self) -> Vec<f64> {
        self.joints.iter().map(|j| j.home).collect()
    }

    /// Check `q` has the right length, is finite and lies within the joint limits.
    pub fn check_q(&self, q: &[f64]) -> Result<()> {
        self.check_q_size(q)?;
        for (j, x) in self.joints.iter().zip(q) {
            if *x < j.lower - 1e-9 || *x > j.upper + 1e-9 {
                return Err(KinError::Value {
                    what: format!("joint {}", j.name),
                    value: *x,
                    message: format!("outside its limits [{}, {}] {}", j.lower, j.upper, j.unit()),
                });
            }
        }
        Ok(())
    }

    /// Check `q` has the right length and is finite (limits not enforced).
    pub fn check_q_size(&self, q: &[f64]) -> Result<()> {
        if q.len() != self.nq() {
            return Err(KinError::Size { what: format!("q of model {}", self.name), expected: self.nq(), got: q.len() });
        }
        if let Some((j, x)) = self.joints.iter().zip(q).find(|(_, x)| !x.is_finite()) {
            return Err(KinError::Value { what: format!("joint {}", j.name), value: *x, message: "not finite".into() });
        }
        Ok(())
    }

    /// Compile a model file. `load_serial` is not needed here: serial equivalence is checked by
    /// [`crate::check`].
    pub fn compile(mut spec: ModelSpec) -> Result<Model> {
        let n = spec.joints.len();
        // A link_length effect edits the DH table itself; the spec keeps the file's numbers.
        let file_spec = spec.clone();
        crate::effects::apply_link_lengths(&mut spec)?;
        crate::effects::apply_counterweight(&mut spec)?;
        let mut parameters = BTreeMap::new();
        for (k, p) in &spec.parameters {
            if !p.value.is_finite() {
                return Err(KinError::field(format!("parameters.{k}.value"), format!("{} is not finite", p.value)));
            }
            parameters.insert(k.clone(), p.value);
        }
        let joint_names: Vec<String> = spec.joints.iter().map(|j| j.name.clone()).collect();
        let mut joints = Vec::with_capacity(n);
        for (i, j) in spec.joints.iter().enumerate() {
            let field = |f: &str| format!("joints[{i}] ({}).{f}", j.name);
            for (f, v) in [("lower", j.lower), ("upper", j.upper), ("effort_limit", j.effort_limit)] {
                if !v.is_finite() {
                    return Err(KinError::field(field(f), format!("{v} is not finite")));
                }
            }
            if j.lower > j.upper {
                return Err(KinError::field(field("lower"), format!("{} is above upper = {}", j.lower, j.upper)));
            }
            if joint_names[..i].contains(&j.name) {
                return Err(KinError::field(field("name"), format!("`{}` appears twice", j.name)));
            }
            let home = j.home.unwrap_or(0.0_f64.clamp(j.lower, j.upper));
            if !home.is_finite() || home < j.lower || home > j.upper {
                return Err(KinError::field(field("home"), format!("{home} is not within [{}, {}]", j.lower, j.upper)));
            }
            joints.push(Joint {
                name: j.name.clone(),
                kind: j.kind,
                lower: j.lower,
                upper: j.upper,
                effort_limit: j.effort_limit,
                home,
            });
        }
        let scope = Scope { parameters: &parameters, joints: &joint_names };
        let order = frame_order(&spec)?;
        let mut frames: Vec<Frame> = Vec::with_capacity(order.len());
        let mut position = vec![usize::MAX; spec.frames.len()];
        for (pos, &(fi, parent)) in order.iter().enumerate() {
            position[fi] = pos;
            let fs = &spec.frames[fi];
            let field = |f: &str| format!("frames[{fi}] ({}).{f}", fs.name);
            let value = |v: &Value, f: &str| -> Result<Affine> {
                match v {
                    Value::Number(x) if x.is_finite() => Ok(Affine::constant(n, *x)),
                    Value::Number(x) => Err(KinError::field(field(f), format!("{x} is not finite"))),
                    Value::Expr(e) => parse_affine(e, &field(f), &scope),
                }
            };
            let a = value(&fs.a, "a")?;
            let alpha = value(&fs.alpha, "alpha")?;
            let d = value(&fs.d, "d")?;
            let theta = value(&fs.theta, "theta")?;
            for (aff, f) in [(&a, "a"), (&alpha, "alpha")] {
                if !aff.is_constant() {
                    return Err(KinError::field(field(f), "must not depend on a joint"));
                }
            }
            let (pre, post, motion) = if let Some(t) = &fs.transform {
                if fs.joint != FrameJoint::Fixed {
                    return Err(KinError::field(field("transform"), "only a fixed frame may be given as a transform"));
                }
                if [&fs.a, &fs.alpha, &fs.d, &fs.theta].iter().any(|v| **v != Value::Number(0.0)) {
                    return Err(KinError::field(field("transform"), "give either a transform or DH entries, not both"));
                }
                let p = pose_from_rows(t, &field("transform"))?;
                (Pose::identity(), None, Motion::Fixed(p))
            } else {
                let (pre, post) = match spec.convention {
                    Convention::Modified => (rx(alpha.offset) * tx(a.offset), None),
                    Convention::Standard => (Pose::identity(), Some(tx(a.offset) * rx(alpha.offset))),
                };
                let motion = match fs.joint {
                    FrameJoint::Fixed => {
                        if !theta.is_constant() || !d.is_constant() {
                            return Err(KinError::field(field("joint"), "a fixed frame's theta and d must not depend on a joint"));
                        }
                        let mut p = pre * rz(theta.offset) * tz(d.offset);
                        if let Some(post) = &post {
                            p *= post;
                        }
                        Motion::Fixed(p)
                    }
                    FrameJoint::Revolute => {
                        if !d.is_constant() {
                            return Err(KinError::field(field("d"), "a revolute frame's d must not depend on a joint"));
                        }
                        if theta.is_constant() {
                            // Locked revolute (the paper lists some as R with a constant angle).
                            let mut p = pre * rz(theta.offset) * tz(d.offset);
                            if let Some(post) = &post {
                                p *= post;
                            }
                            Motion::Fixed(p)
                        } else {
                            Motion::Revolute { d0: d.offset }
                        }
                    }
                    FrameJoint::Prismatic => {
                        if !theta.is_constant() {
                            return Err(KinError::field(field("theta"), "a prismatic frame's theta must not depend on a joint"));
                        }
                        if d.is_constant() {
                            // Locked prismatic: as for revolute frames with a constant angle.
                            let mut p = pre * rz(theta.offset) * tz(d.offset);
                            if let Some(post) = &post {
                                p *= post;
                            }
                            Motion::Fixed(p)
                        } else {
                            Motion::Prismatic
                        }
                    }
                };
                let pre = match motion {
                    Motion::Prismatic => pre * rz(theta.offset),
                    _ => pre,
                };
                (pre, post, motion)
            };
            let (a_num, alpha_num) =
                if fs.transform.is_some() { (f64::NAN, f64::NAN) } else { (a.offset, alpha.offset) };
            frames.push(Frame {
                index: fs.index.unwrap_or(pos as i64 + 1),
                name: fs.name.clone(),
                parent: parent.map(|p| position[p]),
                body: 0,
                joint: fs.joint,
                a: a_num,
                alpha: alpha_num,
                theta,
                d,
                pre,
                post,
                motion,
            });
        }
        for (i, f) in frames.iter().enumerate() {
            if frames[..i].iter().any(|g| g.name == f.name) {
                return Err(KinError::field(format!("frames ({}).name", f.name), "frame name appears twice"));
            }
            if frames[..i].iter().any(|g| g.index == f.index) {
                return Err(KinError::field(format!("frames ({}).index", f.name), format!("frame number {} appears twice", f.index)));
            }
        }
        let coupling = match &spec.coupling {
            None => None,
            Some(rows) => Some(matrix_from_rows(rows, "coupling")?),
        };
        let mut model = Model {
            name: spec.name.clone(),
            title: spec.title.clone(),
            joints,
            frames,
            bodies: Vec::new(),
            closures: Vec::new(),
            rcm: None,
            tip: 0,
            base: Pose::identity(),
            coupling,
            spec: file_spec,
            origin: None,
            tool_file: None,
            parts: Vec::new(),
            effects: Vec::new(),
            eval: Eval::default(),
        };
        model.tip = match &spec.tip {
            Some(r) => model.frame_id(r).map_err(|e| KinError::field("tip", e.to_string()))?,
            None => model.frames.len().saturating_sub(1),
        };
        if model.frames.is_empty() {
            return Err(KinError::field("frames", "a model needs at least one frame"));
        }
        let effects = crate::effects::check_effects(&model)?;
        crate::effects::apply_kinematic(&mut model, &effects)?;
        model.effects = effects;
        let declared: Vec<Option<String>> =
            (0..model.frames.len()).map(|i| model.spec_frame(i).and_then(|f| f.body.clone())).collect();
        model.finalize(&declared)?;
        model.check_inertials()?;
        model.check_drive()?;
        model.check_inertial_covariance()?;
        crate::closure::compile_closures(&mut model)?;
        if let Some(r) = &spec.rcm {
            let frame = model.frame_id(&r.frame).map_err(|e| KinError::field("rcm.frame", e.to_string()))?;
            let point = crate::rcm::locate_rcm(&model, frame);
            model.rcm = Some(Rcm { frame, point });
        }
        Ok(model)
    }
}

impl Model {
    /// The `[[inertials]]` of the model file: each names a body once and is physical
    /// ([`crate::BodyInertia::check`]).
    fn check_inertials(&self) -> Result<()> {
        for (i, e) in self.spec.inertials.iter().enumerate() {
            let what = format!("inertials[{i}] ({})", e.body);
            if !self.bodies.iter().any(|b| b.name == e.body) {
                let valid: Vec<&str> = self.bodies.iter().map(|b| b.name.as_str()).collect();
                return Err(KinError::field(format!("{what}.body"), format!("model {} has no body `{}` (valid: {})", self.name, e.body, valid.join(", "))));
            }
            if self.spec.inertials[..i].iter().any(|o| o.body == e.body) {
                return Err(KinError::field(format!("{what}.body"), "body appears twice"));
            }
            crate::BodyInertia::new(e.mass, e.com, e.inertia).check(&what)?;
        }
        Ok(())
    }

    /// The model file's `[drive]`: an armature per joint, every figure finite and non-negative.
    fn check_drive(&self) -> Result<()> {
        let Some(d) = &self.spec.drive else { return Ok(()) };
        if d.armature.len() != self.nq() {
            return Err(KinError::field("drive.armature", format!("has {} entries, model {} has {} joints", d.armature.len(), self.name, self.nq())));
        }
        let bad = |v: f64| !v.is_finite() || v < 0.0;
        if bad(d.damping) {
            return Err(KinError::field("drive.damping", format!("{} is not a finite non-negative number", d.damping)));
        }
        if let Some((k, v)) = d.armature.iter().enumerate().find(|(_, v)| bad(**v)) {
            return Err(KinError::field(format!("drive.armature[{k}] ({})", self.joints[k].name), format!("{v} is not a finite non-negative number")));
        }
        Ok(())
    }

    /// The model file's `[inertial_covariance]`: known bodies, each once, and a lower triangular
    /// factor of the right size with finite entries and a positive diagonal.
    fn check_inertial_covariance(&self) -> Result<()> {
        let Some(c) = &self.spec.inertial_covariance else { return Ok(()) };
        for (i, name) in c.bodies.iter().enumerate() {
            if !self.bodies.iter().any(|b| &b.name == name) {
                return Err(KinError::field(format!("inertial_covariance.bodies[{i}]"), format!("model {} has no body `{name}`", self.name)));
            }
            if c.bodies[..i].contains(name) {
                return Err(KinError::field(format!("inertial_covariance.bodies[{i}]"), format!("body `{name}` appears twice")));
            }
        }
        let n = c.bodies.len() * crate::dynamics::PARAMETERS_PER_BODY;
        if c.cholesky.len() != n {
            return Err(KinError::field("inertial_covariance.cholesky", format!("has {} rows; {} bodies need {n}", c.cholesky.len(), c.bodies.len())));
        }
        for (i, row) in c.cholesky.iter().enumerate() {
            let what = format!("inertial_covariance.cholesky[{i}]");
            if row.len() != i + 1 {
                return Err(KinError::field(what, format!("has {} entries; row {i} of a lower triangular factor has {}", row.len(), i + 1)));
            }
            if let Some((k, v)) = row.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(KinError::field(format!("{what}[{k}]"), format!("{v} is not a finite number")));
            }
            if !(row[i] > 0.0) {
                return Err(KinError::field(format!("{what}[{i}]"), format!("{:.6e}: the diagonal of a Cholesky factor is positive", row[i])));
            }
        }
        Ok(())
    }

    /// The covariance of the parameters of `bodies` (each [`crate::dynamics::PARAMETERS_PER_BODY`]
    /// in order, positions in [`Model::bodies`]) from the model file's `[inertial_covariance]`,
    /// as its lower Cholesky factor; `None` if the file has none or it leaves out one of them.
    pub fn inertial_covariance_factor(&self, bodies: &[usize]) -> Option<nalgebra::DMatrix<f64>> {
        let c = self.spec.inertial_covariance.as_ref()?;
        let per = crate::dynamics::PARAMETERS_PER_BODY;
        let pos: Vec<usize> = bodies
            .iter()
            .map(|&b| {
                let name = &self.bodies.get(b)?.name;
                c.bodies.iter().position(|n| n == name)
            })
            .collect::<Option<_>>()?;
        let n = c.bodies.len() * per;
        let full = nalgebra::DMatrix::from_fn(n, n, |i, k| if k <= i { c.cholesky[i][k] } else { 0.0 });
        // The requested parameters' rows of L: their covariance is L_s L_s^T, refactored.
        let rows: Vec<usize> = pos.iter().flat_map(|p| p * per..(p + 1) * per).collect();
        let sel = full.select_rows(&rows);
        (&sel * sel.transpose()).cholesky().map(|ch| ch.l())
    }

    /// Body `b`'s inertial from the model file's `[[inertials]]`, if it has one.
    pub fn file_inertia(&self, b: usize) -> Option<crate::BodyInertia> {
        let name = &self.bodies.get(b)?.name;
        self.spec.inertials.iter().find(|e| &e.body == name).map(|e| crate::BodyInertia::new(e.mass, e.com, e.inertia))
    }
}

/// A dense matrix from rows, checking it is rectangular and finite.
pub(crate) fn matrix_from_rows(rows: &[Vec<f64>], field: &str) -> Result<nalgebra::DMatrix<f64>> {
    let nr = rows.len();
    let nc = rows.first().map_or(0, |r| r.len());
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != nc) {
        return Err(KinError::field(format!("{field}[{i}]"), format!("row has {} entries, expected {nc}", r.len())));
    }
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err(KinError::field(field, "has a non-finite entry"));
    }
    Ok(nalgebra::DMatrix::from_fn(nr, nc, |i, j| rows[i][j]))
}

/// Depth-first order of the spec's frames with each one's parent (spec positions), or an error
/// naming an unknown parent or a cycle.
fn frame_order(spec: &ModelSpec) -> Result<Vec<(usize, Option<usize>)>> {
    let nf = spec.frames.len();
    let mut parent: Vec<Option<usize>> = Vec::with_capacity(nf);
    for (i, f) in spec.frames.iter().enumerate() {
        let field = format!("frames[{i}] ({}).parent", f.name);
        let p = match &f.parent {
            FrameRef::Index(0) => None,
            FrameRef::Name(s) if s == "base" => None,
            r => {
                let found = spec.frames.iter().enumerate().position(|(k, g)| match r {
                    FrameRef::Index(x) => g.index.unwrap_or(k as i64 + 1) == *x,
                    FrameRef::Name(s) => g.name == *s,
                });
                match found {
                    Some(k) if k == i => return Err(KinError::field(field, format!("`{r}` is the frame itself"))),
                    Some(k) => Some(k),
                    None => {
                        let valid = std::iter::once("0 (base)".to_string())
                            .chain(spec.frames.iter().enumerate().map(|(k, g)| format!("{} ({})", g.index.unwrap_or(k as i64 + 1), g.name)));
                        return Err(KinError::field(field, KinError::unknown("frame", &r.to_string(), valid).to_string()));
                    }
                }
            }
        };
        parent.push(p);
    }
    // Depth-first from the base, children in file order.
    let mut order = Vec::with_capacity(nf);
    let mut stack: Vec<usize> = (0..nf).rev().filter(|&i| parent[i].is_none()).collect();
    while let Some(i) = stack.pop() {
        order.push((i, parent[i]));
        stack.extend((0..nf).rev().filter(|&k| parent[k] == Some(i)));
    }
    if order.len() < nf {
        let missing: Vec<&str> =
            (0..nf).filter(|i| !order.iter().any(|(k, _)| k == i)).map(|i| spec.frames[i].name.as_str()).collect();
        return Err(KinError::field("frames", format!("frames {} form a cycle (none reaches the base)", missing.join(", "))));
    }
    Ok(order)
}
