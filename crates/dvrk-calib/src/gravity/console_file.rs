//! A model's holding torque written as the dVRK console's MTM gravity-compensation file
//! (`gc-MTMR.json`, version 2.0), which the console loads through the MTM's arm configuration
//! (`"gravity_compensation"`, `"gravity-compensation"` in 2.x releases) and evaluates with its
//! own regressor (sawIntuitiveResearchKit `robGravityCompensationMTM`, the CUHK
//! `dvrk-gravity-compensation` parameterisation):
//!
//! - 40 parameters per velocity direction: 10 weights of the links' gravity terms (g = 9.81
//!   times the sines and cosines of q2, q2 + q3 and the wrist's q4..q6, in the console's products),
//!   then per joint 1..6 a quartic polynomial in its own angle (offsets, springs);
//! - per joint, `tau = w R(q) pos + (1 - w) R(q) neg`, with `w` from the joint's velocity
//!   (`db_vel_vec`, `sat_vec_vec`, `fric_comp_ratio_vec`), clipped to
//!   `[safe_lower_torque_limit, safe_upper_torque_limit]` (N·m).
//!
//! The console's regressor is not our model's: the parameters are fitted (least squares) to the
//! model's holding torque ([`dvrk_kin::dynamics::holding_torque`]) over poses spread through its
//! joint limits, and the fit's residual is reported: the part of the model (cross springs
//! between joints, another gravity direction) the console's form cannot carry. `pos` and `neg`
//! are equal and the friction ratio 0: the model's holding torque has no direction (the console
//! blends nothing).

use crate::error::{CalibError, Result};
use dvrk_kin::dynamics::{holding_torque, DynamicsData, DynamicsModel};
use dvrk_kin::{BodyInertia, Model};
use nalgebra::{DMatrix, DVector, Vector3};
use serde::Serialize;

/// Parameters of the console's regressor.
pub const PARAMETERS: usize = 40;
/// Joints the console's MTM compensation covers (the seventh, the roll, gets none).
pub const JOINTS: usize = 7;
/// The MTM's joints in the dVRK's order, which the console's regressor is written for.
pub const MTM_JOINTS: [&str; JOINTS] = ["outer_yaw", "shoulder_pitch", "elbow_pitch", "wrist_platform", "wrist_pitch", "wrist_yaw", "wrist_roll"];
/// The console's gravity (m/s^2), hard-coded in its regressor.
pub const CONSOLE_G: f64 = 9.81;

/// The console's regressor at joint positions `q` (rad, the MTM's 7 joints in the dVRK's order;
/// q7 unused): row j, column k is joint j's torque (N·m) per unit of parameter k.
pub fn regressor(q: &[f64]) -> [[f64; PARAMETERS]; JOINTS] {
    let g = CONSOLE_G;
    let (s2, c2) = q[1].sin_cos();
    let (s23, c23) = (q[1] + q[2]).sin_cos();
    let (s4, c4) = q[3].sin_cos();
    let (s5, c5) = q[4].sin_cos();
    let (s6, c6) = q[5].sin_cos();
    let mut r = [[0.0; PARAMETERS]; JOINTS];
    // The gravity terms shared by the shoulder and the elbow (both turn everything past q2 + q3).
    let shared = [
        g * c23,
        -g * s23,
        g * c23 * c4,
        -g * c23 * s4,
        -g * (c23 * c4 * s5 + s23 * c5),
        g * (c23 * c4 * c5 - s23 * s5),
        g * (s23 * s5 * c6 + c23 * (s4 * s6 - c4 * c5 * c6)),
        g * (c23 * (s4 * c6 + c4 * c5 * s6) - s23 * s5 * s6),
    ];
    r[1][0] = g * s2;
    r[1][1] = g * c2;
    r[1][2..10].copy_from_slice(&shared);
    r[2][2..10].copy_from_slice(&shared);
    r[3][4..10].copy_from_slice(&[
        -g * s23 * s4,
        -g * s23 * c4,
        g * s23 * s4 * s5,
        -g * s23 * s4 * c5,
        g * s23 * (c4 * s6 + s4 * c5 * c6),
        g * s23 * (c4 * c6 - s4 * c5 * s6),
    ]);
    r[4][6..10].copy_from_slice(&[-g * (c23 * s5 + s23 * c4 * c5), g * (c23 * c5 - s23 * c4 * s5), g * c6 * (s23 * c4 * s5 - c23 * c5), g * s6 * (c23 * c5 - s23 * c4 * s5)]);
    r[5][8..10].copy_from_slice(&[g * (s23 * s4 * c6 + c23 * s5 * s6 + s23 * c4 * c5 * s6), g * (c23 * s5 * c6 - s23 * s4 * s6 + s23 * c4 * c5 * c6)]);
    // Each of joints 1..6: 1, q, q^2, q^3, q^4 of its own angle.
    for j in 0..6 {
        let mut p = 1.0;
        for k in 0..5 {
            r[j][10 + 5 * j + k] = p;
            p *= q[j];
        }
    }
    r
}

