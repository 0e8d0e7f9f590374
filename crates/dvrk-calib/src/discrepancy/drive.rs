//! Signatures of a joint's two-mass drive (compliance, backlash): nonlinear in their parameter,
//! so each is a 1-D profile, and each grid point is a small simulation of its own. The encoder
//! sits on the motor, whose recorded motion is prescribed; the link, reduced to its own joint
//! (inertia `M_jj` and gravity stiffness from the model, the model's load along the recorded
//! motion), is integrated behind the transmission at the recording's rate; the drive's torque
//! then goes through the analysis' filter like the measured effort. This is a different
//! implementation from dvrk-sim's (a full multibody with a second body per drive), on purpose.

use super::candidates::Table;
use super::signals::{column, Prepared};
use crate::error::Result;
use dvrk_kin::{DynamicsData, DynamicsModel};
use nalgebra::DMatrix;

/// Transmission damping ratio on the motor's mode (dvrk-sim's drive convention).
const DAMPING_RATIO: f64 = 0.1;

/// Bandwidth of the stiff contact behind a play without compliance (rad/s on the motor inertia),
/// where nothing says otherwise.
pub const CONTACT_BANDWIDTH: f64 = 2.0 * std::f64::consts::PI * 300.0;

/// The contact bandwidths a play is also profiled over (rad/s): how stiff the teeth are once
/// engaged is as unknown as the play, and a contact too stiff or too soft biases the play's width.
pub const CONTACT_BANDWIDTHS: [f64; 5] = [250.0, 500.0, 1000.0, 2000.0, 4000.0];

/// Integration sub-steps per recorded sample.
const SUBSTEPS: usize = 4;

/// The transmission law.
#[derive(Debug, Clone, Copy)]
pub enum Law {
    /// Spring of this stiffness (N·m/rad, N/m).
    Compliance(f64),
    /// Play of half-width `half` (rad, m), a stiff contact beyond it with natural frequency
    /// `contact` on the motor inertia (rad/s).
    Backlash { half: f64, contact: f64 },
}

/// What one joint's drive simulation needs, along the analysed samples.
pub struct JointLoad {
    pub joint: usize,
    /// Link-side effort the model predicts along the recorded (motor) motion (N·m, N).
    pub load: Vec<f64>,
    /// Column `j` of the link mass matrix, `[sample][joint]` (`M_jj` its own inertia; kg m^2, kg).
    pub inertia: Table,
    /// d(effort_k)/dq_j of every joint k, from gravity and the rest of the arm, `[sample][joint]`
    /// (N·m/rad, N/m).
    pub stiffness: Table,
    /// d(effort_k)/d(qd_j) of every joint k, `[sample][joint]` (N·m s/rad, N s/m): the other
    /// joints' Coriolis and centrifugal share of the link's lag rate.
    pub rate: Table,
    /// Motor inertia (kg m^2, kg).
    pub motor: f64,
    /// The link side's own damping on its joint (N·m s/rad, N s/m): acts on the link's lag rate.
    pub damping: f64,
}

/// The link mass matrix at every analysed sample (kg m^2, kg).
pub fn link_inertias(model: &dvrk_kin::Model, dm: &DynamicsModel, prep: &Prepared) -> Result<Vec<DMatrix<f64>>> {
    let nq = model.nq();
    let mut data = DynamicsData::new(model);
    let mut out = Vec::with_capacity(prep.t.len());
    for q in &prep.q {
        let mut m = DMatrix::zeros(nq, nq);
        dvrk_kin::mass_matrix(model, dm, &mut data, q, &mut m)?;
        out.push(m);
    }
    Ok(out)
}

