//! Physical effects of a model: the `[[effects]]` section of a model file.
//!
//! The rigid-body model is not the robot: cables, friction and springs are. Each effect has a
//! name from a fixed vocabulary, the joint or link it acts on, parameters with units and
//! physical bounds. Where they act:
//! - kinematics (applied when the model is compiled): `joint_offset` (the encoder's zero: the
//!   joint's true angle is the reading plus `offset`), `link_length` (a DH `a` or `d` changed by
//!   `a`, `d` metres), `base_registration` (the base frame moved by `x y z`, rotation vector
//!   `rx ry rz`);
//! - dynamics (dvrk-kin's [`effort`] and [`effect_inertias`], and dvrk-sim's physics):
//!   `coulomb_friction` (its level `fc`, with optional winding `fq q^2` and Stribeck
//!   `fs exp(-(qd / vs)^2)` terms: [`coulomb_level`], and presliding `fd`, `sigma`: a Dahl state
//!   carried along the motion, [`crate::presliding`]), `viscous_friction`, `spring`,
//!   `cable_spring` (a configuration-dependent spring: `k1 q + k2 q^2 + k3 q^3`, any signs),
//!   `payload_mass`;
//! - both: `counterweight_error` (the counterweight's travel per unit insertion `mu`, replacing
//!   the model's parameter of that name, and its mass `mass`, the body's inertia scaled with it:
//!   the same block, heavier or lighter); the counterweight is the body a frame moving by `mu`
//!   carries;
//! - actuator space (the tool's cable-driven wrist, the MTM's elbow and platform): friction and
//!   springs at an actuator, `actuator_coulomb_friction`, `actuator_viscous_friction`,
//!   `actuator_spring`, a spring from other actuators' positions, `actuator_cross_spring` (`kN`:
//!   N·m/rad from actuator N, `-sum kN a_N`: a cable routed over another's pulley, the tool's
//!   cross-channel springs `dvrk identify` fits), and its motor's reflected inertia,
//!   `motor_inertia`, each on `actuator`
//!   (1-based, a column of the model's coupling `q = C a`). An actuator moves by
//!   `a = (C^-1 q)_k` and its force reaches the joints by virtual work as `C^-T f`: one actuator's
//!   friction loads every joint its cables couple. A model without a coupling has its actuators
//!   on its joints (`C = I`);
//! - the simulated drive and sensors (dvrk-sim): `joint_compliance`, `backlash`, `latency`;
//! - the recording's clocks and the drive's history (the discrepancy workflow's kinematic
//!   channel): `clock_offset` (`seconds`, either sign: the tracker's clock late against the
//!   joint stream's when positive), `motion_play` (`b`, half the gap of a lightly loaded drive:
//!   the link holds where it was when the motor reverses until the gap is crossed,
//!   [`motion_play`]);
//! - kinematics and dynamics: `coupling_error` (`dRC`: the true actuator-to-joint coupling is the
//!   model's plus `dRC` at 1-based row R, column C; the controller reads joints through the
//!   model's). The compiled model's frames follow the true joints of the joints read, so its
//!   kinematics and inverse dynamics (the effort the controller reports) honour it; dvrk-sim
//!   builds the mechanism on the true joints and maps its sensors and motors
//!   ([`crate::coupling`]).
//!
//! ```toml
//! [[effects]]
//! name = "coulomb_friction"
//! joint = "outer_yaw"
//! parameters = { fc = 0.05, offset = -0.01 }   # N·m
//! source = "dvrk identify on psm_one_results.csv"
//! ```

use crate::error::{KinError, Result};
use crate::model::Model;
use crate::spec::FrameRef;
use crate::JointType;

use std::collections::BTreeMap;

pub use crate::spec::EffectSpec;
pub use crate::vocabulary::{coupling_entry_name, coupling_error_range, cross_spring_source, Effect, EffectKind, ParameterInfo, Target, COUPLING_ERROR_FRACTION, CROSS_SPRING_RANGE};
pub(crate) use crate::vocabulary::coupling_entry;
pub use crate::play::motion_play;


