//! Geometric Jacobians of frames with respect to the actuated joints.

use crate::error::{KinError, Result};
use crate::fk::Data;
use crate::model::{Model, Motion};
use nalgebra::{Matrix6xX, Vector3};

/// Geometric Jacobian of `frame` (6 x nq) for the placements in `data`: rows 0-2 the linear
/// velocity of the frame origin (m/s per rad/s or m/s), rows 3-5 the angular velocity (rad/s),
/// both in world axes. Passive frames contribute through their affine maps (`d theta / d q_k`).
/// `out` must be 6 x nq; it is overwritten.
pub fn frame_jacobian(model: &Model, data: &Data, frame: usize, out: &mut Matrix6xX<f64>) -> Result<()> {
    if out.ncols() != model.nq() {
        return Err(KinError::Size { what: "Jacobian columns (nq)".into(), expected: model.nq(), got: out.ncols() });
    }
    if frame >= model.frames.len() {
        return Err(KinError::Size { what: "frame index bound".into(), expected: model.frames.len(), got: frame });
    }
    out.fill(0.0);
    let p = data.frames[frame].translation.vector;
    let mut cur = Some(frame);
    while let Some(j) = cur {
        let f = &model.frames[j];
        cur = f.parent;
        let Some(var) = f.variable() else { continue };
        let (lin, ang) = joint_motion_at(model, data, j, &p);
        for (k, c) in var.joints() {
            for r in 0..3 {
                out[(r, k)] += c * lin[r];
                out[(r + 3, k)] += c * ang[r];
            }
        }
    }
    Ok(())
}

impl Model {
    /// Geometric Jacobian (6 x nq) of `frame` at `q` (allocates; see [`frame_jacobian`]).
    pub fn jacobian(&self, q: &[f64], frame: usize) -> Result<Matrix6xX<f64>> {
        let mut data = Data::new(self);
        crate::fk::forward_kinematics(self, &mut data, q)?;
        let mut j = Matrix6xX::zeros(self.nq());
        frame_jacobian(self, &data, frame, &mut j)?;
        Ok(j)
    }
}

/// Velocity of world point `p` (linear, m per unit of the joint variable) and angular velocity
/// (rad per unit) when the variable of moving frame `j` alone changes, for the placements in
/// `data`. The joint axis is the z axis of `parent * pre` (before the motion, so standard-DH
/// `post` transforms do not move it).
pub(crate) fn joint_motion_at(model: &Model, data: &Data, j: usize, p: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let f = &model.frames[j];
    let axis_frame = match f.parent {
        Some(pp) => data.frames[pp] * f.pre,
        None => model.base * f.pre,
    };
    let z: Vector3<f64> = axis_frame.rotation.matrix().column(2).into();
    match f.motion {
        Motion::Revolute { .. } => (z.cross(&(p - axis_frame.translation.vector)), z),
        _ => (z, Vector3::zeros()),
    }
}
