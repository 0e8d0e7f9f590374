//! The kinematic channel: a tracker's poses of a marker on one link against the model's forward
//! kinematics at the encoder positions, with the tracker's and the marker's placements estimated
//! as nuisance ([`super::registration`]). Candidates with a kinematic signature, each linear in
//! one parameter: a joint's encoder offset, a DH length of a link between the base and the marker,
//! a latency of the joint stream (the tracker sees the link now, the encoders late), and the
//! drives' link-side deflection: compliance (load / stiffness) and play (half the gap, on the side
//! the load pushes). Scored as the torque channel is: likelihood ratio on an effective sample
//! size, change in BIC, held-out check.

use crate::recordings::joint_log::JointLog;
use crate::recordings::marker_log::MarkerLog;
use super::registration::{pose_difference, whiten, Registration};
use super::report::{CandidateReport, EffectReport, KinematicReport};
use super::signals::Prepared;
use super::stats::{chi2_sf, effective_fraction};
use crate::error::{CalibError, Result};
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::{compute_frame_placements, Data, FrameRef, Model, Pose};
use nalgebra::{DVector, Vector6};
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
        matches!(self.kind, EffectKind::Latency | EffectKind::JointCompliance | EffectKind::Backlash).then_some(0.0)
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
            self.find(EffectKind::from_name(&e.name)?, joint, link.as_deref())
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
}

