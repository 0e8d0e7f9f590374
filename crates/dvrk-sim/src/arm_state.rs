//! Per-arm state of a running sim: the control layer both engines share (actuators, effects,
//! gravity compensation, what an arm builds before its engine's part) and, for the rapier
//! engine, the arm's handles into its world.

use crate::control::Actuator;
use crate::error::Result;
use crate::options::SimOptions;
use crate::rapier_world::{Cable, ClosurePoints, Drive, ExplicitCoriolis, TreeDof};
use crate::scene::Scene;
use dvrk_kin::Model;
use nalgebra::Vector3;
use rapier3d_f64::prelude::*;

/// Per-arm data.
#[derive(Debug, Clone)]
pub struct ArmState {
    pub name: String,
    pub model: Model,
    /// Joint offset of this arm in the scene's joint vector.
    pub q_offset: usize,
    /// Rigid body of each dvrk-kin body.
    pub bodies: Vec<RigidBodyHandle>,
    pub(crate) dofs: Vec<TreeDof>,
    pub(crate) drives: Vec<Drive>,
    pub(crate) closures: Vec<ClosurePoints>,
    pub(crate) cables: Vec<Cable>,
    pub actuators: Vec<Actuator>,
    /// What the arm does in the tracking test.
    pub tracking: crate::scene::Tracking,
    /// The arm carrying this one and the frame its mount is on (`None`: the world).
    pub parent: Option<(usize, usize)>,
    /// The rapier world of this arm's group (see [`Sim`]).
    pub(crate) world: usize,
    /// The model's friction, springs, two-mass drives and latency ([`crate::effects`]).
    pub effects: crate::effects::ArmEffects,
    /// Gravity feed-forward on the PID efforts, if the scene asks for it.
    pub(crate) gravity_compensation: Option<GravityCompensation>,
    /// The explicit part of each drive's joint damping (N·m s/rad, N s/m per unit of its
    /// coordinate), on the velocity the step starts with; rapier applies the rest implicitly
    /// ([`DRIVE_DAMPING_EXPLICIT`]).
    pub(crate) explicit_damping: f64,
    /// With [`Coriolis::Explicit`]: what undoes rapier's implicit Coriolis.
    pub(crate) coriolis: Option<ExplicitCoriolis>,
}

impl ArmState {
    /// Scene arm `arm` without a rapier part (the reduced engine's, whose trees hold the
    /// mechanism; `world` is unused there).
    pub(crate) fn without_rapier(arm: &crate::scene::Arm, q_offset: usize, effects: crate::effects::ArmEffects, gravity_compensation: Option<GravityCompensation>) -> ArmState {
        ArmState {
            name: arm.name.clone(),
            model: arm.model.clone(),
            q_offset,
            bodies: Vec::new(),
            dofs: Vec::new(),
            drives: Vec::new(),
            closures: Vec::new(),
            cables: Vec::new(),
            actuators: actuators(arm),
            tracking: arm.tracking,
            parent: arm.parent,
            world: 0,
            effects,
            gravity_compensation,
            explicit_damping: 0.0,
            coriolis: None,
        }
    }

    /// The controllers' efforts on this arm's links (N·m, N) into `effects.drive`: the
    /// actuators on the measured joints (gravity feed-forward first), through a coupling
    /// error's map and any compliant transmission, plus the friction and spring effects on the
    /// links. Both engines apply these. `q`..`qd_link`: the scene's vectors.
    pub(crate) fn link_efforts(&mut self, q: &[f64], qd: &[f64], q_link: &[f64], qd_link: &[f64], dt: f64) {
        let (off, n) = (self.q_offset, self.model.nq());
        self.effects.update_forces(&q_link[off..off + n], &qd_link[off..off + n]);
        if let Some(gc) = self.gravity_compensation.as_mut() {
            // A measured q outside the model's checks (never from the sim) leaves it at zero.
            if dvrk_kin::gravity_torque(&self.model, &gc.dynamics, &mut gc.data, &q[off..off + n], &gc.gravity, &mut gc.torque).is_err() {
                gc.torque.fill(0.0);
            }
        }
        for k in 0..n {
            let i = off + k;
            if let Some(gc) = &self.gravity_compensation {
                self.actuators[k].feedforward = gc.torque[k];
            }
            self.effects.drive[k] = self.actuators[k].update(q[i], qd[i], dt);
        }
        if let Some(c) = self.effects.coupling.as_mut() {
            c.torque_to_link(&mut self.effects.drive);
        }
        for k in 0..n {
            let i = off + k;
            if let Some(t) = self.effects.transmissions[k].as_mut() {
                self.effects.drive[k] = t.step(self.effects.drive[k], q_link[i], qd_link[i], dt);
            }
            self.effects.drive[k] += self.effects.force[k];
        }
    }

