//! The model's physical effects as physics of the simulation (not corrections of its outputs):
//! - `coulomb_friction`, `viscous_friction`, `spring`: joint forces from the joint's own motion,
//!   applied with the actuator's effort every step;
//! - `joint_compliance`, `backlash`: a two-mass drive. The motor (the armature: reflected rotor
//!   inertia) is driven by the actuator and turns the joint through a transmission: a spring of
//!   the given stiffness (compliance), with a dead zone of width `2 b` (play), damped. The
//!   encoder sits on the motor, as on the dVRK: the controller and the recorded `measured_js`
//!   see the motor; the link lags by the deflection or the play;
//! - `latency`: the measured joint stream (what the controller and the recorder see) is the
//!   state `seconds` ago;
//! - `coupling_error`: the mechanism is built on the true joints (`q_true = B q`, dvrk-kin's
//!   [`dvrk_kin::Model::coupling_error_map`]); the controller reads `B^-1 q_true` and its
//!   efforts reach the joints as `B^-T tau` (the motors push through the true cables);
//! - `payload_mass`: mass and inertia added to the link's body when the sim is built;
//! - `counterweight_error`: the counterweight's mass when the sim is built, its travel per unit
//!   insertion in the compiled model's kinematics (its cable follows the insertion by that ratio);
//! - `joint_offset`, `link_length`, `base_registration`: already in the compiled model's
//!   kinematics, which the sim is built from.
//!
//! Allocation happens at build time only.

use crate::error::{Result, SimError};
use dvrk_kin::effects::{Effect, EffectKind};
use dvrk_kin::presliding::PreslidingState;
use dvrk_kin::Model;
use nalgebra::{DMatrix, DVector, DVectorView};

/// Velocity (rad/s, m/s) below which the Coulomb force is smoothed (`tanh(qd / v)`): a stiff
/// regularisation of stick; kept stable by [`ArmEffects::new`] against the joint's drive inertia.
pub const COULOMB_VELOCITY: f64 = 1e-3;

/// Natural frequency of the stiff contact that stands in for a rigid transmission behind a
/// backlash without compliance (rad/s); explicit integration keeps `w dt` at 0.2.
const CONTACT_BANDWIDTH_DT: f64 = 0.2;

/// The largest `w dt` the explicit transmission step holds for a drive's motor mode `w`.
const MODE_DT: f64 = 0.5;

/// The motor side of a two-mass drive.
#[derive(Debug, Clone)]
pub struct Transmission {
    /// N·m/rad or N/m.
    pub stiffness: f64,
    /// N·m s/rad or N s/m (on the motor-link velocity difference).
    pub damping: f64,
    /// Half the play (rad or m).
    pub half_play: f64,
    /// Motor inertia (kg m^2 or kg).
    pub inertia: f64,
    /// Motor position and velocity (joint units).
    pub position: f64,
    pub velocity: f64,
}

impl Transmission {
    /// The torque the transmission puts on the link for link position `q`, velocity `qd`.
    pub fn torque(&self, q: f64, qd: f64) -> f64 {
        let x = self.position - q;
        let stretch = if x > self.half_play {
            x - self.half_play
        } else if x < -self.half_play {
            x + self.half_play
        } else {
            0.0
        };
        let engaged = stretch != 0.0 || self.half_play == 0.0;
        self.stiffness * stretch + if engaged { self.damping * (self.velocity - qd) } else { 0.0 }
    }

    /// Advance the motor by `dt` under actuator effort `effort`, the link at `q`, `qd`; returns
    /// the torque on the link (semi-implicit Euler).
    pub fn step(&mut self, effort: f64, q: f64, qd: f64, dt: f64) -> f64 {
        let t = self.torque(q, qd);
        self.velocity += dt * (effort - t) / self.inertia;
        self.position += dt * self.velocity;
        t
    }
}

