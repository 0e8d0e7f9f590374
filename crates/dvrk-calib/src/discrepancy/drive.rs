//! Signatures of a joint's two-mass drive (compliance, backlash): nonlinear in their parameter,
//! so each is a 1-D profile, and each grid point is a small simulation of its own. The encoder
//! sits on the motor, whose recorded motion (with the detail the band leaves out, up to
//! [`MOTOR_DETAIL_CUTOFF`]) holds it below `MOTOR_TIE` and leaves it free above; the link,
//! reduced to its own joint (inertia `M_jj` and gravity stiffness from the model, the model's
//! load along the recorded motion), is integrated behind the transmission at 4 times the
//! recording's rate; the drive's torque then goes through the analysis' filter like the
//! measured effort. This is a different implementation from dvrk-sim's (a full multibody with a
//! second body per drive), on purpose.

use super::candidates::Table;
use super::signals::{column, Prepared};
use crate::error::Result;
use crate::filter::derivative;
use dvrk_kin::{DynamicsData, DynamicsModel};
use nalgebra::{DMatrix, DVector, Matrix4, Vector3, Vector4};

/// Transmission damping ratio on the motor's mode (dvrk-sim's drive convention).
const DAMPING_RATIO: f64 = 0.1;

/// Bandwidth of the stiff contact behind a play without compliance (rad/s on the motor inertia).
/// Not profiled: once the motor's recorded detail drives the play, the contact's stiffness
/// (tried 500-4000 rad/s) no longer shows in the band, and profiling it overfitted (seed 1:
/// 500 rad/s chosen against the truth's 1600, held-out 1.26 -> 1.81 of the floor).
const CONTACT_BANDWIDTH: f64 = 2.0 * std::f64::consts::PI * 300.0;

/// Low-pass (Hz) on the encoder's detail (its raw motion less the band's) the motor is tied to.
/// A play's impacts kink the motor's motion, which the band smears over +-50 ms: tied to the
/// band's motion alone, the motor reached each impact 1-2 mrad off and recoiled back too soon.
/// Below it the recorded kinks; above it the tie leaves the recoil to the simulated motor.
/// Measured (seed 1 play, no noise, the pitch's band mismatch at the true b, N·m): without the
/// detail 2.3e-2; 50 Hz 5.3e-3, 100 Hz 5.9e-3, 150 Hz 7.0e-3 (2 µrad of encoder noise: +2%).
pub const MOTOR_DETAIL_CUTOFF: f64 = 100.0;

/// Bandwidth (rad/s) below which the motor follows the recorded motion, through a critically
/// damped tie on its inertia; above it the motor is free. The encoder records the motor, so its
/// motion in the band is known; an impact's recoil (milliseconds) is faster than the band shows,
/// and prescribing the band's motion made the motor an immovable wall the link rebounded off
/// (b +6.1%, +6.4% on two plays, against +0.2%, -3.3% tied at 600, before the start-path fix).
/// Too loose a tie and the joint's own effort reads the play narrow; too stiff and plays whose
/// link crosses with its load near zero go wrong (why is not found: 1051 below, 27.5 s).
/// Backlash table, seeds 1030-1059 (`detection_rate_table`): 600 rad/s 25/30 intervals cover,
/// b -0.48% on average, held-out median 1.11 of the floor; 900 29/30, +0.19% (RMS 1.00%), 1.07,
/// but the rattling seed 1059 (load hovering near zero) +4.6%, held-out 4.4 (600: -0.2%, 2.4);
/// 1200 ran away on seed 1051 (b +7.8%, held-out 5.6; 600: -0.46%, 1.11; 900: +0.26%, 1.05).
/// Seeds 1000-1029: 600 22/30, -0.48% (RMS 0.79%), 1.13; 900 29/30, -0.07% (RMS 0.45%), 1.09.
/// Low noise (effort noise / 100), b on seeds 1021, 1046, 1017, 1039: 600 +0.02, -0.66, -0.71,
/// -0.29%; 900 on 1017 -0.49%; 1200 +0.46, +0.08, -1.20, +0.02%.
const MOTOR_TIE: f64 = 900.0;

/// Integration sub-steps per recorded sample.
const SUBSTEPS: usize = 4;

