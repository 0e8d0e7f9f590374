//! The workflow on the torque channel: the nominal model's effort against the measured one, every
//! candidate fitted on the first part of the recording with its physical bounds, scored (change
//! in BIC and a nested-model likelihood-ratio test on an effective sample size that accounts for
//! the residuals' autocorrelation; a block-bootstrap p-value where a bound is active), checked on
//! the held-out part, and a verdict.

use super::candidates::{self, Candidate, Table};
use super::joint_log::JointLog;
use super::report::{CandidateReport, EffectReport, JointRms, Report};
use super::signals::{prepare, Predictor, Prepared, Processing};
use super::stats::{bounded_least_squares, chi2_sf, effective_fraction};
use crate::error::{CalibError, Result};
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::Model;
use dvrk_sim::Scene;
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// Thresholds and settings.
#[derive(Debug, Clone)]
pub struct Options {
    pub processing: Processing,
    /// Strong evidence: a change in BIC above this (Kass and Raftery's "very strong", 10).
    pub min_delta_bic: f64,
    /// ... and a nested-model p-value below this (0.05 shared among ~40 candidates).
    pub max_p_value: f64,
    /// ... and the fitted effect at least this many times its joint's effort noise (RMS): below,
    /// the residual left by the rigid model's own small errors would be named as an effect.
    pub min_effect_to_noise: f64,
    /// Two candidates whose changes in BIC differ by less than this are not told apart.
    pub ambiguity_bic: f64,
    /// Bootstrap replicates for p-values on a bound.
    pub bootstrap: usize,
    /// Replay the setpoints through the simulator before and after (the tracking channel).
    pub tracking: bool,
    pub seed: u64,
}

impl Default for Options {
    fn default() -> Self {
        Options { processing: Processing::default(), min_delta_bic: 10.0, max_p_value: 1e-3, min_effect_to_noise: 1.0, ambiguity_bic: 10.0, bootstrap: 199, tracking: true, seed: 1 }
    }
}

/// The report and, when an effect is named, the model with it.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub report: Report,
    pub named: Option<EffectSpec>,
}

/// Scores of one candidate.
#[derive(Debug, Clone)]
struct Score {
    x: Vec<f64>,
    ci: Vec<[f64; 2]>,
    delta_bic: f64,
    p_value: f64,
    heldout_p: f64,
    effect_to_noise: f64,
    /// The fitted effect's effort `[sample][joint]` over the whole analysed span.
    effect: Table,
}

/// Rows (train or held out) of the active joints, each divided by its noise floor.
struct Rows<'a> {
    prep: &'a Prepared,
    range: std::ops::Range<usize>,
}

impl Rows<'_> {
    fn len(&self) -> usize {
        self.range.len() * self.prep.active.len()
    }
    fn vector(&self, t: &Table) -> DVector<f64> {
        let p = self.prep;
        DVector::from_iterator(self.len(), self.range.clone().flat_map(|i| p.active.iter().map(move |&k| t[i][k] / p.floor[k])))
    }
    /// The per-joint time series of a row vector (for the autocorrelation).
    fn series(&self, v: &DVector<f64>) -> Vec<Vec<f64>> {
        let na = self.prep.active.len();
        (0..na).map(|a| (0..self.range.len()).map(|i| v[i * na + a]).collect()).collect()
    }
}

fn residual(prep: &Prepared, pred: &Table, filtered: bool) -> Table {
    let m = if filtered { &prep.effort } else { &prep.raw_effort };
    m.iter().zip(pred).map(|(e, p)| e.iter().zip(p).map(|(a, b)| a - b).collect()).collect()
}

fn lr(n_eff: f64, rss0: f64, rss1: f64) -> f64 {
    (n_eff * (rss0 / rss1.max(1e-300)).ln()).max(0.0)
}