/// The measured stream `steps` behind the true one (ring buffers sized at build).
#[derive(Debug, Clone)]
pub struct Delay {
    pub steps: usize,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    head: usize,
}

impl Delay {
    fn new(steps: usize, q0: &[f64]) -> Delay {
        Delay { steps, q: vec![q0.to_vec(); steps + 1], qd: vec![vec![0.0; q0.len()]; steps + 1], head: 0 }
    }

    /// Push the current state; write the delayed one into `q`, `qd`.
    pub fn push(&mut self, q: &mut [f64], qd: &mut [f64]) {
        self.head = (self.head + 1) % (self.steps + 1);
        self.q[self.head].copy_from_slice(q);
        self.qd[self.head].copy_from_slice(qd);
        let tail = (self.head + 1) % (self.steps + 1);
        q.copy_from_slice(&self.q[tail]);
        qd.copy_from_slice(&self.qd[tail]);
    }
}

/// A coupling error between the joints read and the true ones: `q_true = B q_read`, efforts by
/// virtual work (`tau_true = B^-T tau_read`). Matrices and scratch sized at build.
#[derive(Debug, Clone)]
pub struct CouplingMap {
    /// `B`
    pub to_link: DMatrix<f64>,
    /// `B^-1`
    to_read: DMatrix<f64>,
    /// `B^-T`
    torque_to_link: DMatrix<f64>,
    scratch: DVector<f64>,
}

impl CouplingMap {
    fn new(b: DMatrix<f64>) -> Option<CouplingMap> {
        let inv = b.clone().try_inverse()?;
        let n = b.nrows();
        Some(CouplingMap { torque_to_link: inv.transpose(), to_read: inv, to_link: b, scratch: DVector::zeros(n) })
    }

    fn apply(m: &DMatrix<f64>, scratch: &mut DVector<f64>, x: &mut [f64]) {
        scratch.gemv(1.0, m, &DVectorView::from_slice(x, x.len()), 0.0);
        x.copy_from_slice(scratch.as_slice());
    }

    /// True joint positions or velocities `x` to what the controller reads, in place.
    pub fn read(&mut self, x: &mut [f64]) {
        Self::apply(&self.to_read, &mut self.scratch, x);
    }

    /// The controller's efforts `x` to the true joints' efforts, in place.
    pub fn torque_to_link(&mut self, x: &mut [f64]) {
        Self::apply(&self.torque_to_link, &mut self.scratch, x);
    }

    /// Positions read `x` to the true joints'.
    pub fn link(&self, x: &[f64]) -> Vec<f64> {
        (&self.to_link * DVector::from_column_slice(x)).as_slice().to_vec()
    }
}

/// Per joint, the drive's inertia the simulator gives it (kg m^2, kg): the scene's armature plus
/// the diagonal of the motors' coupled inertia (`motor_inertia` effects, `C^-T diag(I) C^-1`).
/// rapier's multibody and MuJoCo hold a diagonal armature only, so the cross terms are not
/// simulated (dvrk-kin's inverse dynamics has them).
pub fn drive_armature(model: &Model, armature: &[f64]) -> Vec<f64> {
    let n = model.nq();
    let mut motor = nalgebra::DMatrix::zeros(n, n);
    dvrk_kin::effects::motor_inertia_matrix(&model.effects, &mut motor);
    armature.iter().enumerate().map(|(k, a)| a + if k < n { motor[(k, k)] } else { 0.0 }).collect()
}

/// The largest time step (s) that resolves every compliant drive of `model` (`joint_compliance`
/// on a drive of inertia [`drive_armature`]): the motor's mode `w = sqrt(k / I)` needs
/// `w dt <= MODE_DT` (0.5) in the explicit transmission step. Infinite when no drive is
/// compliant (backlash alone takes a contact stiffness scaled to the step).
pub fn max_stable_dt(model: &Model, armature: &[f64]) -> f64 {
    let inertia = drive_armature(model, armature);
    model
        .effects
        .iter()
        .filter(|e| e.kind == EffectKind::JointCompliance)
        .filter_map(|e| {
            let j = e.joint?;
            let (k, i) = (e.get("stiffness"), *inertia.get(j)?);
            (k > 0.0 && i > 0.0).then(|| MODE_DT / (k / i).sqrt())
        })
        .fold(f64::INFINITY, f64::min)
}