/// Check the model's `[[effects]]` against the vocabulary, the model's joints and frames and the
/// physical bounds; `field` errors name `effects[i] (name)` and the parameter.
pub fn check_effects(model: &Model) -> Result<Vec<Effect>> {
    let mut out = Vec::with_capacity(model.spec.effects.len());
    for (i, e) in model.spec.effects.iter().enumerate() {
        let field = |f: &str| format!("effects[{i}] ({}).{f}", e.name);
        let kind = EffectKind::from_name(&e.name).ok_or_else(|| {
            let names: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
            KinError::field(format!("effects[{i}].name"), format!("`{}` is not an effect (vocabulary: {})", e.name, names.join(", ")))
        })?;
        let joint = match (kind.target(), &e.joint) {
            (Target::Joint, Some(j)) => Some(model.joint_id(j).map_err(|err| KinError::field(field("joint"), err.to_string()))?),
            (Target::Joint, None) => return Err(KinError::field(field("joint"), "missing: this effect acts on a joint")),
            (_, Some(j)) => return Err(KinError::field(field("joint"), format!("`{j}` given, but {} does not act on a joint", e.name))),
            (_, None) => None,
        };
        let frame = match (kind.target(), &e.link) {
            (Target::Link, Some(l)) => Some(model.frame_id(l).map_err(|err| KinError::field(field("link"), err.to_string()))?),
            (Target::Link, None) => return Err(KinError::field(field("link"), "missing: this effect acts on a link (frame number or name)")),
            (_, Some(l)) => return Err(KinError::field(field("link"), format!("`{l}` given, but {} does not act on a link", e.name))),
            (_, None) => None,
        };
        let (actuator, transmission) = match (kind.target(), e.actuator) {
            (Target::Actuator, Some(a)) => {
                let (k, w) = actuator_transmission(model, a).map_err(|m| KinError::field(field("actuator"), m))?;
                (Some(k), w)
            }
            (Target::Actuator, None) => return Err(KinError::field(field("actuator"), format!("missing: this effect acts on an actuator (1..={}, a column of the coupling)", model.nq()))),
            (_, Some(a)) => return Err(KinError::field(field("actuator"), format!("`{a}` given, but {} does not act on an actuator", e.name))),
            (_, None) => (None, Vec::new()),
        };
        // An actuator's units are those of the joint it drives on the coupling's diagonal (the
        // PSM's third actuator is the insertion's, in m and N).
        let prismatic = joint.or(actuator).is_some_and(|j| model.joints[j].kind == JointType::Prismatic);
        let mut parameters = BTreeMap::new();
        let mut cross = Vec::new();
        if kind == EffectKind::ActuatorCrossSpring {
            let n = model.nq();
            let mut u = vec![0.0; n];
            for (name, v) in &e.parameters {
                // (N = its own actuator: a spring on its own position, as an actuator_spring at rest 0;
                // an identification's cross terms mapped through a coupling give those too.)
                let source = cross_spring_source(name).filter(|s| (1..=n).contains(s)).ok_or_else(|| {
                    KinError::field(field(&format!("parameters.{name}")), format!("{v}: expected kN, N an actuator (1..={n}): the stiffness from actuator N's position"))
                })?;
                let [lo, hi] = CROSS_SPRING_RANGE;
                if !(v.is_finite() && (lo..=hi).contains(v)) {
                    return Err(KinError::field(field(&format!("parameters.{name}")), format!("{v} is outside its physical bounds [{lo}, {hi}]")));
                }
                let (_, w) = actuator_transmission(model, source).map_err(|m| KinError::field(field(&format!("parameters.{name}")), m))?;
                for (j, c) in w {
                    u[j] += v * c;
                }
                parameters.insert(name.clone(), *v);
            }
            if parameters.is_empty() {
                return Err(KinError::field(field("parameters"), "missing: at least one kN (the stiffness from actuator N's position)"));
            }
            cross = u.into_iter().enumerate().filter(|(_, x)| *x != 0.0).collect();
        } else if kind == EffectKind::CouplingError {
            let c = model.coupling_matrix().ok_or_else(|| KinError::field(field("name"), format!("model `{}` has no actuator coupling to be in error", model.name)))?;
            for (name, v) in &e.parameters {
                match coupling_entry(name) {
                    Some((r, col)) if (1..=c.nrows()).contains(&r) && (1..=c.ncols()).contains(&col) => {
                        let [lo, hi] = coupling_error_range(&c, r - 1);
                        if !(v.is_finite() && (lo..=hi).contains(v)) {
                            return Err(KinError::field(
                                field(&format!("parameters.{name}")),
                                format!("{v} is outside [{lo}, {hi}]: {COUPLING_ERROR_FRACTION} of row {r}'s largest coupling entry"),
                            ));
                        }
                        parameters.insert(name.clone(), *v);
                    }
                    _ => {
                        return Err(KinError::field(
                            field(&format!("parameters.{name}")),
                            format!("{v}: expected dRC (1-based row, column of the {}x{} coupling)", c.nrows(), c.ncols()),
                        ))
                    }
                }
            }
        } else {
            let infos = kind.parameters();
            if let Some(unknown) = e.parameters.keys().find(|k| !infos.iter().any(|p| p.name == k.as_str())) {
                let names: Vec<&str> = infos.iter().map(|p| p.name).collect();
                return Err(KinError::field(field(&format!("parameters.{unknown}")), format!("not a parameter of {} (parameters: {})", e.name, names.join(", "))));
            }
            for info in infos {
                let unit = if prismatic { info.prismatic_unit } else { info.unit };
                let v = match (e.parameters.get(info.name), info.default) {
                    (Some(v), _) => *v,
                    (None, Some(d)) => d,
                    (None, None) => return Err(KinError::field(field(&format!("parameters.{}", info.name)), format!("missing ({unit})"))),
                };
                let [lower, upper] = info.bounds(prismatic);
                if !(v.is_finite() && v >= lower && v <= upper) {
                    return Err(KinError::field(field(&format!("parameters.{}", info.name)), format!("{v} {unit} is outside its physical bounds [{lower}, {upper}]")));
                }
                parameters.insert(info.name.to_string(), v);
            }
        }
        let frame = match kind {
            EffectKind::CounterweightError => Some(model.counterweight_frame().ok_or_else(|| {
                KinError::field(field("name"), format!("model `{}` has no counterweight (no frame moves by the parameter `{COUNTERWEIGHT_TRAVEL}`)", model.name))
            })?),
            _ => frame,
        };
        out.push(Effect { kind, joint, frame, actuator, transmission, cross, parameters });
    }
    Ok(out)
}

