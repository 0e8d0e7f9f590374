//! The kinematic channel: a tracker's poses of a marker on one link against the model's forward
//! kinematics at the encoder positions, with the tracker's and the marker's placements estimated
//! as nuisance ([`super::registration`]). Candidates with a kinematic signature, each linear in
//! one parameter: a joint's encoder offset, a DH length of a link between the base and the marker,
//! the offset between the tracker's and the joint stream's clocks (either sign: the tracker late
//! or early), the drives' link-side deflection: compliance (load / stiffness) and play (half the
//! gap, on the side the load pushes), and a lightly loaded drive's play by motion direction (the
//! link held after the motor reverses until the gap is crossed). The clock offset and the motion
//! play are refitted exactly (Gauss-Newton on the recomputed residual), the others are linear.
//! Scored as the torque channel is: likelihood ratio on an effective sample size, change in BIC,
//! held-out check.

use dvrk_sim::recording::JointLog;
use dvrk_sim::recording::MarkerLog;
use super::registration::{pose_difference, whiten, Registration};
use super::report::{CandidateReport, EffectReport, KinematicReport};
use super::signals::Prepared;
use super::stats::{chi2_sf, effective_fraction};
use crate::error::{CalibError, Result};
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::{compute_frame_placements, Data, FrameRef, Model, Pose};
use nalgebra::{DMatrix, DVector, Vector6};
use std::collections::BTreeMap;

/// One candidate's fit on the kinematic channel.
#[derive(Debug, Clone)]
pub struct KinematicScore {
    pub kind: EffectKind,
    pub joint: Option<usize>,
    /// Frame name of a `link_length`.
    pub link: Option<String>,
    /// The fitted parameter: `offset` (rad, m), `a` (m), `seconds`, `compliance` (1 / stiffness:
    /// rad/(N·m), m/N) or `b` (rad, m).
    pub parameter: &'static str,
    pub value: f64,
    /// Its variance (from the noise, inflated for the residuals' autocorrelation).
    pub variance: f64,
    /// Likelihood ratio against the registration alone, its change in BIC and p-value.
    pub stat: f64,
    pub delta_bic: f64,
    pub p_value: f64,
    /// p-value of the held-out improvement.
    pub heldout_p: f64,
    /// RMS of the fitted effect (the part the registration cannot absorb) over the noise.
    pub effect_to_noise: f64,
    /// Normalised RMS after (fitted part, held-out part).
    pub rms_after: [f64; 2],
}

impl KinematicScore {
    /// The parameter's physical lower bound (none for offsets and lengths).
    pub fn lower(&self) -> Option<f64> {
        matches!(self.kind, EffectKind::Latency | EffectKind::JointCompliance | EffectKind::Backlash | EffectKind::MotionPlay).then_some(0.0)
    }

    /// `kind on joint`, `kind a on link`, or `kind`, marked as the kinematic channel's.
    pub fn label(&self, model: &Model) -> String {
        match (&self.joint, &self.link) {
            (Some(j), _) => format!("{} on {} (kinematic)", self.kind.name(), model.joints[*j].name),
            (_, Some(l)) => format!("{} {} on {l} (kinematic)", self.kind.name(), self.parameter),
            _ => format!("{} (kinematic)", self.kind.name()),
        }
    }

    /// The effect as a model file writes it, its 95% interval, in the vocabulary's parameters.
    pub fn spec(&self, model: &Model, source: &str) -> (EffectSpec, BTreeMap<String, [f64; 2]>) {
        let h = 1.96 * self.variance.max(0.0).sqrt();
        let (lo, hi) = (self.value - h, self.value + h);
        let mut p = BTreeMap::new();
        let mut ci = BTreeMap::new();
        match self.kind {
            EffectKind::JointCompliance => {
                p.insert("stiffness".into(), if self.value > 0.0 { 1.0 / self.value } else { 1e8 });
                ci.insert("stiffness".into(), [if hi > 0.0 { 1.0 / hi } else { 1e8 }, if lo > 0.0 { 1.0 / lo } else { f64::INFINITY }]);
            }
            EffectKind::LinkLength => {
                p.insert("a".into(), self.value);
                p.insert("d".into(), 0.0);
                ci.insert("a".into(), [lo, hi]);
            }
            _ => {
                p.insert(self.parameter.into(), self.value);
                ci.insert(self.parameter.into(), [lo, hi]);
            }
        }
        let spec = EffectSpec {
            name: self.kind.name().into(),
            joint: self.joint.map(|j| model.joints[j].name.clone()),
            link: self.link.clone().map(FrameRef::Name),
            actuator: None,
            parameters: p,
            source: source.into(),
        };
        (spec, ci)
    }
}

/// A one-parameter fit's evidence: value, variance and likelihood ratio against zero.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    pub value: f64,
    pub variance: f64,
    pub stat: f64,
}

