//! The axis of rotation between two marker clusters (paper section 2.4, eq. 1-2): a point `g`
//! and a direction `h` in the frame of the reference cluster `a`, from the poses of `a` and of
//! the moving cluster `b` in the tracker frame.
//!
//! - SARA (Ehrig et al. 2007, symmetrical axis of rotation approach), the default: every point
//!   `x` of the axis has fixed coordinates `x_a` in `a` and `x_b` in `b`, so
//!   `R_a,i x_a + p_a,i = R_b,i x_b + p_b,i` for every sample. Stacked, `[R_a,i  -R_b,i] x = p_b,i - p_a,i`
//!   is a linear least-squares problem whose solution set is the axis: the null vector of the
//!   normal matrix is the direction (in both frames), the minimum-norm solution a point. Both
//!   clusters may move; with `a` the tracker itself (`R_a = I`) it is the hinge form of eq. 4.
//! - Gamage & Lasenby (2002): points of `b` carried into `a` by the relative transforms of eq. 1
//!   move on circles about the axis. The direction is the least-variance direction of the summed
//!   covariance of their trajectories; the point solves the linear centre equations in the plane
//!   normal to it. The bias that marker noise puts into both is removed as Halvorsen (2003)
//!   does for the centre of rotation: the noise variance is the smallest eigenvalue.
//!
//! The point reported is the one closest to the origin of `a` (the axis has no preferred point).

use crate::error::{CalibError, Result};
use crate::mocap::motion_range::{motion_range, MotionRange};
use dvrk_kin::Pose;
use nalgebra::{Matrix3, Matrix6, Rotation3, SymmetricEigen, Vector3, Vector6};

// The motion thresholds are shared by the axis and pivot fits.
pub use crate::mocap::motion_range::{MIN_RANGE, MIN_SAMPLES, WARN_RANGE};

/// Which estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AxisMethod {
    /// Symmetrical axis of rotation approach (linear least squares in both frames).
    #[default]
    Sara,
    /// Gamage & Lasenby on the relative transforms, bias-compensated.
    GamageLasenby,
}

impl AxisMethod {
    /// The name used on the command line, in configuration files and in JSON.
    pub fn name(&self) -> &'static str {
        match self {
            AxisMethod::Sara => "sara",
            AxisMethod::GamageLasenby => "gamage-lasenby",
        }
    }
}

impl std::str::FromStr for AxisMethod {
    type Err = CalibError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "sara" => Ok(AxisMethod::Sara),
            "gamage-lasenby" => Ok(AxisMethod::GamageLasenby),
            _ => Err(CalibError::field("method", format!("`{s}` is not an axis method; valid: sara, gamage-lasenby"))),
        }
    }
}

/// Options of [`fit_axis`].
#[derive(Debug, Clone, PartialEq)]
pub struct AxisOptions {
    pub method: AxisMethod,
    /// Samples whose residual exceeds this many times the median are dropped and the fit
    /// repeated (0 disables).
    pub outlier_factor: f64,
    /// Points of the moving cluster (its frame, m) that Gamage & Lasenby follow: its markers
    /// when known; by default the origin and 50 mm along each axis.
    pub points: Option<Vec<Vector3<f64>>>,
    /// Gamage & Lasenby: remove the noise bias (Halvorsen). Exact for independent isotropic
    /// noise on each followed point (raw markers, [`gamage_lasenby_points`]); points carried
    /// through noisy poses have correlated, anisotropic noise, which it only reduces.
    pub bias_correction: bool,
}

impl Default for AxisOptions {
    fn default() -> Self {
        AxisOptions { method: AxisMethod::Sara, outlier_factor: 6.0, points: None, bias_correction: true }
    }
}