/// Actuator `a` (1-based) of `model`: its 0-based index and its row of `C^-1` as (joint, weight)
/// pairs, the joints it moves with ([`Effect::transmission`]); the message of a bad number or a
/// singular coupling.
pub fn actuator_transmission(model: &Model, a: usize) -> std::result::Result<(usize, Vec<(usize, f64)>), String> {
    let n = model.nq();
    if !(1..=n).contains(&a) {
        return Err(format!("{a} is not an actuator of model `{}` (1..={n}, a column of its coupling)", model.name));
    }
    let c = model.coupling_matrix().unwrap_or_else(|| nalgebra::DMatrix::identity(n, n));
    let inv = c.try_inverse().ok_or_else(|| format!("model `{}`'s coupling is singular: its actuators' motions are not defined", model.name))?;
    let row = inv.row(a - 1);
    // Round-off of the inverse is not a cable.
    let tiny = 1e-12 * row.amax();
    Ok((a - 1, row.iter().enumerate().filter(|(_, w)| w.abs() > tiny).map(|(j, w)| (j, *w)).collect()))
}


/// The model parameter a counterweight's travel per unit insertion goes by (Table 4's mu).
const COUNTERWEIGHT_TRAVEL: &str = "mu";

/// Whether the expression `e` names the identifier `name`.
fn names(e: &crate::spec::Value, name: &str) -> bool {
    matches!(e, crate::spec::Value::Expr(x) if x.split(|c: char| !(c.is_alphanumeric() || c == '_')).any(|w| w == name))
}