    /// The link position (rad, m) and velocity a position-mode drive `k` holds: its target,
    /// through a coupling error's map to the true joint.
    pub(crate) fn held_target(&self, k: usize) -> (f64, f64) {
        match &self.effects.coupling {
            Some(c) => self.actuators.iter().enumerate().fold((0.0, 0.0), |(p, v), (j, a)| (p + c.to_link[(k, j)] * a.target, v + c.to_link[(k, j)] * a.target_velocity)),
            None => (self.actuators[k].target, self.actuators[k].target_velocity),
        }
    }
}

/// The model's gravity torque at the measured joints, added to PID efforts (dvrk-kin's
/// Newton-Euler on the same inertials, payloads included).
#[derive(Debug, Clone)]
pub(crate) struct GravityCompensation {
    pub(crate) dynamics: dvrk_kin::DynamicsModel,
    pub(crate) data: dvrk_kin::DynamicsData,
    /// m/s^2, world
    pub(crate) gravity: Vector3<f64>,
    /// N·m, N per joint
    pub(crate) torque: Vec<f64>,
}

/// What both engines build of a scene arm before their own part.
pub(crate) struct ArmPhysics {
    /// The mechanism on the true joints: those of a coupling error's map (`q_true = B q`), which
    /// the controller reads through ([`crate::effects`]).
    pub link_model: Model,
    /// The arm's start configuration on those joints (home unless the scene says otherwise).
    pub home: Vec<f64>,
    /// The bodies' inertials with any payload_mass effect added.
    pub inertias: Vec<dvrk_kin::BodyInertia>,
    /// Per joint, the drive's inertia ([`crate::effects::drive_armature`]).
    pub armature: Vec<f64>,
    pub effects: crate::effects::ArmEffects,
}

impl ArmPhysics {
    pub(crate) fn new(arm: &crate::scene::Arm, dt: f64) -> Result<ArmPhysics> {
        let link_model = arm.model.without_coupling_error();
        let home = match arm.model.coupling_error_map() {
            Some(b) => (b * nalgebra::DVector::from_column_slice(&arm.start)).as_slice().to_vec(),
            None => arm.start.clone(),
        };
        let inertias = dvrk_kin::effects::effect_inertias(&link_model, &link_model.effects, &arm.inertials.body_inertias(&link_model)?)?;
        let armature = crate::effects::drive_armature(&arm.model, &arm.armature);
        let effects = crate::effects::ArmEffects::new(&arm.name, &arm.model, &armature, &arm.start, dt)?;
        Ok(ArmPhysics { link_model, home, inertias, armature, effects })
    }
}

impl GravityCompensation {
    /// The gravity feed-forward of `arm` if its scene asks for it: on the joints read (the model
    /// with its coupling error), with the bodies' `inertias` (payloads included).
    pub(crate) fn of(arm: &crate::scene::Arm, scene: &Scene, options: &SimOptions, inertias: &[dvrk_kin::BodyInertia]) -> Result<Option<GravityCompensation>> {
        if !arm.gravity_compensation {
            return Ok(None);
        }
        let g = if options.no_gravity { [0.0; 3] } else { scene.gravity };
        Ok(Some(GravityCompensation {
            dynamics: dvrk_kin::DynamicsModel::new(&arm.model, inertias.to_vec())?,
            data: dvrk_kin::DynamicsData::new(&arm.model),
            gravity: Vector3::from(g),
            torque: vec![0.0; arm.model.nq()],
        }))
    }
}

/// The actuators of `arm`: PID with its gains, holding its start.
pub(crate) fn actuators(arm: &crate::scene::Arm) -> Vec<Actuator> {
    arm.model.joints.iter().enumerate().map(|(k, j)| Actuator::new(arm.gains[k], j.effort_limit, arm.start[k])).collect()
}
