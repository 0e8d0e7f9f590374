//! The reduced-coordinate engine: forward dynamics in the actuated joints, `M(q) q'' = tau -
//! h(q, q')`, with dvrk-kin's composite-rigid-body mass matrix and Newton-Euler bias on the
//! closed-loop tree. Every passive frame of a dVRK arm is an affine function of its joints
//! (`phi = C q + b`: the parallelograms, the counterweight's and the jaw's cables), so the loops
//! are closed exactly by construction and a step costs one CRBA, one RNEA and a small Cholesky.
//!
//! The step is rapier's scheme in these coordinates: semi-implicit Euler, the joint damping and
//! armature implicit, a position-mode drive an implicit acceleration-based spring (as rapier's
//! motor), limits as inelastic stops. The drive efforts, effects, transmissions, latency and
//! coupling errors come from the layer both engines share ([`crate::sim`]). Nothing allocates per
//! step: the arm's buffers are its workspace (the Model/Data split of dvrk-kin).

use crate::error::{Result, SimError};
use dvrk_kin::{DynamicsData, DynamicsModel, Model, Pose};
use nalgebra::{DMatrix, DVector, Vector3};

/// Stiffness of a position-mode drive (1/s^2, per unit of its joint's own inertia): rapier's
/// acceleration-based motor's (`crate::sim`), so both engines hold a joint alike.
pub const POSITION_STIFFNESS: f64 = 1.0e6;
/// Damping of a position-mode drive (1/s), as rapier's.
pub const POSITION_DAMPING: f64 = 6.0e3;

/// One arm's mechanism in its actuated joints: the model (immutable) and its workspace.
#[derive(Debug, Clone)]
pub struct ReducedArm {
    /// The mechanism on the true joints (a coupling error's map is the controller's business).
    model: Model,
    dynamics: DynamicsModel,
    data: DynamicsData,
    /// World, m/s^2.
    gravity: Vector3<f64>,
    /// Drive inertia per joint (kg m^2, kg): the scene's armature with the motors' coupled
    /// inertia, cross terms included (`C^-T diag(I) C^-1`); zero on a joint whose motor sits
    /// behind a compliant transmission (the motor side holds it there).
    drive_inertia: DMatrix<f64>,
    /// Joint damping in the joints, `d sum_i c_i c_i^T` over the tree joints `phi_i = c_i . q`
    /// (N·m s/rad, N s/m): rapier damps every tree joint of the multibody by `d`.
    damping: DMatrix<f64>,
    /// `sum_i c_i c_i^T` (the damping per unit of `d`).
    unit_damping: DMatrix<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// Link positions and velocities (rad, m; rad/s, m/s).
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Per joint: a position-mode target (rad or m, rad/s or m/s), `None` when driven by effort.
    pub hold: Vec<Option<(f64, f64)>>,
    // Workspace.
    mass: DMatrix<f64>,
    bias: Vec<f64>,
    zeros: Vec<f64>,
    rhs: DVector<f64>,
    column: DVector<f64>,
}

/// Gauss-Seidel sweeps over the joint stops met in one step.
const LIMIT_SWEEPS: usize = 4;
/// How far past a stop a step may end before the stop acts (rad or m): rounding, not physics.
const LIMIT_SLOP: f64 = 1e-12;

impl ReducedArm {
    /// The arm of `model` (on its true joints, its `base` the mount in the world) with body
    /// inertias `inertias` (payloads included), per-joint drive `armature` (kg m^2, kg; the
    /// motors' inertia added here), tree-joint `damping` (N·m s/rad), `gravity` (m/s^2) and
    /// `transmission[k]` true where joint k's motor sits behind a compliant drive. Starts at `q`.
    #[allow(clippy::too_many_arguments)]
    pub fn new(model: &Model, effects_model: &Model, inertias: Vec<dvrk_kin::BodyInertia>, armature: &[f64], damping: f64, gravity: [f64; 3], transmission: &[bool], q: &[f64]) -> Result<ReducedArm> {
        let n = model.nq();
        let dynamics = DynamicsModel::new(model, inertias)?;
        let mut drive_inertia = DMatrix::zeros(n, n);
        dvrk_kin::effects::motor_inertia_matrix(&effects_model.effects, &mut drive_inertia);
        for k in 0..n {
            drive_inertia[(k, k)] += armature.get(k).copied().unwrap_or(0.0);
        }
        for (k, held) in transmission.iter().enumerate().take(n) {
            if *held {
                drive_inertia.row_mut(k).fill(0.0);
                drive_inertia.column_mut(k).fill(0.0);
            }
        }
        let mut unit = DMatrix::zeros(n, n);
        for c in tree_joints(model) {
            unit += &c * c.transpose();
        }
        let (lower, upper) = model.joints.iter().map(|j| (j.lower, j.upper)).unzip();
        if q.len() != n {
            return Err(SimError::Build(format!("reduced engine: {} start positions for {} joints", q.len(), n)));
        }
        let mut arm = ReducedArm {
            model: model.clone(),
            data: DynamicsData::new(model),
            dynamics,
            gravity: Vector3::from(gravity),
            drive_inertia,
            damping: &unit * damping,
            unit_damping: unit,
            lower,
            upper,
            q: q.to_vec(),
            qd: vec![0.0; n],
            hold: vec![None; n],
            mass: DMatrix::zeros(n, n),
            bias: vec![0.0; n],
            zeros: vec![0.0; n],
            rhs: DVector::zeros(n),
            column: DVector::zeros(n),
        };
        dvrk_kin::compute_frame_placements(&arm.model, &mut arm.data.kin, &arm.q);
        Ok(arm)
    }

