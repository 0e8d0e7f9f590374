//! The identified model as a model file (`dvrk identify -o`): the model's own file with every
//! body's identified inertial (`[[inertials]]`) and the identified effects in the model's
//! `[[effects]]` vocabulary, so that `dvrk_kin::load` and `dvrk sim --model ARM=FILE` take it
//! as it is. The replay scene ([`super::replay::identified_scene`]) is built from the same model.
//!
//! What goes in as effects, per term of a channel that *is* a model joint (its `to_joint` row and
//! column are the identity: yaw, pitch, insertion, roll), and per joint-space friction term:
//! `coulomb_friction` (fc with the smoothing it was fitted with, offset), `viscous_friction`
//! (fv), `spring` (k, rest 0); the presliding (Dahl) level is the Coulomb effect's `fd` with the
//! displacement `sigma` its state was computed with. A channel that is one of
//! the model's actuators (the tool's, whose motion is `q_actuator = to_joint^-1 q_joint`, the
//! model's own coupling) carries its terms as actuator effects on it: `actuator_coulomb_friction`
//! (fc, fd and sigma, offset, smoothing), `actuator_viscous_friction`, `actuator_spring` and
//! `motor_inertia` (its reflected motor inertia, cross terms and all). The Stribeck and winding
//! terms are the Coulomb effect's `fs` (with `vs`, the Stribeck velocity the fit used) and `fq`;
//! a spring from another channel's position is, exactly, `actuator_cross_spring`s between the
//! model's actuators (`kN`, N the source actuator; the channels' positions and efforts mapped
//! through the channel map and the model's coupling). Other cross-channel terms have no effect
//! to go in: they are listed in the notes with their values (and in
//! [`IdentifiedModel::not_expressed`]); a coupled channel that is
//! not the model's actuator maps its constant offset exactly onto the joints (`offset_joint =
//! to_joint^-T offset_channel`) and its motor inertia's diagonal into `[drive]`. The motor
//! inertias of channels that are joints and the joint damping the fit assumed (none: the
//! viscous frictions hold it) go in the model's `[drive]`,
//! which a scene arm built from the model takes over its own.

use super::problem::{EffectTerm, Param, Processing};
use super::Identification;
use crate::error::{CalibError, Result};
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::effects::EffectSpec;
use dvrk_kin::{BodyInertia, DriveSpec, InertialCovarianceSpec, InertialSpec, Model, ModelSpec};
use nalgebra::DMatrix;
use std::collections::BTreeMap;

/// A model with the identified inertials and effects, and what it could not carry.
#[derive(Debug, Clone)]
pub struct IdentifiedModel {
    /// The model file: the original with `[[inertials]]` for every body and the effects added.
    pub spec: ModelSpec,
    /// The effects added (model-file form).
    pub effects: Vec<EffectSpec>,
    /// Per model joint: the identified reflected motor inertia of a channel that is that joint
    /// (kg m^2, kg for the insertion), `None` elsewhere (the model's `[drive]` holds it).
    pub armature: Vec<Option<f64>>,
    /// Identified terms that no effect of the vocabulary expresses, as `name = value unit`.
    pub not_expressed: Vec<String>,
    /// Bodies the identification left degenerate: the file carries their prior inertial.
    pub kept_prior: Vec<String>,
}

/// The joint a channel is, if its column and row of `to_joint` are the identity's.
fn channel_joint(to_joint: &DMatrix<f64>, c: usize) -> Option<usize> {
    let n = to_joint.nrows();
    (0..n).find(|&j| (0..n).all(|k| to_joint[(j, k)] == f64::from(u8::from(k == c))) && (0..to_joint.ncols()).all(|k| to_joint[(k, c)] == f64::from(u8::from(k == j))))
}

