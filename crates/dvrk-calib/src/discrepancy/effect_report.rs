//! A scored candidate as a model-file effect and as the report's entry: its parameters and
//! intervals, what it explains per joint, and for a payload where it sits and which placements on
//! other bodies explain as much.

use super::candidates::{self, Candidate, Table};
use super::fit::Fitter;
use super::payload::{Normal, Placement};
use super::profiles::{profiled_name, profiled_spec};
use super::report::{EffectReport, JointExplained};
use super::scoring::{Score, Scored};
use super::signals::{add, residual, rms, Prepared};
use crate::error::Result;
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::Model;
use std::collections::BTreeMap;

/// A scored effect's model-file form (a kinematic-channel-only one's as that channel gives it).
pub(super) fn spec_of(model: &Model, e: &Scored) -> EffectSpec {
    match &e.kinematic {
        Some((spec, _)) => spec.clone(),
        None => fitted_spec(model, e.candidate, e.kind, e.joint, &e.score),
    }
}

/// The torque channel's fit `s` of candidate `c` (a profile's, of `kind` on `joint`, without one).
fn fitted_spec(model: &Model, c: Option<&Candidate>, kind: EffectKind, joint: Option<usize>, s: &Score) -> EffectSpec {
    match c {
        Some(c) => c.spec(model, &s.x, s.profiled, "dvrk discrepancy"),
        None => profiled_spec(model, kind, joint, s.x[0]),
    }
}

/// The 95% intervals of the torque channel's fit `s`, by parameter name.
fn intervals(c: Option<&Candidate>, kind: EffectKind, s: &Score) -> BTreeMap<String, [f64; 2]> {
    let mut m = BTreeMap::new();
    match c {
        None => {
            m.insert(profiled_name(kind).into(), s.ci[0]);
        }
        Some(c) if matches!(c.kind, EffectKind::Spring | EffectKind::ActuatorSpring) => {
            m.insert("k".into(), s.ci[0]);
        }
        Some(c) if matches!(c.kind, EffectKind::PayloadMass) => {
            m.insert("mass".into(), s.ci[0]);
        }
        Some(c) => {
            for ((n, ci), a) in c.names.iter().zip(&s.ci).zip(&c.at) {
                m.insert(n.clone(), [ci[0] + a, ci[1] + a]);
            }
        }
    }
    m
}

/// What the report of an effect needs of the analysis.
pub(super) struct EffectReporter<'a> {
    pub(super) model: &'a Model,
    pub(super) prep: &'a Prepared,
    /// The prediction (the residual's).
    pub(super) base: &'a Table,
    pub(super) fit: &'a Fitter<'a>,
    /// The nominal residual.
    pub(super) r: &'a Table,
    /// Every scored candidate (a payload's equivalents are among them).
    pub(super) scored: &'a [Scored<'a>],
    /// Each payload body's normal equations ([`super::payload::candidates`]).
    pub(super) normals: &'a BTreeMap<String, Normal>,
    /// Per joint, the band RMS of the residual before (the nuisance refitted) and of the
    /// measured effort, on the training part.
    pub(super) before_rms: &'a [f64],
    pub(super) effort_rms: &'a [f64],
    /// Where each payload's body turns about (m), and the spread of that point; a translating
    /// body's crank (m); its family ([`super::payload_family::family`]).
    pivots: BTreeMap<String, Pivot>,
    ambiguity_bic: f64,
    /// m/s^2, the base frame's.
    gravity: nalgebra::Vector3<f64>,
    /// Every frame's pose at the sampled recorded configurations
    /// ([`super::payload_family::sampled_frames`]; none without a payload candidate): what the
    /// pivots, the cranks and the family's gravity-equivalent placements are found over.
    frames: Vec<Vec<dvrk_kin::Pose>>,
}

/// How a payload's body moves (see [`EffectReporter::pivots`]).
struct Pivot {
    body: usize,
    point: [f64; 3],
    rms: f64,
    crank: Option<f64>,
    family: Option<Vec<usize>>,
    /// The family's last joint and the axis (unit, link frame) the body turns about with it.
    axis: Option<(usize, [f64; 3])>,
}