/// The transmission law.
#[derive(Debug, Clone, Copy)]
pub enum Law {
    /// Spring of this stiffness (N·m/rad, N/m).
    Compliance(f64),
    /// Play of half-width `half` (rad, m), a stiff contact beyond it (`CONTACT_BANDWIDTH` on
    /// the motor inertia).
    Backlash { half: f64 },
}

/// What one joint's drive simulation needs, along the analysed samples.
#[derive(Debug, Clone)]
pub struct JointLoad {
    pub joint: usize,
    /// Link-side effort the model predicts along the recorded (motor) motion (N·m, N).
    pub load: Vec<f64>,
    /// Column `j` of the link mass matrix, `[sample][joint]` (`M_jj` its own inertia; kg m^2, kg).
    pub inertia: Table,
    /// d(effort_k)/dq_j of every joint k, from gravity and the rest of the arm, `[sample][joint]`
    /// (N·m/rad, N/m).
    pub stiffness: Table,
    /// d(effort_k)/d(qd_j) of every joint k, `[sample][joint]` (N·m s/rad, N s/m): the
    /// Coriolis and centrifugal share of the link's lag rate, and on joint `j` itself with the
    /// link's own damping (the link's flight across a play is damped by it).
    pub rate: Table,
    /// Motor inertia (kg m^2, kg).
    pub motor: f64,
    /// Added to `load` where it drives the link (N·m, N; analysed samples): the refitted
    /// inertias' share at this joint ([`JointLoad::corrected`]). The signature is taken against
    /// `load` plus it: the drive's own change of the effort.
    pub correction: Vec<f64>,
    /// The motor's recorded detail ([`motor_detail`]; rad, m; raw samples).
    pub detail: Vec<f64>,
}

impl JointLoad {
    /// This load with the nuisance inertias' `change` added: to what drives the link (a link in
    /// free flight across a play moves under its load alone, and the truth's inertias 3% off the
    /// model's put its impacts a millisecond off), to its inertia and to its stiffness (a
    /// compliance's deflection is the load over the stiffness, and its signature the inertia and
    /// stiffness times that deflection: the outer pitch's stiffness moved 0.45% per 1% of its
    /// `M_jj`, seed 1039).
    pub fn corrected(&self, change: &LoadChange) -> JointLoad {
        let mut out = self.clone();
        let j = self.joint;
        for (c, row) in out.correction.iter_mut().zip(&change.effort) {
            *c += row[j];
        }
        for (table, delta) in [(&mut out.inertia, &change.inertia), (&mut out.stiffness, &change.stiffness)] {
            for (row, d) in table.iter_mut().zip(delta) {
                row.iter_mut().zip(d).for_each(|(x, y)| *x += y);
            }
        }
        out
    }
}

/// Positions, velocities and accelerations per sample (rad, m; /s; /s^2).
pub type Motion<'a> = (&'a [Vec<f64>], &'a [Vec<f64>], &'a [Vec<f64>]);

/// What a change of the bodies' inertial parameters changes in joint `j`'s load, along the
/// analysed samples, each `[sample][joint]`.
#[derive(Debug, Clone)]
pub struct LoadChange {
    /// Every joint's effort along the recorded motion (N·m, N).
    pub effort: Table,
    /// Column `j` of the link mass matrix (kg m^2, kg).
    pub inertia: Table,
    /// Every joint's effort derivative in `q_j` (N·m/rad, N/m).
    pub stiffness: Table,
}