fn unit(term: EffectTerm, prismatic: bool) -> &'static str {
    match (term, prismatic) {
        (EffectTerm::Coulomb | EffectTerm::Offset | EffectTerm::Stribeck | EffectTerm::Dahl, false) => "N·m",
        (EffectTerm::Coulomb | EffectTerm::Offset | EffectTerm::Stribeck | EffectTerm::Dahl, true) => "N",
        (EffectTerm::Viscous, false) => "N·m s/rad",
        (EffectTerm::Viscous, true) => "N s/m",
        (EffectTerm::Armature, false) => "kg m^2",
        (EffectTerm::Armature, true) => "kg",
        (EffectTerm::Spring, false) => "N·m/rad",
        (EffectTerm::Spring, true) => "N/m",
        (EffectTerm::Winding, false) => "N·m/rad^2",
        (EffectTerm::Winding, true) => "N/m^2",
        (EffectTerm::CableLinear, false) => "N·m/rad",
        (EffectTerm::CableLinear, true) => "N/m",
        (EffectTerm::CableQuadratic, false) => "N·m/rad^2",
        (EffectTerm::CableQuadratic, true) => "N/m^2",
        (EffectTerm::CableCubic, false) => "N·m/rad^3",
        (EffectTerm::CableCubic, true) => "N/m^3",
    }
}

/// Body `b`'s identified inertia made strictly physical, or `None` if its mass is not positive.
///
/// The solver holds each pseudo-inertia positive semidefinite to its tolerance, so a tiny body
/// on the cone's boundary (a tool link of 1e-9 kg m^2) can break the triangle inequality of its
/// principal moments by round-off (measured: 9.5e-13 kg m^2 on tool_pitch_link), which
/// [`BodyInertia::check`] refuses. The nearest moments that obey it (negative ones to 0, the two
/// smaller raised equally until the largest is their sum) change the body by that round-off,
/// where keeping the CAD prior would replace the body altogether.
fn physical_body(id: &Identification, b: usize) -> Option<BodyInertia> {
    let p: &[f64; PARAMETERS_PER_BODY] = id.theta.as_slice()[b * PARAMETERS_PER_BODY..(b + 1) * PARAMETERS_PER_BODY].try_into().ok()?;
    let raw = BodyInertia::from_parameters_unchecked(p)?;
    let eig = nalgebra::SymmetricEigen::new(raw.inertia);
    let mut e = eig.eigenvalues.map(|x| x.max(0.0));
    let (k, _) = e.argmax();
    let excess = e[k] - (e.sum() - e[k]);
    if excess > 0.0 {
        for i in (0..3).filter(|&i| i != k) {
            e[i] += 0.5 * excess;
        }
    }
    let inertia = eig.eigenvectors * nalgebra::Matrix3::from_diagonal(&e) * eig.eigenvectors.transpose();
    let inertia = 0.5 * (inertia + inertia.transpose());
    let ine = BodyInertia { inertia, ..raw };
    ine.check("identified body").ok().map(|_| ine)
}