impl<'a> EffectReporter<'a> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        model: &'a Model,
        prep: &'a Prepared,
        base: &'a Table,
        fit: &'a Fitter<'a>,
        r: &'a Table,
        scored: &'a [Scored<'a>],
        normals: &'a BTreeMap<String, Normal>,
        rms: (&'a [f64], &'a [f64]),
        ambiguity_bic: f64,
        gravity: nalgebra::Vector3<f64>,
    ) -> Result<Self> {
        let mut pivots = BTreeMap::new();
        let home = model.home();
        // Every body with a load's normal equations: a family member that is no candidate of
        // its own (see `super::payload::candidates`) is still an equivalent placement.
        let any = scored.iter().any(|e| e.kind == EffectKind::PayloadMass);
        let frames = if any { super::payload_family::sampled_frames(model, &prep.q)? } else { Vec::new() };
        for link in normals.keys().filter(|_| any).cloned() {
            if let Some(f) = model.frames.iter().position(|f| f.name == link) {
                let body = model.frames[f].body;
                let (point, rms) = super::payload::pivot(model, body, &frames);
                let crank = super::payload_family::crank(model, body, &frames);
                let family = super::payload_family::family(model, body, &home)?;
                let axis = match family.as_ref().and_then(|f| f.last()) {
                    Some(&j) if crank.is_none() => super::payload_family::turning_axis(model, body, j, &home)?.map(|a| (j, a)),
                    _ => None,
                };
                pivots.insert(link, Pivot { body, point, rms, crank, family, axis });
            }
        }
        Ok(EffectReporter { model, prep, base, fit, r, scored, normals, before_rms: rms.0, effort_rms: rms.1, pivots, ambiguity_bic, gravity, frames })
    }

    /// Per joint, what an effect's effort `effect` (its nuisance's share included) explains.
    fn explained(&self, effect: &Table) -> Vec<JointExplained> {
        let mut with = self.base.clone();
        add(&mut with, effect);
        let f1 = residual(self.prep, &with, true);
        let tr = 0..self.prep.split;
        self.prep
            .active
            .iter()
            .map(|&k| {
                let (b, a) = (self.before_rms[k], rms(&f1, k, tr.clone()));
                JointExplained { joint: self.model.joints[k].name.clone(), unit: self.model.joints[k].effort_unit(), rms_before: b, rms_after: a, share_of_effort: (b - a) / self.effort_rms[k].max(1e-300) }
            })
            .collect()
    }

    /// The payloads on other bodies that explain as much as `best`'s (within the ambiguity,
    /// each at its own best placement), and on every other body of its family
    /// ([`super::payload_family`]) the placement whose gravity loads the joints as the named
    /// `mass` (kg) at `place` (m) does, each with how far behind the named one it is: what the
    /// load's inertia says against it, its gravity being the same.
    fn equivalents(&self, best: &Scored, mass: f64, place: [f64; 3]) -> Vec<Placement> {
        let family = |link: &str| self.pivots.get(link).and_then(|p| p.family.as_ref());
        let named = best.candidate.and_then(|c| c.link.clone()).unwrap_or_default();
        let own = family(&named);
        let others = || self.scored.iter().filter(|e| e.kind == EffectKind::PayloadMass && e.label != best.label);
        let mut out: Vec<Placement> = others().filter(|e| !e.score.at_edge && e.score.delta_bic > best.score.delta_bic - self.ambiguity_bic).filter_map(|e| self.own_fit(e, best)).collect();
        let (Some(own), Some(pn), Some(normal)) = (own, self.pivots.get(&named), self.normals.get(&named)) else { return out };
        let gained = super::payload::gain(normal, mass, &place);
        let upper = EffectKind::PayloadMass.range("mass").map_or(20.0, |r| r[1]);
        let reach = EffectKind::PayloadMass.range("x").map_or(1.0, |r| r[1]);
        let listed: Vec<String> = out.iter().map(|p| p.link.clone()).collect();
        for (link, p) in self.pivots.iter().filter(|(l, p)| **l != named && p.family.as_ref() == Some(own) && !listed.contains(l)) {
            let Some(normal) = self.normals.get(link) else { continue };
            let Some(eq) = super::payload_family::gravity_equivalent(self.model, &self.gravity, pn.body, mass, place, p.body, p.point, &self.frames) else { continue };
            if eq.mismatch > GRAVITY_MISMATCH || eq.mass > upper || eq.place.iter().any(|x| x.abs() >= reach) {
                continue;
            }
            let behind = (gained - super::payload::gain(normal, eq.mass, &eq.place)) / best.score.chi2_unit.max(1e-300);
            out.push(self.placement(link.clone(), eq.mass, eq.place, best.score.delta_bic - behind, behind));
        }
        // A member with no such placement whose own best load the recording supports (above
        // the ambiguity threshold): that load, with how far behind it is (even at a bound of
        // its place: it then stands in for part of the load only).
        for e in others().filter(|e| e.score.delta_bic > self.ambiguity_bic) {
            if let Some(p) = self.own_fit(e, best).filter(|p| family(&p.link) == Some(own) && !out.iter().any(|q| q.link == p.link)) {
                out.push(p);
            }
        }
        // Ties (the same load on bodies that turn alike) in the links' order.
        out.sort_by(|a, b| ((a.behind_bic * 1e3).round()).total_cmp(&(b.behind_bic * 1e3).round()).then_with(|| a.link.cmp(&b.link)));
        out
    }

    /// Scored payload `e` at its own best placement, with how far behind `best` it is.
    fn own_fit(&self, e: &Scored, best: &Scored) -> Option<Placement> {
        let c = e.candidate?;
        Some(self.placement(c.link.clone()?, e.score.x[0], payload_place(c, &e.score.x), e.score.delta_bic, best.score.delta_bic - e.score.delta_bic))
    }

    /// `mass` (kg) at `position` (m) on `link` as the report's placement.
    fn placement(&self, link: String, mass: f64, position: [f64; 3], delta_bic: f64, behind_bic: f64) -> Placement {
        let first_moment = self.pivots.get(&link).map_or(f64::NAN, |p| mass * p.crank.unwrap_or_else(|| (nalgebra::Vector3::from(position) - nalgebra::Vector3::from(p.point)).norm()));
        Placement { link, mass, position, delta_bic, first_moment, behind_bic }
    }

    /// Payload candidate `c`'s fit without each of the recording's [`super::nuisance::FOLDS`]
    /// parts in turn: per part its mass (kg) and first moment's vector about `pivot` (kg m,
    /// `m (at - pivot) + (m dx, m dy, m dz)`: linear in the fit, defined for any mass); `None`
    /// without the candidate's columns.
    fn fold_first_moments(&self, c: &Candidate, pivot: &[f64; 3]) -> Option<Vec<(f64, nalgebra::Vector3<f64>)>> {
        if c.columns.len() != 4 {
            return None;
        }
        let fits = self.fit.fold_fits(self.r, &c.columns, &c.bounds()).ok()?;
        Some(fits.iter().flatten().map(|x| (x[0], nalgebra::Vector3::from_fn(|k, _| x[0] * (c.at[k + 1] - pivot[k]) + x[k + 1]))).collect())
    }

    /// The family's sentence: what its members share, which of them the recording cannot tell
    /// from the named body, and which the inertia argues against and how strongly.
    fn family_note(&self, link: &str, equivalent: &[Placement]) -> Option<String> {
        let own = self.pivots.get(link)?.family.as_ref()?;
        let members: Vec<&Placement> = equivalent.iter().filter(|p| self.pivots.get(&p.link).and_then(|q| q.family.as_ref()) == Some(own)).collect();
        let joints: Vec<&str> = own.iter().map(|&j| self.model.joints[j].name.as_str()).collect();
        let (tied, behind): (Vec<&Placement>, Vec<&Placement>) = members.iter().partition(|p| p.behind_bic < self.ambiguity_bic);
        let mut note = format!("a load on any body that moves with {} alone loads them through gravity alike up to its placement", joints.join(" and "));
        if members.is_empty() {
            note += &format!("; no other body of them carries one that explains the recording: {link} only");
        }
        if !tied.is_empty() {
            let names: Vec<&str> = tied.iter().map(|p| p.link.as_str()).collect();
            note += &format!("; one on {} explains it as well (the recording cannot tell them from {link})", names.join(", "));
        }
        if !behind.is_empty() {
            let names: Vec<String> = behind.iter().map(|p| format!("{} (first moment {:.4} kg m, delta BIC {:.1} behind)", p.link, p.first_moment, p.behind_bic)).collect();
            note += &format!("; {link} is preferred to {}: what the load's inertia and the place its gravity acts at say", names.join(", "));
        }
        Some(note)
    }

    /// A scored candidate as a model-file effect and as the report's entry; `effect`: its fitted
    /// effort where the caller has it already (else rebuilt).
    pub(super) fn report(&self, e: &Scored, effect: Option<&Table>) -> Result<(EffectSpec, EffectReport)> {
        let s = &e.score;
        let (mut spec, ci95) = match &e.kinematic {
            Some((spec, ci)) => (spec.clone(), ci.clone()),
            None => (fitted_spec(self.model, e.candidate, e.kind, e.joint, s), intervals(e.candidate, e.kind, s)),
        };
        let payload = match e.candidate {
            Some(c) if c.kind == EffectKind::PayloadMass => c.link.as_ref().and_then(|l| Some((l, self.pivots.get(l)?, self.normals.get(l)?))).map(|(link, pivot, normal)| {
                let (pv, spread, crank) = (&pivot.point, &pivot.rms, pivot.crank);
                let place = payload_place(c, &s.x);
                let mut pr = super::payload::profile(normal, place, s.x[0].max(1e-6), *pv, s.chi2_unit);
                // A translating body's place does not move its gravity: the mass's own interval
                // (the fit's) is its first moment's, over the crank.
                if crank.is_some() {
                    pr.mass = [pr.mass[0].min(s.ci[0][0]), pr.mass[1].max(s.ci[0][1])];
                }
                // The first moment's spread over the recording's parts holds what the
                // likelihood's interval does not: a model error the weight's signature shares.
                let folds = self.fold_first_moments(c, pv).unwrap_or_default();
                if let Some(half) = jackknife_half(&folds.iter().map(|(m, v)| crank.map_or(v.norm(), |r| m * r)).collect::<Vec<_>>()) {
                    match crank {
                        Some(r) => {
                            let m = s.x[0];
                            pr.mass = [pr.mass[0].min(m - half / r), pr.mass[1].max(m + half / r)];
                        }
                        None => {
                            let moment = s.x[0] * (nalgebra::Vector3::from(place) - nalgebra::Vector3::from(*pv)).norm();
                            pr.first_moment = [pr.first_moment[0].min(moment - half), pr.first_moment[1].max(moment + half)];
                        }
                    }
                }
                // A mass at the vocabulary's bound: the lightest placement within the interval
                // stands for it, in the report and the model file.
                let upper = EffectKind::PayloadMass.range("mass").map_or(20.0, |r| r[1]);
                let bounded = s.x[0] >= upper * (1.0 - 1e-9) && pr.mass[0] < s.x[0];
                let equivalent = match bounded {
                    true => self.equivalents(e, pr.mass[0], pr.lightest_place),
                    false => self.equivalents(e, s.x[0], place),
                };
                let family = self.family_note(link, &equivalent);
                let report = if bounded {
                    let (mass, at) = (pr.mass[0], pr.lightest_place);
                    spec.parameters.insert("mass".into(), mass);
                    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
                        spec.parameters.insert((*axis).into(), at[k]);
                    }
                    let unbounded = (s.x[0], (nalgebra::Vector3::from(place) - nalgebra::Vector3::from(*pv)).norm());
                    super::payload::report(at, mass, &pr, *pv, *spread, crank, equivalent, Some(unbounded))
                } else {
                    super::payload::report(place, s.x[0], &pr, *pv, *spread, crank, equivalent, None)
                };
                // About the family's last joint's axis (the pitch's through the remote centre):
                // what that joint's gravity fixes; a translating body's is its crank's.
                let joint = pivot.family.as_ref().and_then(|f| f.last()).map(|&j| self.model.joints[j].name.clone());
                let axis_moment = match (crank, pivot.axis) {
                    (Some(_), _) => Some((report.first_moment, report.first_moment_ci95)),
                    (None, Some((_, a))) => {
                        let a = nalgebra::Vector3::from(a);
                        let off_axis = |v: &nalgebra::Vector3<f64>| (v - a * a.dot(v)).norm();
                        let v = nalgebra::Vector3::from(report.position) - nalgebra::Vector3::from(*pv);
                        let (d, d_axis) = (v.norm(), off_axis(&v));
                        let moment = report.mass * d_axis;
                        // The pivot interval scaled to the axis, widened to the axis' jackknife.
                        let scale = if d > 0.0 { d_axis / d } else { 1.0 };
                        let mut ci = [report.first_moment_ci95[0] * scale, report.first_moment_ci95[1] * scale];
                        if let Some(half) = jackknife_half(&folds.iter().map(|(_, v)| off_axis(v)).collect::<Vec<_>>()) {
                            ci = [ci[0].min(moment - half), ci[1].max(moment + half)];
                        }
                        Some((moment, ci))
                    }
                    (None, None) => None,
                }
                .filter(|_| joint.is_some());
                super::payload::PayloadReport {
                    family,
                    axis_joint: axis_moment.and(joint),
                    axis_first_moment: axis_moment.map(|m| m.0),
                    axis_first_moment_ci95: axis_moment.map(|m| m.1),
                    ..report
                }
            }),
            _ => None,
        };
        let report = EffectReport {
            name: spec.name.clone(),
            joint: spec.joint.clone(),
            link: spec.link.as_ref().map(|l| l.to_string()),
            actuator: spec.actuator,
            parameters: spec.parameters.clone(),
            ci95,
            delta_bic: s.delta_bic,
            p_value: s.p_value,
            payload,
            explained: match (&e.kinematic, effect) {
                (Some(_), _) => Vec::new(),
                (None, Some(t)) => self.explained(t),
                (None, None) => self.explained(&e.efforts(self.fit, self.r)?.0),
            },
        };
        Ok((spec, report))
    }
}

