//! Inverse kinematics of a tool tip, iterative as the dVRK controller does it (Newton steps on
//! the Jacobian), with position as the primary task and orientation in its null space so that
//! arms with fewer than six joints (the ECM) reach the position exactly and the orientation as
//! well as they can.

use crate::error::{KinError, Result};
use crate::fk::{compute_frame_placements, Data};
use crate::jacobian::frame_jacobian;
use crate::model::{sample_configurations, Model, Pose};
use nalgebra::{DMatrix, DVector, Matrix6xX, Vector3};
use std::f64::consts::PI;

/// Options of [`inverse_kinematics`].
#[derive(Debug, Clone)]
pub struct IkOptions {
    /// Frame to place (default: the model's tip).
    pub frame: Option<usize>,
    /// Converged when the position error is below this (m).
    pub position_tolerance: f64,
    /// Converged when the orientation error is below this (rad); ignored for arms with fewer
    /// than six joints moving the frame.
    pub orientation_tolerance: f64,
    /// Newton iterations per start.
    pub max_iterations: usize,
    /// Extra starts spread over the joint range, tried when the seed does not converge.
    pub restarts: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions { frame: None, position_tolerance: 1e-9, orientation_tolerance: 1e-9, max_iterations: 200, restarts: 16 }
    }
}

/// A solution of [`inverse_kinematics`].
#[derive(Debug, Clone)]
pub struct IkSolution {
    /// Joint positions (rad / m).
    pub q: Vec<f64>,
    /// Remaining position error (m).
    pub position_error: f64,
    /// Remaining orientation error (rad).
    pub orientation_error: f64,
    pub iterations: usize,
}

fn pose_error(target: &Pose, current: &Pose) -> (Vector3<f64>, Vector3<f64>) {
    let ep = target.translation.vector - current.translation.vector;
    let eo = crate::so3::log(&(target.rotation * current.rotation.inverse()));
    (ep, eo)
}

/// Solve `FK(q)[frame] == target` (target in the world frame of the model).
///
/// Errors: the target is out of reach (reports how far the best attempt stayed), or every
/// solution violates a joint limit (names the joint and value).
pub fn inverse_kinematics(model: &Model, target: &Pose, seed: &[f64], opts: &IkOptions) -> Result<IkSolution> {
    model.check_q_size(seed)?;
    let t = target.translation.vector;
    if t.iter().any(|x| !x.is_finite()) || target.rotation.matrix().iter().any(|x| !x.is_finite()) {
        return Err(KinError::Ik("target pose has a non-finite entry".into()));
    }
    let frame = opts.frame.unwrap_or(model.tip);
    let mut data = Data::new(model);
    let mut jac = Matrix6xX::zeros(model.nq());
    // Joints that move the frame at all.
    compute_frame_placements(model, &mut data, seed);
    frame_jacobian(model, &data, frame, &mut jac)?;
    let active: Vec<usize> = (0..model.nq()).filter(|&k| jac.column(k).norm() > 0.0).collect();
    let full_pose = active.len() >= 6;

    let mut starts = vec![seed.to_vec()];
    starts.extend(sample_configurations(&model.joints, opts.restarts));
    let mut best: Option<IkSolution> = None;
    let mut limit_violation: Option<KinError> = None;
    for start in starts {
        let sol = newton(model, &mut data, &mut jac, frame, target, start, &active, opts);
        let converged = sol.position_error <= opts.position_tolerance
            && (!full_pose || sol.orientation_error <= opts.orientation_tolerance);
        if converged {
            let mut sol = sol;
            wrap_into_limits(model, &mut sol.q, seed);
            match model.check_q(&sol.q) {
                Ok(()) => return Ok(sol),
                Err(e) => {
                    limit_violation.get_or_insert(e);
                }
            }
        } else if best.as_ref().is_none_or(|b| sol.position_error < b.position_error) {
            best = Some(sol);
        }
    }
    if let Some(e) = limit_violation {
        return Err(KinError::Ik(format!("the target is reached only outside the joint limits: {e}")));
    }
    let b = best.expect("at least one start");
    Err(KinError::Ik(format!(
        "target out of reach: closest approach leaves {:.3} mm position error and {:.3} deg orientation error",
        b.position_error * 1e3,
        b.orientation_error.to_degrees()
    )))
}