/// A fitted axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisFit {
    pub method: AxisMethod,
    /// Point of the axis closest to the origin of the reference cluster, in its frame (m).
    pub point: Vector3<f64>,
    /// Unit direction, reference frame.
    pub direction: Vector3<f64>,
    /// The same point in the moving cluster's frame (m).
    pub point_moving: Vector3<f64>,
    /// The direction in the moving cluster's frame.
    pub direction_moving: Vector3<f64>,
    /// Covariance of `point` normal to the axis (m^2, reference frame; along-axis part removed).
    pub point_cov: Matrix3<f64>,
    /// Covariance of `point_moving` normal to the axis (m^2, moving frame).
    pub point_moving_cov: Matrix3<f64>,
    /// Covariance of `direction` (rad^2 for its two tilts, reference frame).
    pub direction_cov: Matrix3<f64>,
    /// RMS distance between the axis point as carried by each cluster (m).
    pub rms: f64,
    /// That distance per sample used, in order (m): the axis residuals to plot.
    pub residuals: Vec<f64>,
    /// Common samples used.
    pub samples: usize,
    /// Samples dropped as outliers.
    pub outliers: usize,
    /// Rotation ranges of the moving cluster relative to the reference: `ranges[0]` is the joint's
    /// range, `ranges[1]` the wobble about other directions.
    pub motion: MotionRange,
    /// Second-smallest eigenvalue of the normal matrix over n (0: the axis is undetermined).
    pub conditioning: f64,
    pub warnings: Vec<String>,
}

impl AxisFit {
    /// RMS standard deviation of the point normal to the axis (m): `sqrt(trace(point_cov))`.
    pub fn point_std(&self) -> f64 {
        self.point_cov.trace().max(0.0).sqrt()
    }
    /// RMS standard deviation of the direction (rad): `sqrt(trace(direction_cov))`.
    pub fn direction_std(&self) -> f64 {
        self.direction_cov.trace().max(0.0).sqrt()
    }
}

/// The axis between `reference` and `moving`, given at the same instants (tracker frame).
/// `what` names the axis in messages.
pub fn fit_axis(reference: &[Pose], moving: &[Pose], options: &AxisOptions, what: &str) -> Result<AxisFit> {
    if reference.len() != moving.len() {
        return Err(CalibError::data(what, format!("{} reference poses but {} moving poses", reference.len(), moving.len())));
    }
    let n_all = reference.len();
    if n_all < MIN_SAMPLES {
        return Err(CalibError::data(what, format!("{n_all} common sample(s) of the two clusters; an axis needs at least {MIN_SAMPLES}")));
    }
    for (i, p) in reference.iter().chain(moving).enumerate() {
        if !p.to_homogeneous().iter().all(|x| x.is_finite()) {
            return Err(CalibError::data(what, format!("pose {} is not finite", i % n_all)));
        }
    }
    let mut keep = vec![true; n_all];
    let relative: Vec<Rotation3<f64>> = reference.iter().zip(moving).map(|(a, b)| a.rotation.inverse() * b.rotation).collect();
    let motion = motion_range(&relative);
    let (r0, r1) = (motion.ranges[0].to_degrees(), motion.ranges[1].to_degrees());
    if motion.ranges[0] < MIN_RANGE {
        return Err(CalibError::motion(
            what,
            format!("the clusters turned {r0:.2} deg relative to each other over {n_all} samples; an axis needs at least {:.1} deg", MIN_RANGE.to_degrees()),
        ));
    }
    let mut est = sara(reference, moving, &keep, what)?;
    let mut outliers = 0;
    for _ in 0..3 {
        if options.outlier_factor <= 0.0 {
            break;
        }
        let mut d: Vec<f64> = (0..n_all).filter(|&i| keep[i]).map(|i| est.residual(&reference[i], &moving[i]).norm()).collect();
        let mid = d.len() / 2;
        let median = *d.select_nth_unstable_by(mid, f64::total_cmp).1;
        let limit = (options.outlier_factor * median).max(1e-9);
        let mut dropped = 0;
        for i in 0..n_all {
            if keep[i] && est.residual(&reference[i], &moving[i]).norm() > limit {
                keep[i] = false;
                dropped += 1;
            }
        }
        if dropped == 0 {
            break;
        }
        outliers += dropped;
        est = sara(reference, moving, &keep, what)?;
    }
    if options.method == AxisMethod::GamageLasenby {
        let default_points = [Vector3::zeros(), Vector3::x() * 0.05, Vector3::y() * 0.05, Vector3::z() * 0.05];
        let points = options.points.as_deref().unwrap_or(&default_points);
        let (g, h) = gamage_lasenby(reference, moving, &keep, points, options.bias_correction, what)?;
        // Keep SARA's sign of the direction, and carry the point into the moving frame.
        let h = if h.dot(&est.ha) < 0.0 { -h } else { h };
        let mut gb = Vector3::zeros();
        let mut hb = Vector3::zeros();
        let mut n = 0.0;
        for i in (0..n_all).filter(|&i| keep[i]) {
            let rel = reference[i].inverse() * moving[i];
            gb += rel.inverse_transform_point(&g.into()).coords;
            hb += rel.rotation.inverse_transform_vector(&h);
            n += 1.0;
        }
        est.ga = g;
        est.ha = h;
        est.gb = gb / n;
        est.hb = (hb / n).normalize();
    }
    let n = keep.iter().filter(|k| **k).count();
    // Robust (sandwich) covariances from the residuals of the point and of the direction.
    let mut meat_x = Matrix6::zeros();
    let mut meat_h = Matrix6::zeros();
    let mut ss = 0.0;
    let mut residuals = Vec::with_capacity(n_all);
    let v1 = Vector6::from_iterator(est.ha.iter().chain(est.hb.iter()).copied()) / std::f64::consts::SQRT_2;
    for i in (0..n_all).filter(|&i| keep[i]) {
        let (a, b) = (&reference[i], &moving[i]);
        let r = est.residual(a, b);
        ss += r.norm_squared();
        residuals.push(r.norm());
        let jr = jt(a, b, &r);
        meat_x += jr * jr.transpose();
        let d = a.rotation * v1.fixed_rows::<3>(0).into_owned() - b.rotation * v1.fixed_rows::<3>(3).into_owned();
        let jd = jt(a, b, &d);
        meat_h += jd * jd.transpose();
    }
    let dof = (3 * n) as f64 / ((3 * n) as f64 - 5.0);
    let cx = est.pinv * meat_x * est.pinv * dof;
    let ch = est.pinv * meat_h * est.pinv * dof;
    let proj = Matrix3::identity() - est.ha * est.ha.transpose();
    let point_cov = proj * cx.fixed_view::<3, 3>(0, 0) * proj;
    let proj_b = Matrix3::identity() - est.hb * est.hb.transpose();
    let point_moving_cov = proj_b * cx.fixed_view::<3, 3>(3, 3) * proj_b;
    let direction_cov = proj * ch.fixed_view::<3, 3>(0, 0) * proj * 2.0;
    let mut warnings = Vec::new();
    if motion.ranges[0] < WARN_RANGE {
        warnings.push(format!(
            "{what}: motion range too small for a meaningful axis: the clusters turned {r0:.1} deg relative to each other (at least \
             {:.0} deg is advised); axis point std {:.3} mm",
            WARN_RANGE.to_degrees(),
            point_cov.trace().max(0.0).sqrt() * 1e3
        ));
    }
    if motion.ranges[1] > 0.1 * motion.ranges[0] {
        warnings.push(format!(
            "{what}: the relative motion is not a rotation about one axis: {r0:.1} deg about the main direction but {r1:.1} deg about \
             another (a loose cluster, or two joints between the clusters)"
        ));
    }
    if outliers > 0 {
        warnings.push(format!("{what}: {outliers} of {n_all} samples dropped as outliers (residual over {} x median)", options.outlier_factor));
    }
    Ok(AxisFit {
        method: options.method,
        point: est.ga,
        direction: est.ha,
        point_moving: est.gb,
        direction_moving: est.hb,
        point_cov,
        point_moving_cov,
        direction_cov,
        rms: (ss / n as f64).sqrt(),
        residuals,
        samples: n,
        outliers,
        motion,
        conditioning: est.conditioning,
        warnings,
    })
}

