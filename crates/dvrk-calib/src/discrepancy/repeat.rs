//! Step 4 of the workflow: the named effect added to the model and the analysis run again, until
//! nothing more is supported (the residual is what the candidates cannot explain: at the noise
//! floor when the model is complete), an ambiguity stops it, or the rounds run out.

use super::generate::with_effect;
use super::joint_log::JointLog;
use super::plot::Residuals;
use super::report::{Report, StepReport};
use super::workflow::{discrepancy, Options};
use crate::error::Result;
use dvrk_kin::effects::EffectSpec;
use dvrk_kin::Model;
use dvrk_sim::Scene;

/// The rounds' combined report and the model with every named effect.
#[derive(Debug, Clone)]
pub struct Repeated {
    /// The first round's candidates and "before" figures, every named effect, the last round's
    /// "after" figures, and one step per round.
    pub report: Report,
    pub model: Model,
    pub named: Vec<EffectSpec>,
    /// The first round's residual before and the last round's after, for the plot.
    pub residuals: Residuals,
}

/// Run [`discrepancy`] up to `max_rounds` times, each round on the model with the effects named
/// so far. The tracking channel (if `o.tracking`) is replayed on the last round only.
pub fn discrepancy_repeated(model: &Model, scene: &Scene, arm: &str, log: &JointLog, o: &Options, max_rounds: usize) -> Result<Repeated> {
    let mut current = model.clone();
    let mut named: Vec<EffectSpec> = Vec::new();
    let mut report: Option<Report> = None;
    let mut residuals: Option<Residuals> = None;
    let mut steps = Vec::new();
    let quiet = Options { tracking: false, ..o.clone() };
    for round in 1..=max_rounds.max(1) {
        let out = discrepancy(&current, scene, arm, log, &quiet)?;
        let r = out.report;
        steps.push(StepReport {
            round,
            verdict: r.verdict.clone(),
            named: r.effects.first().map(|e| e.label()),
            rms_before: r.rms_before,
            rms_after: r.rms_after,
            rms_heldout_before: r.rms_heldout_before,
            rms_heldout_after: r.rms_heldout_after,
            raw_rms_heldout_after: r.raw_rms_heldout_after,
        });
        // The same effect on the same joint or link again: its linearised fit has not converged
        // in one step, or it stands in for something the vocabulary lacks; stop rather than stack.
        // (A coupling error's entries are its parameters: another entry is another effect.)
        let same = |n: &EffectSpec, e: &EffectSpec| {
            n.name == e.name && n.joint == e.joint && n.link == e.link && (n.joint.is_some() || n.link.is_some() || n.parameters.keys().eq(e.parameters.keys()))
        };
        if out.named.as_ref().is_some_and(|e| named.iter().any(|n| same(n, e))) {
            if let Some(s) = steps.last_mut() {
                s.verdict = "repeated".into();
            }
            break;
        }
        // The first round gives the candidates and the "before" figures; each later one adds its
        // named effect and the "after" figures.
        let merged = match report.as_mut() {
            Some(m) => {
                m.effects.extend(r.effects.iter().cloned());
                m
            }
            None => report.insert(r.clone()),
        };
        match residuals.as_mut() {
            Some(res) => res.after = out.residuals.after,
            None => residuals = Some(out.residuals),
        }
        merged.rms_after = r.rms_after;
        merged.rms_heldout_after = r.rms_heldout_after;
        merged.raw_rms_heldout_after = r.raw_rms_heldout_after;
        merged.joints = r.joints;
        if let (Some(m), Some(k)) = (merged.kinematic.as_mut(), r.kinematic.as_ref()) {
            m.rms_after = k.rms_after;
            m.rms_heldout_after = k.rms_heldout_after;
        }
        if r.verdict == "ambiguous" {
            merged.experiment = r.experiment;
        }
        let Some(e) = out.named else { break };
        current = with_effect(&current, &e)?;
        named.push(e);
        merged.verdict = "named".into();
    }
    let (Some(mut report), Some(residuals)) = (report, residuals) else {
        return Err(crate::error::CalibError::data("discrepancy", "no round was analysed"));
    };
    if o.tracking {
        let a = scene.arm_index(arm).map_err(|e| crate::error::CalibError::field("--arm", e.to_string()))?;
        report.tracking = Some(super::tracking::compare(scene, a, log, model, (!named.is_empty()).then_some(&current))?);
    }
    report.steps = steps;
    Ok(Repeated { report, model: current, named, residuals })
}