/// `model` with `id`'s inertials and effects. `prior` (one per body, [`Model::bodies`] order)
/// fills in a degenerate body; `to_joint` is the recording's channel-to-joint map
/// ([`super::JointLog::to_joint`]); `recording` names the source.
pub fn identified_model(model: &Model, id: &Identification, processing: &Processing, to_joint: &DMatrix<f64>, prior: &[BodyInertia], recording: &str) -> Result<IdentifiedModel> {
    let (nq, nc) = (model.nq(), id.channels.len());
    if to_joint.nrows() != nq || to_joint.ncols() != nc || prior.len() != model.bodies.len() {
        return Err(CalibError::data(
            "identified model",
            format!("to_joint is {}x{} and the prior has {} bodies; model {} needs {nq}x{nc} and {}", to_joint.nrows(), to_joint.ncols(), prior.len(), model.name, model.bodies.len()),
        ));
    }
    let inv_t = to_joint.clone().try_inverse().ok_or_else(|| CalibError::data("identified model", "the channel-to-joint map is singular"))?.transpose();
    let prismatic = |j: usize| model.joints[j].kind == dvrk_kin::JointType::Prismatic;
    let mut by_joint: BTreeMap<(usize, &'static str), BTreeMap<String, f64>> = BTreeMap::new();
    let mut armature = vec![None; nq];
    let mut not_expressed = Vec::new();
    // Channel c is the model's actuator c when its motion is the actuator's: row c of
    // to_joint^-1 equals row c of the coupling's inverse (the WPI channels 5..7).
    let model_inv = model.coupling_matrix().and_then(|c| c.try_inverse());
    let actuator: Vec<bool> = (0..nc)
        .map(|c| channel_joint(to_joint, c).is_none() && nc == nq && model_inv.as_ref().is_some_and(|m| (0..nq).all(|j| (m[(c, j)] - inv_t[(j, c)]).abs() <= 1e-9 * m.row(c).amax())))
        .collect();
    // A channel's spring from another channel's position as springs between the model's
    // actuators (a = C^-1 q): the channels' positions are x = T^-1 q = P a (P = T^-1 C), and a
    // channel effort reaches the actuators as f = M tau_channel (M = C^T T^-T), so the term
    // theta x_s on channel c is, on actuator A, sum_N M[A, c] theta P[s, N] a_N.
    let coupling = model.coupling_matrix().unwrap_or_else(|| DMatrix::identity(nq, nq));
    let to_actuator = (nc == nq).then(|| (coupling.transpose() * &inv_t, inv_t.transpose() * &coupling));
    let mut by_actuator: BTreeMap<(usize, &'static str), BTreeMap<String, f64>> = BTreeMap::new();
    let mut channel_offset = vec![0.0; nc];
    let mut channel_armature = vec![0.0; nc];
    for (i, p) in id.layout.params.iter().enumerate() {
        let value = id.theta[i];
        // The joint the term acts on, and the Coulomb smoothing it was fitted with.
        let (term, target) = match *p {
            Param::Body { .. } => continue,
            Param::Joint { term, joint } => (term, Some((joint, processing.coulomb_velocity_of(joint)))),
            Param::Effect { term, channel } => match channel_joint(to_joint, channel) {
                Some(j) => (term, Some((j, processing.coulomb_velocity_of(channel)))),
                // A channel that is one of the model's actuators: its terms are actuator effects.
                None if actuator[channel] => {
                    let smoothing = processing.coulomb_velocity_of(channel);
                    let (name, key) = match term {
                        EffectTerm::Coulomb => ("actuator_coulomb_friction", "fc"),
                        EffectTerm::Dahl => ("actuator_coulomb_friction", "fd"),
                        EffectTerm::Offset => ("actuator_coulomb_friction", "offset"),
                        EffectTerm::Viscous => ("actuator_viscous_friction", "fv"),
                        EffectTerm::Spring => ("actuator_spring", "k"),
                        EffectTerm::Armature => ("motor_inertia", "inertia"),
                        EffectTerm::Stribeck => ("actuator_coulomb_friction", "fs"),
                        EffectTerm::Winding => ("actuator_coulomb_friction", "fq"),
                        // Channel-space cable terms are not offered (IdentifyOptions adds them on joints).
                        EffectTerm::CableLinear | EffectTerm::CableQuadratic | EffectTerm::CableCubic => {
                            not_expressed.push(format!("{} = {value:.6} {}", id.estimates[i].name, unit(term, false)));
                            continue;
                        }
                    };
                    let e = by_actuator.entry((channel, name)).or_default();
                    *e.entry(key.into()).or_default() += value;
                    if name == "actuator_coulomb_friction" {
                        e.insert("smoothing".into(), smoothing);
                    }
                    if term == EffectTerm::Stribeck {
                        e.insert("vs".into(), processing.stribeck_velocity);
                    }
                    if term == EffectTerm::Dahl {
                        e.insert("sigma".into(), processing.dahl_displacement_of(channel));
                    }
                    continue;
                }
                None if term == EffectTerm::Offset => {
                    channel_offset[channel] += value;
                    continue;
                }
                None if term == EffectTerm::Armature => {
                    channel_armature[channel] = value;
                    not_expressed.push(format!("{} = {value:.6} {} (in [drive] as the diagonal of its joint-space image; the cross terms are not)", id.estimates[i].name, unit(term, false)));
                    continue;
                }
                None => (term, None),
            },
            // A spring from another channel's position: springs between the model's actuators.
            // (Beside a presliding level they need its state: with the level folded into the
            // Coulomb one they made WPI `two`'s wrist pitch worse, 0.0083 -> 0.0098 N·m.)
            Param::Cross { term: EffectTerm::Spring, channel, source } if to_actuator.is_some() => {
                let Some((m, pm)) = &to_actuator else { continue };
                let tiny = 1e-12 * m.amax() * pm.amax();
                for a in 0..nq {
                    for n in 0..nq {
                        let k = m[(a, channel)] * value * pm[(source, n)];
                        if k.abs() > tiny * value.abs() {
                            *by_actuator.entry((a, "actuator_cross_spring")).or_default().entry(format!("k{}", n + 1)).or_default() += k;
                        }
                    }
                }
                continue;
            }
            Param::Cross { term, .. } => (term, None),
        };
        let Some((j, smoothing)) = target else {
            let u = match *p {
                Param::Effect { channel, .. } | Param::Cross { channel, .. } => unit(term, channel_joint(to_joint, channel).is_some_and(prismatic)),
                _ => unit(term, false),
            };
            not_expressed.push(format!("{} = {value:.6} {u}", id.estimates[i].name));
            continue;
        };
        match term {
            EffectTerm::Coulomb => {
                let e = by_joint.entry((j, "coulomb_friction")).or_default();
                *e.entry("fc".into()).or_default() += value;
                e.insert("smoothing".into(), smoothing);
            }
            // The offset is the effort the drive adds; the effect's offset is that same effort
            // (dvrk-kin's `effort` subtracts it from the joint's).
            EffectTerm::Offset => *by_joint.entry((j, "coulomb_friction")).or_default().entry("offset".into()).or_default() += value,
            EffectTerm::Viscous => *by_joint.entry((j, "viscous_friction")).or_default().entry("fv".into()).or_default() += value,
            EffectTerm::Spring => *by_joint.entry((j, "spring")).or_default().entry("k".into()).or_default() += value,
            EffectTerm::CableLinear | EffectTerm::CableQuadratic | EffectTerm::CableCubic => {
                *by_joint.entry((j, "cable_spring")).or_default().entry(term.symbol().into()).or_default() += value
            }
            EffectTerm::Armature => armature[j] = Some(value),
            // The presliding level with the displacement its state was computed with.
            EffectTerm::Dahl => {
                let e = by_joint.entry((j, "coulomb_friction")).or_default();
                *e.entry("fd".into()).or_default() += value;
                e.entry("smoothing".into()).or_insert(smoothing);
                let channel = match *p {
                    Param::Effect { channel, .. } => channel,
                    _ => j,
                };
                e.insert("sigma".into(), processing.dahl_displacement_of(channel));
            }
            // The Coulomb level's winding and Stribeck terms.
            EffectTerm::Winding | EffectTerm::Stribeck => {
                let e = by_joint.entry((j, "coulomb_friction")).or_default();
                *e.entry(if term == EffectTerm::Winding { "fq" } else { "fs" }.into()).or_default() += value;
                e.entry("smoothing".into()).or_insert(smoothing);
                if term == EffectTerm::Stribeck {
                    e.insert("vs".into(), processing.stribeck_velocity);
                }
            }
        }
    }
    // Constant offsets of coupled channels, exactly, on the joints.
    if channel_offset.iter().any(|o| *o != 0.0) {
        for j in 0..nq {
            let o: f64 = (0..nc).map(|c| inv_t[(j, c)] * channel_offset[c]).sum();
            if o != 0.0 {
                *by_joint.entry((j, "coulomb_friction")).or_default().entry("offset".into()).or_default() += o;
            }
        }
    }
    let source = format!("dvrk identify from {recording}");
    let mut effects = Vec::new();
    for ((j, name), mut parameters) in by_joint {
        if name == "coulomb_friction" {
            parameters.entry("fc".into()).or_insert(0.0);
        }
        effects.push(EffectSpec { name: name.into(), joint: Some(model.joints[j].name.clone()), link: None, actuator: None, parameters, source: source.clone() });
    }
    for ((c, name), mut parameters) in by_actuator {
        if name == "actuator_coulomb_friction" {
            parameters.entry("fc".into()).or_insert(0.0);
        }
        effects.push(EffectSpec { name: name.into(), joint: None, link: None, actuator: Some(c + 1), parameters, source: source.clone() });
    }
    let mut inertials = Vec::with_capacity(model.bodies.len());
    let mut kept_prior = Vec::new();
    for (b, body) in model.bodies.iter().enumerate() {
        let (ine, from) = match physical_body(id, b) {
            Some(ine) => (ine, source.clone()),
            None => {
                kept_prior.push(body.name.clone());
                (prior[b], "prior (the identification left this body degenerate)".to_string())
            }
        };
        let i = ine.inertia;
        inertials.push(InertialSpec { body: body.name.clone(), mass: ine.mass, com: [ine.com.x, ine.com.y, ine.com.z], inertia: [[i[(0, 0)], i[(0, 1)], i[(0, 2)]], [i[(1, 0)], i[(1, 1)], i[(1, 2)]], [i[(2, 0)], i[(2, 1)], i[(2, 2)]]], source: from });
    }
    // The drive the efforts were fitted with: the viscous frictions hold all the joint damping
    // (a scene's too: identified on a simulated recording, fv is its damping), the motor inertias
    // are the identified ones; a tool actuator's maps to the joints as to_joint^-T diag(im)
    // to_joint^-1, of which a per-joint armature holds the diagonal.
    let drive_armature = (0..nq).map(|j| armature[j].unwrap_or_else(|| (0..nc).map(|c| inv_t[(j, c)].powi(2) * channel_armature[c]).sum())).collect();
    let mut spec = model.spec.clone();
    spec.drive = Some(DriveSpec { damping: 0.0, armature: drive_armature, source: source.clone() });
    spec.effects.extend(effects.iter().cloned());
    spec.inertials = inertials;
    // How well the recording determined the inertials: a later analysis (`dvrk discrepancy`)
    // holds them that tightly, so a payload cannot hide in them. Bodies kept at their prior
    // keep the prior's variance, which the covariance already gives them.
    spec.inertial_covariance = id.inertial_covariance.clone().cholesky().map(|ch| InertialCovarianceSpec {
        bodies: model.bodies.iter().map(|b| b.name.clone()).collect(),
        cholesky: (0..ch.l_dirty().nrows()).map(|i| (0..=i).map(|k| ch.l_dirty()[(i, k)]).collect()).collect(),
        source: format!("dvrk identify from {recording}: the inertial parameters' covariance at the effort sensors' noise, marginal over the effects"),
    });
    spec.title = format!("{} (identified from {recording})", spec.title);
    spec.notes = format!(
        "{}\n\nIdentified by `dvrk identify` from {recording}: [[inertials]] for every body (physically consistent: each \
body's pseudo-inertia positive semidefinite, {} of {} inertial parameters determined by the data (their uncertainty shrunk more \
than twofold below the prior's), the rest by the CAD prior), \
the effects added at the end of [[effects]], and the drive they were fitted with ([drive]: no joint damping beyond the viscous \
frictions, the identified motor inertias).{}{}",
        spec.notes.trim_end(),
        id.layout.params.iter().zip(&id.estimates).filter(|(p, e)| matches!(p, Param::Body { .. }) && e.identifiable).count(),
        id.layout.nbodies * PARAMETERS_PER_BODY,
        if kept_prior.is_empty() { String::new() } else { format!(" Bodies left degenerate, with their prior inertial: {}.", kept_prior.join(", ")) },
        if not_expressed.is_empty() {
            String::new()
        } else {
            format!(
                "\nNot expressible as effects (cross-channel terms other than the springs between actuators; the tool's actuator channels' \
friction, springs and motor inertias are actuator effects):\n{}",
                not_expressed.iter().map(|s| format!("- {s}")).collect::<Vec<_>>().join("\n")
            )
        }
    );
    Model::compile(spec.clone()).map_err(|e| CalibError::context("identified model", e))?;
    Ok(IdentifiedModel { spec, effects, armature, not_expressed, kept_prior })
}

/// The text of the output file: [`identified_model`]'s model file with a header.
pub fn output_toml(identified: &IdentifiedModel, recording: &str) -> Result<String> {
    let body = identified.spec.to_toml().map_err(|e| CalibError::context("identification output", e))?;
    Ok(format!(
        "# Model {} identified by `dvrk identify` from {recording}: [[inertials]] (kg, m, kg m^2, per body in its first DH frame),\n\
# [[effects]] (N·m or N; N·m s/rad or N s/m; N·m/rad or N/m) and [drive] (joint damping; motor inertias, kg m^2 or kg).\n\
# Load it with `dvrk sim --model ARM=FILE`.\n\n{body}",
        identified.spec.name
    ))
}