#[allow(clippy::too_many_arguments)]
fn newton(
    model: &Model,
    data: &mut Data,
    jac: &mut Matrix6xX<f64>,
    frame: usize,
    target: &Pose,
    mut q: Vec<f64>,
    active: &[usize],
    opts: &IkOptions,
) -> IkSolution {
    let na = active.len();
    let mut iterations = 0;
    for it in 0..opts.max_iterations {
        iterations = it;
        compute_frame_placements(model, data, &q);
        let (ep, eo) = pose_error(target, &data.frames[frame]);
        if !(ep.norm().is_finite() && eo.norm().is_finite()) {
            break;
        }
        if ep.norm() <= opts.position_tolerance * 0.1 && eo.norm() <= opts.orientation_tolerance * 0.1 {
            break;
        }
        frame_jacobian(model, data, frame, jac).expect("sized for the model");
        let jp = DMatrix::from_fn(3, na, |r, c| jac[(r, active[c])]);
        let jo = DMatrix::from_fn(3, na, |r, c| jac[(r + 3, active[c])]);
        // Position first; orientation in the null space of the position task (damped).
        let jp_pinv = damped_pinv(&jp, 1e-10);
        let dq1 = &jp_pinv * DVector::from_column_slice(ep.as_slice());
        let null = DMatrix::identity(na, na) - &jp_pinv * &jp;
        let jo_n = &jo * &null;
        let eo_rest = DVector::from_column_slice(eo.as_slice()) - &jo * &dq1;
        let dq2 = &null * damped_pinv(&jo_n, 1e-8) * eo_rest;
        let dq = dq1 + dq2;
        // Limit the step so Newton stays in the basin (0.3 rad or 0.05 m at most).
        let scale = active
            .iter()
            .enumerate()
            .map(|(i, &k)| {
                let cap = match model.joints[k].kind {
                    crate::spec::JointType::Revolute => 0.3,
                    crate::spec::JointType::Prismatic => 0.05,
                };
                (dq[i].abs() / cap).max(1.0)
            })
            .fold(1.0, f64::max);
        // Projected Newton: stay inside the joint limits so the iteration finds the branch the
        // arm can reach (wrist solutions come in pairs, one often outside the range).
        for (i, &k) in active.iter().enumerate() {
            let j = &model.joints[k];
            q[k] = (q[k] + dq[i] / scale).clamp(j.lower, j.upper);
        }
    }
    compute_frame_placements(model, data, &q);
    let (ep, eo) = pose_error(target, &data.frames[frame]);
    IkSolution { q, position_error: ep.norm(), orientation_error: eo.norm(), iterations }
}

/// `J^T (J J^T + lambda^2 I)^-1`
fn damped_pinv(j: &DMatrix<f64>, lambda: f64) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(j.ncols(), j.nrows());
    if j.iter().any(|x| !x.is_finite()) {
        return out; // no step: the caller reports the error it could not reduce
    }
    // Bounded iterations: an SVD that does not converge gives no step rather than a hang.
    let Some(svd) = j.clone().try_svd(true, true, f64::EPSILON, 1000) else { return out };
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else { return out };
    let s = svd.singular_values;
    for (i, &si) in s.iter().enumerate() {
        if si > 1e-12 {
            let f = si / (si * si + lambda * lambda);
            out += vt.row(i).transpose() * u.column(i).transpose() * f;
        }
    }
    out
}

/// Bring revolute joints into their limits by whole turns, nearest the seed.
fn wrap_into_limits(model: &Model, q: &mut [f64], seed: &[f64]) {
    for (k, j) in model.joints.iter().enumerate() {
        if j.kind != crate::spec::JointType::Revolute {
            continue;
        }
        let mut best = q[k];
        let mut best_d = f64::INFINITY;
        for turns in -3..=3 {
            let v = q[k] + 2.0 * PI * turns as f64;
            if v >= j.lower - 1e-9 && v <= j.upper + 1e-9 && (v - seed[k]).abs() < best_d {
                best = v;
                best_d = (v - seed[k]).abs();
            }
        }
        q[k] = best;
    }
}
