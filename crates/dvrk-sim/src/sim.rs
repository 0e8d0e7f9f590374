//! A running simulation ([`Sim`]): one API over both engines (setpoints, modes, gains, efforts,
//! the measured and link-side joints, stepping, energy and closure checks). The rapier engine's
//! world is built by `rapier_build.rs` and lives in `rapier_world.rs` (one rigid body per
//! dvrk-kin body, the frame tree as one multibody per arm, each loop closed by a spherical
//! impulse joint, passive joints outside any loop tied to their driver by a cable); the reduced
//! engine is [`crate::reduced`]. The control layer both share is `arm_state.rs`.
//!
//! Every tree joint's rapier coordinate equals the dvrk-kin frame variable (`theta` or `d`, an
//! affine map of `q`), so joint values read back directly.

use crate::control::{Actuator, Gains, Mode, POSITION_DAMPING, POSITION_STIFFNESS};
use crate::error::{Result, SimError};
use crate::rapier_world::*;
use crate::scene::Scene;
use dvrk_kin::Pose;
use rapier3d_f64::math::Vector as RVec;
use rapier3d_f64::prelude::*;

pub use crate::arm_state::ArmState;
pub use crate::options::{ClosingLinks, Colliders, Coriolis, Engine, LoopMode, SimOptions};
pub use crate::rapier_world::{from_rapier, mass_properties, to_rapier};

/// A running simulation. Built once from a [`Scene`]; [`Sim::step`] allocates nothing of its own.
pub struct Sim {
    pub scene_name: String,
    pub dt: f64,
    pub time: f64,
    pub arms: Vec<ArmState>,
    /// One rapier world per independent arm group (an arm on the fixed world and the arms it
    /// carries); `ArmState::world` indexes it.
    pub(crate) worlds: Vec<World>,
    pub(crate) parallel: bool,
    pub(crate) gravity: RVec,
    /// Measured q, qd and applied effort of every joint of the scene (rad, m; /s; N·m, N).
    pub(crate) q: Vec<f64>,
    pub(crate) qd: Vec<f64>,
    /// The links' own joint positions and velocities (rad, m; /s): equal to `q`, `qd` unless an
    /// effect (a compliant drive, play, latency, a coupling error: then the true joints)
    /// separates what is measured from the link.
    pub(crate) q_link: Vec<f64>,
    pub(crate) qd_link: Vec<f64>,
    /// With the reduced engine, each tree of arms (an arm on the world and those it carries;
    /// then `worlds` is empty), and per scene arm its tree and place in the tree's arm list.
    pub(crate) reduced: Vec<crate::reduced::ReducedTree>,
    pub(crate) reduced_place: Vec<(usize, usize)>,
}

impl Sim {
    /// Build `scene` on the engine `options` (or the scene) choose, rapier by default, with every
    /// joint at its home position, in PID mode holding home.
    pub fn new(scene: &Scene, options: &SimOptions) -> Result<Sim> {
        // Each engine's builder returns its parts: the rapier worlds, or the reduced trees with
        // each scene arm's place in them.
        let (arms, worlds, reduced, reduced_place, nq) = if options.engine.or(scene.engine) == Some(Engine::Reduced) {
            let (arms, trees, place, nq) = crate::reduced::build(scene, options)?;
            (arms, Vec::new(), trees, place, nq)
        } else {
            let (arms, worlds, nq) = crate::rapier_build::build(scene, options)?;
            (arms, worlds, Vec::new(), Vec::new(), nq)
        };
        let g = if options.no_gravity { [0.0; 3] } else { scene.gravity };
        let mut sim = Sim {
            scene_name: scene.name.clone(),
            dt: scene.dt,
            time: 0.0,
            arms,
            worlds,
            parallel: options.parallel,
            gravity: RVec::new(g[0], g[1], g[2]),
            q: vec![0.0; nq],
            qd: vec![0.0; nq],
            q_link: vec![0.0; nq],
            qd_link: vec![0.0; nq],
            reduced,
            reduced_place,
        };
        sim.read_state();
        sim.apply_modes(scene)?;
        Ok(sim)
    }

