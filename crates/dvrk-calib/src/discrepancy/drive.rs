//! Signatures of a joint's two-mass drive (compliance, backlash): nonlinear in their parameter,
//! so each is a 1-D profile, and each grid point is a small simulation of its own. The encoder
//! sits on the motor, whose recorded motion holds it in the band and leaves it free above
//! ([`MOTOR_TIE`]); the link, reduced to its own joint (inertia `M_jj` and gravity stiffness from
//! the model, the model's load along the recorded motion), is integrated behind the transmission
//! at 4 times the recording's rate; the drive's torque then goes through the analysis' filter
//! like the measured effort. This is a different implementation from dvrk-sim's (a full
//! multibody with a second body per drive), on purpose.

use super::candidates::Table;
use super::signals::{column, Prepared};
use crate::error::Result;
use dvrk_kin::{DynamicsData, DynamicsModel};
use nalgebra::{DMatrix, Matrix4, Vector4};

/// Transmission damping ratio on the motor's mode (dvrk-sim's drive convention).
const DAMPING_RATIO: f64 = 0.1;

/// Bandwidth of the stiff contact behind a play without compliance (rad/s on the motor inertia),
/// where nothing says otherwise.
pub const CONTACT_BANDWIDTH: f64 = 2.0 * std::f64::consts::PI * 300.0;

/// The contact bandwidths a play is also profiled over (rad/s): how stiff the teeth are once
/// engaged is as unknown as the play, and a contact too stiff or too soft biases the play's width.
pub const CONTACT_BANDWIDTHS: [f64; 5] = [250.0, 500.0, 1000.0, 2000.0, 4000.0];

/// Bandwidth (rad/s) below which the motor follows the recorded motion, through a critically
/// damped tie on its inertia; above it the motor is free. The encoder records the motor, so its
/// motion in the band is known; an impact's recoil (milliseconds) is faster than the band shows,
/// and prescribing the band's motion made the motor an immovable wall the link rebounded off.
/// Measured on two plays at effort noise / 100 (before the start-path fix): seed 1 at 300, 600,
/// 1200 rad/s left held-out RMS 0.029, 0.024, 0.024 N·m; seed 2 at 600, 1000 left 0.036, 0.043
/// (0.083 with the band's motion prescribed). At 600, b came out +0.2% (seed 1, ENR 5) and -3.3%
/// (prescribed: +6.1%, +6.4%).
const MOTOR_TIE: f64 = 600.0;

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

