//! A joint's cable torque measured on its own, as the prior of its configuration-dependent spring:
//! the WPI authors' joint test of the MTM platform (`joint_test_cable.csv`: the joint swept slowly
//! one way, then back), read as recorded ([`dvrk_sim::recording::read_joint_test`]).
//!
//! The first half of the rows one direction, the second half the other. As the authors did, 100
//! samples are dropped at each end of each half; the mean of the two directions at a position is
//! the cable's torque there (friction changes sign with the direction, the cable does not), half
//! their difference the friction.

use super::problem::EffectTerm;
use crate::error::{CalibError, Result};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

/// Samples dropped at each end of each sweep (the authors' `data_process.m`).
const DROPPED: usize = 100;
/// Bins of the position range the two sweeps both cover.
const BINS: usize = 60;

/// A prior on the `cable_spring` of model joint `joint`: its coefficients `k1, k2, k3`
/// (N·m/rad, N·m/rad^2, N·m/rad^3) and their standard deviations.
#[derive(Debug, Clone, PartialEq)]
pub struct JointSpringPrior {
    pub joint: usize,
    pub value: [f64; 3],
    pub std: [f64; 3],
    /// Where it comes from (the test file).
    pub source: String,
}

impl JointSpringPrior {
    /// The prior's value and standard deviation of `term` (one of the cable terms).
    pub fn of(&self, term: EffectTerm) -> Option<(f64, f64)> {
        let k = match term {
            EffectTerm::CableLinear => 0,
            EffectTerm::CableQuadratic => 1,
            EffectTerm::CableCubic => 2,
            _ => return None,
        };
        Some((self.value[k], self.std[k]))
    }
}

/// What the joint test shows.
#[derive(Debug, Clone, PartialEq)]
pub struct CableTest {
    /// The prior fitted (`k1 q + k2 q^2 + k3 q^3`, plus a constant that is the joint's offset).
    pub prior: JointSpringPrior,
    /// The constant term (N·m).
    pub constant: f64,
    /// The position range both sweeps cover (rad).
    pub range: (f64, f64),
    /// RMS of the cubic's misfit to the two directions' mean (N·m).
    pub misfit_rms: f64,
    /// Mean of half the two directions' difference: the joint's friction (N·m).
    pub friction: f64,
}

/// Read the joint test `path` of model joint `joint` and fit its cable torque. The prior's
/// standard deviations are a quarter of each coefficient's magnitude plus its standard error: the
/// test was made on another day than the recordings it serves (the cable's tension drifts).
pub fn from_joint_test(path: &Path, joint: usize) -> Result<CableTest> {
    let rows = dvrk_sim::recording::read_joint_test(path)?;
    let half = rows.len() / 2;
    if half < 2 * DROPPED + 2 * BINS {
        return Err(CalibError::file(path, format!("{} rows; a joint test of two sweeps needs at least {}", rows.len(), 2 * (2 * DROPPED + 2 * BINS))));
    }
    let sweeps = [&rows[DROPPED..half - DROPPED], &rows[half + DROPPED..rows.len() - DROPPED]];
    let span = |s: &[(f64, f64)]| s.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (q, _)| (lo.min(*q), hi.max(*q)));
    let ((a_lo, a_hi), (b_lo, b_hi)) = (span(sweeps[0]), span(sweeps[1]));
    let (lo, hi) = (a_lo.max(b_lo), a_hi.min(b_hi));
    if hi - lo < 0.1 {
        return Err(CalibError::file(path, format!("the two sweeps overlap over {:.3} rad ({lo:.3}..{hi:.3}); a joint test sweeps one range both ways", (hi - lo).max(0.0))));
    }
    // Per bin and direction, the mean effort; bins both directions reach.
    let width = (hi - lo) / BINS as f64;
    let mut sums = [[(0.0, 0usize); BINS]; 2];
    for (d, sweep) in sweeps.iter().enumerate() {
        for (q, tau) in sweep.iter() {
            let b = ((q - lo) / width).floor();
            if (0.0..BINS as f64).contains(&b) {
                let e = &mut sums[d][b as usize];
                e.0 += tau;
                e.1 += 1;
            }
        }
    }
    let mut points = Vec::new();
    let mut friction = 0.0;
    for b in 0..BINS {
        let ((sa, na), (sb, nb)) = (sums[0][b], sums[1][b]);
        if na > 0 && nb > 0 {
            let (ta, tb) = (sa / na as f64, sb / nb as f64);
            points.push((lo + (b as f64 + 0.5) * width, 0.5 * (ta + tb)));
            friction += 0.5 * (ta - tb).abs();
        }
    }
    if points.len() < 8 {
        return Err(CalibError::file(path, format!("{} positions reached both ways; the fit needs 8", points.len())));
    }
    friction /= points.len() as f64;
    let a = DMatrix::from_fn(points.len(), 4, |r, c| points[r].0.powi(c as i32));
    let y = DVector::from_iterator(points.len(), points.iter().map(|p| p.1));
    let ata = a.transpose() * &a;
    let inv = ata.clone().try_inverse().ok_or_else(|| CalibError::file(path, "the swept positions do not determine a cubic"))?;
    let x = &inv * a.transpose() * &y;
    let residual = &y - &a * &x;
    let var = residual.norm_squared() / (points.len() - 4) as f64;
    let se = |k: usize| (var * inv[(k, k)]).sqrt();
    let value = [x[1], x[2], x[3]];
    let std = [0, 1, 2].map(|k| 0.25 * value[k].abs() + se(k + 1));
    Ok(CableTest {
        prior: JointSpringPrior { joint, value, std, source: path.display().to_string() },
        constant: x[0],
        range: (lo, hi),
        misfit_rms: (residual.norm_squared() / points.len() as f64).sqrt(),
        friction,
    })
}