    /// Each arm's drives in the mode its scene entry asks for.
    pub(crate) fn apply_modes(&mut self, scene: &Scene) -> Result<()> {
        for (a, arm) in scene.arms.iter().enumerate() {
            if arm.mode != Mode::Pid {
                for k in 0..arm.model.nq() {
                    self.set_mode(self.arms[a].q_offset + k, arm.mode)?;
                }
            }
        }
        Ok(())
    }

    /// The physics engine stepping this sim.
    pub fn engine(&self) -> Engine {
        if self.reduced.is_empty() {
            Engine::Rapier
        } else {
            Engine::Reduced
        }
    }

    /// Number of joints of the scene (all arms).
    pub fn nq(&self) -> usize {
        self.q.len()
    }

    /// Measured joint positions (rad, m), scene order (arm by arm).
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Measured joint velocities (rad/s, m/s).
    pub fn qd(&self) -> &[f64] {
        &self.qd
    }

    /// (arm, joint) of scene joint `i`.
    fn locate(&self, i: usize) -> Result<(usize, usize)> {
        for (a, arm) in self.arms.iter().enumerate() {
            if i < arm.q_offset + arm.model.nq() {
                return Ok((a, i - arm.q_offset));
            }
        }
        Err(SimError::value("joint index", i as f64, format!("the scene has {} joints", self.nq())))
    }

    /// The model joint of scene joint `i`: its name, kind, limits (rad or m) and effort limit.
    pub fn joint(&self, i: usize) -> Result<&dvrk_kin::Joint> {
        let (a, k) = self.locate(i)?;
        Ok(&self.arms[a].model.joints[k])
    }

    /// The actuator of scene joint `i`.
    pub fn actuator(&self, i: usize) -> Result<&Actuator> {
        let (a, k) = self.locate(i)?;
        Ok(&self.arms[a].actuators[k])
    }

    fn joint_name(&self, a: usize, k: usize) -> String {
        format!("{} joint {}", self.arms[a].name, self.arms[a].model.joints[k].name)
    }

    /// Switch joint `i` to `mode`. Entering position mode holds the current target.
    pub fn set_mode(&mut self, i: usize, mode: Mode) -> Result<()> {
        let (a, k) = self.locate(i)?;
        let act = &mut self.arms[a].actuators[k];
        if act.mode != mode {
            act.integral = 0.0;
        }
        act.mode = mode;
        self.apply_position_motor(a, k);
        Ok(())
    }

    /// Position target (rad, m) and velocity feed-forward (rad/s, m/s) of joint `i`. Non-finite
    /// values are rejected; targets outside the joint limits are clamped to them.
    pub fn set_target(&mut self, i: usize, position: f64, velocity: f64) -> Result<()> {
        let (a, k) = self.locate(i)?;
        // The name only on error: a controller calls this every step (no allocation).
        if !position.is_finite() {
            return Err(SimError::value(format!("{} target position", self.joint_name(a, k)), position, "must be finite"));
        }
        if !velocity.is_finite() {
            return Err(SimError::value(format!("{} target velocity", self.joint_name(a, k)), velocity, "must be finite"));
        }
        let (lower, upper) = (self.arms[a].model.joints[k].lower, self.arms[a].model.joints[k].upper);
        let act = &mut self.arms[a].actuators[k];
        act.target = position.clamp(lower, upper);
        act.target_velocity = velocity;
        // A coupling error: every drive's true target moves with this one.
        let coupled = self.arms[a].effects.coupling.is_some();
        for m in 0..self.arms[a].actuators.len() {
            if (m == k || coupled) && self.arms[a].actuators[m].mode == Mode::Position {
                self.apply_position_motor(a, m);
            }
        }
        Ok(())
    }

