//! What an identification reports: effects grouped by the vocabulary of the effects issue, the
//! bodies' identified inertials, the JSON summary of `dvrk identify`, and the output file.

use super::problem::{EffectTerm, Param};
use super::Identification;
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::Model;
use serde::Serialize;
use serde_json::{json, Map, Value};

/// One effect of one channel, named from the effects vocabulary.
#[derive(Debug, Clone, Serialize)]
pub struct EffectEstimate {
    /// `coulomb_friction` (fc, fo), `viscous_friction` (fv), `spring` (k), `armature` (im).
    pub name: &'static str,
    /// The recorded channel (joint, or `<joint> actuator` for the tool's actuator channels).
    pub joint: String,
    /// Parameter values (N·m or N; N·m s/rad or N s/m; kg m^2 or kg; N·m/rad or N/m).
    pub parameters: Map<String, Value>,
    /// Their posterior standard deviations.
    pub std: Map<String, Value>,
}

fn effect_name(term: EffectTerm) -> &'static str {
    match term {
        EffectTerm::Coulomb | EffectTerm::Offset => "coulomb_friction",
        EffectTerm::Viscous => "viscous_friction",
        EffectTerm::Armature => "armature",
        EffectTerm::Spring => "spring",
        EffectTerm::CableLinear | EffectTerm::CableQuadratic | EffectTerm::CableCubic => "cable_spring",
        EffectTerm::Stribeck => "stribeck_friction",
        EffectTerm::Winding => "winding_friction",
        EffectTerm::Dahl => "presliding_friction",
    }
}

fn cross_name(term: EffectTerm) -> &'static str {
    match term {
        EffectTerm::Spring => "coupling_spring",
        EffectTerm::Viscous => "coupling_viscous",
        EffectTerm::Armature => "coupling_inertia",
        _ => "coupling_friction",
    }
}

/// The effects of an identification, one entry per (effect, channel).
pub fn effects(id: &Identification) -> Vec<EffectEstimate> {
    let mut out: Vec<EffectEstimate> = Vec::new();
    for (i, p) in id.layout.params.iter().enumerate() {
        let (name, joint) = match *p {
            Param::Effect { term, channel } => (effect_name(term), id.channels[channel].clone()),
            Param::Joint { term, joint } => (effect_name(term), id.joints[joint].clone()),
            Param::Cross { term, channel, source } => (cross_name(term), format!("{} from {}", id.channels[channel], id.channels[source])),
            Param::Body { .. } => continue,
        };
        let term = match *p {
            Param::Effect { term, .. } | Param::Joint { term, .. } | Param::Cross { term, .. } => term,
            Param::Body { .. } => continue,
        };
        let e = match out.iter_mut().position(|e| e.name == name && e.joint == joint) {
            Some(k) => &mut out[k],
            None => {
                out.push(EffectEstimate { name, joint, parameters: Map::new(), std: Map::new() });
                out.last_mut().expect("just pushed")
            }
        };
        e.parameters.insert(term.symbol().into(), json!(id.estimates[i].value));
        e.std.insert(term.symbol().into(), json!(id.estimates[i].std));
    }
    out
}

/// Body `b`'s identified inertial as the inertials files hold it (mass, centre of mass, inertia
/// about it), or `None` for a degenerate body on the boundary of physical consistency.
fn body_entry(model: &Model, id: &Identification, b: usize) -> Option<(f64, [f64; 3], [[f64; 3]; 3])> {
    let bi = id.body_inertia(b, &model.bodies[b].name).ok()?;
    let i = bi.inertia;
    Some((bi.mass, [bi.com.x, bi.com.y, bi.com.z], [[i[(0, 0)], i[(0, 1)], i[(0, 2)]], [i[(1, 0)], i[(1, 1)], i[(1, 2)]], [i[(2, 0)], i[(2, 1)], i[(2, 2)]]]))
}

/// The JSON summary of `dvrk identify` (without the validation, which the caller adds).
pub fn summary(model: &Model, id: &Identification, recording: &str, format: &str, rigid_only: &[f64]) -> Value {
    let bodies: Vec<Value> = (0..model.bodies.len())
        .map(|b| {
            let base = b * PARAMETERS_PER_BODY;
            let std: Vec<f64> = (base..base + PARAMETERS_PER_BODY).map(|i| id.estimates[i].std).collect();
            match body_entry(model, id, b) {
                Some((m, c, i)) => json!({"name": model.bodies[b].name, "mass": m, "com": c, "inertia": i, "parameter_std": std, "min_pseudo_inertia_eigen": id.fit.min_eigen[b]}),
                None => json!({"name": model.bodies[b].name, "degenerate": true, "parameter_std": std, "min_pseudo_inertia_eigen": id.fit.min_eigen[b]}),
            }
        })
        .collect();
    let unidentifiable: Vec<&str> = id.estimates.iter().filter(|e| !e.identifiable).map(|e| e.name.as_str()).collect();
    let active: Vec<String> = id
        .fit
        .at_bound
        .iter()
        .map(|i| format!("{} >= 0", id.estimates[*i].name))
        .chain(id.fit.degenerate_bodies.iter().map(|b| format!("{} pseudo-inertia PSD (on the boundary)", model.bodies[*b].name)))
        .collect();
    json!({
        "model": model.name,
        "recording": recording,
        "format": format,
        "samples": id.samples,
        "channels": id.channels,
        "relative_error": id.relative_error,
        "rigid_body_only": rigid_only,
        "parameters": id.layout.len(),
        "base_parameters": id.base_parameters,
        "physically_consistent": id.fit.min_eigen.iter().all(|l| *l > -1e-9),
        "cutting_plane_rounds": id.fit.rounds,
        "active_constraints": active,
        "unidentifiable": unidentifiable,
        "warnings": id.warnings,
        "effects": effects(id),
        "bodies": bodies,
    })
}
