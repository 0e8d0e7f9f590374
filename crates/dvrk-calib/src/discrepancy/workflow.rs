//! The workflow on the torque channel: the nominal model's effort against the measured one, every
//! candidate fitted on the first part of the recording with its physical bounds, scored (change
//! in BIC and a nested-model likelihood-ratio test on an effective sample size that accounts for
//! the residuals' autocorrelation; a block-bootstrap p-value where a bound is active), checked on
//! the held-out part, and a verdict.

use super::baseline::Baseline;
use super::candidates::{self, Candidate, Table};
use super::effect_report::{spec_of, EffectReporter};
use super::explain::{mimicked_note, unexplained_guess};
use super::fit::{Fitter, Rows};
pub use super::options::{Options, Outcome};
use super::plot::Residuals;
use super::profiles::{self, profiled_spec};
use super::report::{CandidateReport, JointRms, Report};
use super::scoring::{score_linear, Effort, Score, Scored};
use super::signals::{add, normalised_rms, prepare, raw_rms, residual, rms, shifted, Predictor, Prepared};
use super::signature::Signature;
use super::stats::chi2_sf;
use super::verdict::{verdict, Gates};
use crate::error::{CalibError, Result};
use dvrk_sim::recording::JointLog;
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::Model;
use dvrk_sim::Scene;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// Whether two effects are the same one: a kind on one joint, link or actuator (a coupling error, on
/// neither, by its entry: the parameter it names), whatever their values.
pub fn same_effect(a: &EffectSpec, b: &EffectSpec) -> bool {
    a.name == b.name && a.joint == b.joint && a.link == b.link && a.actuator == b.actuator && (a.joint.is_some() || a.link.is_some() || a.actuator.is_some() || a.parameters.keys().eq(b.parameters.keys()))
}

/// Secant passes of a coupling error's signature (two: a 5% entry error's 2.4% under-read
/// becomes 0.06%, then 1e-5).
const SECANT_PASSES: usize = 2;

/// Candidates the report lists (the strongest first).
const REPORTED: usize = 12;

/// The kinematic channel's evidence joined to the torque channel's: a candidate both channels
/// fit (an offset, latency, a drive's compliance or play) gets their combined likelihood ratio at
/// the precision-weighted value (so a torque fit the tracker contradicts loses its support); a
/// candidate only the tracker sees (a DH length, an offset gravity does not load) is added.
fn with_kinematic(scored: &mut Vec<Scored>, kc: &super::kinematic::KinematicChannel, model: &Model) {
    use super::kinematic::{combine, Evidence};
    let mut used = vec![false; kc.candidates.len()];
    for s in scored.iter_mut() {
        // The joint stream late by L is, to the tracker, its clock L early: the torque channel's
        // latency takes the clock offset's evidence at -L; the offset stays a candidate of its own
        // (a tracker late against encoders and efforts alike the torque channel cannot see).
        let clock = s.kind == EffectKind::Latency;
        let same = |k: &super::kinematic::KinematicScore| if clock { k.kind == EffectKind::ClockOffset } else { k.kind == s.kind && k.joint == s.joint && k.link.is_none() };
        let Some(i) = kc.candidates.iter().position(same) else { continue };
        let k = &kc.candidates[i];
        used[i] = !clock;
        let kv = if clock { -k.value } else { k.value };
        let sc = &mut s.score;
        // Compliance is linear in 1 / stiffness on the tracker: combine there.
        let compliance = s.kind == EffectKind::JointCompliance;
        let to = |v: f64| if compliance { 1.0 / v.max(1e-300) } else { v };
        let [lo, hi] = sc.ci[0];
        let (a, b) = (to(lo), to(hi));
        let torque = Evidence { value: to(sc.x[0]), variance: ((a - b).abs() / 3.92).powi(2), stat: sc.stat };
        let both = combine(&torque, &Evidence { value: kv, variance: k.variance, stat: k.stat }, if clock { Some(0.0) } else { k.lower() });
        let h = 1.96 * both.variance.sqrt();
        sc.delta_bic += both.stat - sc.stat;
        sc.stat = both.stat;
        sc.p_value = if both.stat > 0.0 { chi2_sf(both.stat, 1) } else { 1.0 };
        sc.heldout_p = sc.heldout_p.min(k.heldout_p);
        sc.effect_to_noise = sc.effect_to_noise.max(k.effect_to_noise);
        sc.x[0] = to(both.value);
        sc.ci[0] = if compliance { [to(both.value + h), if both.value - h > 0.0 { to(both.value - h) } else { f64::INFINITY }] } else { [both.value - h, both.value + h] };
        s.label += " (torque and kinematic)";
    }
    for (k, _) in kc.candidates.iter().zip(&used).filter(|(_, u)| !**u) {
        let (spec, ci) = k.spec(model, "dvrk discrepancy");
        scored.push(Scored {
            candidate: None,
            kind: k.kind,
            label: k.label(model),
            score: Score {
                x: vec![k.value],
                ci: vec![[k.value; 2]],
                delta_bic: k.delta_bic,
                stat: k.stat,
                p_value: k.p_value,
                heldout_p: k.heldout_p,
                cv_p: None,
                effect_to_noise: k.effect_to_noise,
                // No change of the predicted effort.
                signature_at: None,
                chi2_unit: 0.0,
                profiled: None,
                at_edge: false,
                nuisance_correlation: None,
            },
            joint: k.joint,
            kinematic: Some((spec, ci)),
            effort: Effort::Zero,
        });
    }
}

