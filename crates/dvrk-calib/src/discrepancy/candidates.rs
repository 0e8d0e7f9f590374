//! The candidate effects of the torque channel and their signatures, taken from the model itself:
//! the change of the model's predicted effort when the effect is added (finite differences of
//! dvrk-kin's inverse dynamics on a model compiled with the effect), per unit of each parameter.
//! Every signature is linear in its parameters here except latency, whose 1-D profile (the
//! prediction shifted in time) is scanned in [`super::workflow`].

use super::generate::with_effect;
use super::signals::{Predictor, Prepared};
use crate::error::Result;
use dvrk_kin::effects::{EffectKind, EffectSpec};
use dvrk_kin::spec::FrameRef;
use std::collections::BTreeMap;

/// `[sample][joint]` effort table (N·m, N per unit of a parameter).
pub type Table = Vec<Vec<f64>>;

/// A candidate: an effect of the vocabulary on one joint or link, and its signature.
#[derive(Debug, Clone)]
pub struct Candidate {
    pub kind: EffectKind,
    pub joint: Option<usize>,
    /// Frame name of a link effect.
    pub link: Option<String>,
    /// Fitted parameters (their names), each with its signature column and lower bound.
    pub names: Vec<&'static str>,
    pub columns: Vec<Table>,
    pub lower: Vec<Option<f64>>,
    /// The joint whose effort the effect changes most (for the effect size).
    pub focus: usize,
}

impl Candidate {
    /// `kind on joint` or `kind on link`.
    pub fn label(&self, model: &dvrk_kin::Model) -> String {
        match (&self.joint, &self.link) {
            (Some(j), _) => format!("{} on {}", self.kind.name(), model.joints[*j].name),
            (_, Some(l)) => format!("{} on {l}", self.kind.name()),
            _ => self.kind.name().to_string(),
        }
    }

    /// The model-file parameters of fitted values `x` (in [`Candidate::names`] order).
    pub fn parameters(&self, x: &[f64]) -> BTreeMap<String, f64> {
        let mut p = BTreeMap::new();
        match self.kind {
            EffectKind::Spring => {
                p.insert("k".into(), x[0]);
                // The rest position is only defined where there is a spring.
                p.insert("rest".into(), if x[0] > 1e-6 { x[1] / x[0] } else { 0.0 });
            }
            EffectKind::JointCompliance => {
                p.insert("stiffness".into(), if x[0] > 0.0 { 1.0 / x[0] } else { 1e8 });
            }
            EffectKind::PayloadMass => {
                p.insert("mass".into(), x[0]);
                for (i, c) in ["x", "y", "z"].iter().enumerate() {
                    // The position is only defined where there is a mass (1 g and more).
                    p.insert((*c).into(), if x[0] > 1e-3 { x[i + 1] / x[0] } else { 0.0 });
                }
            }
            _ => {
                for (n, v) in self.names.iter().zip(x) {
                    p.insert((*n).into(), *v);
                }
            }
        }
        p
    }

    /// The effect as a model file writes it.
    pub fn spec(&self, model: &dvrk_kin::Model, x: &[f64], source: &str) -> EffectSpec {
        EffectSpec {
            name: self.kind.name().into(),
            joint: self.joint.map(|j| model.joints[j].name.clone()),
            link: self.link.clone().map(FrameRef::Name),
            parameters: self.parameters(x),
            source: source.into(),
        }
    }
}

/// A joint-local column: `f(sample)` on joint `j`, 0 elsewhere.
fn local(prep: &Prepared, nq: usize, j: usize, f: impl Fn(usize) -> f64) -> Table {
    (0..prep.t.len())
        .map(|i| {
            let mut r = vec![0.0; nq];
            r[j] = f(i);
            r
        })
        .collect()
}

fn diff(a: &Table, b: &Table, h: f64) -> Table {
    a.iter().zip(b).map(|(x, y)| x.iter().zip(y).map(|(u, v)| (u - v) / h).collect()).collect()
}

/// RMS over samples of column `j` of a table.
fn rms_joint(t: &Table, j: usize) -> f64 {
    (t.iter().map(|r| r[j] * r[j]).sum::<f64>() / t.len().max(1) as f64).sqrt()
}

/// Frames a payload is tried on: the instrument's bodies (what a grasped object or a heavier
/// tool loads), those the model has.
pub const PAYLOAD_FRAMES: [&str; 3] = ["main_insertion", "tool_roll", "tool_yaw"];