/// The place (m, link frame) of payload candidate `c`'s fit `x`: where it is a point mass
/// ([`candidates::payload_at`]), else the place it was linearised at.
fn payload_place(c: &Candidate, x: &[f64]) -> [f64; 3] {
    candidates::payload_at(&c.at, x).unwrap_or([c.at[1], c.at[2], c.at[3]])
}

/// How much of the named load's gravity (relative RMS of its potential over the recording) a
/// family member's closest placement may leave unmatched and still be listed (with how far
/// behind it is): a load on a body that only translates has its first moment along its crank,
/// one on a body the insertion moves follows the insertion too; beyond this the body carries
/// no equivalent load.
const GRAVITY_MISMATCH: f64 = 0.2;

/// The half-width of a 95% interval of a value from its estimates without each of the
/// recording's parts (the jackknife: `(k - 1) / k` times their spread, Student's t at `k - 1`);
/// `None` from fewer than three.
fn jackknife_half(values: &[f64]) -> Option<f64> {
    let k = values.len();
    if k < 3 {
        return None;
    }
    let mean = values.iter().sum::<f64>() / k as f64;
    let var = (k - 1) as f64 / k as f64 * values.iter().map(|m| (m - mean).powi(2)).sum::<f64>();
    Some(student_t975(k - 1) * var.sqrt())
}

/// Student's t 97.5% point at `dof` degrees of freedom (2 to 9; the normal's 1.96 beyond).
fn student_t975(dof: usize) -> f64 {
    const T: [f64; 8] = [4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262];
    dof.checked_sub(2).and_then(|i| T.get(i)).copied().unwrap_or(1.96)
}
