//! Which effects make the difference: the identification repeated with the chosen options'
//! features switched on one at a time (cumulative), each row's error on the fitted recording
//! and, when given, on a held-out one.

use super::problem::{EffectTerm, Processing};
use super::{identify, Identification, IdentifyOptions, JointLog};
use crate::error::Result;
use dvrk_kin::{BodyInertia, Model};
use serde::Serialize;

/// One row of the ablation.
#[derive(Debug, Clone, Serialize)]
pub struct AblationRow {
    /// What this row adds to the one before.
    pub effects: String,
    /// Per channel, on the fitted recording.
    pub relative_error: Vec<f64>,
    /// Per channel, on the held-out recording (absent without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<Vec<f64>>,
}

/// The cumulative steps from the rigid body alone to `options`, skipping steps `options` does
/// not take. The last step is `options` itself.
pub fn steps(options: &IdentifyOptions) -> Vec<(String, IdentifyOptions)> {
    let mut out: Vec<(String, IdentifyOptions)> = Vec::new();
    let mut o = options.rigid_only();
    o.processing = Processing { channel_cutoff: Vec::new(), channel_coulomb_velocity: Vec::new(), ..options.processing.clone() };
    o.prior_fraction = IdentifyOptions::full(Vec::new()).prior_fraction;
    o.small_bodies = Vec::new();
    out.push(("rigid body only (CAD prior, one cut-off)".into(), o.clone()));
    let has = |t: EffectTerm| options.terms.effects.contains(&t);
    let friction: Vec<EffectTerm> = [EffectTerm::Coulomb, EffectTerm::Offset, EffectTerm::Viscous].into_iter().filter(|t| has(*t)).collect();
    if !friction.is_empty() {
        o.terms.effects = friction;
        out.push(("+ channel friction (Coulomb, offset, viscous)".into(), o.clone()));
    }
    if has(EffectTerm::Armature) {
        o.terms.effects.push(EffectTerm::Armature);
        out.push(("+ reflected motor inertia".into(), o.clone()));
    }
    if has(EffectTerm::Spring) && !options.terms.spring_channels.is_empty() {
        o.terms.effects.push(EffectTerm::Spring);
        o.terms.spring_channels = options.terms.spring_channels.clone();
        out.push(("+ springs".into(), o.clone()));
    }
    if has(EffectTerm::Stribeck) {
        o.terms.effects.push(EffectTerm::Stribeck);
        out.push(("+ Stribeck friction".into(), o.clone()));
    }
    if o.processing != options.processing {
        o.processing = options.processing.clone();
        out.push(("+ per-channel cut-offs and Coulomb velocities".into(), o.clone()));
    }
    if o.prior_fraction != options.prior_fraction {
        o.prior_fraction = options.prior_fraction;
        out.push((format!("+ weak CAD prior ({}x magnitude)", options.prior_fraction), o.clone()));
    }
    if o.small_bodies != options.small_bodies {
        o.small_bodies = options.small_bodies.clone();
        let names: Vec<&str> = options.small_bodies.iter().map(|b| b.name.as_str()).collect();
        out.push((format!("+ small-part prior ({})", names.join(", ")), o.clone()));
    }
    if !options.terms.joint_friction.is_empty() {
        o.terms.joint_friction = options.terms.joint_friction.clone();
        // The PSM's are its tool's wrist and jaw; the MTM's every joint.
        let which = if options.terms.joint_friction.contains(&0) { "joint-space friction" } else { "joint-space wrist friction" };
        out.push((format!("+ {which}"), o.clone()));
    }
    if !options.terms.joint_springs.is_empty() {
        o.terms.joint_springs = options.terms.joint_springs.clone();
        out.push(("+ configuration-dependent joint springs (cubic)".into(), o.clone()));
    }
    if !options.terms.cross.is_empty() {
        o.terms.cross = options.terms.cross.clone();
        out.push(("+ tool cross-coupling".into(), o.clone()));
    }
    if !options.terms.winding_channels.is_empty() {
        o.terms.winding_channels = options.terms.winding_channels.clone();
        out.push(("+ winding friction (Coulomb level growing with position^2)".into(), o.clone()));
    }
    if !options.terms.dahl_channels.is_empty() {
        o.terms.dahl_channels = options.terms.dahl_channels.clone();
        out.push(("+ presliding (Dahl) friction".into(), o.clone()));
    }
    // Whatever differs still (terms in another order): the chosen options as the last row.
    if o != *options {
        out.push(("= chosen options".into(), options.clone()));
    }
    out
}

/// Run every step of [`steps`] on `rec` (and `held_out`); `chosen`: the identification with
/// `options` itself, when the caller has it (the last step then reuses it).
pub fn ablation(
    model: &Model,
    prior: &[BodyInertia],
    rec: &JointLog,
    held_out: Option<&JointLog>,
    options: &IdentifyOptions,
    chosen: Option<&Identification>,
) -> Result<Vec<AblationRow>> {
    steps(options)
        .into_iter()
        .map(|(effects, o)| {
            let fitted;
            let id = match chosen.filter(|_| o == *options) {
                Some(id) => id,
                None => {
                    fitted = identify(model, prior, rec, &o)?.0;
                    &fitted
                }
            };
            let validation = held_out.map(|h| id.validate(model, h, &o).map(|(raw, _)| raw)).transpose()?;
            Ok(AblationRow { effects, relative_error: id.relative_error.clone(), validation })
        })
        .collect()
}
