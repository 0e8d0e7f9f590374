//! A candidate effect of the torque channel: what it is (an effect of the vocabulary on a joint,
//! link or actuator), its signature columns per unit of each parameter, its bounds, and how its
//! fit is written as a model-file effect; and the column helpers every family of candidates
//! builds with ([`super::candidates`], [`super::friction_terms`], [`super::payload`]).

use super::signals::Prepared;
use super::signature::Signature;
use super::stats::Bounds;
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::spec::FrameRef;
use std::collections::BTreeMap;

/// A candidate: an effect of the vocabulary on one joint or link, and its signature.
#[derive(Debug, Clone)]
pub struct Candidate {
    pub kind: EffectKind,
    pub joint: Option<usize>,
    /// Frame name of a link effect.
    pub link: Option<String>,
    /// The actuator (0-based column of the coupling) of an actuator effect.
    pub actuator: Option<usize>,
    /// Fitted parameters (their names), each with its signature column.
    pub names: Vec<String>,
    pub columns: Vec<Signature>,
    /// The model's own value of each parameter (0: the effect is absent): a fit is a change
    /// from it, reported as the new value. A payload's: 0 and the place (m) its columns are
    /// linearised at ([`payload_at`]).
    pub at: Vec<f64>,
    /// The parameters' physical ranges where the model sets them (a coupling entry's:
    /// [`dvrk_kin::effects::coupling_error_range`]); `None`: the vocabulary's.
    pub range: Option<Vec<[f64; 2]>>,
    /// The joint whose effort the effect changes most (for the effect size).
    pub focus: usize,
    /// A nonlinear parameter profiled on a grid: its name and, per grid value, the columns that
    /// replace [`Candidate::columns`] (the fit keeps the best).
    pub profile: Option<(&'static str, Vec<(f64, Vec<Signature>)>)>,
    /// Parameters the effect is written with as they are (a Stribeck term's `fc` 0 and the
    /// smoothing its columns were taken at, [`super::friction_terms`]).
    pub fixed: Vec<(&'static str, f64)>,
}

impl Candidate {
    /// `kind on joint`, `kind on link`, `kind on actuator N` (1-based), or `coupling_error dRC`;
    /// a Coulomb friction's other terms and a cross spring name their parameter (`coulomb_friction
    /// fs on outer_yaw`, `actuator_cross_spring k6 on actuator 5`).
    pub fn label(&self, model: &dvrk_kin::Model) -> String {
        let kind = match self.names.first().map(String::as_str) {
            Some(term) if self.kind == EffectKind::ActuatorCrossSpring || (matches!(self.kind, EffectKind::CoulombFriction | EffectKind::ActuatorCoulombFriction) && term != "fc") => format!("{} {term}", self.kind.name()),
            _ => self.kind.name().to_string(),
        };
        match (&self.joint, &self.link) {
            (Some(j), _) => format!("{kind} on {}", model.joints[*j].name),
            (_, Some(l)) => format!("{kind} on {l}"),
            _ if self.actuator.is_some() => format!("{kind} on actuator {}", self.actuator.unwrap_or(0) + 1),
            // One candidate per entry of the coupling matrix.
            _ if self.kind == EffectKind::CouplingError => format!("{} {}", self.kind.name(), self.names.join(" ")),
            _ => self.kind.name().to_string(),
        }
    }

    /// The bounds of each fitted change from [`Candidate::at`]: the parameter's physical range
    /// ([`Candidate::range`], else the vocabulary's; a product such as a payload's `mx` or a
    /// spring's `k_rest` is free).
    pub fn bounds(&self) -> Vec<Bounds> {
        let within = |r: Option<[f64; 2]>, at: f64| r.map_or(Bounds::FREE, |[lo, hi]| Bounds::within(lo - at, hi - at));
        match &self.range {
            Some(ranges) => ranges.iter().zip(&self.at).map(|(r, at)| within(Some(*r), *at)).collect(),
            None => self.names.iter().zip(&self.at).map(|(n, at)| within(self.kind.range(n), *at)).collect(),
        }
    }

    /// The model-file parameters of fitted values `x` (in [`Candidate::names`] order) and the
    /// profiled parameter's chosen value.
    pub fn parameters(&self, x: &[f64], profiled: Option<f64>) -> BTreeMap<String, f64> {
        let mut p: BTreeMap<String, f64> = self.fixed.iter().map(|(n, v)| ((*n).to_string(), *v)).collect();
        if let (Some((name, _)), Some(v)) = (&self.profile, profiled) {
            p.insert((*name).into(), v);
        }
        match self.kind {
            EffectKind::Spring | EffectKind::ActuatorSpring => {
                p.insert("k".into(), x[0]);
                // The rest position is only defined where there is a spring.
                p.insert("rest".into(), if x[0] > 1e-6 { x[1] / x[0] } else { 0.0 });
            }
            EffectKind::JointCompliance => {
                p.insert("stiffness".into(), if x[0] > 0.0 { 1.0 / x[0] } else { 1e8 });
            }
            EffectKind::PayloadMass => {
                p.insert("mass".into(), x[0]);
                // The position is only defined where there is a mass (1 g and more).
                let at = payload_at(&self.at, x).unwrap_or([0.0; 3]);
                for (c, v) in ["x", "y", "z"].iter().zip(at) {
                    p.insert((*c).into(), v);
                }
            }
            _ => {
                for ((n, v), a) in self.names.iter().zip(x).zip(&self.at) {
                    p.insert(n.clone(), a + v);
                }
            }
        }
        p
    }

    /// Lets its signature columns go (the profile's grid too), keeping what it is: a candidate
    /// the report will not show needs only its fit.
    pub fn drop_columns(&mut self) {
        self.columns = Vec::new();
        if let Some((_, grid)) = &mut self.profile {
            grid.iter_mut().for_each(|g| g.1 = Vec::new());
        }
    }

    /// The effect as a model file writes it.
    pub fn spec(&self, model: &dvrk_kin::Model, x: &[f64], profiled: Option<f64>, source: &str) -> EffectSpec {
        EffectSpec {
            name: self.kind.name().into(),
            joint: self.joint.map(|j| model.joints[j].name.clone()),
            link: self.link.clone().map(FrameRef::Name),
            actuator: self.actuator.map(|a| a + 1),
            parameters: self.parameters(x, profiled),
            source: source.into(),
        }
    }
}

pub(super) fn names(n: &[&str]) -> Vec<String> {
    n.iter().map(|s| s.to_string()).collect()
}

/// A joint-local column: `f(sample)` on joint `j`, 0 elsewhere.
pub(super) fn local(prep: &Prepared, nq: usize, j: usize, f: impl Fn(usize) -> f64) -> Signature {
    Signature::on_joint(nq, j, (0..prep.t.len()).map(f).collect())
}

/// A per-actuator signal `a(sample)` as joint efforts: `w_j a` on each joint of `w`.
pub(super) fn spread(nq: usize, w: &[(usize, f64)], a: &[f64]) -> Signature {
    let mut out = Signature::on_joints(nq, a.len());
    for (j, c) in w {
        out.set(*j, a.iter().map(|x| c * x).collect());
    }
    out
}

/// A payload's position (m, in its frame) from a fit `x = (m, m dx, m dy, m dz)` of a candidate
/// linearised at `at` ([`super::payload`]): `at + d`, each coordinate within the vocabulary's
/// range (+-1 m). `None` below 1 g, where the position is not defined.
pub fn payload_at(at: &[f64], x: &[f64]) -> Option<[f64; 3]> {
    let r = EffectKind::PayloadMass.range("x").unwrap_or([-1.0, 1.0]);
    (x[0] > 1e-3).then(|| std::array::from_fn(|k| (at[k + 1] + x[k + 1] / x[0]).clamp(r[0], r[1])))
}

/// The joint whose effort `column` moves most against its noise.
pub(crate) fn focus_of(prep: &Prepared, column: &Signature) -> usize {
    prep.active.iter().copied().max_by(|a, b| (column.rms(*a) / prep.noise[*a]).total_cmp(&(column.rms(*b) / prep.noise[*b]))).unwrap_or(0)
}