/// Fit and score a linear candidate.
fn score_linear(c: &Candidate, prep: &Prepared, r: &Table, o: &Options, rng: &mut ChaCha8Rng) -> Result<Score> {
    let train = Rows { prep, range: 0..prep.split };
    let hold = Rows { prep, range: prep.split..prep.t.len() };
    let p = c.columns.len();
    let a = DMatrix::from_columns(&c.columns.iter().map(|col| train.vector(col)).collect::<Vec<_>>());
    let y = train.vector(r);
    let x = bounded_least_squares(&a, &y, &c.lower)?;
    let e1 = &y - &a * &x;
    let (rss0, rss1) = (y.norm_squared(), e1.norm_squared());
    let n = train.len() as f64;
    let frac = effective_fraction(&train.series(&e1));
    let n_eff = n * frac;
    let stat = lr(n_eff, rss0, rss1);
    let delta_bic = stat - p as f64 * n_eff.ln();
    let on_bound = c.lower.iter().zip(x.iter()).any(|(lo, v)| lo.is_some_and(|lo| *v <= lo + 1e-12 * (1.0 + lo.abs())));
    let p_value = if on_bound && o.bootstrap > 0 {
        // Block bootstrap under the null: the fitted model's residual resampled in blocks as
        // long as its correlation, refitted.
        let block = (1.0 / frac).ceil().max(1.0) as usize;
        let na = prep.active.len();
        let steps = train.range.len();
        let mut exceed = 0;
        for _ in 0..o.bootstrap {
            let mut ys = DVector::zeros(y.len());
            let mut i = 0;
            while i < steps {
                let s = rng.random_range(0..steps.saturating_sub(block).max(1));
                for d in 0..block.min(steps - i) {
                    for k in 0..na {
                        ys[(i + d) * na + k] = e1[(s + d) * na + k];
                    }
                }
                i += block;
            }
            let xs = bounded_least_squares(&a, &ys, &c.lower)?;
            let rs = (&ys - &a * &xs).norm_squared();
            if lr(n_eff, ys.norm_squared(), rs) >= stat {
                exceed += 1;
            }
        }
        (1 + exceed) as f64 / (o.bootstrap + 1) as f64
    } else {
        chi2_sf(stat, p)
    };
    // Intervals: the least-squares covariance, inflated for the autocorrelation.
    let s2 = rss1 / (n - p as f64).max(1.0);
    let cov = (a.transpose() * &a).try_inverse().unwrap_or_else(|| DMatrix::from_element(p, p, f64::INFINITY)) * (s2 / frac);
    let ci = (0..p).map(|i| {
        let h = 1.96 * cov[(i, i)].max(0.0).sqrt();
        [x[i] - h, x[i] + h]
    });
    let ci: Vec<[f64; 2]> = ci.collect();
    let ah = DMatrix::from_columns(&c.columns.iter().map(|col| hold.vector(col)).collect::<Vec<_>>());
    let yh = hold.vector(r);
    let eh = &yh - &ah * &x;
    let nh = hold.len() as f64 * effective_fraction(&hold.series(&eh));
    let heldout_p = chi2_sf(lr(nh, yh.norm_squared(), eh.norm_squared()), p);
    let effect: Table = (0..prep.t.len()).map(|i| (0..r[0].len()).map(|k| c.columns.iter().zip(x.iter()).map(|(col, v)| col[i][k] * v).sum()).collect()).collect();
    let size = (effect[..prep.split].iter().map(|e| e[c.focus].powi(2)).sum::<f64>() / prep.split as f64).sqrt() / prep.noise[c.focus];
    Ok(Score { x: x.iter().copied().collect(), ci, delta_bic, p_value, heldout_p, effect_to_noise: size, effect })
}