impl Model {
    /// The counterweight's frame (position in [`Model::frames`]): the first whose DH figures move
    /// by the parameter `mu` (Table 4's counterweight travel); `None` without one.
    pub fn counterweight_frame(&self) -> Option<usize> {
        (0..self.frames.len()).find(|&i| self.spec_frame(i).is_some_and(|f| [&f.a, &f.alpha, &f.d, &f.theta].into_iter().any(|v| names(v, COUNTERWEIGHT_TRAVEL))))
    }
}

/// The spec with a `counterweight_error`'s `mu` in place of the model's parameter (before
/// compiling; the last one wins).
pub(crate) fn apply_counterweight(spec: &mut crate::ModelSpec) -> Result<()> {
    let name = EffectKind::CounterweightError.name();
    let Some((i, mu)) = spec.effects.iter().enumerate().filter(|(_, e)| e.name == name).last().map(|(i, e)| (i, e.parameters.get("mu").copied())) else {
        return Ok(());
    };
    // A missing or out-of-bounds mu is reported by check_effects with the other parameters.
    let Some(mu) = mu else { return Ok(()) };
    let p = spec.parameters.get_mut(COUNTERWEIGHT_TRAVEL).ok_or_else(|| {
        KinError::field(format!("effects[{i}] ({name}).parameters.mu"), format!("the model has no parameter `{COUNTERWEIGHT_TRAVEL}` (a counterweight's travel) for it to replace"))
    })?;
    p.value = mu;
    Ok(())
}

/// A Coulomb friction's level (N·m, N) at its joint's or actuator's position `a` (rad, m) and
/// velocity `v` (rad/s, m/s): `fc + fq a^2 + fs exp(-(v / vs)^2)` (its winding and Stribeck
/// terms), never below 0 (friction does not push).
pub fn coulomb_level(e: &Effect, a: f64, v: f64) -> f64 {
    let fs = e.get("fs");
    let stribeck = if fs == 0.0 { 0.0 } else { fs * (-(v / e.get("vs")).powi(2)).exp() };
    (e.get("fc") + e.get("fq") * a * a + stribeck).max(0.0)
}

/// Joint-space effort (N·m, N) of the friction and spring effects at `q`, `qd`, added to `out`:
/// `-(level sign(qd) + fd sign(qd) + offset) - fv qd - k (q - rest)` per joint, the force the
/// effect exerts on the joint, with the Coulomb level `fc + fq q^2 + fs exp(-(qd / vs)^2)`
/// (winding and Stribeck terms; never below 0: friction does not push) and the presliding level
/// `fd` at its sliding limit (no history here: [`crate::presliding::effort_with_presliding`] carries it); an
/// actuator's the same law in its position `a = w . q` and velocity, reaching joint `j` as `w_j
/// f` ([`Effect::transmission`]), and an `actuator_cross_spring`'s force `-u . q`
/// ([`Effect::cross`]) the same way. The sign is smoothed, `tanh(qd / v)`, with `v` the larger of
/// `velocity_scale` and the effect's `smoothing` (rad/s, m/s; both 0: a hard sign).
pub fn effort(effects: &[Effect], q: &[f64], qd: &[f64], velocity_scale: f64, out: &mut [f64]) {
    effort_impl(effects, q, qd, None, velocity_scale, out)
}