/// `J_i^T v` for the row block `J_i = [R_a  -R_b]`.
#[inline]
fn jt(a: &Pose, b: &Pose, v: &Vector3<f64>) -> Vector6<f64> {
    let x = a.rotation.inverse_transform_vector(v);
    let y = -b.rotation.inverse_transform_vector(v);
    Vector6::new(x.x, x.y, x.z, y.x, y.y, y.z)
}

struct Estimate {
    ga: Vector3<f64>,
    ha: Vector3<f64>,
    gb: Vector3<f64>,
    hb: Vector3<f64>,
    /// Pseudo-inverse of the normal matrix without its null direction.
    pinv: Matrix6<f64>,
    conditioning: f64,
}

impl Estimate {
    /// The axis point carried by `a` minus the same point carried by `b` (m, tracker frame).
    #[inline]
    fn residual(&self, a: &Pose, b: &Pose) -> Vector3<f64> {
        (a.rotation * self.ga + a.translation.vector) - (b.rotation * self.gb + b.translation.vector)
    }
}

fn sara(reference: &[Pose], moving: &[Pose], keep: &[bool], what: &str) -> Result<Estimate> {
    let mut n = 0.0;
    let mut cross = Matrix3::zeros();
    let mut rhs = Vector6::zeros();
    for ((a, b), _) in reference.iter().zip(moving).zip(keep).filter(|(_, k)| **k) {
        n += 1.0;
        cross += a.rotation.matrix().transpose() * b.rotation.matrix();
        rhs += jt(a, b, &(b.translation.vector - a.translation.vector));
    }
    let mut normal = Matrix6::identity() * n;
    normal.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-cross));
    normal.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-cross.transpose()));
    let eig = SymmetricEigen::new(normal / n);
    let mut order = [0usize, 1, 2, 3, 4, 5];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let conditioning = eig.eigenvalues[order[1]];
    if conditioning < 1e-10 {
        return Err(CalibError::motion(what, "the relative motion does not determine an axis (the clusters moved together)"));
    }
    let mut pinv = Matrix6::zeros();
    for &k in &order[1..] {
        let v = eig.eigenvectors.column(k);
        pinv += v * v.transpose() / (eig.eigenvalues[k] * n);
    }
    let x = pinv * rhs;
    let null = eig.eigenvectors.column(order[0]);
    let ha = Vector3::new(null[0], null[1], null[2]);
    let hb = Vector3::new(null[3], null[4], null[5]);
    let (la, lb) = (ha.norm(), hb.norm());
    if la < 0.5 || lb < 0.5 {
        return Err(CalibError::motion(what, "the least-squares null direction is not an axis shared by both clusters"));
    }
    let (ha, hb) = (ha / la, hb / lb);
    let xa = Vector3::new(x[0], x[1], x[2]);
    let xb = Vector3::new(x[3], x[4], x[5]);
    // Slide along the axis (the null direction) to the point closest to a's origin.
    let s = ha.dot(&xa);
    Ok(Estimate { ga: xa - ha * s, ha, gb: xb - hb * s, hb, pinv, conditioning })
}