/// Two independent channels' evidence on one parameter, each taken as quadratic about its own
/// value: the precision-weighted value (at `lower` or above), its variance, and the summed
/// likelihood ratio there (each channel's ratio less what the move away from its value costs it).
/// Channels that disagree beyond their noise reveal a model error neither interval holds: the
/// variance is scaled by the disagreement's chi-square when above 1 (the Particle Data Group's
/// scale factor for inconsistent measurements).
pub fn combine(a: &Evidence, b: &Evidence, lower: Option<f64>) -> Evidence {
    let finite = |v: f64| if v.is_finite() && v > 0.0 { v } else { f64::INFINITY };
    let (va, vb) = (finite(a.variance), finite(b.variance));
    let w = 1.0 / va + 1.0 / vb;
    let mut value = (a.value / va + b.value / vb) / w;
    if let Some(lo) = lower {
        value = value.max(lo);
    }
    let cost = |e: &Evidence, v: f64| if v.is_finite() { (value - e.value).powi(2) / v } else { 0.0 };
    let stat = (a.stat - cost(a, va) + b.stat - cost(b, vb)).max(0.0);
    let chi2 = if (va + vb).is_finite() { (a.value - b.value).powi(2) / (va + vb) } else { 0.0 };
    Evidence { value, variance: chi2.max(1.0) / w, stat }
}

/// The channel's figures and ranked candidates.
#[derive(Debug, Clone)]
pub struct KinematicChannel {
    pub topic: String,
    /// The marker's link (frame name).
    pub link: String,
    /// Tracked poses analysed, and the first held-out one.
    pub samples: usize,
    pub split: usize,
    /// Time of the first held-out pose (s).
    pub heldout_from: f64,
    /// Tracker noise per axis: position (m), rotation (rad), from fourth differences.
    pub sigma: [f64; 2],
    pub registration: Registration,
    /// Normalised RMS (1 at the tracker's noise) with the registration alone: fitted, held out.
    pub rms_before: [f64; 2],
    /// Every candidate, best change in BIC first.
    pub candidates: Vec<KinematicScore>,
}

/// `[x, y, z, rotation vector]` of a pose (m, rad).
fn pose6(p: &Pose) -> [f64; 6] {
    let (t, w) = (p.translation.vector, dvrk_kin::so3::log(&p.rotation));
    [t.x, t.y, t.z, w.x, w.y, w.z]
}

impl KinematicChannel {
    /// The channel's report, its "after" with the named effect where the tracker sees it; a
    /// candidate is `supported` by this channel alone when `strong(delta BIC, p-value, held-out
    /// p-value, effect-to-noise)`.
    pub fn report(&self, model: &Model, named: Option<&EffectSpec>, source: &str, strong: &dyn Fn(f64, f64, f64, f64) -> bool) -> KinematicReport {
        let after = named.and_then(|e| {
            let joint = e.joint.as_ref().and_then(|n| model.joints.iter().position(|j| &j.name == n));
            let link = e.link.as_ref().map(|l| l.to_string());
            // The joint stream's latency is, to the tracker, its clock's offset.
            let kind = match EffectKind::from_name(&e.name)? {
                EffectKind::Latency => EffectKind::ClockOffset,
                k => k,
            };
            self.find(kind, joint, link.as_deref())
        });
        let [after_fit, after_held] = after.map_or(self.rms_before, |k| k.rms_after);
        KinematicReport {
            topic: self.topic.clone(),
            link: self.link.clone(),
            samples: self.samples,
            heldout_from: self.heldout_from,
            noise_position: self.sigma[0],
            noise_rotation: self.sigma[1],
            tracker_from_base: pose6(&self.registration.tracker_from_base),
            link_from_marker: pose6(&self.registration.link_from_marker),
            rms_before: self.rms_before[0],
            rms_after: after_fit,
            rms_heldout_before: self.rms_before[1],
            rms_heldout_after: after_held,
            candidates: self
                .candidates
                .iter()
                .take(8)
                .map(|k| {
                    let (spec, ci95) = k.spec(model, source);
                    CandidateReport {
                        label: k.label(model),
                        effect: EffectReport {
                            name: spec.name,
                            joint: spec.joint,
                            link: spec.link.map(|l| l.to_string()),
                            actuator: spec.actuator,
                            parameters: spec.parameters,
                            ci95,
                            delta_bic: k.delta_bic,
                            p_value: k.p_value,
                            payload: None,
                            explained: Vec::new(),
                        },
                        heldout_p_value: k.heldout_p,
                        heldout_cv_p_value: None,
                        effect_to_noise: k.effect_to_noise,
                        supported: strong(k.delta_bic, k.p_value, k.heldout_p, k.effect_to_noise),
                        nuisance_correlation: None,
                    }
                })
                .collect(),
        }
    }