    /// Open-loop effort of joint `i` (N·m, N), used in effort mode; clamped at the effort limit.
    pub fn set_effort(&mut self, i: usize, effort: f64) -> Result<()> {
        let (a, k) = self.locate(i)?;
        if !effort.is_finite() {
            return Err(SimError::value(format!("{} effort", self.joint_name(a, k)), effort, "must be finite"));
        }
        self.arms[a].actuators[k].effort_command = effort;
        Ok(())
    }

    /// Feed-forward effort of joint `i` added to its PID output (N·m, N; inside the effort
    /// limit): a recorded effort replayed under weak feedback, say. Arms with gravity
    /// compensation overwrite it every step.
    pub fn set_feedforward(&mut self, i: usize, effort: f64) -> Result<()> {
        let (a, k) = self.locate(i)?;
        if !effort.is_finite() {
            return Err(SimError::value(format!("{} feed-forward", self.joint_name(a, k)), effort, "must be finite"));
        }
        self.arms[a].actuators[k].feedforward = effort;
        Ok(())
    }

    /// PID gains of joint `i`; rejected unless finite and non-negative.
    pub fn set_gains(&mut self, i: usize, gains: Gains) -> Result<()> {
        let (a, k) = self.locate(i)?;
        gains.check(&self.joint_name(a, k))?;
        self.arms[a].actuators[k].gains = gains;
        Ok(())
    }

    /// Joint damping (N·m s/rad, N s/m) of every tree joint, and armature scale, for all arms
    /// (the energy check turns both off).
    pub fn set_damping_and_armature(&mut self, damping: f64, armature_scale: f64) -> Result<()> {
        for (name, v) in [("damping", damping), ("armature scale", armature_scale)] {
            if !v.is_finite() || v < 0.0 {
                return Err(SimError::value(name, v, "must be finite and non-negative"));
            }
        }
        if !self.reduced.is_empty() {
            for r in self.reduced.iter_mut() {
                r.set_damping_and_armature(damping, armature_scale);
            }
            return Ok(());
        }
        // Arms carried by another arm share its multibody: scale each multibody's armature once.
        let mut done: Vec<(usize, MultibodyIndex)> = Vec::new();
        for arm in &self.arms {
            let mbs = &mut self.worlds[arm.world].multibody_joints;
            let (index, _) = multibody_index(mbs, arm.dofs[0].handle)?;
            if done.contains(&(arm.world, index)) {
                continue;
            }
            done.push((arm.world, index));
            let (mb, _) = mbs.get_mut(arm.dofs[0].handle).ok_or_else(|| SimError::Build("multibody vanished".into()))?;
            for x in mb.damping_mut().iter_mut() {
                *x = damping;
            }
            for x in mb.armature_mut().iter_mut() {
                *x *= armature_scale;
            }
        }
        // The drives' damping: part implicit, part explicit, as built.
        for arm in self.arms.iter_mut() {
            arm.explicit_damping = explicit_share(damping);
            for dr in &arm.drives {
                let Some((mb, link)) = self.worlds[arm.world].multibody_joints.get_mut(arm.dofs[dr.dof].handle) else { continue };
                let Some(assembly) = mb.link(link).map(|l| l.assembly_id()) else { continue };
                split_drive_damping(mb, assembly, damping);
            }
        }
        Ok(())
    }

    /// Rapier's implicit position motor on a drive in position mode (stiff, unlimited), off otherwise.
    fn apply_position_motor(&mut self, a: usize, k: usize) {
        if !self.reduced.is_empty() {
            // The reduced engine reads the targets every step.
            return;
        }
        let arm = &self.arms[a];
        let act = &arm.actuators[k];
        let dr = &arm.drives[k];
        let dof = &arm.dofs[dr.dof];
        let axis = if dof.revolute { JointAxis::AngX } else { JointAxis::LinX };
        let Some((mb, link)) = self.worlds[arm.world].multibody_joints.get_mut(dof.handle) else { return };
        let Some(l) = mb.link_mut(link) else { return };
        if act.mode == Mode::Position {
            // Under a coupling error the drive holds the true joint the targets read as.
            let (position, velocity) = arm.held_target(k);
            l.joint.data.set_motor_model(axis, MotorModel::AccelerationBased);
            l.joint.data.set_motor(axis, dr.c * position + dr.b, dr.c * velocity, POSITION_STIFFNESS, POSITION_DAMPING);
            l.joint.data.set_motor_max_force(axis, Real::MAX);
        } else {
            l.joint.data.set_motor(axis, 0.0, 0.0, 0.0, 0.0);
            l.joint.data.set_motor_max_force(axis, 0.0);
        }
    }