/// Linear interpolation of analysed-sample values `v` at raw sample `s`.
fn at_raw(prep: &Prepared, v: &[f64], s: usize) -> f64 {
    let k = &prep.keep;
    if s <= k[0] {
        return v[0];
    }
    if s >= k[k.len() - 1] {
        return v[v.len() - 1];
    }
    let i = k.partition_point(|&x| x <= s) - 1;
    let w = (s - k[i]) as f64 / (k[i + 1] - k[i]) as f64;
    v[i] * (1.0 - w) + v[i + 1] * w
}

/// The change in the joint's effort (analysed samples, `[sample][joint]`, only `load.joint`
/// non-zero) when its drive obeys `law` instead of being rigid.
pub fn signature(prep: &Prepared, jl: &JointLoad, law: Law, nq: usize) -> Table {
    let j = jl.joint;
    let n = prep.fast_qd[j].len();
    let dt = prep.dt / (prep.keep.get(1).map_or(1, |s| s - prep.keep[0]) as f64);
    let h = dt / SUBSTEPS as f64;
    let (k, half) = match law {
        Law::Compliance(k) => (k, 0.0),
        Law::Backlash { half, contact } => (jl.motor * contact * contact, half),
    };
    let c = 2.0 * DAMPING_RATIO * (k * jl.motor).sqrt();
    let (first, last) = (prep.keep[0], prep.keep[prep.keep.len() - 1]);
    // e = link - motor, de its rate; the transmission passes F(-e, -de).
    let l0 = jl.load[0];
    let mut e = -(l0 / k) - half * l0.signum();
    let mut de = 0.0;
    let mut out = vec![0.0; n];
    // The link's lag e, its rate and acceleration, for the other joints' share
    // (M_kj e'' + dtau_k/dqd_j e' + dtau_k/dq_j e).
    let (mut lag, mut lag_rate, mut lag_acc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (inertia_j, stiffness_j) = (column(&jl.inertia, j), column(&jl.stiffness, j));
    for s in first..=last {
        let (load, m, g) = (at_raw(prep, &jl.load, s), at_raw(prep, &inertia_j, s).max(1e-9), at_raw(prep, &stiffness_j, s));
        let de0 = de;
        let mut force = 0.0;
        for _ in 0..SUBSTEPS {
            // The regime at the step's start; within it the law is linear, integrated implicitly
            // (stable at any contact stiffness): F = kk (-e - shift) - cc de.
            let d = -e;
            let (kk, shift) = if d > half { (k, half) } else if d < -half { (k, -half) } else { (0.0, 0.0) };
            let cc = if kk > 0.0 { c } else { 0.0 };
            // The load holds the link's inertia and damping along the motor's motion: what is
            // left is m e'' = F - load - g e - d e'.
            let rhs = (-kk * (e + shift) - load - g * e) / m;
            let cc_link = jl.damping;
            let stiff = (kk + g) / m;
            de = (de + h * rhs) / (1.0 + h * (cc + cc_link) / m + h * h * stiff.max(0.0));
            e += h * de;
            force = kk * (-e - shift) - cc * de;
        }
        out[s] = force - load;
        lag[s] = e;
        lag_rate[s] = de;
        lag_acc[s] = (de - de0) / dt;
    }
    // Held flat outside the simulated span (no step for the filter to ring on).
    let (a, b) = (out[first], out[last]);
    out[..first].fill(a);
    out[last + 1..].fill(b);
    let mut table = vec![vec![0.0; nq]; prep.t.len()];
    for k in 0..nq {
        let col: Vec<f64> = if k == j {
            prep.band(&out)
        } else {
            let (mk, gk, ck) = (column(&jl.inertia, k), column(&jl.stiffness, k), column(&jl.rate, k));
            let raw: Vec<f64> = (0..n).map(|s| at_raw(prep, &mk, s) * lag_acc[s] + at_raw(prep, &gk, s) * lag[s] + at_raw(prep, &ck, s) * lag_rate[s]).collect();
            prep.band(&raw)
        };
        for (row, v) in table.iter_mut().zip(col) {
            row[k] = v;
        }
    }
    table
}