/// Run the workflow: `model` against `log`, for arm `arm` of `scene` (whose inertials, drive and
/// gains are the rest of the model).
pub fn discrepancy(model: &Model, scene: &Scene, arm_name: &str, log: &JointLog, o: &Options) -> Result<Outcome> {
    same_joints(model, log)?;
    if !log.has_efforts() {
        return super::kinematic_only::discrepancy(model, scene, arm_name, log, o);
    }
    let mut prep = prepare(log, &o.processing)?;
    discrepancy_prepared(model, scene, arm_name, log, &mut prep, o)
}

/// The recording's joints are the model's.
pub(super) fn same_joints(model: &Model, log: &JointLog) -> Result<()> {
    let names: Vec<String> = model.joints.iter().map(|j| j.name.clone()).collect();
    if log.names != names {
        return Err(CalibError::data("recording", format!("joints {:?} are not the model's {:?}", log.names, names)));
    }
    Ok(())
}

/// [`discrepancy`] on a recording with measured efforts already prepared (`prep`: [`prepare`]
/// with `o.processing`), so that rounds share one preparation and a long recording's samples
/// need not stay in memory: of `log` only its joint names, its markers (the kinematic channel)
/// and, with `o.tracking`, its setpoints and positions are read. `prep` is given back as it came
/// (its noise floor is raised for the model's encoder noise during the run).
pub fn discrepancy_prepared(model: &Model, scene: &Scene, arm_name: &str, log: &JointLog, prep: &mut Prepared, o: &Options) -> Result<Outcome> {
    let floor = prep.floor.clone();
    let out = analyse(model, scene, arm_name, log, prep, o);
    prep.floor = floor;
    out
}