    /// Read the links' q, qd from the multibody coordinates, then what is measured: the motor of
    /// a two-mass drive, delayed by the arm's latency.
    pub(crate) fn read_state(&mut self) {
        if self.reduced.is_empty() {
            self.read_links();
        } else {
            for (arm, &(t, k)) in self.arms.iter().zip(&self.reduced_place) {
                let (off, js) = (arm.q_offset, self.reduced[t].joints(k));
                self.q_link[off..off + js.len()].copy_from_slice(&self.reduced[t].q[js.clone()]);
                self.qd_link[off..off + js.len()].copy_from_slice(&self.reduced[t].qd[js]);
            }
        }
        for arm in self.arms.iter_mut() {
            let (off, n) = (arm.q_offset, arm.model.nq());
            for k in 0..n {
                let i = off + k;
                (self.q[i], self.qd[i]) = match &arm.effects.transmissions[k] {
                    Some(t) => (t.position, t.velocity),
                    None => (self.q_link[i], self.qd_link[i]),
                };
            }
            if let Some(c) = arm.effects.coupling.as_mut() {
                c.read(&mut self.q[off..off + n]);
                c.read(&mut self.qd[off..off + n]);
            }
            if let Some(d) = arm.effects.delay.as_mut() {
                d.push(&mut self.q[off..off + n], &mut self.qd[off..off + n]);
            }
        }
    }

    /// The links' q, qd from the rapier multibody coordinates.
    fn read_links(&mut self) {
        for arm in self.arms.iter_mut() {
            for (k, dr) in arm.drives.iter().enumerate() {
                let i = arm.q_offset + k;
                let dof = &arm.dofs[dr.dof];
                let Some((mb, link)) = self.worlds[arm.world].multibody_joints.get(dof.handle) else { continue };
                let Some(l) = mb.link(link) else { continue };
                let coord = l.joint().coords()[if dof.revolute { 3 } else { 0 }];
                let q = (coord - dr.b) / dr.c;
                // The velocity is the coordinate's change over the step: exactly what the
                // integrator applied (coords += v dt), and independent of rapier's DoF ordering.
                if self.time > 0.0 {
                    self.qd_link[i] = (q - self.q_link[i]) / self.dt;
                }
                self.q_link[i] = q;
            }
        }
    }

    /// The links' own joint positions (rad, m), which the measured [`Sim::q`] differs from
    /// under a compliant drive, play, latency or a coupling error (the true joints, `B q`).
    pub fn q_link(&self) -> &[f64] {
        &self.q_link
    }