    /// The candidate for `kind` on `joint` / `link`, if this channel has one.
    pub fn find(&self, kind: EffectKind, joint: Option<usize>, link: Option<&str>) -> Option<&KinematicScore> {
        self.candidates.iter().find(|c| c.kind == kind && c.joint == joint && c.link.as_deref() == link)
    }

    /// What the channel's candidates say of the clocks and of a play, for the report's notes: which
    /// stream is late and by how much (with its 95% interval) when a clock offset is `named`, and
    /// for a named play which of the two plays the evidence prefers on its joint, and why.
    pub fn notes(&self, model: &Model, named: Option<&EffectSpec>, supported: &dyn Fn(&KinematicScore) -> bool) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(k) = named.filter(|e| e.name == EffectKind::ClockOffset.name()).and_then(|_| self.find(EffectKind::ClockOffset, None, None)) {
            let h = 1.96e3 * k.variance.max(0.0).sqrt();
            let (ms, lo, hi) = (1e3 * k.value, 1e3 * k.value - h, 1e3 * k.value + h);
            out.push(match k.value >= 0.0 {
                true => format!("clock offset: the tracker's poses ({}) are {ms:.2} ms late against the joint stream (95% interval {lo:.2} to {hi:.2} ms): a pose stamped t shows the link at the encoders' t - {ms:.2} ms", self.topic),
                false => format!("clock offset: the joint stream is {:.2} ms late against the tracker's poses ({}) (95% interval of the tracker's offset {lo:.2} to {hi:.2} ms): a pose stamped t shows the link at the encoders' t + {:.2} ms", -ms, self.topic, -ms),
            });
        }
        let play = named.filter(|e| e.name == EffectKind::MotionPlay.name() || e.name == EffectKind::Backlash.name());
        if let Some((j, joint)) = play.and_then(|e| model.joints.iter().enumerate().find(|(_, jt)| e.joint.as_deref() == Some(jt.name.as_str()))) {
            let (Some(m), Some(b)) = (self.find(EffectKind::MotionPlay, Some(j), None), self.find(EffectKind::Backlash, Some(j), None)) else { return out };
            let d = m.delta_bic - b.delta_bic;
            let other = if d >= 0.0 { b } else { m };
            let also = if supported(other) { "; both are supported" } else { "" };
            let d = m.delta_bic - b.delta_bic;
            out.push(match d >= 0.0 {
                true => format!("play on {}: by motion direction (b {:.3e}) over the load's side (b {:.3e}) by delta BIC {d:.1}{also}: the link stays where it was when the motor reverses until the gap is crossed, whatever its load's sign", joint.name, m.value, b.value),
                false => format!("play on {}: on the load's side (b {:.3e}) rather than by motion direction (b {:.3e}) by delta BIC {:.1}{also}: the link rests on the side its load pushes, not where the motor last left it", joint.name, b.value, m.value, -d),
            });
        }
        out
    }
}

/// The samples of `t` (increasing) that bracket time `x` and the weight of the later one:
/// `x` is `i - 1` and `i` mixed `1 - w : w`, held at the ends.
fn bracket(t: &[f64], x: f64) -> (usize, f64) {
    let i = t.partition_point(|v| *v <= x).clamp(1, t.len() - 1);
    (i, ((x - t[i - 1]) / (t[i] - t[i - 1])).clamp(0.0, 1.0))
}

/// Linear interpolation of `table[sample][k]` (sampled at `t`) at time `x`, held at the ends.
fn interp(t: &[f64], table: &[Vec<f64>], x: f64, out: &mut [f64]) {
    let (i, w) = bracket(t, x);
    for (k, o) in out.iter_mut().enumerate() {
        *o = table[i - 1][k] + w * (table[i][k] - table[i - 1][k]);
    }
}

/// The tracker's noise (position m, rotation rad) per axis from fourth differences of the
/// tracked poses (motion contributes jerk x dt^3, negligible at tracker rates).
fn tracker_noise(poses: &[Pose]) -> [f64; 2] {
    let c = [1.0, -4.0, 6.0, -4.0, 1.0];
    let (mut sp, mut sr, mut n) = (0.0, 0.0, 0usize);
    for w in poses.windows(5) {
        let mut d = Vector6::zeros();
        for (k, p) in w.iter().enumerate() {
            d += c[k] * pose_difference(p, &w[2]);
        }
        sp += d.fixed_rows::<3>(0).norm_squared();
        sr += d.fixed_rows::<3>(3).norm_squared();
        n += 1;
    }
    // Var of the fourth difference of white noise: 70 sigma^2, per axis (three axes).
    let f = 70.0 * 3.0 * n.max(1) as f64;
    [(sp / f).sqrt().max(1e-9), (sr / f).sqrt().max(1e-9)]
}

/// What the workflow needs to score the channel.
pub struct Inputs<'a> {
    pub model: &'a Model,
    pub log: &'a JointLog,
    pub markers: &'a MarkerLog,
    pub prep: &'a Prepared,
    /// Motor inertia per joint (kg m^2, kg): the drive's load is the effort less its share.
    pub armature: &'a [f64],
}

