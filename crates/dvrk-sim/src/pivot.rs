//! Pivot calibration (paper eq. 3-5): the fixed point `b_post` (world) that a point `b_tip`
//! fixed in a moving frame keeps passing through, from sampled poses of that frame.

use dvrk_kin::Pose;
use nalgebra::{DMatrix, DVector, Vector3};

/// A pivot: the point fixed in the moving frame and the fixed point it keeps passing through (m),
/// with the fit's residuals. (dvrk-calib's `PivotFit` is the calibration's report, with intervals.)
#[derive(Debug, Clone, PartialEq)]
pub struct PivotPoint {
    /// The point in the moving frame.
    pub tip: Vector3<f64>,
    /// The fixed point in the world.
    pub post: Vector3<f64>,
    /// RMS over samples of |b_post - R b_tip - p| (m).
    pub rms: f64,
    /// Largest of the same (m).
    pub max: f64,
}

/// Least-squares pivot fit of `poses` (at least 3 distinct orientations); `None` when the
/// orientations do not determine the point (rank-deficient).
pub fn pivot_fit(poses: &[Pose]) -> Option<PivotPoint> {
    let n = poses.len();
    if n < 3 {
        return None;
    }
    let mut a = DMatrix::zeros(3 * n, 6);
    let mut b = DVector::zeros(3 * n);
    for (i, p) in poses.iter().enumerate() {
        let r = p.rotation.matrix();
        for row in 0..3 {
            for col in 0..3 {
                a[(3 * i + row, col)] = r[(row, col)];
            }
            a[(3 * i + row, 3 + row)] = -1.0;
            b[3 * i + row] = -p.translation.vector[row];
        }
    }
    let svd = a.svd(true, true);
    let s = &svd.singular_values;
    if s.iter().copied().fold(f64::INFINITY, f64::min) < 1e-9 * s.max() {
        return None;
    }
    let x = svd.solve(&b, 1e-12).ok()?;
    let tip = Vector3::new(x[0], x[1], x[2]);
    let post = Vector3::new(x[3], x[4], x[5]);
    let res: Vec<f64> = poses.iter().map(|p| (post - (p.rotation * tip + p.translation.vector)).norm()).collect();
    let rms = (res.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
    let max = res.iter().copied().fold(0.0, f64::max);
    Some(PivotPoint { tip, post, rms, max })
}

/// The paper's section 4.2 experiment in simulation: arm `arm` of `scene` sweeps its first two
/// joints over a 3 x 3 grid (`q1_amplitude`, `q2_amplitude` about home, rad, clamped to the
/// limits) under PID, settling `settle` seconds at each point, and the pose of `frame`'s body is
/// pivot-fitted. The fitted `post` is the arm's remote centre of motion in the world (m).
pub fn simulated_rcm(scene: &crate::Scene, arm: usize, frame: &dvrk_kin::FrameRef, q1_amplitude: f64, q2_amplitude: f64, settle: f64) -> crate::Result<PivotPoint> {
    use crate::error::SimError;
    let mut sim = crate::Sim::new(scene, &crate::SimOptions::default())?;
    let a = sim.arms.get(arm).ok_or_else(|| SimError::value("arm index", arm as f64, format!("the scene has {} arms", scene.arms.len())))?;
    let (model, off) = (a.model.clone(), a.q_offset);
    if model.nq() < 2 {
        return Err(SimError::field(&scene.name, &a.name, "a pivot sweep needs two joints"));
    }
    let body = model.frames[model.frame_id(frame)?].body;
    let home = model.home();
    let steps = (settle / sim.dt).round().max(1.0) as usize;
    let mut poses = Vec::with_capacity(9);
    for s1 in [-1.0, 0.0, 1.0] {
        for s2 in [-1.0, 0.0, 1.0] {
            for (k, s, amp) in [(0, s1, q1_amplitude), (1, s2, q2_amplitude)] {
                let j = &model.joints[k];
                sim.set_target(off + k, (home[k] + s * amp).clamp(j.lower, j.upper), 0.0)?;
            }
            for _ in 0..steps {
                sim.step();
            }
            poses.push(sim.body_pose(arm, body));
        }
    }
    pivot_fit(&poses).ok_or_else(|| SimError::field(&scene.name, &model.name, "the sweep did not determine a pivot (amplitudes too small?)"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3};

    #[test]
    fn recovers_an_exact_pivot() {
        let tip = Vector3::new(0.01, -0.2, 0.05);
        let post = Vector3::new(0.3, 0.1, -0.4);
        let poses: Vec<Pose> = (0..20)
            .map(|i| {
                let r = Rotation3::from_euler_angles(0.1 * i as f64, -0.05 * i as f64, 0.02 * (i * i) as f64);
                Pose::from_parts(Translation3::from(post - r * tip), r)
            })
            .collect();
        let f = pivot_fit(&poses).unwrap();
        assert!((f.tip - tip).norm() < 1e-10 && (f.post - post).norm() < 1e-10 && f.rms < 1e-10, "{f:?}");
    }
}