    /// Advance one time step: controllers, efforts applied as joint torques/forces, physics.
    pub fn step(&mut self) {
        if !self.reduced.is_empty() {
            return self.step_reduced();
        }
        // User forces and torques persist in rapier until cleared: clear both every step.
        for w in self.worlds.iter_mut() {
            for (_, rb) in w.bodies.iter_mut() {
                rb.reset_forces(false);
                rb.reset_torques(false);
            }
        }
        for arm in self.arms.iter_mut() {
            let off = arm.q_offset;
            arm.link_efforts(&self.q, &self.qd, &self.q_link, &self.qd_link, self.dt);
            if let Some(c) = arm.coriolis.as_mut() {
                let n = arm.model.nq();
                c.update(&self.q_link[off..off + n], &self.worlds[arm.world].multibody_joints, &arm.dofs, self.dt);
                for (d, f) in arm.dofs.iter().zip(&c.force) {
                    apply_generalized(&mut self.worlds[arm.world].bodies, d, *f);
                }
            }
            for (k, dr) in arm.drives.iter().enumerate() {
                // Generalised force on the drive's coordinate (tau dq = f dcoord), with the
                // explicit part of its damping on the velocity the step starts with (the link's
                // qd: the coordinate's last change over dt, per unit of q).
                let f = arm.effects.drive[k] / dr.c - arm.explicit_damping * dr.c * self.qd_link[off + k];
                if f == 0.0 {
                    continue;
                }
                apply_generalized(&mut self.worlds[arm.world].bodies, &arm.dofs[dr.dof], f);
            }
        }
        self.apply_cables();
        let gravity = self.gravity;
        if self.parallel && self.worlds.len() > 1 {
            use rayon::prelude::*;
            self.worlds.par_iter_mut().for_each(|w| w.step(gravity));
        } else {
            for w in self.worlds.iter_mut() {
                w.step(gravity);
            }
        }
        self.time += self.dt;
        self.read_state();
    }

    /// Cables: the spring-damper tension on each follower and its reaction on the leader.
    fn apply_cables(&mut self) {
        for arm in &self.arms {
            let w = &mut self.worlds[arm.world];
            for c in &arm.cables {
                let (Some((xl, vl)), Some((xf, vf))) = (coordinate(&w.multibody_joints, &arm.dofs[c.leader]), coordinate(&w.multibody_joints, &arm.dofs[c.follower])) else {
                    continue;
                };
                let tension = -c.stiffness * (xf - (c.coeff * xl + c.offset)) - c.damping * (vf - c.coeff * vl);
                apply_generalized(&mut w.bodies, &arm.dofs[c.follower], tension);
                apply_generalized(&mut w.bodies, &arm.dofs[c.leader], -c.coeff * tension);
            }
        }
    }

    /// Scale every cable's damper (1: as built, 0: a lossless cable; the energy check uses 0).
    pub fn set_cable_damping_scale(&mut self, scale: f64) -> Result<()> {
        if !scale.is_finite() || scale < 0.0 {
            return Err(SimError::value("cable damping scale", scale, "must be finite and non-negative"));
        }
        for arm in &mut self.arms {
            for c in &mut arm.cables {
                c.damping = c.built_damping * scale;
            }
        }
        Ok(())
    }

    /// World pose of dvrk-kin body `body` of arm `arm` (its first frame).
    pub fn body_pose(&self, arm: usize, body: usize) -> Pose {
        if let Some(&(t, k)) = self.reduced_place.get(arm) {
            return self.reduced[t].frame_pose(k, self.arms[arm].model.bodies[body].frames[0]);
        }
        let a = &self.arms[arm];
        from_rapier(self.worlds[a.world].bodies[a.bodies[body]].position())
    }

    /// World pose of frame `frame` of arm `arm`, from its body's pose and the model's constant
    /// placement of the frame in the body (m).
    pub fn frame_pose(&self, arm: usize, frame: usize, rel: &Pose) -> Pose {
        let b = self.arms[arm].model.frames[frame].body;
        self.body_pose(arm, b) * rel
    }

    /// Gauss-Seidel sweeps per substep of each rapier world (arm group), in the order the groups'
    /// root arms appear in the scene.
    pub fn group_pgs_iterations(&self) -> Vec<usize> {
        self.worlds.iter().map(|w| w.params.num_internal_pgs_iterations).collect()
    }

    /// Largest loop-closure gap over all arms (m): distance between the two bodies' copies of
    /// each closure point.
    pub fn closure_error(&self) -> f64 {
        let mut worst: f64 = 0.0;
        for r in &self.reduced {
            let gap = r.closure_error();
            if gap.is_nan() {
                return f64::NAN;
            }
            worst = worst.max(gap);
        }
        for arm in &self.arms {
            for c in &arm.closures {
                let bodies = &self.worlds[arm.world].bodies;
                let pa = bodies[c.a].position().transform_point(c.pa);
                let pb = bodies[c.b].position().transform_point(c.pb);
                let gap = (pa - pb).length();
                // A non-finite state is not a closed loop: NaN, never hidden by `max`.
                if gap.is_nan() {
                    return f64::NAN;
                }
                worst = worst.max(gap);
            }
        }
        worst
    }