impl LoadChange {
    /// The change `dpi` (kg, kg m, kg m^2; every body's, in dvrk-kin's regressor order) makes
    /// to joint `j`'s load along `motion` (`q`, `qd`, `qdd` per sample): the effort is linear in
    /// the inertial parameters, so each part is the regressor (at the motion; at unit
    /// acceleration of `j` alone; its derivative in `q_j`) times `dpi`.
    pub fn of(model: &dvrk_kin::Model, dm: &DynamicsModel, gravity: &Vector3<f64>, j: usize, dpi: &DVector<f64>, motion: Motion) -> Result<LoadChange> {
        let (q, qd, qdd) = motion;
        let nq = model.nq();
        let mut data = DynamicsData::new(model);
        let mut y = DMatrix::zeros(nq, dpi.len());
        let (zero, mut unit, mut moved) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
        unit[j] = 1.0;
        let h = 1e-6;
        let n = q.len();
        let mut out = LoadChange { effort: Vec::with_capacity(n), inertia: Vec::with_capacity(n), stiffness: Vec::with_capacity(n) };
        for i in 0..n {
            dvrk_kin::regressor(model, dm, &mut data, &q[i], &zero, &unit, &Vector3::zeros(), &mut y)?;
            out.inertia.push((&y * dpi).iter().copied().collect());
            dvrk_kin::regressor(model, dm, &mut data, &q[i], &qd[i], &qdd[i], gravity, &mut y)?;
            let effort = &y * dpi;
            moved.copy_from_slice(&q[i]);
            moved[j] += h;
            dvrk_kin::regressor(model, dm, &mut data, &moved, &qd[i], &qdd[i], gravity, &mut y)?;
            out.stiffness.push(((&y * dpi - &effort) / h).iter().copied().collect());
            out.effort.push(effort.iter().copied().collect());
        }
        Ok(out)
    }
}

