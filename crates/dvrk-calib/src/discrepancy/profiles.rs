//! The profiled effects, whose signature is not linear in their parameter: latency (the
//! prediction shifted later) and each drive's compliance and play (a simulation of the drive per
//! value). Each is scored over a grid of values ([`score_profile`]); they are scored before the
//! linear candidates are built, while those candidates' columns are not yet in memory.

use super::baseline::Baseline;
use super::drive::{JointLoad, Law};
use super::fit::{Fitter, Rows};
use super::nuisance::Nuisance;
use super::options::Options;
use super::scoring::{geometric, profile_efforts, score_profile, Effort, Score, Scored};
use super::signals::{shifted, sub};
use crate::error::{CalibError, Result};
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::Model;
use nalgebra::DVector;
use std::collections::BTreeMap;

/// Passes of a drive's profile with the link's load, inertia and stiffness corrected by the
/// nuisance inertias ([`super::drive::LoadChange`]): a link in free flight across a play moves
/// under its load alone, and the truth's inertias 3% off the model's put its impacts a
/// millisecond off (seed 1: held-out 3.17 of the floor without, 1.27 with two passes); a
/// compliance's signature is its link's inertia and stiffness times the deflection, and its
/// stiffness moved 0.45% per 1% of the outer pitch's `M_jj` (seeds 1039, 1045: -1.27%, +1.19%
/// uncorrected; -0.13%, +0.05% with two passes, held-out 1.041 and 1.075 of the floor).
const DRIVE_PASSES: usize = 2;

/// The profiled effects' one parameter, by kind (latency, a drive's compliance or play).
pub(super) fn profiled_name(kind: EffectKind) -> &'static str {
    match kind {
        EffectKind::Latency => "seconds",
        EffectKind::JointCompliance => "stiffness",
        _ => "b",
    }
}

/// A profiled effect at `value` as a model file writes it.
pub(super) fn profiled_spec(model: &Model, kind: EffectKind, joint: Option<usize>, value: f64) -> EffectSpec {
    EffectSpec {
        name: kind.name().into(),
        joint: joint.map(|j| model.joints[j].name.clone()),
        link: None,
        actuator: None,
        parameters: BTreeMap::from([(profiled_name(kind).into(), value)]),
        source: "dvrk discrepancy".into(),
    }
}

/// Latency, 0-60 ms: its score and fitted effort. Fitted with the nuisance on the prediction's
/// timeline (`lagged`, else `measured_time`), then profiled again with the nuisance moved by the
/// estimate. `measured_time` is moved in place for that and built again after: a copy would hold
/// the nuisance twice (64 MB more on a 5-minute recording).
pub(super) fn latency<'x>(b: &Baseline, measured_time: &mut Option<Nuisance>, lagged: Option<&Nuisance>, o: &Options) -> Result<(Score, Effort<'x>)> {
    let (prep, base, r) = (b.prep, &b.base, &b.r);
    let shift = |tau: f64| sub(&shifted(base, prep.dt, tau), base);
    let lat_grid: Vec<f64> = (0..=60).map(|i| i as f64 * 1e-3).collect();
    let first = Fitter::new(prep, lagged.or(measured_time.as_ref()));
    let score = score_profile(&first, r, &lat_grid, &shift, None);
    let held = |fitter: &Fitter, score: &Score| {
        let (effect, own) = profile_efforts(fitter, r, &shift(score.signature_at.unwrap_or(0.0)));
        Effort::Held(effect, own)
    };
    // Near the estimate, the profile is then the one a nuisance on the right timeline gives (the
    // null's is not, by the nuisance's misfit over the estimate's shift: nothing next to a
    // latency's evidence).
    let tau = b.lag + score.x[0];
    match measured_time.take() {
        Some(n) if tau > 0.0 => {
            let moved = n.into_retimed(&|t| shifted(t, prep.dt, tau))?;
            let fitter = Fitter::new(prep, Some(&moved));
            let score = score_profile(&fitter, r, &lat_grid, &shift, None);
            let effort = held(&fitter, &score);
            drop(moved);
            *measured_time = b.nuisance(o)?;
            Ok((score, effort))
        }
        unmoved => {
            *measured_time = unmoved;
            let effort = held(&Fitter::new(prep, lagged.or(measured_time.as_ref())), &score);
            Ok((score, effort))
        }
    }
}

/// The drives: compliance and play per moving joint (those `wanted`), each a profile of its own
/// simulation; where one shows, profiled again with the link's load, inertia and stiffness as
/// the fit's nuisance inertias correct them ([`DRIVE_PASSES`]). Each keeps its score and the
/// inertial change its load was last corrected by: its effort is rebuilt from it (a load is three
/// tables, held for every drive 100 MB on 5 minutes).
pub(super) fn drives<'x>(b: &'x Baseline, fit: &Fitter, wanted: &dyn Fn(&EffectSpec) -> bool, o: &Options) -> Result<Vec<Scored<'x>>> {
    let (prep, r, nq, model) = (b.prep, &b.r, b.nq, &b.arm.model);
    let drive_profile = |jl: &JointLoad, law: fn(f64) -> Law, grid: &[f64]| -> Result<(Score, Option<DVector<f64>>)> {
        let profile = |jl: &JointLoad| score_profile(fit, r, grid, &|v| b.delayed(super::drive::signature(prep, jl, law(v), nq)), Some(jl.joint));
        let mut s = profile(jl);
        let mut current = jl.clone();
        let mut change = None;
        for _ in 0..DRIVE_PASSES {
            if s.delta_bic <= o.min_delta_bic {
                break;
            }
            let e1 = Rows::train(prep).vector(&sub(r, &b.delayed(super::drive::signature(prep, &current, law(s.x[0]), nq))));
            let Some(dpi) = fit.nuisance_parameters(&e1) else {
                break;
            };
            current = b.corrected(jl, &dpi)?;
            change = Some(dpi);
            s = profile(&current);
        }
        Ok((s, change))
    };
    let drive_effort = |j: usize, law: fn(f64) -> Law, change: Option<DVector<f64>>| -> Effort<'x> {
        Effort::Profile(Box::new(move |v| {
            let jl = b.joint_load(j, &b.undelayed).ok_or_else(|| CalibError::data("drive", "its joint's load is gone"))?;
            let jl = match &change {
                Some(dpi) => b.corrected(&jl, dpi)?,
                None => jl,
            };
            Ok(b.delayed(super::drive::signature(b.prep, &jl, law(v), b.nq)))
        }))
    };
    let mut drives: Vec<Scored> = Vec::new();
    for &j in &prep.active {
        let Some(jl) = b.joint_load(j, &b.undelayed) else {
            continue;
        };
        let name = &model.joints[j].name;
        if wanted(&profiled_spec(model, EffectKind::JointCompliance, Some(j), 0.0)) {
            let law = Law::Compliance;
            let (s, at) = drive_profile(&jl, law, &geometric(1.0, 1e5, 26))?;
            drives.push(Scored { candidate: None, kind: EffectKind::JointCompliance, label: format!("joint_compliance on {name}"), score: s, joint: Some(j), kinematic: None, effort: drive_effort(j, law, at) });
        }
        if wanted(&profiled_spec(model, EffectKind::Backlash, Some(j), 0.0)) {
            let law = |half| Law::Backlash { half };
            let (s, at) = drive_profile(&jl, law, &geometric(2.5e-4, 0.04, 21))?;
            drives.push(Scored { candidate: None, kind: EffectKind::Backlash, label: format!("backlash on {name}"), score: s, joint: Some(j), kinematic: None, effort: drive_effort(j, law, at) });
        }
    }
    Ok(drives)
}