/// Gamage & Lasenby on poses: the followed points of the moving cluster carried into the
/// reference frame sample by sample (no allocation).
fn gamage_lasenby(reference: &[Pose], moving: &[Pose], keep: &[bool], points: &[Vector3<f64>], correct: bool, what: &str) -> Result<(Vector3<f64>, Vector3<f64>)> {
    let rows: Vec<usize> = (0..keep.len()).filter(|&i| keep[i]).collect();
    gl_core(points.len(), rows.len(), |k, i| reference[rows[i]].inverse_transform_point(&moving[rows[i]].transform_point(&points[k].into())).coords, correct, what)
}

/// Gamage & Lasenby on point trajectories already in the reference frame (raw markers of a
/// cluster turning about an axis fixed in the tracker frame): `trajectories[k][i]` is point k
/// at sample i (m). Returns the axis point closest to the origin and the unit direction.
pub fn gamage_lasenby_points(trajectories: &[Vec<Vector3<f64>>], bias_correction: bool, what: &str) -> Result<(Vector3<f64>, Vector3<f64>)> {
    let n = trajectories.first().map_or(0, Vec::len);
    if trajectories.is_empty() || trajectories.iter().any(|t| t.len() != n) || n < MIN_SAMPLES {
        return Err(CalibError::data(what, format!("{} trajectories of {n} samples; Gamage & Lasenby needs equal lengths of at least {MIN_SAMPLES}", trajectories.len())));
    }
    gl_core(trajectories.len(), n, |k, i| trajectories[k][i], bias_correction, what)
}