/// Joint `j`'s encoder detail (raw less band-filtered position) low-passed at
/// [`MOTOR_DETAIL_CUTOFF`] (or 0.4 of the recording's rate), at the raw samples (rad, m).
pub fn motor_detail(prep: &Prepared, j: usize) -> Vec<f64> {
    let rate = 1.0 / prep.raw_dt();
    let pad = (rate / MOTOR_DETAIL_CUTOFF * 3.0) as usize;
    crate::filter::Butterworth2::new(MOTOR_DETAIL_CUTOFF.min(0.4 * rate), rate).filtfilt(&prep.motor_detail[j], pad)
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

/// Linear interpolation of analysed-sample values `v` at a raw sample's place ([`raw_places`]).
fn at_raw(v: &[f64], (i, w): (usize, f64)) -> f64 {
    if w == 0.0 {
        v[i]
    } else {
        v[i] * (1.0 - w) + v[i + 1] * w
    }
}

/// [`at_raw`]'s place of every raw sample `0..=n`: the analysed sample at or before it and the
/// next one's weight (the analysed samples are every `stride`-th raw one, signals::prepare;
/// before the first and after the last, their values). Looked up, not divided for, per read.
fn raw_places(prep: &Prepared, n: usize) -> Vec<(usize, f64)> {
    let k = &prep.keep;
    let (first, last) = (k[0], k[k.len() - 1]);
    (0..=n)
        .map(|s| {
            if s <= first {
                (0, 0.0)
            } else if s >= last {
                (k.len() - 1, 0.0)
            } else {
                let stride = k[1] - k[0];
                let i = ((s - first) / stride).min(k.len() - 2);
                (i, (s - k[i]) as f64 / stride as f64)
            }
        })
        .collect()
}

/// Continue `v` before `first` by its point reflection about that sample:
/// `v(first - d) = 2 v(first) - v(first + d)`.
fn point_reflect_before(v: &mut [f64], first: usize) {
    for s in 0..first {
        v[s] = 2.0 * v[first] - v[(2 * first - s).min(v.len() - 1)];
    }
}

/// The change in the joint's effort (analysed samples, `[sample][joint]`) when its drive obeys
/// `law` instead of being rigid.
pub fn signature(prep: &Prepared, jl: &JointLoad, law: Law, nq: usize) -> Table {
    let j = jl.joint;
    let n = prep.fast_qd[j].len();
    let dt = prep.raw_dt();
    let h = dt / SUBSTEPS as f64;
    let (k, half) = match law {
        Law::Compliance(k) => (k, 0.0),
        Law::Backlash { half } => (jl.motor * CONTACT_BANDWIDTH * CONTACT_BANDWIDTH, half),
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
    // The motor's tie to the recorded motion (band and detail), critically damped.
    let jm = jl.motor;
    let (kt, ct) = (jm * MOTOR_TIE * MOTOR_TIE, 2.0 * jm * MOTOR_TIE);
    let detail = |s: usize| jl.detail.get(s).or(jl.detail.last()).copied().unwrap_or(0.0);
    // The drive's torque on the link; the link's and motor's deviations from the band's motion.
    let mut force = vec![0.0; n];
    let (mut lag, mut motor) = (vec![0.0; n], vec![0.0; n]);
    let (inertia_j, stiffness_j, rate_j) = (column(&jl.inertia, j), column(&jl.stiffness, j), column(&jl.rate, j));
    let driven: Vec<f64> = jl.load.iter().zip(&jl.correction).map(|(l, c)| l + c).collect();
    // Simulated on to the recording's end: the filter looks past the last analysed sample, and a
    // contact still ringing there, held or reflected, becomes a step (it made the last 50 ms
    // of a play's signature wrong by 10 times the residual's RMS). The load goes on as its point
    // reflection; 0.1 s on, the filter no longer looks.
    let places = raw_places(prep, n);
    let load_at = |s: usize| if s > last { 2.0 * driven[driven.len() - 1] - at_raw(&driven, places[(2 * last).saturating_sub(s)]) } else { at_raw(&driven, places[s]) };
    // State: motor deviation z, link deviation y from the band's motion, and their rates. The
    // start is in the contact, on the slowly forced link's own path: a soft drive started at rest
    // (or after a spin-up on the load reflected) rang at its own mode (5 Hz, in the band) for a
    // second or two, 10 times the rest's residual.
    let mut st = {
        let (m, g, l) = (inertia_j[0].max(1e-9), stiffness_j[0], &driven);
        // A play's side: the load's over the first 50 ms, not at the first sample (a yaw's load
        // touching zero there started its play on the wrong side: 0.25 s of residual at 40
        // times the floor while the link crossed).
        let side = l.iter().take(1 + (0.05 / prep.dt) as usize).sum::<f64>().signum();
        // (Gravity's stiffness only where it does not nearly cancel the drive's.)
        let (shift, ke, ce) = (half * side, if k + g > 0.5 * k { k + g } else { k }, c + rate_j[0]);
        // Forcing P = -(load + k shift) and its rate and curvature (one-sided, on the analysed
        // samples); the path y = P/ke - ce/ke^2 P' + (ce^2/ke^3 - m/ke^2) P''.
        let at = |i: usize| -(l.get(i).copied().unwrap_or(l[0]) + k * shift);
        let da = prep.dt;
        let (p0, p1) = (at(0), (-3.0 * at(0) + 4.0 * at(1) - at(2)) / (2.0 * da));
        let p2 = (at(0) - 2.0 * at(1) + at(2)) / (da * da);
        let y = p0 / ke - ce / (ke * ke) * p1 + (ce * ce / (ke * ke * ke) - m / (ke * ke)) * p2;
        let z = detail(first);
        Vector4::new(z, 0.0, z + y, p1 / ke - ce / (ke * ke) * p2)
    };
    for s in first..n {
        let (load, m, g) = (load_at(s), at_raw(&inertia_j, places[s]).max(1e-9), at_raw(&stiffness_j, places[s]));
        let dl = at_raw(&rate_j, places[s]);
        // The outputs at this sample come from the state at this sample: read after the step to
        // the next one, with the load held over it, they led the load by half a sample (0.5 ms:
        // a compliance's signature 5% off, its stiffness 3-4% low).
        let (z, zd, y, yd) = (st[0], st[1], st[2], st[3]);
        let (kk, shift, cc) = regime(z - y);
        force[s] = kk * (z - y - shift) + cc * (zd - yd);
        lag[s] = y;
        motor[s] = z;
        // Per regime (free, engaged) over this sample's step: s1 = step s0 + forcing f
        // (trapezoidal: stable at any contact stiffness and, unlike implicit Euler, without
        // numerical damping).
        let mut steps: [Option<(Matrix4<f64>, Matrix4<f64>)>; 2] = [None, None];
        let (next, d0, d1) = (load_at(s + 1), detail(s), detail(s + 1));
        // J z'' = load - F - kt (z - d) - ct (z' - d');  m y'' = F - load - g y - dl y';
        // F = kk (z - y - shift) + cc (z' - y'). The load stands for the band's share of F,
        // which the recorded motion already holds: the rest knocks the motor.
        let system = |kk: f64, cc: f64| {
            #[rustfmt::skip]
            let a = Matrix4::new(
                0.0, 1.0, 0.0, 0.0,
                -(kk + kt) / jm, -(cc + ct) / jm, kk / jm, cc / jm,
                0.0, 0.0, 0.0, 1.0,
                kk / m, cc / m, -(kk + g) / m, -(cc + dl) / m,
            );
            a
        };
        // The trapezoidal step over `dh` of system `a`: s1 = step s0 + forcing f.
        let discretise = |a: Matrix4<f64>, dh: f64| {
            let id = Matrix4::identity();
            let inv = (id - a * (0.5 * dh)).try_inverse().unwrap_or(id);
            (inv * (id + a * (0.5 * dh)), inv * dh)
        };
        // The forcing at fraction `w` of the sample's step in a regime (the load and the detail
        // are linear between samples; trapezoidal forcing is their mean over a piece).
        let forcing_at = |w: f64, kk: f64, shift: f64| {
            let l = load + (next - load) * w + kk * shift;
            let tie = kt * (d0 + (d1 - d0) * w) + ct * (d1 - d0) / dt;
            Vector4::new(0.0, (l + tie) / jm, 0.0, -l / m)
        };
        for i in 0..SUBSTEPS {
            // The regime at the substep's start; within it the law is linear.
            let (kk, shift, cc) = regime(st[0] - st[2]);
            let (step, forcing) = *steps[usize::from(kk > 0.0)].get_or_insert_with(|| discretise(system(kk, cc), h));
            let w = (i as f64 + 0.5) / SUBSTEPS as f64;
            let end = step * st + forcing * forcing_at(w, kk, shift);
            let (kk1, shift1, cc1) = regime(end[0] - end[2]);
            if (kk1 > 0.0) == (kk > 0.0) {
                st = end;
                continue;
            }
            // The contact made or broken within the substep: stepped to the edge it crossed in
            // the old regime, on in the new one. Detected only at the substeps' starts, an
            // impact came up to a substep late (seed 1039's yaw play: b 1.0% low at 4 substeps,
            // 0.6% at 16 or with the edge found; over 30 plays single estimates moved by up to
            // 0.8% either way, the mean bias, -0.5%, did not).
            let (before, after) = (st[0] - st[2], end[0] - end[2]);
            let edge = if kk > 0.0 { shift } else { shift1 };
            let theta = ((before - edge) / (before - after)).clamp(0.0, 1.0);
            let w0 = i as f64 / SUBSTEPS as f64;
            let piece = 1.0 / SUBSTEPS as f64;
            let (s1, f1) = discretise(system(kk, cc), theta * h);
            let mid = s1 * st + f1 * forcing_at(w0 + 0.5 * theta * piece, kk, shift);
            let (s2, f2) = discretise(system(kk1, cc1), (1.0 - theta) * h);
            st = s2 * mid + f2 * forcing_at(w0 + (0.5 + 0.5 * theta) * piece, kk1, shift1);
        }
    }
    // Before the simulated span, which starts in the contact, each series goes on as its
    // point reflection (value and slope kept), as the measured effort does there.
    for v in [&mut force, &mut lag, &mut motor] {
        point_reflect_before(v, first);
    }
    let mut table = vec![vec![0.0; nq]; prep.t.len()];
    // The joint's own effort: the drive's torque through the analysis' filter, against the load
    // that drives the link (the correction is the nuisance's, refitted next to the signature:
    // left in the signature it was counted twice, and the held-out residual grew). The load,
    // already in the band, is not filtered again: that lost up to a quarter of a play's
    // signature (its kinks put the load's content near the band's edge).
    for ((row, f), (l, c)) in table.iter_mut().zip(prep.band(&force)).zip(jl.load.iter().zip(&jl.correction)) {
        row[j] = f - l - c;
    }
    // The other joints feel the link's lag behind the motor (the encoder), through the coupling
    // inertia, stiffness and rate: M_kj y'' + dtau_k/dq_j y + dtau_k/dqd_j y'.
    let rel: Vec<f64> = lag.iter().zip(&motor).map(|(y, z)| y - z).collect();
    let rate = derivative(&rel, dt);
    let acc = derivative(&rate, dt);
    for k in (0..nq).filter(|&k| k != j) {
        let (mk, gk, ck) = (column(&jl.inertia, k), column(&jl.stiffness, k), column(&jl.rate, k));
        let raw: Vec<f64> = (0..n).map(|s| at_raw(&mk, places[s]) * acc[s] + at_raw(&gk, places[s]) * rel[s] + at_raw(&ck, places[s]) * rate[s]).collect();
        for (row, v) in table.iter_mut().zip(prep.band(&raw)) {
            row[k] = v;
        }
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use dvrk_kin::BodyInertia;

    /// The effort is linear in the inertial parameters: a change's share of the load, inertia and
    /// stiffness is the difference of the two models' own dynamics (each body scaled 2-8%, at a
    /// moving PSM pose; gravity stiffness by central differences of both).
    #[test]
    fn a_load_change_is_the_difference_of_the_two_models_dynamics() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let scene = dvrk_sim::Scene::load("psm").unwrap();
        let inertias = scene.arms[0].inertials.body_inertias(&model).unwrap();
        let changed: Vec<BodyInertia> =
            inertias.iter().enumerate().map(|(b, i)| BodyInertia::from_parameters(&i.parameters().map(|p| p * (1.02 + 0.01 * (b % 7) as f64)), "test").unwrap()).collect();
        let (dm, dm2) = (DynamicsModel::new(&model, inertias).unwrap(), DynamicsModel::new(&model, changed).unwrap());
        let dpi = DVector::from_vec(dm2.parameters()) - DVector::from_vec(dm.parameters());
        let nq = model.nq();
        let q = vec![vec![0.3, -0.2, 0.12, 0.4, -0.3, 0.2, 0.0][..nq].to_vec()];
        let qd = vec![vec![0.5, -0.4, 0.05, 1.0, 0.8, -0.6, 0.0][..nq].to_vec()];
        let qdd = vec![vec![2.0, 1.0, -0.3, 3.0, -2.0, 1.5, 0.0][..nq].to_vec()];
        let g = Vector3::new(0.0, 0.0, -9.81);
        let j = 1;
        let change = LoadChange::of(&model, &dm, &g, j, &dpi, (&q, &qd, &qdd)).unwrap();
        let mut data = DynamicsData::new(&model);
        let (mut m1, mut m2) = (DMatrix::zeros(nq, nq), DMatrix::zeros(nq, nq));
        dvrk_kin::mass_matrix(&model, &dm, &mut data, &q[0], &mut m1).unwrap();
        dvrk_kin::mass_matrix(&model, &dm2, &mut data, &q[0], &mut m2).unwrap();
        let mut effort = |d: &DynamicsModel, q: &[f64]| {
            let mut tau = vec![0.0; nq];
            dvrk_kin::inverse_dynamics(&model, d, &mut data, q, &qd[0], &qdd[0], &g, &mut tau).unwrap();
            tau
        };
        let (e1, e2) = (effort(&dm, &q[0]), effort(&dm2, &q[0]));
        let h = 1e-6;
        let (mut up, mut down) = (q[0].clone(), q[0].clone());
        up[j] += h;
        down[j] -= h;
        let (u1, u2, d1, d2) = (effort(&dm, &up), effort(&dm2, &up), effort(&dm, &down), effort(&dm2, &down));
        for k in 0..nq {
            let (di, de, ds) = (m2[(k, j)] - m1[(k, j)], e2[k] - e1[k], ((u2[k] - u1[k]) - (d2[k] - d1[k])) / (2.0 * h));
            assert!((change.inertia[0][k] - di).abs() < 1e-9 * (1.0 + m1[(k, j)].abs()), "inertia {k}: {} vs {di}", change.inertia[0][k]);
            assert!((change.effort[0][k] - de).abs() < 1e-9 * (1.0 + e1[k].abs()), "effort {k}: {} vs {de}", change.effort[0][k]);
            assert!((change.stiffness[0][k] - ds).abs() < 1e-4 * (1.0 + ds.abs()), "stiffness {k}: {} vs {ds}", change.stiffness[0][k]);
        }
        // Not vacuous: the change is a few percent of the pitch's own inertia.
        assert!(change.inertia[0][j] > 0.01 * m1[(j, j)], "{} of {}", change.inertia[0][j], m1[(j, j)]);
    }
}
