//! Pivot calibration (paper section 4.1, eq. 3-5): the point `b_tip` fixed in a marker cluster
//! and the point `b_post` fixed in the tracker frame with `b_post = R_i b_tip + p_i` for every
//! sample. With markers on link 8 and q1, q2 moving, that point is the RCM.
//!
//! Three estimators (Yaniv, "Which pivot calibration?", SPIE 2015):
//! - one-step: least squares of the stacked `[R_i -I] [b_tip; b_post] = -p_i` (eq. 4);
//! - two-step: `b_tip` from the mean-centred system `(R_i - mean R) b_tip = -(p_i - mean p)`,
//!   then `b_post = mean(R_i b_tip + p_i)`. It eliminates `b_post` exactly, so it equals the
//!   one-step solution in exact arithmetic; it solves a 3x3 instead of a 6x6 system;
//! - sphere: the marker-frame origins lie on a sphere about `b_post` (algebraic fit), then
//!   `b_tip = mean(R_i^T (b_post - p_i))`. It ignores the orientations.
//!
//! All accumulate sums in one pass over the poses (translations shifted by the first sample so
//! the sums keep their digits), with no per-sample allocation.

use crate::error::{CalibError, Result};
use crate::mocap::motion_range::{motion_range, MotionRange};
use dvrk_kin::Pose;
use nalgebra::{Matrix3, Matrix4, Matrix6, Rotation3, SymmetricEigen, Vector3, Vector4, Vector6};

// The motion thresholds are shared by the axis and pivot fits.
pub use crate::mocap::motion_range::{MIN_RANGE, MIN_SAMPLES, WARN_RANGE};

/// Which estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PivotMethod {
    /// The stacked `[R_i -I]` system of eq. 4 (the paper's).
    #[default]
    OneStep,
    /// Eliminate `b_post`, solve for `b_tip`, then average.
    TwoStep,
    /// Algebraic sphere fit of the marker-frame origins.
    Sphere,
}

impl PivotMethod {
    /// The name used on the command line and in JSON.
    pub fn name(&self) -> &'static str {
        match self {
            PivotMethod::OneStep => "one-step",
            PivotMethod::TwoStep => "two-step",
            PivotMethod::Sphere => "sphere",
        }
    }
}

impl std::str::FromStr for PivotMethod {
    type Err = CalibError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "one-step" => Ok(PivotMethod::OneStep),
            "two-step" => Ok(PivotMethod::TwoStep),
            "sphere" => Ok(PivotMethod::Sphere),
            _ => Err(CalibError::field("method", format!("`{s}` is not a pivot method; valid: one-step, two-step, sphere"))),
        }
    }
}

/// Options of [`pivot_calibration`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PivotOptions {
    pub method: PivotMethod,
    /// Samples whose residual exceeds this many times the median residual are dropped and the
    /// fit repeated (0 disables).
    pub outlier_factor: f64,
}

impl Default for PivotOptions {
    fn default() -> Self {
        PivotOptions { method: PivotMethod::OneStep, outlier_factor: 6.0 }
    }
}

/// A pivot calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct PivotFit {
    pub method: PivotMethod,
    /// `b_tip`: the pivot point in the marker frame (m).
    pub tip: Vector3<f64>,
    /// `b_post`: the pivot point in the tracker frame (m).
    pub pivot: Vector3<f64>,
    /// Covariance of `tip` (m^2), from the residuals (heteroscedasticity-robust sandwich).
    pub tip_cov: Matrix3<f64>,
    /// Covariance of `pivot` (m^2), likewise.
    pub pivot_cov: Matrix3<f64>,
    /// The paper's eq. 5 per tracker axis, with the 1/n its Table 7 figures imply:
    /// `sqrt(mean_i (b_post - R_i b_tip - p_i)_j^2)` for j = x, y, z (m).
    pub rms_per_axis: [f64; 3],
    /// Plain RMS over all 3n residual components (m): `sqrt(sum |e_i|^2 / 3n)`.
    pub rms: f64,
    /// RMS distance of the per-sample pivot points from `pivot` (m): `sqrt(sum |e_i|^2 / n)`.
    pub rms_distance: f64,
    /// Samples used.
    pub samples: usize,
    /// Samples dropped as outliers.
    pub outliers: usize,
    /// Rotation ranges of the marker frame over the samples used.
    pub motion: MotionRange,
    /// Smallest eigenvalue of the normal matrix over n (1: ideal, 0: undetermined).
    pub conditioning: f64,
    /// What the user should know about this result, with numbers.
    pub warnings: Vec<String>,
}