fn analyse(model: &Model, scene: &Scene, arm_name: &str, log: &JointLog, prep: &mut Prepared, o: &Options) -> Result<Outcome> {
    let a = scene.arm_index(arm_name).map_err(|e| CalibError::field("--arm", e.to_string()))?;
    same_joints(model, log)?;
    let mut scene = scene.clone();
    scene.set_model(a, model.clone()).map_err(|e| CalibError::context("model", e))?;
    let arm = &scene.arms[a];
    let mut predictor = Predictor::new(&arm.model, arm, scene.gravity)?;
    prep.include_encoder_noise(&mut predictor)?;
    let prep: &Prepared = prep;
    // 1. The model's prediction along the recorded motion, and its residual.
    let b = Baseline::new(predictor, arm, scene.gravity, prep)?;
    let (nq, r) = (b.nq, &b.r);
    // The inertia nuisance on the measured timeline, and on the prediction's (see
    // [`Nuisance::retimed`]).
    let mut measured_time = b.nuisance(o)?;
    let lagged = match &measured_time {
        Some(n) if b.lag > 0.0 => Some(n.retimed(&|t| shifted(t, prep.dt, b.lag))?),
        _ => None,
    };
    // Whether an effect is analysed (all of them, or [`Options::only`]'s).
    // A payload's refit may move it to another body: named beside an effect it partly stood in
    // for, its first body can be one that took up some of that effect too (seed 11: a payload
    // on the wrist's yaw link named on its pitch link next to the pitch's unnamed friction).
    let payload = EffectKind::PayloadMass.name();
    let wanted = |spec: &EffectSpec| o.only.as_ref().is_none_or(|t| same_effect(spec, t) || (t.name == payload && spec.name == payload));
    // 2. The profiled effects, before the candidates are built: latency's second profile needs a
    // second nuisance (as large as the first), the drives' simulations need room, and the
    // candidates' columns are not yet in memory. Listed after them.
    let latency = match wanted(&profiled_spec(&arm.model, EffectKind::Latency, None, 0.0)) {
        true => Some(profiles::latency(&b, &mut measured_time, lagged.as_ref(), o)?),
        false => None,
    };
    let measured_time = measured_time;
    let nuisance = lagged.as_ref().or(measured_time.as_ref());
    let fit = Fitter::new(prep, nuisance);
    let drives = profiles::drives(&b, &fit, &wanted, o)?;
    // 3. The linear candidates and the payloads, scored.
    let gates = Gates::new(o);
    let (cands, payload_normals) = linear_candidates(&b, &fit, &wanted, o)?;
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let linear: Vec<Score> = cands.iter().map(|c| score_linear(c, &fit, r, o, &mut rng)).collect::<Result<_>>()?;
    // Only a candidate the report can show keeps its columns (its effort and a pair's refit
    // need them): one of the linear candidates' best [`REPORTED`], or one supported. Without a
    // kinematic channel, whose evidence can still reorder them.
    let mut cands = cands;
    if log.markers.is_none() {
        for (c, s) in cands.iter_mut().zip(&linear) {
            let above = linear.iter().filter(|t| t.delta_bic > s.delta_bic).count();
            let supported = !s.at_edge && gates.strong(s.delta_bic, s.p_value, s.confirmed_p(), s.effect_to_noise);
            if above >= REPORTED && !supported {
                c.drop_columns();
            }
        }
    }
    let cands = cands;
    let mut scored: Vec<Scored> = cands
        .iter()
        .zip(linear)
        .map(|(c, s)| Scored { candidate: Some(c), kind: c.kind, label: c.label(&arm.model), score: s, joint: c.joint, kinematic: None, effort: Effort::Linear })
        .collect();
    if let Some((score, effort)) = latency {
        scored.push(Scored { candidate: None, kind: EffectKind::Latency, label: "latency".into(), score, joint: None, kinematic: None, effort });
    }
    scored.extend(drives);
    // 4. The kinematic channel's evidence joined per candidate.
    let kin = match &log.markers {
        Some(mk) => Some(super::kinematic::analyse(&super::kinematic::Inputs { model: &arm.model, log, markers: mk, prep, armature: &b.motor })?),
        None => None,
    };
    if let Some(kc) = &kin {
        with_kinematic(&mut scored, kc, &arm.model);
    }
    scored.sort_by(|x, y| y.score.delta_bic.total_cmp(&x.score.delta_bic));
    // The kinematic channel's own candidates too, when one effect is analysed.
    scored.retain(|e| wanted(&spec_of(&arm.model, e)));
    // 5. Before: the model with its inertias refitted within their prior (the null of every test).
    let mut before = b.base.clone();
    add(&mut before, &fit.nuisance_effort(&Rows::train(prep).vector(r)));
    let f0 = residual(prep, &before, true);
    let tr = 0..prep.split;
    let effort_rms: Vec<f64> = (0..nq).map(|k| rms(&prep.effort, k, tr.clone())).collect();
    let before_rms: Vec<f64> = (0..nq).map(|k| rms(&f0, k, tr.clone())).collect();
    let reporter = EffectReporter::new(&arm.model, prep, &b.base, &fit, r, &scored, &payload_normals, (&before_rms, &effort_rms), o.ambiguity_bic, b.gravity_vector)?;
    // 6. The verdict; after: the model with the named effect, the inertias refitted with it.
    let v = verdict(&scored, gates, &fit, r, prep, o)?;
    let mut effects = Vec::new();
    let mut named = None;
    let mut after = before.clone();
    if let Some((at, effect)) = &v.named {
        let (spec, report) = reporter.report(&scored[*at], Some(effect))?;
        effects.push(report);
        after = b.base.clone();
        add(&mut after, effect);
        named = Some(spec);
    }
    let candidates: Vec<CandidateReport> = scored
        .iter()
        .take(REPORTED)
        .enumerate()
        .map(|(i, entry)| {
            Ok(CandidateReport {
                label: entry.label.clone(),
                // The named one's entry is its effect's, made above.
                effect: match &v.named {
                    Some((at, _)) if *at == i => effects[0].clone(),
                    _ => reporter.report(entry, None)?.1,
                },
                heldout_p_value: entry.score.heldout_p,
                heldout_cv_p_value: entry.score.cv_p,
                effect_to_noise: entry.score.effect_to_noise,
                supported: gates.supported(entry),
                nuisance_correlation: entry.score.nuisance_correlation,
            })
        })
        .collect::<Result<_>>()?;
    // 7. The report.
    let f1 = residual(prep, &after, true);
    let ho = prep.split..prep.t.len();
    let names: Vec<String> = model.joints.iter().map(|j| j.name.clone()).collect();
    let insertion = arm.model.joints.iter().position(|j| j.kind == dvrk_kin::JointType::Prismatic);
    let location = super::locate::locate(prep, &f0, &before, insertion, &names);
    let joints: Vec<JointRms> = prep
        .active
        .iter()
        .map(|&k| {
            let (bk, ak) = (before_rms[k], rms(&f1, k, tr.clone()));
            JointRms {
                joint: names[k].clone(),
                unit: arm.model.joints[k].effort_unit(),
                noise: prep.noise[k],
                band_floor: prep.floor[k],
                band_rms_before: bk,
                band_rms_after: ak,
                band_rms_heldout_before: rms(&f0, k, ho.clone()),
                band_rms_heldout_after: rms(&f1, k, ho.clone()),
                effort_band_rms: effort_rms[k],
                share_explained: (bk - ak) / effort_rms[k].max(1e-300),
                unexplained: unexplained_guess(&arm.model, &names[k], ak / prep.floor[k]),
            }
        })
        .collect();
    let per_joint = |tab: &Table| prep.active.iter().map(|&k| super::signals::column(tab, k)).collect::<Vec<_>>();
    let prismatic = |k: usize| arm.model.joints[k].kind == dvrk_kin::JointType::Prismatic;
    let residuals = Residuals {
        joints: joints.iter().map(|j| j.joint.clone()).collect(),
        units: joints.iter().map(|j| j.unit).collect(),
        position_units: prep.active.iter().map(|&k| if prismatic(k) { "m" } else { "rad" }).collect(),
        t: prep.t.clone(),
        q: per_joint(&prep.q),
        qd: per_joint(&prep.qd),
        load: per_joint(&before),
        before: per_joint(&f0),
        after: per_joint(&f1),
        floor: prep.active.iter().map(|&k| prep.floor[k]).collect(),
        heldout_from: prep.t[prep.split],
    };
    let tracking = match o.tracking {
        true => Some(super::tracking::compare(&scene, a, log, model, named.as_ref().map(|e| model.with_effect(e)).transpose()?.as_ref())?),
        false => None,
    };
    let mimicked = mimicked_note(nuisance, &scored);
    let strong_kinematic = |d: f64, p: f64, h: f64, s: f64| gates.strong_kinematic(d, p, h, s);
    let report = Report {
        verdict: v.verdict.into(),
        channel: if kin.is_some() { "torque+kinematic" } else { "torque" }.into(),
        effects,
        candidates,
        experiment: v.experiment,
        rms_before: normalised_rms(prep, &f0, tr.clone()),
        rms_after: normalised_rms(prep, &f1, tr.clone()),
        rms_heldout_before: normalised_rms(prep, &f0, ho.clone()),
        rms_heldout_after: normalised_rms(prep, &f1, ho.clone()),
        raw_rms_heldout_before: raw_rms(prep, &before, ho.clone()),
        raw_rms_heldout_after: raw_rms(prep, &after, ho.clone()),
        rms_nominal: normalised_rms(prep, r, tr.clone()),
        rms_heldout_nominal: normalised_rms(prep, r, ho.clone()),
        noise_floor: 1.0,
        rms_units: "each joint's effort residual in the analysis band over its noise floor there, RMS over the moving joints".into(),
        joints,
        location,
        tracking,
        kinematic: kin.as_ref().map(|kc| kc.report(&arm.model, named.as_ref(), "dvrk discrepancy", &strong_kinematic)),
        samples: prep.t.len(),
        heldout_from: prep.t[prep.split],
        notes: match &kin {
            Some(kc) => std::iter::once("the kinematic channel's evidence is joined to the torque channel's per candidate; the torque residual after uses the torque channel's own fit".to_string())
                .chain(kc.notes(&arm.model, named.as_ref(), &|k| strong_kinematic(k.delta_bic, k.p_value, k.heldout_p, k.effect_to_noise)))
                .collect(),
            None => vec!["kinematic channel not analysed: it needs a tracked marker (--marker-topic, --marker-link)".into()],
        }
        .into_iter()
        .chain(mimicked)
        .collect(),
        steps: Vec::new(),
    };
    Ok(Outcome { report, named, residuals })
}

