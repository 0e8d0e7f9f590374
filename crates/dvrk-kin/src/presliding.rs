//! Presliding (Dahl) friction: before a joint slides, its friction grows with displacement like a
//! stiff spring and saturates at the sliding level after a displacement `sigma` (the Dahl model,
//! the state `z` in [-1, 1], the force `fd z`). It depends on the motion's history, so it is a
//! state carried along a trajectory: `dvrk identify` fits its level `fd` (the `fd`, `sigma`
//! parameters of a Coulomb friction effect), dvrk-sim steps it with the joints, the discrepancy
//! workflow's baseline computes it along a recording. All three use [`dahl_step`].

use crate::effects::{effort_impl, Effect, EffectKind};

/// The Dahl state after a step `dq` (rad, m) from `z`, for presliding displacement `sigma` (rad,
/// m): the exact solution of `dz/dq = (1 - z sgn(dq)) / sigma` over the step, `z <- s + (z - s)
/// exp(-|dq| / sigma)` with `s = sgn(dq)`, so `z` stays in [-1, 1] whatever the step.
#[inline]
pub fn dahl_step(z: f64, dq: f64, sigma: f64) -> f64 {
    if dq == 0.0 {
        return z;
    }
    let s = dq.signum();
    s + (z - s) * (-dq.abs() / sigma).exp()
}

/// The Dahl state along positions `q` (rad, m, in time order) for presliding displacement
/// `sigma`, starting at 0 ([`dahl_step`] between samples).
pub fn dahl_state(q: &[f64], sigma: f64) -> Vec<f64> {
    let mut z = 0.0;
    let mut prev = q.first().copied().unwrap_or(0.0);
    q.iter()
        .map(|&x| {
            z = dahl_step(z, x - prev, sigma);
            prev = x;
            z
        })
        .collect()
}

/// The position (rad, m) a Coulomb friction effect slides at: its joint's, or its actuator's
/// `w . q`; `None` for other effects.
pub fn friction_position(e: &Effect, q: &[f64]) -> Option<f64> {
    match (e.kind, e.joint) {
        (EffectKind::CoulombFriction, Some(j)) => Some(q[j]),
        (EffectKind::ActuatorCoulombFriction, _) => Some(e.transmission.iter().map(|(j, w)| w * q[*j]).sum()),
        _ => None,
    }
}

/// Whether an effect carries a presliding state (a Coulomb friction with `fd` != 0).
pub fn has_presliding(e: &Effect) -> bool {
    matches!(e.kind, EffectKind::CoulombFriction | EffectKind::ActuatorCoulombFriction) && e.get("fd") != 0.0
}

/// The Dahl states of a list of effects, one per effect (0 for those without presliding), stepped
/// with the joints: the workspace of [`effort_with_presliding`]. Allocates only
/// when built.
#[derive(Debug, Clone)]
pub struct PreslidingState {
    /// Per effect: its Dahl state in [-1, 1].
    pub z: Vec<f64>,
    /// Per effect: its sliding position at the last step (rad, m).
    last: Vec<f64>,
}

impl PreslidingState {
    /// States at rest (0) with `effects` at joint positions `q`.
    pub fn new(effects: &[Effect], q: &[f64]) -> PreslidingState {
        PreslidingState { z: vec![0.0; effects.len()], last: effects.iter().map(|e| friction_position(e, q).unwrap_or(0.0)).collect() }
    }

    /// Step every presliding state to joint positions `q` (the same `effects` as built with).
    pub fn advance(&mut self, effects: &[Effect], q: &[f64]) {
        for (k, e) in effects.iter().enumerate() {
            if !has_presliding(e) {
                continue;
            }
            let Some(a) = friction_position(e, q) else { continue };
            self.z[k] = dahl_step(self.z[k], a - self.last[k], e.get("sigma"));
            self.last[k] = a;
        }
    }
}

/// [`crate::effects::effort`] with each Coulomb friction's presliding force `fd z` from its Dahl
/// state `z` (`states.z[k]` for `effects[k]`) in place of its sliding limit (N·m, N, added to
/// `out`).
pub fn effort_with_presliding(effects: &[Effect], q: &[f64], qd: &[f64], states: &PreslidingState, velocity_scale: f64, out: &mut [f64]) {
    effort_impl(effects, q, qd, Some(&states.z), velocity_scale, out)
}
