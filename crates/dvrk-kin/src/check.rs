//! `dvrk model check`: the figures that say a model is sound.

use crate::closure::{closure_conditioning, max_closure_residual};
use crate::error::{KinError, Result};
use crate::fk::{compute_frame_placements, Data};
use crate::model::{sample_configurations, Model};
use crate::rcm::pivot_residual;
use serde::Serialize;

/// Serial-equivalence figures: the closed-loop frames against the serial dVRK chain.
#[derive(Debug, Clone, Serialize)]
pub struct SerialCheck {
    pub serial_model: String,
    /// Largest position difference over the samples (m), after the constant base transform.
    pub max_position_error_m: f64,
    /// Largest orientation difference (rad).
    pub max_orientation_error_rad: f64,
    /// The base transform, row-major 4x4 (closed-loop base -> serial base).
    pub base_transform: [[f64; 4]; 4],
}

/// Closure conditioning figures.
#[derive(Debug, Clone, Serialize)]
pub struct ConditioningCheck {
    pub rank: usize,
    /// Smallest relevant singular value of the closure Jacobian at home (m/rad).
    pub sigma_min_home: f64,
    /// Its smallest value over the joint range (m/rad), and where.
    pub sigma_min_worst: f64,
    pub worst_q: Vec<f64>,
}

/// All figures of `dvrk model check`.
#[derive(Debug, Clone, Serialize)]
pub struct ModelCheck {
    pub model: String,
    pub frames: usize,
    pub joints: usize,
    pub bodies: usize,
    pub samples: usize,
    /// Largest closure gap over the samples (m).
    pub max_closure_residual_m: Option<f64>,
    /// RCM point in the base frame (m).
    pub rcm: Option<[f64; 3]>,
    /// Largest distance of the insertion axis from the RCM (m).
    pub max_pivot_residual_m: Option<f64>,
    pub conditioning: Option<ConditioningCheck>,
    pub serial_equivalence: Option<SerialCheck>,
    /// True when every figure is within tolerance.
    pub ok: bool,
    /// What failed, in words.
    pub problems: Vec<String>,
}

/// Tolerances of [`check_model`].
pub const CLOSURE_TOL_M: f64 = 1e-9;
pub const PIVOT_TOL_M: f64 = 1e-9;
pub const SERIAL_TOL: f64 = 1e-9;
/// A closure Jacobian singular value below this (m/rad) means a loop is close to flattening.
pub const CONDITIONING_MIN: f64 = 1e-3;

/// The farthest a frame of a sound model is from its base over the joint range (m): the dVRK's
/// arms reach about 1 m, the setup joints' cart about 2.
pub const MAX_REACH_M: f64 = 10.0;

/// Most configurations [`check_model`] takes: each costs a configuration vector in memory
/// (8 bytes per joint) and an FK; 10^7 is a few hundred MB and minutes, more is a mistake.
pub const MAX_CHECK_SAMPLES: usize = 10_000_000;

/// A sample count [`check_model`] takes, or an error saying the range.
pub fn check_samples(samples: usize) -> Result<()> {
    if !(1..=MAX_CHECK_SAMPLES).contains(&samples) {
        return Err(KinError::Value { what: "samples".into(), value: samples as f64, message: format!("must be in 1..={MAX_CHECK_SAMPLES} (each is a configuration evaluated and kept in memory)") });
    }
    Ok(())
}