/// The effects of one arm, ready to step.
#[derive(Debug, Clone)]
pub struct ArmEffects {
    /// Friction and spring effects (dvrk-kin's [`dvrk_kin::effects::effort`]).
    forces: Vec<Effect>,
    /// Per joint: the drive's transmission, if compliant or with play.
    pub transmissions: Vec<Option<Transmission>>,
    pub delay: Option<Delay>,
    pub coupling: Option<CouplingMap>,
    /// Scratch: joint forces of the friction and spring effects (N·m, N).
    pub force: Vec<f64>,
    /// Scratch: the actuators' efforts on their way to the joints (N·m, N).
    pub drive: Vec<f64>,
    velocity_scale: f64,
    /// The Coulomb frictions' presliding (Dahl) states, stepped with the links; `None` when no
    /// effect has a presliding level.
    presliding: Option<PreslidingState>,
}

impl ArmEffects {
    /// The effects of `model` for a sim stepping `dt` with drive inertias `armature` (per joint).
    /// `start`: the joint positions (as read) the arm starts at.
    pub fn new(name: &str, model: &Model, armature: &[f64], start: &[f64], dt: f64) -> Result<ArmEffects> {
        let n = model.nq();
        let coupling = match model.coupling_error_map() {
            Some(b) => Some(CouplingMap::new(b).ok_or_else(|| SimError::Build(format!("{name} effect coupling_error: the map to the true joints is singular")))?),
            None => None,
        };
        let link_start = coupling.as_ref().map(|c| c.link(start));
        let mut out =
            ArmEffects {
            forces: Vec::new(),
            transmissions: vec![None; n],
            delay: None,
            coupling,
            force: vec![0.0; n],
            drive: vec![0.0; n],
            velocity_scale: COULOMB_VELOCITY,
            presliding: None,
        };
        // The motors of two-mass drives sit on the true joints.
        let home = link_start.as_deref().unwrap_or(start);
        for e in &model.effects {
            let what = |j: Option<usize>| format!("{name} effect {}{}", e.kind.name(), j.map(|j| format!(" on {}", model.joints[j].name)).unwrap_or_default());
            match e.kind {
                EffectKind::CoulombFriction
                | EffectKind::ViscousFriction
                | EffectKind::Spring
                | EffectKind::CableSpring
                | EffectKind::ActuatorCoulombFriction
                | EffectKind::ActuatorViscousFriction
                | EffectKind::ActuatorSpring
                | EffectKind::ActuatorCrossSpring => {
                    // The smoothed Coulomb force acts like a damper of fc / v below v: keep its
                    // explicit step stable on the drive's inertia (c dt / I <= 0.5); an
                    // actuator's damps joint j by w_j^2 fc / v.
                    let reach: Vec<(usize, f64)> = match (e.kind, e.joint) {
                        (EffectKind::CoulombFriction, Some(j)) => vec![(j, 1.0)],
                        (EffectKind::ActuatorCoulombFriction, _) => e.transmission.clone(),
                        _ => Vec::new(),
                    };
                    // Its level at rest, where the joints furthest from their zero (the winding term).
                    // (An unlimited joint: ten units.)
                    let reach_limit = |j: usize| model.joints[j].lower.abs().max(model.joints[j].upper.abs()).min(10.0);
                    let far: f64 = reach.iter().map(|(j, w)| (w * reach_limit(*j)).abs()).sum();
                    // (Its sliding limit with any presliding level: the damper bounds the sign's slope.)
                    let level = dvrk_kin::effects::coulomb_level(e, far, 0.0).max(dvrk_kin::effects::coulomb_level(e, 0.0, 0.0)) + e.get("fd").abs();
                    for (j, w) in reach {
                        if armature[j] > 0.0 {
                            out.velocity_scale = out.velocity_scale.max(2.0 * level * w * w * dt / armature[j]);
                        }
                    }
                    out.forces.push(e.clone());
                }
                // A play by motion direction is the same dead zone as a load-side play: where its
                // link rests in the gap is the dynamics' outcome (its load against its friction).
                EffectKind::JointCompliance | EffectKind::Backlash | EffectKind::MotionPlay => {
                    let j = e.joint.ok_or_else(|| SimError::Build(format!("{}: no joint", what(None))))?;
                    let inertia = armature[j];
                    if inertia <= 0.0 {
                        return Err(SimError::Build(format!("{}: the two-mass drive needs the joint's armature (motor inertia) > 0 in the scene", what(Some(j)))));
                    }
                    let t = out.transmissions[j].get_or_insert_with(|| Transmission { stiffness: 0.0, damping: 0.0, half_play: 0.0, inertia, position: home[j], velocity: 0.0 });
                    match e.kind {
                        EffectKind::JointCompliance => t.stiffness = e.get("stiffness"),
                        _ => t.half_play = e.get("b"),
                    }
                }
                EffectKind::Latency => {
                    let steps = (e.get("seconds") / dt).round() as usize;
                    if steps > 0 {
                        out.delay = Some(Delay::new(steps, start));
                    }
                }
                // The motors' inertia is the drives' armature (crate::sim).
                EffectKind::PayloadMass
                | EffectKind::MotorInertia
                | EffectKind::CounterweightError
                | EffectKind::CouplingError
                | EffectKind::JointOffset
                | EffectKind::LinkLength
                | EffectKind::BaseRegistration
                // The tracker's clock: a recording's, not the arm's.
                | EffectKind::ClockOffset => {}
            }
        }
        for (j, t) in out.transmissions.iter_mut().enumerate() {
            let Some(t) = t else { continue };
            // Backlash alone: a stiff contact stands in for the rigid transmission.
            let contact = t.inertia * (CONTACT_BANDWIDTH_DT / dt).powi(2);
            if t.stiffness == 0.0 {
                t.stiffness = contact;
            }
            let w = (t.stiffness / t.inertia).sqrt();
            if w * dt > MODE_DT {
                return Err(SimError::Build(format!(
                    "{name} joint {}: transmission stiffness {} on motor inertia {} has a {w:.0} rad/s mode, too stiff for dt = {dt} s (at most {:.3e}; use a smaller dt)",
                    model.joints[j].name,
                    t.stiffness,
                    t.inertia,
                    t.inertia * (MODE_DT / dt).powi(2)
                )));
            }
            // A lightly damped transmission (damping ratio 0.1 on the motor's own mode).
            t.damping = 0.2 * (t.stiffness * t.inertia).sqrt();
        }
        if out.forces.iter().any(dvrk_kin::presliding::has_presliding) {
            out.presliding = Some(PreslidingState::new(&out.forces, home));
        }
        Ok(out)
    }

    /// The friction and spring forces at the link's `q`, `qd` into [`ArmEffects::force`].
    /// A presliding state steps from the last call's positions to `q` (one call per step).
    pub fn update_forces(&mut self, q: &[f64], qd: &[f64]) {
        self.force.fill(0.0);
        match self.presliding.as_mut() {
            Some(states) => {
                states.advance(&self.forces, q);
                dvrk_kin::presliding::effort_with_presliding(&self.forces, q, qd, states, self.velocity_scale, &mut self.force);
            }
            None => dvrk_kin::effects::effort(&self.forces, q, qd, self.velocity_scale, &mut self.force),
        }
    }
}