/// The `GC_controller` object the console reads.
#[derive(Debug, Clone, Serialize)]
pub struct GcController {
    pub gc_dynamic_params_pos: Vec<f64>,
    pub gc_dynamic_params_neg: Vec<f64>,
    /// N·m per joint: the console clips its torque into these.
    pub safe_upper_torque_limit: Vec<f64>,
    pub safe_lower_torque_limit: Vec<f64>,
    /// rad/s per joint: the velocity dead band and saturation of the direction blend.
    pub db_vel_vec: Vec<f64>,
    pub sat_vec_vec: Vec<f64>,
    /// Per joint, 0..1: how much of `pos - neg` is blended in with the velocity's sign.
    pub fric_comp_ratio_vec: Vec<f64>,
}

/// How well the console's form carries the model's holding torque.
#[derive(Debug, Clone, Serialize)]
pub struct ConsoleFit {
    /// Poses fitted over (spread through the joint limits).
    pub poses: usize,
    /// Per joint 1..7: RMS and largest |console - model| over them (N·m).
    pub residual_rms: Vec<f64>,
    pub residual_max: Vec<f64>,
    /// Per joint: RMS of the model's holding torque over them (N·m).
    pub torque_rms: Vec<f64>,
}

/// The console's gravity-compensation file.
#[derive(Debug, Clone, Serialize)]
pub struct ConsoleGcFile {
    /// "2.0": the console's current format.
    pub version: String,
    #[serde(rename = "ARM_NAME")]
    pub arm_name: String,
    /// Where the parameters came from (the console ignores this and `fit`).
    pub source: String,
    pub fit: ConsoleFit,
    #[serde(rename = "GC_controller")]
    pub gc_controller: GcController,
}

/// `n` poses spread through `model`'s joint limits: an additive recurrence (Weyl) of the square
/// roots of the first primes, so the spread is even and the same every run.
fn spread_poses(model: &Model, n: usize) -> Vec<Vec<f64>> {
    let roots = [2.0f64, 3.0, 5.0, 7.0, 11.0, 13.0, 17.0].map(f64::sqrt);
    (0..n)
        .map(|i| {
            model
                .joints
                .iter()
                .enumerate()
                .map(|(j, jt)| {
                    let u = ((i as f64 + 0.5) * roots[j % roots.len()]).fract();
                    jt.lower + u * (jt.upper - jt.lower)
                })
                .collect()
        })
        .collect()
}