/// The projections a candidate is scored with: the registration's 12 columns taken out of the
/// fitted rows (a candidate is fitted with the registration refitted next to it), the held-out
/// rows corrected as the fitted rows ask.
struct Fitting {
    nuis: DMatrix<f64>,
    qm: DMatrix<f64>,
    r_upper: DMatrix<f64>,
    rows_t: usize,
    rows_h: usize,
    /// The residual with the registration alone: projected fitted rows, corrected held-out rows.
    r_perp: DVector<f64>,
    r_h0: DVector<f64>,
    frac0: f64,
}

/// Time series per pose axis of whitened rows `e` (6 per sample).
fn series(e: &DVector<f64>, rows: usize) -> Vec<Vec<f64>> {
    (0..6).map(|a| (0..rows / 6).map(|s| e[6 * s + a]).collect()).collect()
}

/// RMS of a whitened residual (1 at the tracker's noise).
fn norm_rms(e: &DVector<f64>) -> f64 {
    (e.norm_squared() / e.len().max(1) as f64).sqrt()
}

impl Fitting {
    fn new(nuis: DMatrix<f64>, r: &DVector<f64>, split: usize) -> Fitting {
        let (rows_t, rows_h) = (6 * split, r.len() - 6 * split);
        let qr = nuis.rows(0, rows_t).into_owned().qr();
        let (qm, r_upper) = (qr.q(), qr.r());
        let mut f = Fitting { nuis, qm, r_upper, rows_t, rows_h, r_perp: DVector::zeros(0), r_h0: DVector::zeros(0), frac0: 1.0 };
        f.r_perp = f.project(r);
        f.r_h0 = f.held(r);
        f.frac0 = effective_fraction(&series(&f.r_perp, rows_t));
        f
    }

    /// The fitted rows of `v` with the registration's share taken out.
    fn project(&self, v: &DVector<f64>) -> DVector<f64> {
        let vt = v.rows(0, self.rows_t).into_owned();
        &vt - &self.qm * (self.qm.transpose() * &vt)
    }

    /// A residual's held-out rows once the registration is corrected as its fitted rows ask.
    fn held(&self, e: &DVector<f64>) -> DVector<f64> {
        let coef = self.r_upper.solve_upper_triangular(&(self.qm.transpose() * e.rows(0, self.rows_t))).unwrap_or_else(|| DVector::zeros(12));
        e.rows(self.rows_t, self.rows_h) - self.nuis.rows(self.rows_t, self.rows_h) * coef
    }

    /// The one-parameter fit of `col` to the residual (at `lower` or above).
    fn linear(&self, col: &DVector<f64>, lower: Option<f64>) -> Option<f64> {
        let c = self.project(col);
        let cc = c.norm_squared();
        // What the registration absorbs almost whole is not identifiable from this tracker.
        if cc <= 1e-6 * col.rows(0, self.rows_t).norm_squared() {
            return None;
        }
        let theta = c.dot(&self.r_perp) / cc;
        Some(lower.map_or(theta, |lo| theta.max(lo)))
    }

    /// A candidate's score at `value`: `col` its column there (the whitened pose change per
    /// unit), `r` the residual with the registration alone and `left` the one it leaves (fitted
    /// and held-out rows).
    #[allow(clippy::too_many_arguments)]
    fn score(&self, kind: EffectKind, joint: Option<usize>, link: Option<String>, parameter: &'static str, value: f64, col: &DVector<f64>, r: &DVector<f64>, left: &DVector<f64>) -> KinematicScore {
        let c = self.project(col);
        let cc = c.norm_squared().max(1e-300);
        let e1 = self.project(left);
        let rss0 = self.r_perp.norm_squared();
        let rss1 = e1.norm_squared();
        let frac = effective_fraction(&series(&e1, self.rows_t));
        let n_eff = self.rows_t as f64 * frac;
        let stat = (n_eff * (rss0 / rss1.max(1e-300)).ln()).max(0.0);
        let sigma2 = rss1 / (self.rows_t as f64 - 13.0).max(1.0) / frac;
        let variance = sigma2 / cc * consistency_scale(&c, &e1, sigma2);
        // Held out: the registration (fitted with the candidate) and the candidate carried over.
        let e_h1 = self.held(left);
        let stat_h = (self.rows_h as f64 * self.frac0 * (self.r_h0.norm_squared() / e_h1.norm_squared().max(1e-300)).ln()).max(0.0);
        KinematicScore {
            kind,
            joint,
            link,
            parameter,
            value,
            variance,
            stat,
            delta_bic: stat - n_eff.ln(),
            p_value: if stat > 0.0 { chi2_sf(stat, 1) } else { 1.0 },
            heldout_p: chi2_sf(stat_h, 1),
            // The effect's size on the link's pose in the arm's own frame (what it does to the
            // robot), not the part the placements leave: a 0.5 deg pitch offset moves the shaft by
            // millimetres and leaves 0.4 of the tracker's noise once they are refitted.
            effect_to_noise: norm_rms(&(r - left).rows(0, self.rows_t).into_owned()),
            rms_after: [norm_rms(&e1), norm_rms(&e_h1)],
        }
    }