/// Evaluate a model over `samples` configurations spread over its joint range (1 to
/// [`MAX_CHECK_SAMPLES`]; the CLI and Python both come through this check).
pub fn check_model(model: &Model, samples: usize) -> Result<ModelCheck> {
    check_samples(samples)?;
    let mut data = Data::new(model);
    let configs = sample_configurations(&model.joints, samples);
    let mut closure = None;
    let mut pivot = None;
    // The frame farthest from the base over the samples, and its distance (m).
    let mut reach: Option<(usize, f64)> = None;
    for q in &configs {
        compute_frame_placements(model, &mut data, q);
        for (f, pose) in data.frames.iter().enumerate() {
            let r = pose.translation.vector.norm();
            if reach.is_none_or(|(_, best)| !(r <= best)) {
                reach = Some((f, r));
            }
        }
        if !model.closures.is_empty() {
            closure = Some(closure.unwrap_or(0.0f64).max(max_closure_residual(model, &data)));
        }
        if let Some(p) = pivot_residual(model, &data) {
            pivot = Some(pivot.unwrap_or(0.0f64).max(p));
        }
    }
    let conditioning = closure_conditioning(model, samples.min(2000)).map(|c| ConditioningCheck {
        rank: c.rank,
        sigma_min_home: c.at_home,
        sigma_min_worst: c.worst,
        worst_q: c.worst_q,
    });
    let serial_equivalence = serial_check(model, &configs)?;
    let mut problems = Vec::new();
    // A joint no frame follows is a typo in an expression or a dead joint: the robot has none.
    for (j, joint) in model.joints.iter().enumerate() {
        if model.frames.iter().all(|f| f.theta.coef.get(j).is_none_or(|c| *c == 0.0) && f.d.coef.get(j).is_none_or(|c| *c == 0.0)) {
            problems.push(format!("joint `{}` drives no frame (no frame's theta or d depends on it)", joint.name));
        }
    }
    // Lengths no dVRK has (a DH figure of 1e308 m compiles, and every figure above stays finite).
    if let Some((f, r)) = reach.filter(|(_, r)| !(*r <= MAX_REACH_M)) {
        problems.push(format!("frame `{}` is {} m from the base (a dVRK arm reaches about 1 m; at most {MAX_REACH_M} m is checked)", model.frames[f].name, crate::fmt_number(r)));
    }
    if let Some(c) = closure.filter(|c| *c > CLOSURE_TOL_M) {
        problems.push(format!("closure residual {c:.3e} m exceeds {CLOSURE_TOL_M:e} m"));
    }
    if let Some(p) = pivot.filter(|p| *p > PIVOT_TOL_M) {
        problems.push(format!("pivot residual {p:.3e} m exceeds {PIVOT_TOL_M:e} m"));
    }
    if let Some(c) = conditioning.as_ref().filter(|c| c.sigma_min_worst < CONDITIONING_MIN) {
        problems.push(format!(
            "closure conditioning falls to {:.3e} m/rad (below {CONDITIONING_MIN:e}) at q = {:?}",
            c.sigma_min_worst, c.worst_q
        ));
    }
    if let Some(s) = serial_equivalence.as_ref().filter(|s| s.max_position_error_m > SERIAL_TOL || s.max_orientation_error_rad > SERIAL_TOL) {
        problems.push(format!(
            "differs from {} by {:.3e} m / {:.3e} rad",
            s.serial_model, s.max_position_error_m, s.max_orientation_error_rad
        ));
    }
    Ok(ModelCheck {
        model: model.name.clone(),
        frames: model.frames.len(),
        joints: model.nq(),
        bodies: model.bodies.len(),
        samples,
        max_closure_residual_m: closure,
        rcm: model.rcm.as_ref().map(|r| [r.point.x, r.point.y, r.point.z]),
        max_pivot_residual_m: pivot,
        conditioning,
        serial_equivalence,
        ok: problems.is_empty(),
        problems,
    })
}

fn serial_check(model: &Model, configs: &[Vec<f64>]) -> Result<Option<SerialCheck>> {
    let Some(serial) = crate::load::load_serial_equivalent(model)? else { return Ok(None) };
    let spec = model.spec.serial_equivalent.as_ref().expect("loaded");
    let pairs: Vec<(usize, usize)> = spec
        .pairs
        .iter()
        .map(|[a, b]| Ok((model.frame_id(a)?, serial.frame_id(b)?)))
        .collect::<Result<_>>()
        .map_err(|e: KinError| KinError::field("serial_equivalent.pairs", e.to_string()))?;
    let base = crate::compose::serial_base_transform(model)?;
    let mut sdata = Data::new(&serial);
    let mut data = Data::new(model);
    let (mut ep, mut eo) = (0.0f64, 0.0f64);
    for q in configs {
        compute_frame_placements(model, &mut data, q);
        compute_frame_placements(&serial, &mut sdata, &q[..serial.nq().min(q.len())]);
        for &(a, b) in &pairs {
            let expect = base * sdata.frames[b];
            let got = data.frames[a];
            ep = ep.max((expect.translation.vector - got.translation.vector).norm());
            eo = eo.max(rotation_angle(&(expect.rotation.inverse() * got.rotation)));
        }
    }
    Ok(Some(SerialCheck {
        serial_model: serial.name.clone(),
        max_position_error_m: ep,
        max_orientation_error_rad: eo,
        base_transform: crate::model::pose_to_rows(&base),
    }))
}

/// Angle of a rotation (rad), accurate near zero (acos of the trace is not: it floors at 1e-8).
pub fn rotation_angle(r: &nalgebra::Rotation3<f64>) -> f64 {
    crate::so3::angle(r)
}