/// The linear candidates (those `wanted`), their columns delayed by the model's latency, a
/// coupling error's re-taken at its estimate; then the payloads, and each payload body's normal
/// equations.
fn linear_candidates(b: &Baseline, fit: &Fitter, wanted: &dyn Fn(&EffectSpec) -> bool, o: &Options) -> Result<(Vec<Candidate>, BTreeMap<String, super::payload::Normal>)> {
    let (arm, prep, nq) = (b.arm, b.prep, b.nq);
    let delay_columns = |c: &mut Candidate| {
        let grids = c.profile.iter_mut().flat_map(|(_, g)| g.iter_mut().flat_map(|(_, cols)| cols.iter_mut()));
        for col in c.columns.iter_mut().chain(grids) {
            if b.lag > 0.0 {
                *col = Signature::from_table(&b.delayed(col.to_table()), nq);
            }
        }
    };
    // Payloads on every moving body, each at the place that explains most (the regressor's
    // own columns: exact for a point mass anywhere). Built first, while the other candidates'
    // columns are not yet in memory (each body's ten are, one body at a time); listed last.
    let delayed = |t: Table| b.delayed(t);
    let body_columns = super::payload::BodyColumns { model: &arm.model, dynamics: b.predictor.dynamics(), gravity: &b.gravity_vector, prep, shift: (b.lag > 0.0).then_some(&delayed) };
    let (payloads, payload_normals) = super::payload::candidates(&arm.model, &body_columns, fit, &b.r, prep)?;
    let payloads: Vec<Candidate> = payloads.into_iter().filter(|c| wanted(&c.spec(&arm.model, &[0.0; 4], None, ""))).collect();
    let mut cands = candidates::build(&b.predictor, arm, b.gravity, prep, &b.rigid, &b.offsets)?;
    cands.retain(|c| wanted(&c.spec(&arm.model, &vec![0.0; c.names.len()], None, "")));
    cands.iter_mut().for_each(delay_columns);
    // A coupling error's signature is quadratic in its entry: where one shows, its column is
    // re-taken as the secant through the estimate (a fixed point: the error shrinks by the
    // relative change squared each pass). Its own generator: the bootstrap draws of the
    // others stay as they were.
    let mut secant_rng = ChaCha8Rng::seed_from_u64(o.seed ^ 0x5ecA);
    for c in cands.iter_mut().filter(|c| c.kind == EffectKind::CouplingError) {
        for _ in 0..SECANT_PASSES {
            let s = score_linear(c, fit, &b.r, o, &mut secant_rng)?;
            if s.delta_bic <= o.min_delta_bic || s.x[0].abs() < 1e-9 {
                break;
            }
            *c = candidates::secant(c, s.x[0], &b.predictor, arm, b.gravity, prep, &b.rigid)?;
            delay_columns(c);
        }
    }
    cands.extend(payloads);
    Ok((cands, payload_normals))
}