/// Continue `v` before `first` by its point reflection about that sample:
/// `v(first - d) = 2 v(first) - v(first + d)`.
fn point_reflect_before(v: &mut [f64], first: usize) {
    for s in 0..first {
        v[s] = 2.0 * v[first] - v[(2 * first - s).min(v.len() - 1)];
    }
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
    // The law at stretch d (motor - link): stiffness, the play's shift, damping.
    let regime = |d: f64| {
        if d > half {
            (k, half, c)
        } else if d < -half {
            (k, -half, c)
        } else {
            (0.0, 0.0, 0.0)
        }
    };
    let (first, last) = (prep.keep[0], prep.keep[prep.keep.len() - 1]);
    // The motor's tie to the recorded motion, critically damped.
    let jm = jl.motor;
    let (kt, ct) = (jm * MOTOR_TIE * MOTOR_TIE, 2.0 * jm * MOTOR_TIE);
    // The drive's torque less the load, and the link's lag behind the recorded motion (position,
    // rate, acceleration) for the other joints' share (M_kj y'' + dtau_k/dqd_j y' + dtau_k/dq_j y).
    let mut out = vec![0.0; n];
    let (mut lag, mut lag_rate, mut lag_acc) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (inertia_j, stiffness_j) = (column(&jl.inertia, j), column(&jl.stiffness, j));
    // Simulated on to the recording's end: the filter looks past the last analysed sample, and a
    // contact still ringing there, held or reflected, becomes a step (it made the last 50 ms
    // of a play's signature wrong by 10 times the residual's RMS). The load goes on as its point
    // reflection; 0.1 s on, the filter no longer looks.
    let load_at = |s: usize| if s > last { 2.0 * jl.load[jl.load.len() - 1] - at_raw(prep, &jl.load, (2 * last).saturating_sub(s)) } else { at_raw(prep, &jl.load, s) };
    // State: motor deviation z, link deviation y from the recorded motion, and their rates. The
    // start is in the contact, on the slowly forced link's own path: a soft drive started at rest
    // (or after a spin-up on the load reflected) rang at its own mode (5 Hz, in the band) for a
    // second or two, 10 times the rest's residual.
    let mut st = {
        let (m, g, l) = (inertia_j[0].max(1e-9), stiffness_j[0], &jl.load);
        // (Gravity's stiffness only where it does not nearly cancel the drive's.)
        let (shift, ke, ce) = (half * l[0].signum(), if k + g > 0.5 * k { k + g } else { k }, c + jl.damping);
        // Forcing P = -(load + k shift) and its rate and curvature (one-sided, on the analysed
        // samples); the path y = P/ke - ce/ke^2 P' + (ce^2/ke^3 - m/ke^2) P''.
        let at = |i: usize| -(l.get(i).copied().unwrap_or(l[0]) + k * shift);
        let da = prep.dt;
        let (p0, p1) = (at(0), (-3.0 * at(0) + 4.0 * at(1) - at(2)) / (2.0 * da));
        let p2 = (at(0) - 2.0 * at(1) + at(2)) / (da * da);
        let y = p0 / ke - ce / (ke * ke) * p1 + (ce * ce / (ke * ke * ke) - m / (ke * ke)) * p2;
        Vector4::new(0.0, 0.0, y, p1 / ke - ce / (ke * ke) * p2)
    };
    for s in first..n {
        let (load, m, g) = (load_at(s), at_raw(prep, &inertia_j, s).max(1e-9), at_raw(prep, &stiffness_j, s));
        // What the drive does at this sample, from the state at this sample: an output read
        // after the step to the next sample, its load held over the step, led the load by half
        // a sample (0.5 ms: a compliance's signature 5% off, its stiffness 3-4% low).
        let (z, zd, y, yd) = (st[0], st[1], st[2], st[3]);
        let (kk, shift, cc) = regime(z - y);
        out[s] = kk * (z - y - shift) + cc * (zd - yd) - load;
        lag[s] = y;
        lag_rate[s] = yd;
        lag_acc[s] = (out[s] - g * y - jl.damping * yd) / m;
        // Per regime (free, engaged) over this sample's step: s1 = step s0 + forcing f
        // (trapezoidal: stable at any contact stiffness and, unlike implicit Euler, without
        // numerical damping).
        let mut steps: [Option<(Matrix4<f64>, Matrix4<f64>)>; 2] = [None, None];
        let next = load_at(s + 1);
        for i in 0..SUBSTEPS {
            // The regime at the substep's start; within it the law is linear. The load is linear
            // between samples, and trapezoidal forcing is its mean over the substep.
            let (kk, shift, cc) = regime(st[0] - st[2]);
            let (step, forcing) = steps[usize::from(kk > 0.0)].get_or_insert_with(|| {
                // J z'' = load - F - kt z - ct z';  m y'' = F - load - g y - dl y';
                // F = kk (z - y - shift) + cc (z' - y'). The load stands for the band's share of
                // F, which the recorded motion already holds: the rest knocks the motor.
                #[rustfmt::skip]
                let a = Matrix4::new(
                    0.0, 1.0, 0.0, 0.0,
                    -(kk + kt) / jm, -(cc + ct) / jm, kk / jm, cc / jm,
                    0.0, 0.0, 0.0, 1.0,
                    kk / m, cc / m, -(kk + g) / m, -(cc + jl.damping) / m,
                );
                let id = Matrix4::identity();
                let inv = (id - a * (0.5 * h)).try_inverse().unwrap_or(id);
                (inv * (id + a * (0.5 * h)), inv * h)
            });
            let l = load + (next - load) * (i as f64 + 0.5) / SUBSTEPS as f64 + kk * shift;
            st = *step * st + *forcing * Vector4::new(0.0, l / jm, 0.0, -l / m);
        }
    }
    // Before the simulated span, which starts in the contact, each series goes on as its
    // point reflection (value and slope kept), as the measured effort does there.
    for v in [&mut out, &mut lag, &mut lag_rate, &mut lag_acc] {
        point_reflect_before(v, first);
    }
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
