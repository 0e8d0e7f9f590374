//! The workflow on a recording without efforts: encoders and a tracked marker, the kinematic
//! channel alone (issue 40 item 5). The torque channel needs measured efforts; the kinematic one
//! needs only the encoders and the tracker, and the drive's load where it tests a compliance or
//! play, which the model's own prediction stands in for here (said in the notes).
//!
//! The report keeps the torque report's shape: `channel` is `kinematic`, its normalised RMS are
//! the tracked pose's residual over the tracker's noise (`rms_units` says so), and the fields
//! only efforts give (the raw effort residual, per-joint effort RMS, where along the motion the
//! effort residual is large) are empty or `null`.

use dvrk_sim::recording::JointLog;
use super::kinematic::{analyse, Inputs};
use super::plot::Residuals;
use super::report::Report;
use super::signals::{prepare, Predictor};
use super::options::{Options, Outcome};
use super::separation::separating_experiment;
use crate::error::{CalibError, Result};
use dvrk_kin::Model;
use dvrk_sim::Scene;

/// Run one round on the kinematic channel of `log` (which has a tracked marker and no efforts).
pub fn discrepancy(model: &Model, scene: &Scene, arm_name: &str, log: &JointLog, o: &Options) -> Result<Outcome> {
    let Some(markers) = log.markers.as_ref() else {
        return Err(CalibError::data("recording", "no efforts and no tracked marker: the discrepancy workflow needs measured efforts (the torque channel) or a tracked marker (the kinematic channel)"));
    };
    let a = scene.arm_index(arm_name).map_err(|e| CalibError::field("--arm", e.to_string()))?;
    let mut scene = scene.clone();
    scene.set_model(a, model.clone()).map_err(|e| CalibError::context("model", e))?;
    let arm = &scene.arms[a];
    // Without efforts the prepared effort is zero: the model's prediction stands in for it (the
    // drive's load the kinematic channel deflects compliant joints by).
    let mut prep = prepare(log, &o.processing)?;
    let mut predictor = Predictor::new(&arm.model, arm, scene.gravity)?;
    prep.effort = predictor.series(&prep)?;
    let kc = analyse(&Inputs { model: &arm.model, log, markers, prep: &prep, armature: predictor.armature() })?;
    let strong = |delta_bic: f64, p: f64, heldout_p: f64, size: f64| delta_bic > o.min_delta_bic && p < o.max_p_value && heldout_p < 0.01 && size >= o.min_kinematic_effect_to_noise;
    let supported: Vec<_> = kc.candidates.iter().filter(|k| strong(k.delta_bic, k.p_value, k.heldout_p, k.effect_to_noise)).collect();
    let (mut verdict, mut experiment, mut named, mut label) = ("none", None, None, None);
    if let Some(best) = supported.first() {
        match supported.iter().skip(1).find(|k| best.delta_bic - k.delta_bic < o.ambiguity_bic) {
            Some(rival) => {
                verdict = "ambiguous";
                experiment = Some(separating_experiment(best.kind, rival.kind));
            }
            None => {
                verdict = "named";
                named = Some(best.spec(&arm.model, "dvrk discrepancy").0);
                label = Some(best.label(&arm.model));
            }
        }
    }
    let channel = kc.report(&arm.model, named.as_ref(), "dvrk discrepancy", &strong);
    let effects = channel.candidates.iter().filter(|c| Some(&c.label) == label.as_ref()).map(|c| c.effect.clone()).collect();
    let tracking = match o.tracking {
        true => Some(super::tracking::compare(&scene, a, log, model, named.as_ref().map(|e| model.with_effect(e)).transpose()?.as_ref())?),
        false => None,
    };
    let residuals = Residuals {
        joints: Vec::new(),
        units: Vec::new(),
        position_units: Vec::new(),
        t: Vec::new(),
        q: Vec::new(),
        qd: Vec::new(),
        load: Vec::new(),
        before: Vec::new(),
        after: Vec::new(),
        floor: Vec::new(),
        heldout_from: channel.heldout_from,
    };
    let report = Report {
        verdict: verdict.into(),
        channel: "kinematic".into(),
        effects,
        candidates: channel.candidates.clone(),
        experiment,
        rms_before: channel.rms_before,
        rms_after: channel.rms_after,
        rms_heldout_before: channel.rms_heldout_before,
        rms_heldout_after: channel.rms_heldout_after,
        raw_rms_heldout_before: f64::NAN,
        raw_rms_heldout_after: f64::NAN,
        rms_nominal: channel.rms_before,
        rms_heldout_nominal: channel.rms_heldout_before,
        noise_floor: 1.0,
        rms_units: "the tracked marker's pose residual over the tracker's noise per axis, RMS (the kinematic channel alone: the recording has no efforts)".into(),
        joints: Vec::new(),
        location: Vec::new(),
        tracking,
        samples: channel.samples,
        heldout_from: channel.heldout_from,
        kinematic: Some(channel),
        notes: std::iter::once("no measured efforts in the recording: the kinematic channel alone (the torque channel needs efforts); a compliance's or play's deflection is taken under the model's predicted load".to_string())
            .chain(kc.notes(&arm.model, named.as_ref(), &|k| strong(k.delta_bic, k.p_value, k.heldout_p, k.effect_to_noise)))
            .collect(),
        steps: Vec::new(),
    };
    Ok(Outcome { report, named, residuals })
}