/// `base` shifted by `tau` seconds later (the measured stream lags the link by `tau`), cubic
/// (Catmull-Rom) between samples, held at the ends.
fn shifted(base: &Table, dt: f64, tau: f64) -> Table {
    let n = base.len();
    let at = |i: isize| &base[i.clamp(0, n as isize - 1) as usize];
    (0..n)
        .map(|i| {
            let x = i as f64 + tau / dt;
            let i0 = x.floor() as isize;
            let s = x - i0 as f64;
            let (p0, p1, p2, p3) = (at(i0 - 1), at(i0), at(i0 + 1), at(i0 + 2));
            (0..p1.len())
                .map(|k| {
                    let (a, b, c, d) = (p0[k], p1[k], p2[k], p3[k]);
                    b + 0.5 * s * (c - a + s * (2.0 * a - 5.0 * b + 4.0 * c - d + s * (3.0 * (b - c) + d - a)))
                })
                .collect()
        })
        .collect()
}

/// The latency candidate's 1-D profile over 0-60 ms in 0.5 ms steps.
fn score_latency(prep: &Prepared, base: &Table) -> (Score, f64) {
    let train = Rows { prep, range: 0..prep.split };
    let hold = Rows { prep, range: prep.split..prep.t.len() };
    let rss = |rows: &Rows, tau: f64| -> (f64, DVector<f64>) {
        let sh = shifted(base, prep.dt, tau);
        let e = rows.vector(&residual(prep, &sh, true));
        (e.norm_squared(), e)
    };
    let grid: Vec<f64> = (0..=120).map(|i| i as f64 * 5e-4).collect();
    let profile: Vec<f64> = grid.iter().map(|t| rss(&train, *t).0).collect();
    let best = (0..grid.len()).min_by(|a, b| profile[*a].total_cmp(&profile[*b])).unwrap_or(0);
    let (rss1, e1) = rss(&train, grid[best]);
    let frac = effective_fraction(&train.series(&e1));
    let n_eff = train.len() as f64 * frac;
    let stat = lr(n_eff, profile[0], rss1);
    let inside: Vec<f64> = grid.iter().zip(&profile).filter(|(_, r)| lr(n_eff, **r, rss1) <= 3.841).map(|(t, _)| *t).collect();
    let ci = [inside.first().copied().unwrap_or(grid[best]) - 2.5e-4, inside.last().copied().unwrap_or(grid[best]) + 2.5e-4];
    let (rh0, _) = rss(&hold, 0.0);
    let (rh1, eh) = rss(&hold, grid[best]);
    let nh = hold.len() as f64 * effective_fraction(&hold.series(&eh));
    let effect: Table = shifted(base, prep.dt, grid[best]).iter().zip(base).map(|(a, b)| a.iter().zip(b).map(|(x, y)| x - y).collect()).collect();
    let size = prep
        .active
        .iter()
        .map(|&k| (effect[..prep.split].iter().map(|e| e[k] * e[k]).sum::<f64>() / prep.split as f64).sqrt() / prep.noise[k])
        .fold(0.0, f64::max);
    let p_value = if grid[best] == 0.0 { 1.0 } else { chi2_sf(stat, 1) };
    let score = Score { x: vec![grid[best]], ci: vec![ci], delta_bic: stat - n_eff.ln(), p_value, heldout_p: chi2_sf(lr(nh, rh0, rh1), 1), effect_to_noise: size, effect };
    (score, grid[best])
}

/// The experiment that separates two candidates whose signatures look alike.
pub fn separating_experiment(a: EffectKind, b: EffectKind) -> String {
    use EffectKind::*;
    let pair = |x: EffectKind, y: EffectKind| (a == x && b == y) || (a == y && b == x);
    if pair(ViscousFriction, Latency) {
        "a speed sweep: viscous friction grows with speed at any frequency, a latency's residual with speed times frequency".into()
    } else if pair(JointCompliance, LinkLength) || pair(JointCompliance, JointOffset) || pair(JointCompliance, PayloadMass) {
        "a payload change: a compliant drive's deflection follows the load, a geometric error does not".into()
    } else if pair(CoulombFriction, Backlash) || pair(Backlash, JointOffset) || pair(Backlash, JointCompliance) {
        "a tracker on the link: play shows as dead travel between encoder and link at reversals, friction and offsets do not".into()
    } else if pair(Spring, JointOffset) || pair(Spring, PayloadMass) || pair(JointOffset, PayloadMass) {
        "a slow sweep of the joint at two other poses of the arm: gravity's torque changes with the pose, a spring's does not".into()
    } else {
        format!("a recording that excites {} and {} independently (different speeds, loads and poses)", a.name(), b.name())
    }
}

