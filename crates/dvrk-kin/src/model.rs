//! The immutable model: flat arrays of frames in depth-first order (parent before child), the
//! actuated joints, loop closures, bodies and the RCM. Built once from a [`ModelSpec`]; evaluated
//! with a reusable [`crate::Data`].

use crate::error::{KinError, Result};
use crate::expr::Affine;
use crate::spec::{FrameJoint, FrameRef, JointType, ModelSpec};
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

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

    /// Unit of the effort: `N·m` or `N`.
    pub fn effort_unit(&self) -> &'static str {
        match self.kind {
            JointType::Revolute => "N·m",
            JointType::Prismatic => "N",
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
    pub effects: Vec<crate::vocabulary::Effect>,
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

/// Elementary DH poses: rotations about x and z (rad), translations along x and z (m).
pub(crate) fn rx(alpha: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::x_axis(), alpha))
}
pub(crate) fn rz(theta: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::z_axis(), theta))
}
pub(crate) fn tx(a: f64) -> Pose {
    Pose::from_parts(Translation3::new(a, 0.0, 0.0), Rotation3::identity())
}
pub(crate) fn tz(d: f64) -> Pose {
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

}