/// [`effort`], with each Coulomb friction's presliding force `fd z[k]` from its Dahl state
/// (`z[k]` for `effects[k]`; `None`: at its sliding limit): [`crate::presliding`] carries them.
pub(crate) fn effort_impl(effects: &[Effect], q: &[f64], qd: &[f64], z: Option<&[f64]>, velocity_scale: f64, out: &mut [f64]) {
    let dot = |w: &[(usize, f64)], x: &[f64]| w.iter().map(|(j, c)| c * x[*j]).sum::<f64>();
    let sign = |e: &Effect, v: f64| {
        let scale = velocity_scale.max(e.get("smoothing"));
        if scale > 0.0 {
            (v / scale).tanh()
        } else {
            v.signum() * (v != 0.0) as i32 as f64
        }
    };
    // The Coulomb law's force on its joint or actuator (its negative: friction opposes).
    let coulomb = |k: usize, e: &Effect, a: f64, v: f64| {
        let s = sign(e, v);
        let fd = e.get("fd");
        let presliding = if fd == 0.0 { 0.0 } else { fd * z.map_or(s, |z| z[k]) };
        -(coulomb_level(e, a, v) * s + presliding + e.get("offset"))
    };
    for (k, e) in effects.iter().enumerate() {
        if let Some(j) = e.joint {
            match e.kind {
                EffectKind::CoulombFriction => out[j] += coulomb(k, e, q[j], qd[j]),
                EffectKind::ViscousFriction => out[j] -= e.get("fv") * qd[j],
                EffectKind::Spring => out[j] -= e.get("k") * (q[j] - e.get("rest")),
                EffectKind::CableSpring => out[j] -= q[j] * (e.get("k1") + q[j] * (e.get("k2") + q[j] * e.get("k3"))),
                _ => {}
            }
            continue;
        }
        let w = &e.transmission;
        let f = match e.kind {
            EffectKind::ActuatorCoulombFriction => coulomb(k, e, dot(w, q), dot(w, qd)),
            EffectKind::ActuatorViscousFriction => -e.get("fv") * dot(w, qd),
            EffectKind::ActuatorSpring => -e.get("k") * (dot(w, q) - e.get("rest")),
            EffectKind::ActuatorCrossSpring => -dot(&e.cross, q),
            _ => continue,
        };
        for (j, c) in w {
            out[*j] += c * f;
        }
    }
}

/// Joint-space effort (N·m, N) of the motors' reflected inertias (`motor_inertia`) at joint
/// accelerations `qdd`, added to `out`: `-C^-T diag(I) C^-1 qdd`, the coupled inertia's
/// cross terms included (the actuator's acceleration is `w . qdd`, its inertial force `-I w .
/// qdd` reaches joint `j` as `w_j` times that).
pub fn inertial_effort(effects: &[Effect], qdd: &[f64], out: &mut [f64]) {
    for e in effects.iter().filter(|e| e.kind == EffectKind::MotorInertia) {
        let f = -e.get("inertia") * e.transmission.iter().map(|(j, c)| c * qdd[*j]).sum::<f64>();
        for (j, c) in &e.transmission {
            out[*j] += c * f;
        }
    }
}

/// The joint-space inertia matrix the motors' `motor_inertia` effects add, `C^-T diag(I) C^-1`
/// (kg m^2, kg), added to `m` (nq x nq).
pub fn motor_inertia_matrix(effects: &[Effect], m: &mut nalgebra::DMatrix<f64>) {
    for e in effects.iter().filter(|e| e.kind == EffectKind::MotorInertia) {
        for (j, a) in &e.transmission {
            for (k, b) in &e.transmission {
                m[(*j, *k)] += e.get("inertia") * a * b;
            }
        }
    }
}