    /// An error naming the first joint whose position or velocity is not finite, if any.
    pub fn check_finite(&self) -> Result<()> {
        let (q, qd) = (self.q(), self.qd());
        match (0..q.len()).find(|&i| !(q[i].is_finite() && qd[i].is_finite())) {
            None => Ok(()),
            Some(i) => Err(SimError::Diverged { time: self.time, message: format!("joint {i} at q = {}, qd = {} (the state is left as it is)", q[i], qd[i]) }),
        }
    }

    /// Effort applied at the last step by joint `i`'s actuator (N·m, N).
    pub fn effort(&self, i: usize) -> Result<f64> {
        Ok(self.actuator(i)?.effort)
    }

    /// Largest |generalised velocity| of any tree joint of any arm (rad/s or m/s), for diagnostics.
    pub fn max_tree_velocity(&self) -> f64 {
        if !self.reduced.is_empty() {
            return self.qd_link.iter().fold(0.0, |a: f64, v| a.max(v.abs()));
        }
        self.arms
            .iter()
            .filter_map(|a| self.worlds[a.world].multibody_joints.get(a.dofs[0].handle))
            .map(|(mb, _)| mb.generalized_velocity().amax())
            .fold(0.0, f64::max)
    }

    /// Total mechanical energy (J): kinetic plus gravitational potential of every body, the
    /// kinetic energy of the drives' armature (reflected rotor inertia) and the energy stored in
    /// the cables' springs.
    pub fn energy(&self) -> f64 {
        if !self.reduced.is_empty() {
            return self.reduced.iter().map(|r| r.energy()).sum();
        }
        let g = self.gravity;
        let bodies: f64 = self
            .worlds
            .iter()
            .flat_map(|w| w.bodies.iter())
            .filter(|(_, rb)| rb.is_dynamic())
            .map(|(_, rb)| rb.kinetic_energy() - rb.mass() * g.dot(rb.center_of_mass()))
            .sum();
        let mut extra = 0.0;
        for arm in &self.arms {
            let mbs = &self.worlds[arm.world].multibody_joints;
            for d in &arm.dofs {
                if let Some((mb, link)) = mbs.get(d.handle) {
                    if let Some(l) = mb.link(link) {
                        let v = mb.joint_velocity(l)[0];
                        extra += 0.5 * mb.armature()[l.assembly_id()] * v * v;
                    }
                }
            }
            for c in &arm.cables {
                if let (Some((xl, _)), Some((xf, _))) = (coordinate(mbs, &arm.dofs[c.leader]), coordinate(mbs, &arm.dofs[c.follower])) {
                    let stretch = xf - (c.coeff * xl + c.offset);
                    extra += 0.5 * c.stiffness * stretch * stretch;
                }
            }
        }
        bodies + extra
    }

    /// [`Sim::step`] with the reduced engine.
    pub(crate) fn step_reduced(&mut self) {
        for (a, arm) in self.arms.iter_mut().enumerate() {
            arm.link_efforts(&self.q, &self.qd, &self.q_link, &self.qd_link, self.dt);
            let (t, k) = self.reduced_place[a];
            let tree = &mut self.reduced[t];
            let js = tree.joints(k);
            for (j, i) in js.enumerate() {
                tree.tau[i] = arm.effects.drive[j];
                tree.hold[i] = (arm.actuators[j].mode == crate::control::Mode::Position).then(|| arm.held_target(j));
            }
        }
        // One thread: a tree's step (~10 us for a SUJ with its PSM) is too small a task; rayon's
        // dispatch per step halved the full cart's speed (72x -> 38x real time).
        for tree in self.reduced.iter_mut() {
            tree.step(self.dt);
        }
        self.time += self.dt;
        self.read_state();
    }
}