    /// Gauss-Newton on one parameter whose residual is computed exactly (`left_at`) and whose
    /// column (`col_at`) may be approximate: from `start`, at `lower` or above, until a step is
    /// below `tol`. The value, its column and the residual it leaves.
    fn refine(&self, start: f64, lower: Option<f64>, tol: f64, col_at: &mut dyn FnMut(f64) -> DVector<f64>, left_at: &mut dyn FnMut(f64) -> DVector<f64>) -> (f64, DVector<f64>, DVector<f64>) {
        let mut theta = start;
        let (mut col, mut left) = (col_at(theta), left_at(theta));
        for _ in 0..REFINE_PASSES {
            let c = self.project(&col);
            let cc = c.norm_squared();
            if cc <= 0.0 {
                break;
            }
            let mut next = theta + c.dot(&self.project(&left)) / cc;
            if let Some(lo) = lower {
                next = next.max(lo);
            }
            let step = next - theta;
            theta = next;
            col = col_at(theta);
            left = left_at(theta);
            if step.abs() < tol {
                break;
            }
        }
        (theta, col, left)
    }
}

/// Quarters of the fitted rows a parameter is estimated on for its consistency.
const QUARTERS: usize = 4;

/// The Particle Data Group's scale factor for a parameter fitted with column `c` leaving `e`
/// (the fitted rows, the registration projected out; `sigma2` the residual's variance per row
/// over its effective share): the estimate moved to each quarter of the rows, the chi-square
/// of the four against their mean per degree of freedom, at least 1. A model error the noise
/// does not hold (a kinematic table's rounding, a clock that drifts) reads differently from
/// quarter to quarter and widens the interval; a consistent fit keeps it.
fn consistency_scale(c: &DVector<f64>, e: &DVector<f64>, sigma2: f64) -> f64 {
    let samples = c.len() / 6;
    let (mut est, mut w) = ([0.0; QUARTERS], [0.0; QUARTERS]);
    for q in 0..QUARTERS {
        let (a, b) = (6 * (q * samples / QUARTERS), 6 * ((q + 1) * samples / QUARTERS));
        let (cq, eq) = (c.rows(a, b - a), e.rows(a, b - a));
        let cc = cq.norm_squared();
        if cc <= 0.0 {
            return 1.0;
        }
        est[q] = cq.dot(&eq) / cc;
        w[q] = cc / sigma2.max(1e-300);
    }
    let mean = est.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / w.iter().sum::<f64>();
    let chi2: f64 = est.iter().zip(&w).map(|(x, w)| w * (x - mean).powi(2)).sum();
    (chi2 / (QUARTERS - 1) as f64).max(1.0)
}

/// Gauss-Newton passes of an exactly refitted parameter (a clock offset, a motion play): the
/// linear estimate of a 30 ms offset is 3% off at the dVRK's speeds, one pass takes it to 0.1%.
const REFINE_PASSES: usize = 6;