/// `inertias` with every `payload_mass` added as a point mass on its link's body, and a
/// `counterweight_error`'s mass given to the counterweight (its inertia scaled by the same
/// ratio); each inertia in its body's first frame, [`crate::Model::bodies`] order.
pub fn effect_inertias(model: &Model, effects: &[Effect], inertias: &[crate::BodyInertia]) -> Result<Vec<crate::BodyInertia>> {
    let mut out = inertias.to_vec();
    let fk = model.fk(&model.home())?;
    for e in effects.iter().filter(|e| e.kind == EffectKind::PayloadMass) {
        let Some(f) = e.frame else { continue };
        let b = model.frames[f].body;
        let first = model.bodies[b].frames[0];
        // The point in the body's first frame (constant: both frames are on one body).
        let local = (fk[first].inverse() * fk[f]) * nalgebra::Point3::new(e.get("x"), e.get("y"), e.get("z"));
        out[b] = out[b].with_point_mass(e.get("mass"), &local.coords);
    }
    for e in effects.iter().filter(|e| e.kind == EffectKind::CounterweightError) {
        let Some(f) = e.frame else { continue };
        let b = &mut out[model.frames[f].body];
        // Zero: a counterweight removed (a model needs a positive mass: kept at 1 ug).
        let ratio = e.get("mass").max(1e-9) / b.mass;
        b.mass *= ratio;
        b.inertia *= ratio;
    }
    Ok(out)
}

/// Apply the kinematic effects to a model being compiled: a coupling error maps the joints read
/// to the true ones (`phi = c B q`, [`crate::coupling`]), then the joint offsets enter every
/// frame variable that depends on the joint (`phi = c B (q + offset) + b`: the reading's zero),
/// the registration the base.
pub(crate) fn apply_kinematic(model: &mut Model, effects: &[Effect]) -> Result<()> {
    if let Some(b) = crate::coupling::error_map(model, effects)? {
        crate::coupling::remap_joints(model, &b);
    }
    for e in effects {
        match e.kind {
            EffectKind::JointOffset => {
                let (Some(j), off) = (e.joint, e.get("offset")) else { continue };
                for f in &mut model.frames {
                    f.theta.offset += f.theta.coef[j] * off;
                    f.d.offset += f.d.coef[j] * off;
                    if let crate::model::Motion::Revolute { d0 } = &mut f.motion {
                        *d0 = f.d.offset;
                    }
                }
            }
            EffectKind::BaseRegistration => {
                let r = nalgebra::Rotation3::new(nalgebra::Vector3::new(e.get("rx"), e.get("ry"), e.get("rz")));
                let t = nalgebra::Translation3::new(e.get("x"), e.get("y"), e.get("z"));
                model.base = crate::Pose::from_parts(t, r) * model.base;
            }
            _ => {}
        }
    }
    Ok(())
}

/// The spec with every `link_length` applied to its frame's `a` and `d` (before compiling).
pub(crate) fn apply_link_lengths(spec: &mut crate::ModelSpec) -> Result<()> {
    use crate::spec::Value;
    let edits: Vec<(usize, FrameRef, f64, f64)> = spec
        .effects
        .iter()
        .enumerate()
        .filter(|(_, e)| e.name == "link_length")
        .map(|(i, e)| {
            let link = e.link.clone().ok_or_else(|| KinError::field(format!("effects[{i}] (link_length).link"), "missing: this effect acts on a link (frame number or name)"))?;
            Ok((i, link, e.parameters.get("a").copied().unwrap_or(0.0), e.parameters.get("d").copied().unwrap_or(0.0)))
        })
        .collect::<Result<_>>()?;
    for (i, link, da, dd) in edits {
        let pos = spec.frames.iter().enumerate().position(|(k, f)| match &link {
            FrameRef::Index(x) => f.index.unwrap_or(k as i64 + 1) == *x,
            FrameRef::Name(s) => f.name == *s,
        });
        let Some(pos) = pos else { return Err(KinError::field(format!("effects[{i}] (link_length).link"), format!("no frame `{link}`"))) };
        let add = |v: &Value, delta: f64| match v {
            _ if delta == 0.0 => v.clone(),
            Value::Number(x) => Value::Number(x + delta),
            Value::Expr(e) if delta < 0.0 => Value::Expr(format!("{e} - {:e}", -delta)),
            Value::Expr(e) => Value::Expr(format!("{e} + {delta:e}")),
        };
        let f = &mut spec.frames[pos];
        f.a = add(&f.a, da);
        f.d = add(&f.d, dd);
    }
    Ok(())
}