/// Linear interpolation of `table[sample][k]` (sampled at `t`) at time `x`, held at the ends.
fn interp(t: &[f64], table: &[Vec<f64>], x: f64, out: &mut [f64]) {
    let i = t.partition_point(|v| *v <= x).clamp(1, t.len() - 1);
    let w = ((x - t[i - 1]) / (t[i] - t[i - 1])).clamp(0.0, 1.0);
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
    // The model's own stream and drive effects (a model from an earlier round has them).
    let latency: f64 = model.effects.iter().filter(|e| e.kind == EffectKind::Latency).map(|e| e.get("seconds")).sum();
    let mut deflect: Vec<(usize, f64, f64)> = Vec::new();
    for e in &model.effects {
        match (e.kind, e.joint) {
            (EffectKind::JointCompliance, Some(j)) => deflect.push((j, 1.0 / e.get("stiffness"), 0.0)),
            (EffectKind::Backlash, Some(j)) => deflect.push((j, 0.0, e.get("b"))),
            _ => {}
        }
    }
    let n = keep.len();
    let (mut q, mut qd, mut load) = (vec![vec![0.0; nq]; n], vec![vec![0.0; nq]; n], vec![vec![0.0; nq]; n]);
    let mut qdd = vec![0.0; nq];
    for (s, &m) in keep.iter().enumerate() {
        let t = mk.t[m];
        interp(&i.log.t, &i.log.position, t + latency, &mut q[s]);
        interp(&prep.t, &prep.qd, t, &mut qd[s]);
        interp(&prep.t, &prep.effort, t, &mut load[s]);
        interp(&prep.t, &prep.qdd, t, &mut qdd);
        for k in 0..nq {
            load[s][k] -= i.armature.get(k).copied().unwrap_or(0.0) * qdd[k];
        }
    }
    // Play's side: the sign of the drive's load, smoothed over a few percent of its RMS.
    let load_scale: Vec<f64> = (0..nq).map(|k| 0.03 * (load.iter().map(|l| l[k] * l[k]).sum::<f64>() / n as f64).sqrt().max(1e-9)).collect();
    for (j, c, b) in &deflect {
        for s in 0..n {
            q[s][*j] -= c * load[s][*j] + b * (load[s][*j] / load_scale[*j]).tanh();
        }
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
    // (kind, joint, link, parameter, column, lower bound).
    let mut cands: Vec<(EffectKind, Option<usize>, Option<String>, &'static str, DVector<f64>, Option<f64>)> = Vec::new();
    let seen = |c: &DVector<f64>| c.norm() > 1e-9 * (n as f64).sqrt();
    let per_sample = |j: usize, g: &dyn Fn(usize) -> f64| -> DVector<f64> { DVector::from_fn(6 * n, |row, _| dq[j][row] * g(row / 6)) };
    let mut lat = DVector::zeros(6 * n);
    for &j in &prep.active {
        if !seen(&dq[j]) {
            continue;
        }
        lat += per_sample(j, &|s| qd[s][j]);
        cands.push((EffectKind::JointOffset, Some(j), None, "offset", dq[j].clone(), None));
        cands.push((EffectKind::JointCompliance, Some(j), None, "compliance", per_sample(j, &|s| -load[s][j]), Some(0.0)));
        cands.push((EffectKind::Backlash, Some(j), None, "b", per_sample(j, &|s| -(load[s][j] / load_scale[j]).tanh()), Some(0.0)));
    }
    cands.push((EffectKind::Latency, None, None, "seconds", lat, Some(0.0)));
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
            cands.push((EffectKind::LinkLength, None, Some(name), "a", col, None));
        }
    }
    // Fit each with the registration refitted next to it: project the registration out.
    let rows_t = 6 * split;
    let nt = nuis.rows(0, rows_t).into_owned();
    let qr = nt.clone().qr();
    let qm = qr.q();
    let project = |v: &DVector<f64>| -> DVector<f64> {
        let vt = v.rows(0, rows_t).into_owned();
        &vt - &qm * (qm.transpose() * &vt)
    };
    let nuis_coef = |v: &DVector<f64>| -> DVector<f64> { qr.r().solve_upper_triangular(&(qm.transpose() * v.rows(0, rows_t))).unwrap_or_else(|| DVector::zeros(12)) };
    let r_perp = project(&r);
    let rss0 = r_perp.norm_squared();
    let rows_h = 6 * (n - split);
    // A residual's held-out rows once the registration is corrected as its fitted rows ask.
    let held = |e: &DVector<f64>| -> DVector<f64> { e.rows(rows_t, rows_h) - nuis.rows(rows_t, rows_h) * nuis_coef(e) };
    let r_h0 = held(&r);
    let series = |e: &DVector<f64>, rows: usize| -> Vec<Vec<f64>> { (0..6).map(|a| (0..rows / 6).map(|s| e[6 * s + a]).collect()).collect() };
    let norm_rms = |e: &DVector<f64>| (e.norm_squared() / e.len().max(1) as f64).sqrt();
    let frac0 = effective_fraction(&series(&r_perp, rows_t));
    let mut scores = Vec::new();
    for (kind, joint, link, parameter, col, lower) in cands {
        let c_perp = project(&col);
        let cc = c_perp.norm_squared();
        // What the registration absorbs almost whole is not identifiable from this tracker.
        if cc <= 1e-6 * col.rows(0, rows_t).norm_squared() {
            continue;
        }
        let mut theta = c_perp.dot(&r_perp) / cc;
        if let Some(lo) = lower {
            theta = theta.max(lo);
        }
        let e1 = &r_perp - &c_perp * theta;
        let rss1 = e1.norm_squared();
        let frac = effective_fraction(&series(&e1, rows_t));
        let n_eff = rows_t as f64 * frac;
        let stat = (n_eff * (rss0 / rss1.max(1e-300)).ln()).max(0.0);
        let variance = rss1 / (rows_t as f64 - 13.0).max(1.0) / cc / frac;
        // Held out: the registration (fitted with the candidate) and the candidate carried over.
        let e_h1 = held(&(&r - &col * theta));
        let stat_h = (rows_h as f64 * frac0 * (r_h0.norm_squared() / e_h1.norm_squared().max(1e-300)).ln()).max(0.0);
        scores.push(KinematicScore {
            kind,
            joint,
            link,
            parameter,
            value: theta,
            variance,
            stat,
            delta_bic: stat - n_eff.ln(),
            p_value: if stat > 0.0 { chi2_sf(stat, 1) } else { 1.0 },
            heldout_p: chi2_sf(stat_h, 1),
            effect_to_noise: norm_rms(&(&c_perp * theta)),
            rms_after: [norm_rms(&e1), norm_rms(&e_h1)],
        });
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
        rms_before: [norm_rms(&r_perp), norm_rms(&r_h0)],
        candidates: scores,
    })
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