/// Every candidate for the joints `prep.active`, with `base` the nominal prediction.
pub fn build(predictor: &Predictor, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3], prep: &Prepared, base: &Table) -> Result<Vec<Candidate>> {
    let model = &predictor.model;
    let nq = model.nq();
    let mut out = Vec::new();
    // Smoothing of the friction sign (rad/s, m/s) and of the transmission-torque sign (a fraction
    // of its spread).
    let v = 2.0 * dvrk_sim::effects::COULOMB_VELOCITY;
    for &j in &prep.active {
        out.push(Candidate { kind: EffectKind::CoulombFriction, joint: Some(j), link: None, names: vec!["fc"], columns: vec![local(prep, nq, j, |i| (prep.qd[i][j] / v).tanh())], lower: vec![Some(0.0)], focus: j });
        out.push(Candidate { kind: EffectKind::ViscousFriction, joint: Some(j), link: None, names: vec!["fv"], columns: vec![local(prep, nq, j, |i| prep.qd[i][j])], lower: vec![Some(0.0)], focus: j });
        // k (q - rest) = k q - (k rest): linear in (k, k rest).
        out.push(Candidate {
            kind: EffectKind::Spring,
            joint: Some(j),
            link: None,
            names: vec!["k", "k_rest"],
            columns: vec![local(prep, nq, j, |i| prep.q[i][j]), local(prep, nq, j, |_| -1.0)],
            lower: vec![Some(0.0), None],
            focus: j,
        });
        // The joint's true position is the reading plus the offset: the model's own sensitivity.
        let h = 1e-4;
        let spec = EffectSpec { name: "joint_offset".into(), joint: Some(model.joints[j].name.clone()), link: None, parameters: BTreeMap::from([("offset".into(), h)]), source: String::new() };
        let shifted = Predictor::new(&with_effect(model, &spec)?, arm, gravity)?.series(prep)?;
        let d = diff(&shifted, base, h);
        // Only where the offset shows (gravity or coupling load the joint).
        if rms_joint(&d, j) > 1e-6 {
            // The link-side (transmission) torque: what the model says the drive passes on.
            let link_torque: Vec<f64> = (0..prep.t.len()).map(|i| base[i][j] - arm.armature[j] * prep.qdd[i][j]).collect();
            let spread = (link_torque.iter().map(|x| x * x).sum::<f64>() / link_torque.len() as f64).sqrt().max(1e-9);
            // A compliant drive: the link trails the motor (the encoder) by c * torque.
            let compliance: Table = d.iter().zip(&link_torque).map(|(r, tq)| r.iter().map(|x| -x * tq).collect()).collect();
            // Play: the link trails by b on the side the torque pushes.
            let play: Table = d.iter().zip(&link_torque).map(|(r, tq)| r.iter().map(|x| -x * (tq / (0.02 * spread)).tanh()).collect()).collect();
            out.push(Candidate { kind: EffectKind::JointOffset, joint: Some(j), link: None, names: vec!["offset"], columns: vec![d], lower: vec![None], focus: j });
            out.push(Candidate { kind: EffectKind::JointCompliance, joint: Some(j), link: None, names: vec!["compliance"], columns: vec![compliance], lower: vec![Some(0.0)], focus: j });
            out.push(Candidate { kind: EffectKind::Backlash, joint: Some(j), link: None, names: vec!["b"], columns: vec![play], lower: vec![Some(0.0)], focus: j });
        }
    }
    // Payloads: a point mass m at (x, y, z) in the link's frame is linear in (m, m x, m y, m z)
    // up to its own small inertia m |r|^2.
    for name in PAYLOAD_FRAMES {
        if !model.frames.iter().any(|f| f.name == name) {
            continue;
        }
        let (m, s) = (0.05, 0.02);
        let at = |x: f64, y: f64, z: f64| -> Result<Table> {
            let spec = EffectSpec {
                name: "payload_mass".into(),
                joint: None,
                link: Some(FrameRef::Name(name.into())),
                parameters: BTreeMap::from([("mass".into(), m), ("x".into(), x), ("y".into(), y), ("z".into(), z)]),
                source: String::new(),
            };
            Predictor::new(&with_effect(model, &spec)?, arm, gravity)?.series(prep)
        };
        let p0 = at(0.0, 0.0, 0.0)?;
        let cm = diff(&p0, base, m);
        let cols = vec![cm.clone(), diff(&at(s, 0.0, 0.0)?, &p0, m * s), diff(&at(0.0, s, 0.0)?, &p0, m * s), diff(&at(0.0, 0.0, s)?, &p0, m * s)];
        let focus = prep.active.iter().copied().max_by(|a, b| (rms_joint(&cm, *a) / prep.noise[*a]).total_cmp(&(rms_joint(&cm, *b) / prep.noise[*b]))).unwrap_or(0);
        out.push(Candidate { kind: EffectKind::PayloadMass, joint: None, link: Some(name.into()), names: vec!["mass", "mx", "my", "mz"], columns: cols, lower: vec![Some(0.0), None, None, None], focus });
    }
    Ok(out)
}
