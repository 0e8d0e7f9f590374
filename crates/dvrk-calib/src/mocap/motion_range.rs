//! How much a set of orientations moved: the range of rotation about each principal direction,
//! so a fit can say when the motion was too small for its result to mean anything.
//!
//! The range is `2 sqrt(2)` standard deviations of the rotation vectors along a direction: the
//! peak-to-peak angle of a sinusoidal sweep exactly, and of a uniform sweep to 18 %. Unlike
//! max - min it does not grow with the length of a noisy recording: tracker noise of a few mrad
//! per sample adds in quadrature instead of as its extreme.

use nalgebra::{Matrix3, Rotation3, SymmetricEigen, Vector3};

/// Below this rotation range (rad) a fit is undetermined: an error (axis: about the axis;
/// pivot: about the second direction).
pub const MIN_RANGE: f64 = 1.0 * std::f64::consts::PI / 180.0;
/// Below this rotation range (rad) a fit is reported with a warning.
pub const WARN_RANGE: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// Fewest samples (poses, or common samples of two clusters) a fit accepts.
pub const MIN_SAMPLES: usize = 10;

/// Rotation ranges of a sequence of orientations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotionRange {
    /// Range of rotation (rad) about each principal direction, largest first (module doc).
    pub ranges: [f64; 3],
    /// The principal directions (unit, in the frame of the mean orientation), matching `ranges`.
    pub directions: [Vector3<f64>; 3],
    /// Largest angle (rad) of any sample from the mean orientation.
    pub max_from_mean: f64,
}

impl MotionRange {
    /// Ranges in degrees, largest first (for reports).
    pub fn ranges_deg(&self) -> [f64; 3] {
        self.ranges.map(f64::to_degrees)
    }
}

/// The chordal mean of rotations: the rotation nearest (Frobenius) to their average matrix.
pub fn mean_rotation<'a>(rotations: impl Iterator<Item = &'a Rotation3<f64>>) -> Rotation3<f64> {
    let mut sum = Matrix3::zeros();
    for r in rotations {
        sum += r.matrix();
    }
    Rotation3::from_matrix_eps(&sum, 1e-12, 100, Rotation3::identity())
}

/// The motion range of `rotations`: the scatter of their rotation vectors relative to the mean
/// orientation, along its principal directions. Two passes over the data, no allocation.
pub fn motion_range(rotations: &[Rotation3<f64>]) -> MotionRange {
    let mean = mean_rotation(rotations.iter());
    let inv = mean.inverse();
    let mut scatter = Matrix3::zeros();
    let mut centre = Vector3::zeros();
    let mut max_from_mean: f64 = 0.0;
    for r in rotations {
        let w = dvrk_kin::so3::log(&(inv * r));
        max_from_mean = max_from_mean.max(w.norm());
        centre += w;
        scatter += w * w.transpose();
    }
    let n = rotations.len().max(1) as f64;
    centre /= n;
    scatter = scatter / n - centre * centre.transpose();
    let eig = SymmetricEigen::new(scatter);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let directions = order.map(|k| eig.eigenvectors.column(k).into_owned());
    let ranges = order.map(|k| 2.0 * std::f64::consts::SQRT_2 * eig.eigenvalues[k].max(0.0).sqrt());
    MotionRange { ranges, directions, max_from_mean }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_about_one_axis_has_one_range() {
        let axis = Vector3::new(1.0, 2.0, -0.5).normalize();
        // A sinusoidal sweep of amplitude 0.3 rad over whole periods: range 0.6 rad exactly.
        let rs: Vec<Rotation3<f64>> = (0..1000)
            .map(|i| Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), 0.3 * (i as f64 / 1000.0 * std::f64::consts::TAU).sin()))
            .collect();
        let m = motion_range(&rs);
        assert!((m.ranges[0] - 0.6).abs() < 1e-9, "{:?}", m.ranges);
        // Round-off of ~1e-17 rad^2 in the scatter shows as ~1e-8 rad after the square root.
        assert!(m.ranges[1] < 1e-7 && m.ranges[2] < 1e-7, "{:?}", m.ranges);
        assert!((m.directions[0].dot(&axis).abs() - 1.0).abs() < 1e-9);
        assert!((m.max_from_mean - 0.3).abs() < 1e-9);
    }
}