    /// One step of `dt` (s) under joint efforts `tau` (N·m, N; drives, effects and cables'
    /// reactions already summed). A non-finite state is left as it is (the caller checks).
    pub fn step(&mut self, tau: &[f64], dt: f64) {
        let n = self.q.len();
        let (m, dm) = (&self.model, &self.dynamics);
        if dvrk_kin::inverse_dynamics(m, dm, &mut self.data, &self.q, &self.qd, &self.zeros, &self.gravity, &mut self.bias).is_err()
            || dvrk_kin::mass_matrix(m, dm, &mut self.data, &self.q, &mut self.mass).is_err()
        {
            // dvrk-kin refuses only non-finite input: let it show in the state.
            self.qd.fill(f64::NAN);
            return;
        }
        // (M + dt D) q'' = tau - h - D q': the damping on the velocity the step ends with.
        self.mass += &self.drive_inertia;
        for i in 0..n {
            let damp: f64 = (0..n).map(|j| self.damping[(i, j)] * self.qd[j]).sum();
            self.rhs[i] = tau[i] - self.bias[i] - damp;
        }
        for i in 0..n {
            for j in 0..n {
                self.mass[(i, j)] += dt * self.damping[(i, j)];
            }
        }
        // A held joint: an implicit spring-damper to its target, scaled by its own inertia.
        for k in 0..n {
            if let Some((target, velocity)) = self.hold[k] {
                let mk = self.mass[(k, k)];
                self.rhs[k] += mk * (POSITION_STIFFNESS * (target - self.q[k] - dt * self.qd[k]) + POSITION_DAMPING * (velocity - self.qd[k]));
                self.mass[(k, k)] += mk * (POSITION_STIFFNESS * dt * dt + POSITION_DAMPING * dt);
            }
        }
        let a = std::mem::replace(&mut self.mass, DMatrix::zeros(0, 0));
        // The workspace goes through the factorisation and comes back (no allocation); a
        // non-positive pivot (a non-finite state) gives NaN, not a panic.
        let chol = nalgebra::Cholesky::new_unchecked(a);
        chol.solve_mut(&mut self.rhs);
        for k in 0..n {
            self.qd[k] += dt * self.rhs[k];
        }
        // Limits: a joint that would pass one this step lands on it (an inelastic stop) by an
        // impulse on that joint alone, which moves the others through the mechanism's inertia
        // (`A^-1 e_k`, as rapier's limit constraint does); zeroing its velocity alone jolted the
        // insertion by 0.5 mm when the pitch met its stop. Gauss-Seidel over the stops met.
        for _ in 0..LIMIT_SWEEPS {
            let mut pushed = false;
            for k in 0..n {
                let next = self.q[k] + dt * self.qd[k];
                let land = if next < self.lower[k] - LIMIT_SLOP {
                    self.lower[k]
                } else if next > self.upper[k] + LIMIT_SLOP {
                    self.upper[k]
                } else {
                    continue;
                };
                self.column.fill(0.0);
                self.column[k] = 1.0;
                chol.solve_mut(&mut self.column);
                let impulse = ((land - self.q[k]) / dt - self.qd[k]) / self.column[k];
                for j in 0..n {
                    self.qd[j] += impulse * self.column[j];
                }
                pushed = true;
            }
            if !pushed {
                break;
            }
        }
        self.mass = chol.unpack_dirty();
        for k in 0..n {
            self.q[k] += dt * self.qd[k];
            // What the sweeps left past a stop: held on it.
            if self.q[k] < self.lower[k] {
                self.q[k] = self.lower[k];
                self.qd[k] = self.qd[k].max(0.0);
            } else if self.q[k] > self.upper[k] {
                self.q[k] = self.upper[k];
                self.qd[k] = self.qd[k].min(0.0);
            }
        }
        dvrk_kin::compute_frame_placements(&self.model, &mut self.data.kin, &self.q);
    }

    /// Tree-joint damping `d` (N·m s/rad, N s/m) and a scale on the drive inertias (the energy
    /// check turns both off).
    pub fn set_damping_and_armature(&mut self, d: f64, armature_scale: f64) {
        self.damping.copy_from(&(&self.unit_damping * d));
        self.drive_inertia *= armature_scale;
    }

    /// World pose of body `body` (its first frame) at the current positions.
    pub fn body_pose(&self, body: usize) -> Pose {
        self.data.kin.frames[self.model.bodies[body].frames[0]]
    }