/// Analyse the kinematic channel.
pub fn analyse(i: &Inputs) -> Result<KinematicChannel> {
    let (model, prep, mk) = (i.model, i.prep, i.markers);
    let nq = model.nq();
    let (t0, t1, ts) = (prep.t[0], prep.t[prep.t.len() - 1], prep.t[prep.split]);
    let keep: Vec<usize> = (0..mk.t.len()).filter(|&s| mk.t[s] >= t0 && mk.t[s] <= t1).collect();
    let split = keep.iter().position(|&s| mk.t[s] >= ts).unwrap_or(keep.len());
    if split < 50 || keep.len() - split < 20 {
        return Err(CalibError::data(
            format!("--marker-topic {}", mk.topic),
            format!("{} tracked poses inside the analysed span {t0:.2}..{t1:.2} s (need 50 fitted and 20 held out)", keep.len()),
        ));
    }
    // The model's own stream and drive effects (a model from an earlier round has them): the
    // joint stream's latency and the tracker's clock shift the encoders' time, a motion play
    // puts the link behind the motor, a compliance or a load-side play deflects it.
    let sum = |kind: EffectKind| -> f64 { model.effects.iter().filter(|e| e.kind == kind).map(|e| e.get("seconds")).sum() };
    let shift = sum(EffectKind::Latency) - sum(EffectKind::ClockOffset);
    let mut deflect: Vec<(usize, f64, f64)> = Vec::new();
    let mut encoders = std::borrow::Cow::Borrowed(&i.log.position);
    for e in &model.effects {
        match (e.kind, e.joint) {
            (EffectKind::JointCompliance, Some(j)) => deflect.push((j, 1.0 / e.get("stiffness"), 0.0)),
            (EffectKind::Backlash, Some(j)) => deflect.push((j, 0.0, e.get("b"))),
            (EffectKind::MotionPlay, Some(j)) => {
                let motor: Vec<f64> = encoders.iter().map(|p| p[j]).collect();
                let (mut link, mut side) = (vec![0.0; motor.len()], vec![0.0; motor.len()]);
                dvrk_kin::effects::motion_play(e.get("b"), &motor, &mut link, &mut side);
                for (p, l) in encoders.to_mut().iter_mut().zip(link) {
                    p[j] = l;
                }
            }
            _ => {}
        }
    }
    let n = keep.len();
    let tk: Vec<f64> = keep.iter().map(|&m| mk.t[m]).collect();
    let (mut qd, mut load) = (vec![vec![0.0; nq]; n], vec![vec![0.0; nq]; n]);
    let mut qdd = vec![0.0; nq];
    for (s, &t) in tk.iter().enumerate() {
        interp(&prep.t, &prep.qd, t, &mut qd[s]);
        interp(&prep.t, &prep.effort, t, &mut load[s]);
        interp(&prep.t, &prep.qdd, t, &mut qdd);
        for k in 0..nq {
            load[s][k] -= i.armature.get(k).copied().unwrap_or(0.0) * qdd[k];
        }
    }
    // Play's side: the sign of the drive's load, smoothed over a few percent of its RMS.
    let load_scale: Vec<f64> = (0..nq).map(|k| 0.03 * (load.iter().map(|l| l[k] * l[k]).sum::<f64>() / n as f64).sqrt().max(1e-9)).collect();
    // The link's joints at tracker sample s, the tracker's clock moved by `late` (s) more.
    let q_at = |s: usize, late: f64, out: &mut [f64]| {
        interp(&i.log.t, &encoders, tk[s] + shift - late, out);
        for (j, c, b) in &deflect {
            out[*j] -= c * load[s][*j] + b * (load[s][*j] / load_scale[*j]).tanh();
        }
    };
    let mut q = vec![vec![0.0; nq]; n];
    for (s, qs) in q.iter_mut().enumerate() {
        q_at(s, 0.0, qs);
    }
    let frame = mk.frame;
    let mut data = Data::new(model);
    let fk = |m: &Model, d: &mut Data, qs: &[f64]| -> Pose {
        compute_frame_placements(m, d, qs);
        d.frames[frame]
    };
    let f: Vec<Pose> = q.iter().map(|qs| fk(model, &mut data, qs)).collect();
    let meas: Vec<Pose> = keep.iter().map(|&m| mk.poses[m]).collect();
    let sigma = tracker_noise(&meas);
    let reg = Registration::fit(&f[..split], &meas[..split], sigma)?;
    let (nuis, r) = reg.linearised(&f, &meas, sigma);
    let pred: Vec<Pose> = f.iter().map(|p| reg.predict(p)).collect();
    // The whitened change of the predicted pose, per unit, when sample s's link pose moves to `moved`.
    let change = |col: &mut DVector<f64>, s: usize, moved: &Pose, unit: f64| {
        col.fixed_rows_mut::<6>(6 * s).copy_from(&(whiten(pose_difference(&reg.predict(moved), &pred[s]), sigma) / unit));
    };
    // Per unit of a link-side joint displacement.
    let mut dq: Vec<DVector<f64>> = Vec::new();
    let h = 1e-6;
    let mut qs = vec![0.0; nq];
    for j in 0..nq {
        let mut col = DVector::zeros(6 * n);
        for s in 0..n {
            qs.copy_from_slice(&q[s]);
            qs[j] += h;
            let moved = fk(model, &mut data, &qs);
            change(&mut col, s, &moved, h);
        }
        dq.push(col);
    }
    let fitting = Fitting::new(nuis, &r, split);
    let mut scores = Vec::new();
    let linear = |kind: EffectKind, joint: Option<usize>, link: Option<String>, parameter: &'static str, col: DVector<f64>, lower: Option<f64>, scores: &mut Vec<KinematicScore>| {
        if let Some(theta) = fitting.linear(&col, lower) {
            let left = &r - &col * theta;
            scores.push(fitting.score(kind, joint, link, parameter, theta, &col, &r, &left));
        }
    };
    let seen = |c: &DVector<f64>| c.norm() > 1e-9 * (n as f64).sqrt();
    let per_sample = |j: usize, g: &dyn Fn(usize) -> f64| -> DVector<f64> { DVector::from_fn(6 * n, |row, _| dq[j][row] * g(row / 6)) };
    let moving: Vec<usize> = prep.active.iter().copied().filter(|&j| seen(&dq[j])).collect();
    for &j in &moving {
        linear(EffectKind::JointOffset, Some(j), None, "offset", dq[j].clone(), None, &mut scores);
        linear(EffectKind::JointCompliance, Some(j), None, "compliance", per_sample(j, &|s| -load[s][j]), Some(0.0), &mut scores);
        linear(EffectKind::Backlash, Some(j), None, "b", per_sample(j, &|s| -(load[s][j] / load_scale[j]).tanh()), Some(0.0), &mut scores);
    }
    // The clocks, either sign (the tracker late: its pose shows the link `seconds` earlier),
    // refitted exactly: the pose moves with the joints' speed, nonlinearly at tens of ms.
    let mut clock_col = DVector::zeros(6 * n);
    for &j in &moving {
        clock_col -= per_sample(j, &|s| qd[s][j]);
    }
    if let Some(start) = fitting.linear(&clock_col, None) {
        // With the registration refitted on the fitted rows at each value (the joint fit: a
        // 30 ms offset moves the placements' first fit by more than its linear share).
        let mut data = Data::new(model);
        let mut qs = vec![0.0; nq];
        let mut f_late = vec![Pose::identity(); n];
        let mut left_at = |late: f64| -> DVector<f64> {
            for (s, p) in f_late.iter_mut().enumerate() {
                q_at(s, late, &mut qs);
                *p = fk(model, &mut data, &qs);
            }
            let moved = reg.refined(&f_late[..split], &meas[..split], sigma, 3).unwrap_or_else(|_| reg.clone());
            let mut e = DVector::zeros(6 * n);
            for s in 0..n {
                e.fixed_rows_mut::<6>(6 * s).copy_from(&whiten(pose_difference(&meas[s], &moved.predict(&f_late[s])), sigma));
            }
            e
        };
        let (value, col, left) = fitting.refine(start, None, 1e-7, &mut |_| clock_col.clone(), &mut left_at);
        scores.push(fitting.score(EffectKind::ClockOffset, None, None, "seconds", value, &col, &r, &left));
    }
    // Play by motion direction: the encoders through the play operator, the link's lag
    // (link - motor) taken to the tracker's samples; linear in it (a play is a few mrad).
    for &j in &moving {
        let probe = std::cell::RefCell::new(PlayProbe::new(encoders.iter().map(|p| p[j]).collect(), n));
        let at = |b: f64| probe.borrow_mut().at(b, &i.log.t, &tk, shift);
        // The side at a gap well below the dVRK's plays and well above its encoders' noise.
        let start_gap = if model.joints[j].kind == dvrk_kin::JointType::Prismatic { 2e-5 } else { 5e-4 };
        let mut col_at = |b: f64| {
            at(b.max(start_gap));
            let p = probe.borrow();
            per_sample(j, &|s| -p.side[s])
        };
        let Some(start) = fitting.linear(&col_at(start_gap), Some(0.0)) else { continue };
        let mut left_at = |b: f64| {
            at(b);
            let p = probe.borrow();
            &r - per_sample(j, &|s| p.lag[s])
        };
        let (value, col, left) = fitting.refine(start, Some(0.0), 1e-9, &mut col_at, &mut left_at);
        scores.push(fitting.score(EffectKind::MotionPlay, Some(j), None, "b", value, &col, &r, &left));
    }
    // DH lengths `a` of the moving links between the base and the marker (the pose is linear in
    // a length: the step's size does not matter).
    for (k, lengthened) in observable_lengths(model, frame) {
        let name = model.frames[k].name.clone();
        let mut col = DVector::zeros(6 * n);
        for s in 0..n {
            let moved = fk(&lengthened, &mut data, &q[s]);
            change(&mut col, s, &moved, LENGTH_STEP);
        }
        if seen(&col) {
            linear(EffectKind::LinkLength, None, Some(name), "a", col, None, &mut scores);
        }
    }
    scores.sort_by(|a, b| b.delta_bic.total_cmp(&a.delta_bic));
    Ok(KinematicChannel {
        topic: mk.topic.clone(),
        link: model.frames[frame].name.clone(),
        samples: n,
        split,
        heldout_from: mk.t[keep[split]],
        sigma,
        registration: reg,
        rms_before: [norm_rms(&fitting.r_perp), norm_rms(&fitting.r_h0)],
        candidates: scores,
    })
}