/// Fit the console's parameters to `model`'s holding torque (with `inertias`, under `gravity`
/// in its base frame, m/s^2) over `poses` poses through its joint limits; `arm_name` (`MTMR`)
/// and `source` go into the file. The model must be an MTM: seven joints in the dVRK's order.
pub fn fit(model: &Model, inertias: Vec<BodyInertia>, gravity: &Vector3<f64>, poses: usize, arm_name: &str, source: &str) -> Result<ConsoleGcFile> {
    // The console's regressor is written for the MTM's kinematics, joint by joint.
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    if names != MTM_JOINTS {
        return Err(CalibError::data(&model.name, format!("joints {names:?}: the console's gravity-compensation file is an MTM's (7 joints {MTM_JOINTS:?})")));
    }
    if poses < 2 * PARAMETERS {
        return Err(CalibError::field("poses", format!("{poses}: at least {} to fit {PARAMETERS} parameters", 2 * PARAMETERS)));
    }
    let dm = DynamicsModel::new(model, inertias)?;
    let mut data = DynamicsData::new(model);
    let qs = spread_poses(model, poses);
    let mut tau = vec![0.0; JOINTS];
    let rows = 6 * poses;
    let mut a = DMatrix::<f64>::zeros(rows, PARAMETERS);
    let mut b = DVector::<f64>::zeros(rows);
    let mut torques = Vec::with_capacity(poses);
    for (i, q) in qs.iter().enumerate() {
        holding_torque(model, &dm, &mut data, q, gravity, &mut tau)?;
        let r = regressor(q);
        for j in 0..6 {
            for k in 0..PARAMETERS {
                a[(6 * i + j, k)] = r[j][k];
            }
            b[6 * i + j] = tau[j];
        }
        torques.push(tau.clone());
    }
    // Columns scaled to unit norm: q^4 of a joint with 3 rad of range beside g sin q.
    let scale: Vec<f64> = (0..PARAMETERS).map(|k| a.column(k).norm().max(1e-300)).collect();
    for (k, s) in scale.iter().enumerate() {
        a.column_mut(k).scale_mut(1.0 / s);
    }
    let svd = a.clone().svd(true, true);
    let theta = svd.solve(&b, 1e-12).map_err(|e| CalibError::data(&model.name, format!("the console's regressor could not be fitted: {e}")))?;
    let pos: Vec<f64> = (0..PARAMETERS).map(|k| theta[k] / scale[k]).collect();
    let (mut sq, mut max, mut rms, mut lo, mut hi) = (vec![0.0; JOINTS], vec![0.0; JOINTS], vec![0.0; JOINTS], vec![f64::INFINITY; JOINTS], vec![f64::NEG_INFINITY; JOINTS]);
    // The console's torque at the fitted poses is the scaled fit's (its roll row is empty: 0).
    let fitted = &a * &theta;
    for (i, t) in torques.iter().enumerate() {
        for j in 0..JOINTS {
            let console = if j < 6 { fitted[6 * i + j] } else { 0.0 };
            let d = console - t[j];
            sq[j] += d * d;
            max[j] = f64::max(max[j], d.abs());
            rms[j] += t[j] * t[j];
            lo[j] = lo[j].min(console);
            hi[j] = hi[j].max(console);
        }
    }
    let root = |v: Vec<f64>| v.into_iter().map(|x| (x / poses as f64).sqrt()).collect::<Vec<f64>>();
    // The console clips into the fitted torque's range over the workspace, widened by a tenth of
    // its span (the roll, with no torque, to 0).
    let margin: Vec<f64> = (0..JOINTS).map(|j| 0.1 * (hi[j] - lo[j])).collect();
    Ok(ConsoleGcFile {
        version: "2.0".into(),
        arm_name: arm_name.into(),
        source: source.into(),
        fit: ConsoleFit { poses, residual_rms: root(sq), residual_max: max, torque_rms: root(rms) },
        gc_controller: GcController {
            gc_dynamic_params_neg: pos.clone(),
            gc_dynamic_params_pos: pos,
            safe_upper_torque_limit: (0..JOINTS).map(|j| hi[j] + margin[j]).collect(),
            safe_lower_torque_limit: (0..JOINTS).map(|j| lo[j] - margin[j]).collect(),
            // The console template's dead band and saturation (no effect with pos = neg).
            db_vel_vec: vec![0.02, 0.02, 0.02, 0.01, 0.008, 0.008, 0.01],
            sat_vec_vec: vec![0.2; JOINTS],
            fric_comp_ratio_vec: vec![0.0; JOINTS],
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The regressor's gravity columns are a potential's gradient: row j is d/dq_j of the
    /// same function for every column (checked by central differences of the columns' integral
    /// along each joint, i.e. that the 6x10 gravity block is a Jacobian: its rows' mixed
    /// derivatives agree).
    #[test]
    fn the_gravity_block_is_the_gradient_of_one_potential() {
        let q = [0.3, -0.4, 0.7, 1.1, -0.6, 0.9, 0.0];
        let h = 1e-6;
        for k in 0..10 {
            for i in 1..6 {
                for j in 1..6 {
                    let d = |a: usize, b: usize| {
                        let (mut p, mut m) = (q, q);
                        p[b] += h;
                        m[b] -= h;
                        (regressor(&p)[a][k] - regressor(&m)[a][k]) / (2.0 * h)
                    };
                    let (dij, dji) = (d(i, j), d(j, i));
                    assert!((dij - dji).abs() < 1e-6, "column {k}: d tau_{i}/d q_{j} = {dij}, d tau_{j}/d q_{i} = {dji}");
                }
            }
        }
    }
}

#[cfg(test)]
mod fit_tests {
    use super::*;

    fn identified_mtm() -> (Model, Vec<BodyInertia>) {
        let model = dvrk_kin::load("mtmr-wpi", None).unwrap();
        let inertias = dvrk_sim::scene::builtin_inertials(&model.name, &model).unwrap().with_model(&model).body_inertias(&model).unwrap();
        (model, inertias)
    }

    /// The console's regressor carries the identified MTM's weight exactly (every link, the
    /// parallelogram's and the wrist's: its kinematics are ours) with the roll held, and its
    /// cable springs, which are polynomials of their own joint; what it cannot carry is the
    /// springs between channels.
    #[test]
    fn the_console_form_carries_the_weight_exactly_and_not_the_cross_springs() {
        let (mut model, inertias) = identified_mtm();
        let g = Vector3::new(0.0, 0.0, -9.81);
        let full = fit(&model, inertias.clone(), &g, 400, "MTMR", "test").unwrap();
        use dvrk_kin::effects::EffectKind as K;
        model.effects.retain(|e| !matches!(e.kind, K::ActuatorCrossSpring | K::ActuatorSpring | K::Spring));
        // The console's form has no roll (q7): the gripper's centre off the roll axis (0.3 mN·m
        // on the roll) makes the other joints' torques depend on it by 8e-5 N·m RMS. Roll held.
        model.joints[6].lower = 0.0;
        model.joints[6].upper = 0.0;
        let weight = fit(&model, inertias, &g, 400, "MTMR", "test").unwrap();
        eprintln!("residual rms with every effect {:?}, without the (cross) springs {:?}", full.fit.residual_rms, weight.fit.residual_rms);
        assert!(weight.fit.residual_max[..6].iter().all(|r| *r < 1e-9), "{:?}", weight.fit.residual_max);
        assert!(weight.fit.torque_rms[4] > 0.01, "the wrist has weight: {:?}", weight.fit.torque_rms);
        assert!(full.fit.residual_rms[3] > 1e-3, "the cross springs are not in the console's form");
    }
}
