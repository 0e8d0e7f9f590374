//! Gravity compensation from a model (`dvrk gc`): the efforts that hold the arm still at a
//! configuration (dvrk-kin's [`dvrk_kin::dynamics::holding_torque`]: weight, springs, cable springs,
//! effort offsets), how they compare with a recording's efforts where it moves slowest, and the
//! same written as the dVRK console's MTM gravity-compensation file ([`console_file`]).
//!
//! A product beside calibration, identification and discrepancy: it reads recordings and a model
//! (an identified one, `dvrk identify -o`), and imports none of them.

pub mod console_file;

use crate::error::{CalibError, Result};
use dvrk_sim::recording::JointLog;
use dvrk_kin::dynamics::{holding_torque, DynamicsData, DynamicsModel};
use dvrk_kin::{BodyInertia, Model};
use nalgebra::Vector3;
use serde::Serialize;

/// Per recorded channel: the holding torque against the measured efforts at the slowest samples.
#[derive(Debug, Clone, Serialize)]
pub struct SlowSampleCheck {
    /// The recording's channels (joints or actuators).
    pub channels: Vec<String>,
    /// How many samples (the slowest `fraction` of the recording).
    pub samples: usize,
    /// Their speed: the largest channel velocity over its RMS over the recording, at most.
    pub speed_ratio: f64,
    /// Per channel, RMS of the measured efforts at those samples (N·m, N).
    pub measured_rms: Vec<f64>,
    /// Per channel, RMS of measured minus holding torque there (N·m, N).
    pub error_rms: Vec<f64>,
    /// Per channel, `error_rms / measured_rms`.
    pub relative_error: Vec<f64>,
}

/// The holding torque (N·m, N per joint) of `model` with `inertias` at joint positions `q`.
pub fn torque(model: &Model, inertias: Vec<BodyInertia>, q: &[f64], gravity: &Vector3<f64>) -> Result<Vec<f64>> {
    let dm = DynamicsModel::new(model, inertias)?;
    let mut data = DynamicsData::new(model);
    let mut tau = vec![0.0; model.nq()];
    holding_torque(model, &dm, &mut data, q, gravity, &mut tau)?;
    Ok(tau)
}

/// The holding torque against `rec`'s efforts at its slowest `fraction` of samples (each
/// sample's speed: the largest of its channels' velocities, each over that channel's RMS), in the
/// recording's channels (`to_joint^T` of the joint torques: a WPI MTM's actuators).
pub fn check_slow_samples(model: &Model, inertias: Vec<BodyInertia>, rec: &JointLog, gravity: &Vector3<f64>, fraction: f64) -> Result<SlowSampleCheck> {
    if !(fraction > 0.0 && fraction <= 1.0) {
        return Err(CalibError::field("slowest", format!("{fraction} is not a fraction in (0, 1]")));
    }
    if !rec.has_efforts() {
        return Err(CalibError::data(&rec.source, "the recording carries no efforts to compare with"));
    }
    let (n, nc, nq) = (rec.len(), rec.names.len(), model.nq());
    let map = rec.joint_map();
    if map.nrows() != nq || map.ncols() != nc {
        return Err(CalibError::data(&rec.source, format!("{nc} channels for model {}'s {nq} joints", model.name)));
    }
    let rms: Vec<f64> = (0..nc).map(|c| (rec.velocity.iter().map(|v| v[c] * v[c]).sum::<f64>() / n as f64).sqrt().max(1e-12)).collect();
    let speed = |i: usize| (0..nc).map(|c| rec.velocity[i][c].abs() / rms[c]).fold(0.0, f64::max);
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|a, b| speed(*a).total_cmp(&speed(*b)));
    let k = ((fraction * n as f64).round() as usize).clamp(1, n);
    let dm = DynamicsModel::new(model, inertias)?;
    let mut data = DynamicsData::new(model);
    let (mut q, mut tau) = (vec![0.0; nq], vec![0.0; nq]);
    let (mut measured, mut error) = (vec![0.0; nc], vec![0.0; nc]);
    for &i in &order[..k] {
        for (j, qj) in q.iter_mut().enumerate() {
            *qj = (0..nc).map(|c| map[(j, c)] * rec.position[i][c]).sum();
        }
        holding_torque(model, &dm, &mut data, &q, gravity, &mut tau)?;
        for c in 0..nc {
            let predicted: f64 = (0..nq).map(|j| map[(j, c)] * tau[j]).sum();
            measured[c] += rec.effort[i][c].powi(2);
            error[c] += (rec.effort[i][c] - predicted).powi(2);
        }
    }
    let root = |v: Vec<f64>| v.into_iter().map(|x| (x / k as f64).sqrt()).collect::<Vec<f64>>();
    let (measured_rms, error_rms) = (root(measured), root(error));
    Ok(SlowSampleCheck {
        channels: rec.names.clone(),
        samples: k,
        speed_ratio: speed(order[k - 1]),
        relative_error: error_rms.iter().zip(&measured_rms).map(|(e, m)| e / m.max(1e-300)).collect(),
        measured_rms,
        error_rms,
    })
}
