//! Step 4 of the workflow: the named effect added to the model and the analysis run again, until
//! nothing more is supported (the residual is what the candidates cannot explain: at the noise
//! floor when the model is complete), an ambiguity stops it, or the rounds run out.

use super::generate::with_effect;
use super::joint_log::JointLog;
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
}

/// Run [`discrepancy`] up to `max_rounds` times, each round on the model with the effects named
/// so far. The tracking channel (if `o.tracking`) is replayed on the last round only.
pub fn discrepancy_repeated(model: &Model, scene: &Scene, arm: &str, log: &JointLog, o: &Options, max_rounds: usize) -> Result<Repeated> {
    let mut current = model.clone();
    let mut named = Vec::new();
    let mut first: Option<Report> = None;
    let mut steps = Vec::new();
    let quiet = Options { tracking: false, ..o.clone() };
    for round in 0..max_rounds.max(1) {
        let out = discrepancy(&current, scene, arm, log, &quiet)?;
        let r = out.report;
        steps.push(StepReport {
            round: round + 1,
            verdict: r.verdict.clone(),
            named: r.effects.first().map(|e| match e.joint.clone().or(e.link.clone()) {
                Some(at) => format!("{} on {at}", e.name),
                None => e.name.clone(),
            }),
            rms_before: r.rms_before,
            rms_after: r.rms_after,
            rms_heldout_before: r.rms_heldout_before,
            rms_heldout_after: r.rms_heldout_after,
            raw_rms_heldout_after: r.raw_rms_heldout_after,
        });
        let effects = r.effects.clone();
        let last = r.clone();
        let first = first.get_or_insert(r);
        // The same effect on the same joint or link again: its linearised fit has not converged
        // in one step, or it stands in for something the vocabulary lacks; stop rather than stack.
        let again = out.named.as_ref().is_some_and(|e| named.iter().any(|n: &EffectSpec| n.name == e.name && n.joint == e.joint && n.link == e.link));
        if again {
            if let Some(s) = steps.last_mut() {
                s.verdict = "repeated".into();
            }
            break;
        }
        let stop = match out.named {
            Some(e) => {
                current = with_effect(&current, &e)?;
                named.push(e);
                false
            }
            None => true,
        };
        if round > 0 {
            first.effects.extend(effects);
        }
        first.verdict = if named.is_empty() { last.verdict.clone() } else { "named".into() };
        if last.verdict == "ambiguous" {
            first.verdict = if named.is_empty() { "ambiguous".into() } else { "named".into() };
            first.experiment = last.experiment.clone();
        }
        first.rms_after = last.rms_after;
        first.rms_heldout_after = last.rms_heldout_after;
        first.raw_rms_heldout_after = last.raw_rms_heldout_after;
        first.joints = last.joints.clone();
        if stop {
            break;
        }
    }
    let mut report = first.expect("at least one round");
    // The last round's "after" is with every named effect: its own before is the model with all
    // but its own named one; with none named in it, before and after are equal.
    if o.tracking {
        report.tracking = Some(super::tracking::compare_models(scene, arm, log, model, &current)?);
    }
    report.steps = steps;
    Ok(Repeated { report, model: current, named })
}