/// RMS (noise-normalised: each joint's band-limited residual over its noise floor in the band)
/// over the active joints: 1 at the noise floor.
fn normalised_rms(prep: &Prepared, r: &Table, range: std::ops::Range<usize>) -> f64 {
    let n = (range.len() * prep.active.len()).max(1) as f64;
    (range.flat_map(|i| prep.active.iter().map(move |&k| (i, k))).map(|(i, k)| (r[i][k] / prep.floor[k]).powi(2)).sum::<f64>() / n).sqrt()
}

fn rms(r: &Table, k: usize, range: std::ops::Range<usize>) -> f64 {
    let n = range.len().max(1) as f64;
    (range.map(|i| r[i][k] * r[i][k]).sum::<f64>() / n).sqrt()
}

/// Run the workflow: `model` against `log`, for arm `arm` of `scene` (whose inertials, drive and
/// gains are the rest of the model).
pub fn discrepancy(model: &Model, scene: &Scene, arm_name: &str, log: &JointLog, o: &Options) -> Result<Outcome> {
    let a = scene.arm_index(arm_name).map_err(|e| CalibError::field("--arm", e.to_string()))?;
    let names: Vec<String> = model.joints.iter().map(|j| j.name.clone()).collect();
    if log.names != names {
        return Err(CalibError::data("recording", format!("joints {:?} are not the model's {:?}", log.names, names)));
    }
    let mut scene = scene.clone();
    scene.set_model(a, model.clone()).map_err(|e| CalibError::data("model", e.to_string()))?;
    let arm = &scene.arms[a];
    let prep = prepare(log, &o.processing)?;
    let mut predictor = Predictor::new(&arm.model, arm, scene.gravity)?;
    let base = predictor.series(&prep)?;
    let r = residual(&prep, &base, true);
    let cands = candidates::build(&predictor, arm, scene.gravity, &prep, &base)?;
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let mut scored: Vec<(Option<&Candidate>, EffectKind, String, Score)> = Vec::new();
    for c in &cands {
        let s = score_linear(c, &prep, &r, o, &mut rng)?;
        scored.push((Some(c), c.kind, c.label(&arm.model), s));
    }
    let (lat, _) = score_latency(&prep, &base);
    scored.push((None, EffectKind::Latency, "latency".into(), lat));
    scored.sort_by(|x, y| y.3.delta_bic.total_cmp(&x.3.delta_bic));
    let supported = |s: &Score| s.delta_bic > o.min_delta_bic && s.p_value < o.max_p_value && s.heldout_p < 0.01 && s.effect_to_noise >= o.min_effect_to_noise;
    let spec_of = |c: Option<&Candidate>, s: &Score| -> EffectSpec {
        match c {
            Some(c) => c.spec(&arm.model, &s.x, "dvrk discrepancy"),
            None => EffectSpec { name: "latency".into(), joint: None, link: None, parameters: BTreeMap::from([("seconds".into(), s.x[0])]), source: "dvrk discrepancy".into() },
        }
    };
    let ci_of = |c: Option<&Candidate>, s: &Score| -> BTreeMap<String, [f64; 2]> {
        let mut m = BTreeMap::new();
        match c.map(|c| (c.kind, c)) {
            None => {
                m.insert("seconds".into(), [s.ci[0][0].max(0.0), s.ci[0][1]]);
            }
            Some((EffectKind::JointCompliance, _)) => {
                // stiffness = 1 / compliance: the interval inverted (unbounded above when the
                // compliance's interval reaches 0).
                let [lo, hi] = s.ci[0];
                m.insert("stiffness".into(), [1.0 / hi, if lo > 0.0 { 1.0 / lo } else { f64::INFINITY }]);
            }
            Some((EffectKind::Spring, _)) => {
                m.insert("k".into(), s.ci[0]);
            }
            Some((EffectKind::PayloadMass, _)) => {
                m.insert("mass".into(), s.ci[0]);
            }
            Some((_, c)) => {
                for (n, ci) in c.names.iter().zip(&s.ci) {
                    m.insert((*n).into(), *ci);
                }
            }
        }
        m
    };
    let winners: Vec<usize> = (0..scored.len()).filter(|&i| supported(&scored[i].3)).collect();
    let mut verdict = "none";
    let mut experiment = None;
    let mut effects = Vec::new();
    let mut named = None;
    let mut after = base.clone();
    if let Some(&b) = winners.first() {
        let best = &scored[b];
        let rival = winners.iter().skip(1).map(|&i| &scored[i]).find(|s| s.2 != best.2 && s.1 != best.1 && best.3.delta_bic - s.3.delta_bic < o.ambiguity_bic);
        if let Some(rv) = rival {
            verdict = "ambiguous";
            experiment = Some(separating_experiment(best.1, rv.1));
        } else {
            verdict = "named";
            let spec = spec_of(best.0, &best.3);
            effects.push(EffectReport {
                name: spec.name.clone(),
                joint: spec.joint.clone(),
                link: best.0.and_then(|c| c.link.clone()),
                parameters: spec.parameters.clone(),
                ci95: ci_of(best.0, &best.3),
                delta_bic: best.3.delta_bic,
                p_value: best.3.p_value,
            });
            for (x, e) in after.iter_mut().zip(&best.3.effect) {
                for (u, v) in x.iter_mut().zip(e) {
                    *u += v;
                }
            }
            named = Some(spec);
        }
    }
    let candidates: Vec<CandidateReport> = scored
        .iter()
        .take(12)
        .map(|(c, _, label, s)| {
            let spec = spec_of(*c, s);
            CandidateReport {
                label: label.clone(),
                name: spec.name,
                joint: spec.joint,
                link: spec.link.map(|l| l.to_string()),
                parameters: spec.parameters,
                ci95: ci_of(*c, s),
                delta_bic: s.delta_bic,
                p_value: s.p_value,
                heldout_p_value: s.heldout_p,
                effect_to_noise: s.effect_to_noise,
                supported: supported(s),
            }
        })
        .collect();
    let (f0, f1) = (residual(&prep, &base, true), residual(&prep, &after, true));
    let (tr, ho) = (0..prep.split, prep.split..prep.t.len());
    let joints = prep
        .active
        .iter()
        .map(|&k| JointRms {
            joint: arm.model.joints[k].name.clone(),
            unit: if arm.model.joints[k].kind == dvrk_kin::JointType::Prismatic { "N" } else { "N·m" },
            noise: prep.noise[k],
            band_floor: prep.floor[k],
            band_rms_before: rms(&f0, k, tr.clone()),
            band_rms_after: rms(&f1, k, tr.clone()),
            band_rms_heldout_before: rms(&f0, k, ho.clone()),
            band_rms_heldout_after: rms(&f1, k, ho.clone()),
        })
        .collect();
    let tracking = if o.tracking { Some(super::tracking::compare(&scene, a, log, named.as_ref())?) } else { None };
    let report = Report {
        verdict: verdict.into(),
        channel: "torque".into(),
        effects,
        candidates,
        experiment,
        rms_before: normalised_rms(&prep, &f0, tr.clone()),
        rms_after: normalised_rms(&prep, &f1, tr.clone()),
        rms_heldout_before: normalised_rms(&prep, &f0, ho.clone()),
        rms_heldout_after: normalised_rms(&prep, &f1, ho.clone()),
        noise_floor: 1.0,
        rms_units: "each joint's effort residual in the analysis band over its noise floor there, RMS over the moving joints".into(),
        joints,
        tracking,
        samples: prep.t.len(),
        heldout_from: prep.t[prep.split],
        notes: vec!["kinematic channel (marker tracker) not analysed yet: it needs --marker-topic data".into()],
    };
    Ok(Outcome { report, named })
}
