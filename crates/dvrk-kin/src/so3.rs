//! Rotation logarithm and angle that stay accurate near zero, where `acos` of the trace loses
//! half the digits (its floor is about 1e-8 rad).

use nalgebra::{Rotation3, Vector3};

/// Rotation vector (axis * angle, rad) of `r`.
pub fn log(r: &Rotation3<f64>) -> Vector3<f64> {
    let m = r.matrix();
    // 2 sin(theta) * axis from the skew-symmetric part; cos(theta) from the trace.
    let v = Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5;
    let s = v.norm();
    let c = (m.trace() - 1.0) * 0.5;
    let theta = s.atan2(c);
    if theta < 1e-6 {
        v // sin(theta) / theta = 1 to 1e-13
    } else if theta < std::f64::consts::PI - 1e-6 {
        v * (theta / s)
    } else {
        r.scaled_axis() // near pi the skew part vanishes; nalgebra's eigen-based axis is exact there
    }
}

/// Angle of `r` (rad), in [0, pi].
pub fn angle(r: &Rotation3<f64>) -> f64 {
    let m = r.matrix();
    let v = Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5;
    v.norm().atan2((m.trace() - 1.0) * 0.5)
}