impl PivotFit {
    /// Standard deviations of `tip` along the marker axes (m).
    pub fn tip_std(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| self.tip_cov[(k, k)].max(0.0).sqrt())
    }
    /// Standard deviations of `pivot` along the tracker axes (m).
    pub fn pivot_std(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| self.pivot_cov[(k, k)].max(0.0).sqrt())
    }
    /// The per-sample pivot points `R_i b_tip + p_i` (the point cloud of Figure 9), tracker frame (m).
    pub fn cloud(&self, poses: &[Pose]) -> Vec<Vector3<f64>> {
        poses.iter().map(|p| p.rotation * self.tip + p.translation.vector).collect()
    }
}

/// Least-squares pivot point of `poses` (marker frame in the tracker frame).
pub fn pivot_calibration(poses: &[Pose], options: &PivotOptions) -> Result<PivotFit> {
    let what = "pivot calibration";
    if poses.len() < MIN_SAMPLES {
        return Err(CalibError::data(what, format!("{} pose(s); it needs at least {MIN_SAMPLES} spread over two joint motions", poses.len())));
    }
    if let Some(i) = poses.iter().position(|p| !p.to_homogeneous().iter().all(|x| x.is_finite())) {
        return Err(CalibError::data(what, format!("pose {i} is not finite")));
    }
    let all: Vec<Rotation3<f64>> = poses.iter().map(|p| p.rotation).collect();
    let motion_all = motion_range(&all);
    let too_small = |m: &MotionRange, n: usize| {
        CalibError::motion(
            what,
            format!(
                "the marker frame turned {:.2} deg and {:.2} deg about its two main directions over {n} samples; a pivot needs \
                 rotation about two directions of at least {:.1} deg each (move q1 and q2)",
                m.ranges[0].to_degrees(),
                m.ranges[1].to_degrees(),
                MIN_RANGE.to_degrees()
            ),
        )
    };
    if motion_all.ranges[1] < MIN_RANGE {
        return Err(too_small(&motion_all, poses.len()));
    }
    let mut keep = vec![true; poses.len()];
    let mut outliers = 0;
    let mut est = solve(poses, &keep, options.method)?;
    // Drop samples far off the fit (a swapped or ghost marker) and refit, at most three times.
    for _ in 0..3 {
        if options.outlier_factor <= 0.0 {
            break;
        }
        let mut d: Vec<f64> = poses.iter().zip(&keep).filter(|(_, k)| **k).map(|(p, _)| residual(p, &est).norm()).collect();
        let mid = d.len() / 2;
        let median = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
        let limit = (options.outlier_factor * median).max(1e-9);
        let mut dropped = 0;
        for (p, k) in poses.iter().zip(keep.iter_mut()) {
            if *k && residual(p, &est).norm() > limit {
                *k = false;
                dropped += 1;
            }
        }
        if dropped == 0 {
            break;
        }
        outliers += dropped;
        est = solve(poses, &keep, options.method)?;
    }
    let used: Vec<Rotation3<f64>> = poses.iter().zip(&keep).filter(|(_, k)| **k).map(|(p, _)| p.rotation).collect();
    let n = used.len();
    let motion = motion_range(&used);
    let (r0, r1) = (motion.ranges[0].to_degrees(), motion.ranges[1].to_degrees());
    if motion.ranges[1] < MIN_RANGE || est.conditioning < 1e-12 {
        return Err(too_small(&motion, n));
    }
    // Residual statistics and the robust covariance, in one more pass.
    let mut ss = Vector3::zeros();
    let mut meat = Matrix6::zeros();
    for (p, _) in poses.iter().zip(&keep).filter(|(_, k)| **k) {
        let e = residual(p, &est);
        ss += e.component_mul(&e);
        let g = Vector6::from_iterator(p.rotation.inverse_transform_vector(&e).iter().copied().chain((-e).iter().copied()));
        meat += g * g.transpose();
    }
    let dof = (3 * n) as f64 / ((3 * n) as f64 - 6.0);
    let cov = est.normal_inverse * meat * est.normal_inverse * dof;
    let (tip_cov, pivot_cov) = match options.method {
        PivotMethod::Sphere => (est.sphere_tip_cov.unwrap_or(cov.fixed_view::<3, 3>(0, 0).into_owned()), est.sphere_pivot_cov.unwrap_or(cov.fixed_view::<3, 3>(3, 3).into_owned())),
        _ => (cov.fixed_view::<3, 3>(0, 0).into_owned(), cov.fixed_view::<3, 3>(3, 3).into_owned()),
    };
    let nf = n as f64;
    let rms_per_axis = [(ss.x / nf).sqrt(), (ss.y / nf).sqrt(), (ss.z / nf).sqrt()];
    let total = ss.sum();
    let mut warnings = Vec::new();
    if motion.ranges[1] < WARN_RANGE {
        let s = pivot_cov.diagonal().map(|x| x.max(0.0).sqrt() * 1e3);
        warnings.push(format!(
            "motion range too small for a meaningful pivot: the marker frame turned {r0:.1} deg and {r1:.1} deg about its two main \
             directions (at least {:.0} deg each is advised); pivot std ({:.3}, {:.3}, {:.3}) mm",
            WARN_RANGE.to_degrees(),
            s.x,
            s.y,
            s.z
        ));
    }
    if outliers > 0 {
        warnings.push(format!("{outliers} of {} samples dropped as outliers (residual over {} x median)", poses.len(), options.outlier_factor));
    }
    Ok(PivotFit {
        method: options.method,
        tip: est.tip,
        pivot: est.pivot,
        tip_cov,
        pivot_cov,
        rms_per_axis,
        rms: (total / (3.0 * nf)).sqrt(),
        rms_distance: (total / nf).sqrt(),
        samples: n,
        outliers,
        motion,
        conditioning: est.conditioning,
        warnings,
    })
}