    /// Largest loop-closure gap (m) at the current positions: the two frames' copies of each
    /// closure point (zero to rounding: the loops are closed by construction; a check).
    pub fn closure_error(&self) -> f64 {
        let f = &self.data.kin.frames;
        self.model
            .closures
            .iter()
            .map(|c| (f[c.frame] * nalgebra::Point3::from(c.point) - f[c.partner] * nalgebra::Point3::from(c.partner_point)).norm())
            .fold(0.0, |a: f64, g| if g.is_nan() { f64::NAN } else { a.max(g) })
    }

    /// Total mechanical energy (J): `q'^T (M + drive inertia) q' / 2` plus the bodies'
    /// gravitational potential. Allocates (a diagnostic).
    pub fn energy(&self) -> f64 {
        let n = self.q.len();
        let mut data = self.data.clone();
        let mut mass = DMatrix::zeros(n, n);
        if dvrk_kin::mass_matrix(&self.model, &self.dynamics, &mut data, &self.q, &mut mass).is_err() {
            return f64::NAN;
        }
        mass += &self.drive_inertia;
        let v = DVector::from_column_slice(&self.qd);
        let kinetic = 0.5 * (v.transpose() * &mass * &v)[0];
        let potential: f64 = self
            .dynamics
            .inertias()
            .iter()
            .zip(&self.model.bodies)
            .map(|(b, body)| {
                let pose = &data.kin.frames[body.frames[0]];
                -b.mass * self.gravity.dot(&(pose * nalgebra::Point3::from(b.com)).coords)
            })
            .sum();
        kinetic + potential
    }
}

/// The coefficient vector `c` of every tree joint (`phi = c . q + b`; the first moving frame of
/// each body, as rapier's multibody has them).
fn tree_joints(model: &Model) -> Vec<DVector<f64>> {
    let n = model.nq();
    model
        .bodies
        .iter()
        .enumerate()
        .filter_map(|(bi, b)| {
            let f = b.frames.iter().find(|&&f| model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi))?;
            let var = model.frames[*f].variable().filter(|v| !v.is_constant())?;
            Some(DVector::from_iterator(n, (0..n).map(|k| var.coef.get(k).copied().unwrap_or(0.0))))
        })
        .collect()
}

impl crate::sim::Sim {
    /// [`crate::sim::Sim::new`] with the reduced engine: every arm on the world, no contacts.
    pub(crate) fn new_reduced(scene: &crate::scene::Scene, options: &crate::sim::SimOptions) -> Result<crate::sim::Sim> {
        use crate::sim::{ArmState, Colliders, GravityCompensation};
        if options.colliders == Colliders::Contacts {
            return Err(SimError::Build("the reduced engine has no contacts: use the rapier engine for --contacts".into()));
        }
        let g = if options.no_gravity { [0.0; 3] } else { scene.gravity };
        let (mut arms, mut reduced) = (Vec::with_capacity(scene.arms.len()), Vec::with_capacity(scene.arms.len()));
        let mut q_offset = 0;
        for arm in &scene.arms {
            if arm.parent.is_some() {
                return Err(SimError::Build(format!(
                    "{}: an arm carried by another (the setup joints' scenes) is not in the reduced engine yet; use the rapier engine",
                    arm.name
                )));
            }
            // The mechanism on the true joints, as the rapier path builds it.
            let link_model = arm.model.without_coupling_error();
            let home = match arm.model.coupling_error_map() {
                Some(b) => (b * DVector::from_column_slice(&arm.start)).as_slice().to_vec(),
                None => arm.start.clone(),
            };
            let inertias = dvrk_kin::effects::effect_inertias(&link_model, &link_model.effects, &arm.inertials.body_inertias(&link_model)?)?;
            let armature = crate::effects::drive_armature(&arm.model, &arm.armature);
            let effects = crate::effects::ArmEffects::new(&arm.name, &arm.model, &armature, &arm.start, scene.dt)?;
            let behind: Vec<bool> = effects.transmissions.iter().map(Option::is_some).collect();
            reduced.push(ReducedArm::new(&link_model, &arm.model, inertias.clone(), &arm.armature, arm.damping, g, &behind, &home)?);
            let gravity_compensation = GravityCompensation::of(arm, scene, options, &inertias)?;
            arms.push(ArmState::without_rapier(&arm.name, &arm.model, q_offset, crate::sim::actuators(arm), arm.tracking, effects, gravity_compensation));
            q_offset += arm.model.nq();
        }
        let mut sim = crate::sim::Sim::assemble(scene, options, arms, Vec::new(), q_offset);
        sim.reduced = reduced;
        sim.read_state();
        sim.apply_modes(scene)?;
        Ok(sim)
    }

    /// [`crate::sim::Sim::step`] with the reduced engine.
    pub(crate) fn step_reduced(&mut self) {
        for (arm, r) in self.arms.iter_mut().zip(self.reduced.iter_mut()) {
            arm.link_efforts(&self.q, &self.qd, &self.q_link, &self.qd_link, self.dt);
            for k in 0..r.hold.len() {
                r.hold[k] = (arm.actuators[k].mode == crate::control::Mode::Position).then(|| arm.held_target(k));
            }
            r.step(&arm.effects.drive, self.dt);
        }
        self.time += self.dt;
        self.read_state();
    }
}
