//! Pivot calibration (paper eq. 3-5): the fixed point `b_post` (world) that a point `b_tip`
//! fixed in a moving frame keeps passing through, from sampled poses of that frame.

use dvrk_kin::Pose;
use nalgebra::{DMatrix, DVector, Vector3};

/// Result of a pivot fit (m).
#[derive(Debug, Clone, PartialEq)]
pub struct PivotFit {
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
pub fn pivot_fit(poses: &[Pose]) -> Option<PivotFit> {
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
    Some(PivotFit { tip, post, rms, max })
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