/// `R b_tip + p - b_post` (m, tracker frame).
#[inline]
fn residual(p: &Pose, e: &Estimate) -> Vector3<f64> {
    p.rotation * e.tip + p.translation.vector - e.pivot
}

struct Estimate {
    tip: Vector3<f64>,
    pivot: Vector3<f64>,
    /// Inverse of the one-step normal matrix `sum J_i^T J_i` (for the covariance).
    normal_inverse: Matrix6<f64>,
    conditioning: f64,
    sphere_tip_cov: Option<Matrix3<f64>>,
    sphere_pivot_cov: Option<Matrix3<f64>>,
}

fn solve(poses: &[Pose], keep: &[bool], method: PivotMethod) -> Result<Estimate> {
    let what = "pivot calibration";
    // Shift translations by the first kept sample: sums of p ~ metres would otherwise swamp the
    // millimetre differences the fit depends on.
    let shift = poses.iter().zip(keep).find(|(_, k)| **k).map(|(p, _)| p.translation.vector).unwrap_or_default();
    let mut n = 0.0;
    let mut sum_r = Matrix3::zeros();
    let mut sum_rtp = Vector3::zeros();
    let mut sum_p = Vector3::zeros();
    for (pose, _) in poses.iter().zip(keep).filter(|(_, k)| **k) {
        let r = pose.rotation.matrix();
        let p = pose.translation.vector - shift;
        n += 1.0;
        sum_r += r;
        sum_rtp += r.transpose() * p;
        sum_p += p;
    }
    // One-step normal matrix [[nI, -sum R^T], [-sum R, nI]] (also used for the covariance).
    let mut normal = Matrix6::zeros();
    normal.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Matrix3::identity() * n));
    normal.fixed_view_mut::<3, 3>(3, 3).copy_from(&(Matrix3::identity() * n));
    normal.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-sum_r.transpose()));
    normal.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-sum_r));
    let eig = SymmetricEigen::new(normal / n);
    let conditioning = eig.eigenvalues.min();
    let normal_inverse = normal.try_inverse().unwrap_or_else(|| Matrix6::from_element(f64::NAN));
    let singular = || CalibError::motion(what, "the poses do not determine a pivot point (the marker frame did not rotate)");
    let mut sphere_tip_cov = None;
    let mut sphere_pivot_cov = None;
    let (tip, pivot) = match method {
        PivotMethod::OneStep => {
            if conditioning < 1e-14 {
                return Err(singular());
            }
            let rhs = Vector6::from_iterator((-sum_rtp).iter().copied().chain(sum_p.iter().copied()));
            let x = normal_inverse * rhs;
            (Vector3::new(x[0], x[1], x[2]), Vector3::new(x[3], x[4], x[5]))
        }
        PivotMethod::TwoStep => {
            let m = Matrix3::identity() * n - sum_r.transpose() * sum_r / n;
            let rhs = -(sum_rtp - sum_r.transpose() * sum_p / n);
            let tip = m.try_inverse().ok_or_else(singular)? * rhs;
            (tip, (sum_r * tip + sum_p) / n)
        }
        PivotMethod::Sphere => {
            let mut a = Matrix4::zeros();
            let mut b = Vector4::zeros();
            for (pose, _) in poses.iter().zip(keep).filter(|(_, k)| **k) {
                let q = pose.translation.vector - shift;
                let m = Vector4::new(2.0 * q.x, 2.0 * q.y, 2.0 * q.z, 1.0);
                a += m * m.transpose();
                b += m * q.norm_squared();
            }
            let ainv = a.try_inverse().ok_or_else(|| CalibError::motion(what, "the marker-frame origins do not span a sphere"))?;
            let x = ainv * b;
            let centre = Vector3::new(x[0], x[1], x[2]);
            let mut meat = Matrix4::zeros();
            let mut tip = Vector3::zeros();
            for (pose, _) in poses.iter().zip(keep).filter(|(_, k)| **k) {
                let q = pose.translation.vector - shift;
                let m = Vector4::new(2.0 * q.x, 2.0 * q.y, 2.0 * q.z, 1.0);
                let r = q.norm_squared() - m.dot(&x);
                meat += m * m.transpose() * (r * r);
                tip += pose.rotation.inverse_transform_vector(&(centre - q));
            }
            tip /= n;
            let cc = (ainv * meat * ainv).fixed_view::<3, 3>(0, 0).into_owned() * (n / (n - 4.0).max(1.0));
            let rbar = Rotation3::from_matrix_eps(&sum_r, 1e-12, 100, Rotation3::identity());
            sphere_pivot_cov = Some(cc);
            sphere_tip_cov = Some(rbar.matrix().transpose() * cc * rbar.matrix());
            (tip, centre)
        }
    };
    if !(tip.iter().chain(pivot.iter()).all(|x| x.is_finite())) {
        return Err(singular());
    }
    Ok(Estimate { tip, pivot: pivot + shift, normal_inverse, conditioning, sphere_tip_cov, sphere_pivot_cov })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, Unit};

    /// Poses of a frame whose point `tip` stays at `pivot` while it turns about two axes.
    fn pivoting(tip: Vector3<f64>, pivot: Vector3<f64>, range: f64) -> Vec<Pose> {
        (0..400)
            .map(|i| {
                let t = i as f64 / 400.0 * std::f64::consts::TAU;
                let r = Rotation3::from_axis_angle(&Vector3::z_axis(), range * t.sin())
                    * Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(1.0, 0.2, 0.0)), range * (3.0 * t).cos())
                    * Rotation3::from_axis_angle(&Vector3::y_axis(), 0.7);
                Pose::from_parts(Translation3::from(pivot - r * tip), r)
            })
            .collect()
    }

    #[test]
    fn every_method_finds_an_exact_pivot() {
        let tip = Vector3::new(0.04, -0.13, 0.02);
        let pivot = Vector3::new(1.1, -0.4, 2.3);
        let poses = pivoting(tip, pivot, 0.5);
        for method in [PivotMethod::OneStep, PivotMethod::TwoStep, PivotMethod::Sphere] {
            let f = pivot_calibration(&poses, &PivotOptions { method, ..Default::default() }).unwrap();
            assert!((f.tip - tip).norm() < 1e-9, "{method:?} {}", (f.tip - tip).norm());
            assert!((f.pivot - pivot).norm() < 1e-9, "{method:?}");
            assert!(f.rms < 1e-9 && f.warnings.is_empty(), "{:?}", f.warnings);
        }
    }

    #[test]
    fn too_little_motion_is_an_error_and_small_motion_a_warning() {
        let tip = Vector3::new(0.04, -0.13, 0.02);
        let pivot = Vector3::new(1.1, -0.4, 2.3);
        let e = pivot_calibration(&pivoting(tip, pivot, 0.0), &PivotOptions::default()).unwrap_err().to_string();
        assert!(e.contains("0.00 deg and 0.00 deg"), "{e}");
        // 2 degrees peak about each axis: a result, with the ranges it saw in the warning.
        let f = pivot_calibration(&pivoting(tip, pivot, 2f64.to_radians()), &PivotOptions::default()).unwrap();
        assert_eq!(f.warnings.len(), 1);
        assert!(f.warnings[0].contains("motion range too small"), "{:?}", f.warnings);
        let e = pivot_calibration(&pivoting(tip, pivot, 0.5)[..5], &PivotOptions::default()).unwrap_err().to_string();
        assert!(e.contains("5 pose(s)"), "{e}");
    }
}
