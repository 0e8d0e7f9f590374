//! The PSM DH parameters that the Table 6 axis distances imply (section 2.4): the lengths of the
//! two parallelograms and the angle between the bottom- and top-link pivots on the back link.
//!
//! The model idealises both loops as parallelograms (models/psm.toml, notes 2-4), so each DH
//! length is the mean of the two measured opposite sides, and the difference between them is
//! reported (a real arm whose sides differ by more than the noise is not a parallelogram).
//! `beta1` itself is not taken from the angles: it is fixed by the RCM condition
//! `a6 sin(beta1) = a9` (note 2), which [`crate::mocap::apply`] enforces; what the axes give
//! configuration-free is `beta2 - beta1`, the angle 6-3-7 on the back link.

use crate::mocap::axis_distances::{AxesReport, Line};
use crate::error::{CalibError, Result};
use nalgebra::{Matrix3, Vector3};

/// A value with its standard deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub value: f64,
    pub std: f64,
}

/// The PSM lengths and angle implied by the axes.
#[derive(Debug, Clone, PartialEq)]
pub struct PsmDh {
    /// Short side of the first parallelogram (m): mean of 3-4 and 6-c1; frame 4's `a` minus frame 3's.
    pub l34: Estimate,
    /// Long side of the first parallelogram (m): mean of 3-6 and 4-c1; frame 6's `a`.
    pub a6: Estimate,
    /// Back-link pivot to top-link pivot (m): 3-7; frame 7's `a`.
    pub a7: Estimate,
    /// Long side of the second parallelogram (m): mean of 6-8 and 7-c2; frame 8's `a`.
    pub a8: Estimate,
    /// Short side of the second parallelogram (m): 6-7 (a check: it follows from a6, a7 and the angle).
    pub l67: Estimate,
    /// `beta2 - beta1` (rad): the signed angle 6-3-7 on the back link.
    pub beta_difference: Estimate,
    /// Opposite sides' differences (m): `3-6 - 4-c1`, `3-4 - 6-c1`, `6-8 - 7-c2`.
    pub mismatch: [(&'static str, f64); 3],
    /// `angle(3-4, 3-6) - pi/2` at the reference instant (rad): beta1 plus the q2 of that
    /// instant, so equal to beta1 only at q2 = 0.
    pub beta1_at_reference: Option<f64>,
}

/// The labels [`psm_dh`] needs.
pub const PSM_AXES: [&str; 7] = ["3", "4", "6", "7", "8", "c1", "c2"];

/// Signed angle from `u` to `v` about `m` (rad).
fn signed_angle(u: &Vector3<f64>, v: &Vector3<f64>, m: &Vector3<f64>) -> f64 {
    m.dot(&u.cross(v)).atan2(u.dot(v))
}

/// The DH lengths and angle from an axes report with the seven PSM axes.
pub fn psm_dh(report: &AxesReport) -> Result<PsmDh> {
    let missing: Vec<&str> = PSM_AXES.iter().copied().filter(|a| report.axis(a).is_none()).collect();
    if !missing.is_empty() {
        return Err(CalibError::data(
            "PSM DH parameters",
            format!("need axes {}; the configuration lacks {}", PSM_AXES.join(", "), missing.join(", ")),
        ));
    }
    let d = |a: &str, b: &str| -> Result<Estimate> {
        report
            .distance(a, b)
            .map(|x| Estimate { value: x.distance, std: x.std })
            .ok_or_else(|| CalibError::data("PSM DH parameters", format!("no distance {a}-{b} (the two axes share no body and have no common instant)")))
    };
    let mean = |x: Estimate, y: Estimate| Estimate { value: 0.5 * (x.value + y.value), std: 0.5 * (x.std.powi(2) + y.std.powi(2)).sqrt() };
    let (d34, d6c1, d36, d4c1, d68, d7c2) = (d("3", "4")?, d("6", "c1")?, d("3", "6")?, d("4", "c1")?, d("6", "8")?, d("7", "c2")?);
    // The angle 6-3-7 in a body all three axes are fixed in (the back link).
    let body = ["3", "6", "7"]
        .iter()
        .map(|a| report.axis(a).map(|x| [x.reference.clone(), x.moving.clone()]))
        .collect::<Option<Vec<_>>>()
        .and_then(|v| v[0].iter().find(|b| v[1].contains(b) && v[2].contains(b)).cloned())
        .ok_or_else(|| CalibError::data("PSM DH parameters", "axes 3, 6 and 7 must share a body (the back link) for the angle 6-3-7"))?;
    let lines: Vec<Line> = ["3", "6", "7"].iter().filter_map(|a| report.line_in(a, &body)).collect();
    let m = {
        let h = lines[0].direction;
        lines.iter().fold(Vector3::zeros(), |acc, l| acc + l.direction * l.direction.dot(&h).signum()).normalize()
    };
    let angle = |p: &[Vector3<f64>; 3]| {
        let proj = |v: Vector3<f64>| v - m * m.dot(&v);
        signed_angle(&proj(p[1] - p[0]), &proj(p[2] - p[0]), &m)
    };
    let pts = [lines[0].point, lines[1].point, lines[2].point];
    let gamma = angle(&pts);
    // First-order standard deviation: central differences over each point's coordinates.
    let mut var = 0.0;
    for k in 0..3 {
        let mut grad = Vector3::zeros();
        for c in 0..3 {
            let h = 1e-7;
            let (mut a, mut b) = (pts, pts);
            a[k][c] += h;
            b[k][c] -= h;
            grad[c] = (angle(&a) - angle(&b)) / (2.0 * h);
        }
        let cov: Matrix3<f64> = lines[k].cov;
        var += (grad.transpose() * cov * grad)[(0, 0)];
    }
    // Which mirror: the side of 3-6 that 3-7 lies on, seen from 3-4 (tracker frame, joint zero).
    let g = |a: &str| report.axis(a).and_then(|x| x.in_plane);
    let (sign, beta1_at_reference) = match (g("3"), g("4"), g("6"), g("7"), report.plane_normal) {
        (Some(p3), Some(p4), Some(p6), Some(p7), Some(m)) => {
            let a436 = signed_angle(&(p4 - p3), &(p6 - p3), &m);
            let a637 = signed_angle(&(p6 - p3), &(p7 - p3), &m);
            (a436.signum() * a637.signum(), Some(a436.abs() - std::f64::consts::FRAC_PI_2))
        }
        _ => {
            return Err(CalibError::data(
                "PSM DH parameters",
                "axes 3, 4, 6 and 7 are not all in the tracker frame at one instant, so the sign of beta2 - beta1 is unknown",
            ))
        }
    };
    Ok(PsmDh {
        l34: mean(d34, d6c1),
        a6: mean(d36, d4c1),
        a7: d("3", "7")?,
        a8: mean(d68, d7c2),
        l67: d("6", "7")?,
        beta_difference: Estimate { value: sign * gamma.abs(), std: var.max(0.0).sqrt() },
        mismatch: [("3-6 - 4-c1", d36.value - d4c1.value), ("3-4 - 6-c1", d34.value - d6c1.value), ("6-8 - 7-c2", d68.value - d7c2.value)],
        beta1_at_reference,
    })
}