/// The least-squares axis of Gamage & Lasenby (2002) from `k` points over `n` samples:
/// `C = sum_k cov(v_k)`, `b = 1/2 sum_k (mean(v |v|^2) - mean(v) mean(|v|^2))`; the direction is
/// the eigenvector of C's smallest eigenvalue, the point solves `C g = b` in the plane normal to
/// it. Halvorsen's compensation: noise of variance s^2 per coordinate adds `k s^2 I` to C and
/// `s^2 sum_k mean(v_k)` to b; along the axis the points do not move, so the smallest
/// eigenvalue of C is `k s^2` and both terms can be removed.
fn gl_core(k: usize, n: usize, point: impl Fn(usize, usize) -> Vector3<f64>, correct: bool, what: &str) -> Result<(Vector3<f64>, Vector3<f64>)> {
    // Shifted by the first sample of point 0 so the sums keep their digits.
    let shift = point(0, 0);
    let nf = n as f64;
    let mut c = Matrix3::zeros();
    let mut b = Vector3::zeros();
    let mut mean_sum = Vector3::zeros();
    for p in 0..k {
        let mut s1 = Vector3::zeros();
        let mut s2 = Matrix3::zeros();
        let mut s3 = Vector3::zeros();
        let mut s4 = 0.0;
        for i in 0..n {
            let v = point(p, i) - shift;
            let q = v.norm_squared();
            s1 += v;
            s2 += v * v.transpose();
            s3 += v * q;
            s4 += q;
        }
        let mean = s1 / nf;
        c += s2 / nf - mean * mean.transpose();
        b += 0.5 * (s3 / nf - mean * (s4 / nf));
        mean_sum += mean;
    }
    let eig = SymmetricEigen::new(c);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let lambda_min = if correct { eig.eigenvalues[order[0]].max(0.0) } else { 0.0 };
    let h: Vector3<f64> = eig.eigenvectors.column(order[0]).into_owned();
    let b = b - mean_sum * (lambda_min / k as f64);
    let mut g = Vector3::zeros();
    for &i in &order[1..] {
        let l = eig.eigenvalues[i] - lambda_min;
        if l <= 1e-14 * eig.eigenvalues[order[2]].abs().max(1e-300) {
            return Err(CalibError::motion(what, "the followed points do not sweep a plane about the axis"));
        }
        let v = eig.eigenvectors.column(i);
        g += v * (v.dot(&b) / l);
    }
    let g = g + shift;
    Ok((g - h * h.dot(&g), h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, Unit};

    /// Two clusters on either side of a hinge through `g` (tracker frame) along `h`, the
    /// reference cluster also moving.
    fn hinge() -> (Vec<Pose>, Vec<Pose>, Vector3<f64>, Vector3<f64>) {
        // Returns the axis in a's frame.
        let h = Unit::new_normalize(Vector3::new(0.2, -0.3, 1.0));
        let g = Vector3::new(0.5, 0.1, 1.5);
        let a0 = Pose::from_parts(Translation3::new(0.45, 0.2, 1.4), Rotation3::from_euler_angles(0.1, 0.2, 0.3));
        let b0 = Pose::from_parts(Translation3::new(0.7, 0.05, 1.6), Rotation3::from_euler_angles(-0.4, 0.0, 1.0));
        let mut ra = Vec::new();
        let mut rb = Vec::new();
        for i in 0..300 {
            let t = i as f64 / 300.0 * std::f64::consts::TAU;
            // The whole hinge wanders; b turns about the hinge by up to 0.6 rad.
            let base = Pose::from_parts(Translation3::new(0.01 * t.sin(), 0.0, 0.02 * t.cos()), Rotation3::from_euler_angles(0.05 * t.sin(), 0.03 * t.cos(), 0.0));
            let turn = Pose::from_parts(Translation3::from(g), Rotation3::from_axis_angle(&h, 0.6 * (2.0 * t).sin()))
                * Pose::from_parts(Translation3::from(-g), Rotation3::identity());
            ra.push(base * a0);
            rb.push(base * turn * b0);
        }
        (ra, rb, a0.inverse_transform_point(&g.into()).coords, a0.inverse_transform_vector(&h))
    }

    #[test]
    fn both_methods_find_an_exact_hinge() {
        let (ra, rb, ga, ha) = hinge();
        let ga = ga - ha * ha.dot(&ga);
        for method in [AxisMethod::Sara, AxisMethod::GamageLasenby] {
            let f = fit_axis(&ra, &rb, &AxisOptions { method, ..Default::default() }, "test axis").unwrap();
            assert!((f.direction.dot(&ha).abs() - 1.0).abs() < 1e-12, "{method:?}");
            assert!((f.point - ga).norm() < 1e-9, "{method:?}: {}", (f.point - ga).norm());
            assert!(f.rms < 1e-9 && f.warnings.is_empty(), "{method:?}: {} {:?}", f.rms, f.warnings);
            assert!((f.motion.ranges[0] - 1.2).abs() < 1e-6, "{:?}", f.motion.ranges);
        }
    }

    #[test]
    fn clusters_moving_together_have_no_axis() {
        let (ra, _, _, _) = hinge();
        let rb: Vec<Pose> = ra.iter().map(|a| a * Pose::translation(0.1, 0.0, 0.0)).collect();
        let e = fit_axis(&ra, &rb, &AxisOptions::default(), "axis 3").unwrap_err().to_string();
        assert!(e.starts_with("axis 3: the clusters turned 0.00 deg"), "{e}");
    }
}