/// One joint's motion play on the joint stream, taken to the tracker's samples (buffers kept
/// between the values a fit tries).
struct PlayProbe {
    motor: Vec<f64>,
    link: Vec<f64>,
    side_log: Vec<f64>,
    /// At the tracker's samples: the link's lag behind the motor (link - motor), the gap's side.
    lag: Vec<f64>,
    side: Vec<f64>,
}

impl PlayProbe {
    fn new(motor: Vec<f64>, samples: usize) -> PlayProbe {
        let m = motor.len();
        PlayProbe { motor, link: vec![0.0; m], side_log: vec![0.0; m], lag: vec![0.0; samples], side: vec![0.0; samples] }
    }

    /// The play of half-width `b` (rad, m) on stream `t_log`, read at `tk + shift`.
    fn at(&mut self, b: f64, t_log: &[f64], tk: &[f64], shift: f64) {
        dvrk_kin::effects::motion_play(b, &self.motor, &mut self.link, &mut self.side_log);
        for (s, t) in tk.iter().enumerate() {
            let (i, w) = bracket(t_log, t + shift);
            let lag = |k: usize| self.link[k] - self.motor[k];
            self.lag[s] = lag(i - 1) + w * (lag(i) - lag(i - 1));
            self.side[s] = self.side_log[i - 1] + w * (self.side_log[i] - self.side_log[i - 1]);
        }
    }
}

