//! Forward kinematics of every frame of a tree.

use crate::error::Result;
use crate::model::{Angle, Model, Motion, Pose};
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

/// Reusable workspace of a model: every buffer sized once, nothing allocated per evaluation.
#[derive(Debug, Clone)]
pub struct Data {
    /// World pose of each frame (`nframes`), filled by [`forward_kinematics`].
    pub frames: Vec<Pose>,
    /// `(sin q_k, cos q_k)` of the joints the angles use (`nq`).
    trig: Vec<(f64, f64)>,
}

impl Data {
    /// Allocate the workspace of `model`.
    pub fn new(model: &Model) -> Self {
        Data { frames: vec![Pose::identity(); model.frames.len()], trig: vec![(0.0, 1.0); model.nq()] }
    }
}

/// Compute the world pose of every frame at joint positions `q` (rad / m) into `data.frames`.
/// Checks the size and finiteness of `q`, not the joint limits.
pub fn forward_kinematics<'d>(model: &Model, data: &'d mut Data, q: &[f64]) -> Result<&'d [Pose]> {
    model.check_q_size(q)?;
    compute_frame_placements(model, data, q);
    Ok(&data.frames)
}

/// [`forward_kinematics`] without the checks, for loops that already checked `q`.
/// Panics only if `q` or `data` do not belong to `model`.
#[inline]
pub fn compute_frame_placements(model: &Model, data: &mut Data, q: &[f64]) {
    let eval = &model.eval;
    for &k in &eval.trig_joints {
        data.trig[k] = q[k].sin_cos();
    }
    for (i, f) in model.frames.iter().enumerate() {
        let local = match &f.motion {
            Motion::Fixed(p) => *p,
            Motion::Revolute { d0 } => {
                let (s, c) = match &eval.angle[i] {
                    Some(Angle::Unit { joint, sign, sin_b, cos_b }) => {
                        let (sq, cq) = data.trig[*joint];
                        (sign * sq * cos_b + cq * sin_b, cq * cos_b - sign * sq * sin_b)
                    }
                    Some(Angle::General { terms, offset }) => {
                        terms.iter().fold(*offset, |acc, (k, c)| acc + c * q[*k]).sin_cos()
                    }
                    None => f.theta.eval(q).sin_cos(),
                };
                let mut p = rz_tz(&f.pre, s, c, *d0);
                if let Some(post) = &f.post {
                    p *= post;
                }
                p
            }
            Motion::Prismatic => {
                let (terms, offset) = &eval.lin[i];
                let d = terms.iter().fold(*offset, |acc, (k, c)| acc + c * q[*k]);
                let r = f.pre.rotation.matrix();
                let mut p = Pose::from_parts(
                    Translation3::from(f.pre.translation.vector + r.column(2) * d),
                    f.pre.rotation,
                );
                if let Some(post) = &f.post {
                    p *= post;
                }
                p
            }
        };
        data.frames[i] = match f.parent {
            Some(p) => data.frames[p] * local,
            None => model.base * local,
        };
    }
}

/// `pre * Rz(theta) * Tz(d)` from `sin(theta)`, `cos(theta)`, without forming `Rz`.
#[inline]
fn rz_tz(pre: &Pose, s: f64, c: f64, d: f64) -> Pose {
    let r = pre.rotation.matrix();
    let c0: Vector3<f64> = r.column(0) * c + r.column(1) * s;
    let c1: Vector3<f64> = r.column(1) * c - r.column(0) * s;
    let c2: Vector3<f64> = r.column(2).into();
    Pose::from_parts(
        Translation3::from(pre.translation.vector + c2 * d),
        Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[c0, c1, c2])),
    )
}

impl Model {
    /// World poses of every frame at `q` (allocates a workspace: use [`forward_kinematics`] in loops).
    pub fn fk(&self, q: &[f64]) -> Result<Vec<Pose>> {
        let mut data = Data::new(self);
        forward_kinematics(self, &mut data, q)?;
        Ok(data.frames)
    }
}