/// The step (m) of a DH length's finite difference.
const LENGTH_STEP: f64 = 1e-4;

/// The frames between the base and `frame` whose DH length `a` the tracker can see, base first,
/// each with `model` compiled with that `a` longer by `LENGTH_STEP`: a moving joint before the
/// length turns it, and one at or after it (modified DH: the frame's own joint acts after its
/// `a`) turns what follows; a length outside both is absorbed by the tracker's or the marker's
/// placement.
pub fn observable_lengths(model: &Model, frame: usize) -> Vec<(usize, Model)> {
    let mut chain = vec![frame];
    let mut at = model.frames[frame].parent;
    while let Some(k) = at {
        chain.push(k);
        at = model.frames[k].parent;
    }
    let moving: Vec<usize> = chain.iter().copied().filter(|&c| model.frames[c].is_moving()).collect();
    chain
        .iter()
        .rev()
        .copied()
        .filter(|&k| model.frames[k].a != 0.0)
        .filter(|&k| moving.iter().any(|&c| c != k && is_ancestor(model, c, k)) && moving.iter().any(|&c| is_ancestor(model, k, c)))
        // A length that would make one declared body two, or open a closed loop, is not one the
        // mechanism can have on its own (a loop's links change together).
        .filter_map(|k| model.with_effect(&length_effect(model, k, LENGTH_STEP)).ok().filter(keeps_loops_closed).map(|m| (k, m)))
        .collect()
}

/// True when `model`'s closures stay shut (below 1 um) at home and at two other poses.
fn keeps_loops_closed(model: &Model) -> bool {
    let mut data = Data::new(model);
    let home = model.home();
    [0.0, 0.3, -0.3].iter().all(|s| {
        let q: Vec<f64> = home.iter().zip(&model.joints).map(|(h, j)| (h + s * (j.upper - j.lower) * 0.5).clamp(j.lower, j.upper)).collect();
        compute_frame_placements(model, &mut data, &q);
        dvrk_kin::max_closure_residual(model, &data) < 1e-6
    })
}

/// `link_length` on frame `k`: its DH `a` changed by `da` (m).
pub fn length_effect(model: &Model, k: usize, da: f64) -> EffectSpec {
    EffectSpec {
        name: "link_length".into(),
        joint: None,
        link: Some(FrameRef::Name(model.frames[k].name.clone())),
        actuator: None,
        parameters: BTreeMap::from([("a".into(), da), ("d".into(), 0.0)]),
        source: String::new(),
    }
}

/// True when frame `a` is `k` or one of its ancestors.
fn is_ancestor(model: &Model, a: usize, k: usize) -> bool {
    let mut at = Some(k);
    while let Some(x) = at {
        if x == a {
            return true;
        }
        at = model.frames[x].parent;
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Consistent channels: the precision-weighted mean and summed ratio; inconsistent ones: the
    /// interval widened by the scale factor to reach both values; a bound holds.
    #[test]
    fn combined_evidence_weighs_and_widens() {
        let a = Evidence { value: 1.0, variance: 0.01, stat: 100.0 };
        let b = Evidence { value: 1.1, variance: 0.04, stat: 30.0 };
        let c = combine(&a, &b, None);
        assert!((c.value - 1.02).abs() < 1e-12 && (c.variance - 0.008).abs() < 1e-12, "{c:?}");
        // Each channel pays for the move: 0.02^2 / 0.01 + 0.08^2 / 0.04.
        assert!((c.stat - (130.0 - 0.04 - 0.16)).abs() < 1e-9);
        let far = Evidence { value: 2.0, variance: 0.01, stat: 50.0 };
        let d = combine(&a, &far, None);
        // chi2 = 1 / 0.02 = 50: the variance 0.005 x 50, the half-width 1.96 x 0.5 reaches both.
        assert!((d.value - 1.5).abs() < 1e-12 && (d.variance - 0.25).abs() < 1e-12, "{d:?}");
        let e = combine(&Evidence { value: -1.0, variance: 0.01, stat: 0.0 }, &Evidence { value: -0.5, variance: 0.01, stat: 0.0 }, Some(0.0));
        assert_eq!(e.value, 0.0);
    }
}
