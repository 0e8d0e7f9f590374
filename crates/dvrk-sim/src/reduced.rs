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
//! step: the tree's buffers are its workspace (the Model/Data split of dvrk-kin).
//!
//! An arm carried by another (a PSM on its setup joints) is one tree with it: the arms are merged
//! into one dvrk-kin model ([`dvrk_kin::compose::merge`]), so the setup joints feel the arm they
//! carry exactly, as in rapier's shared multibody.

use crate::arm_state::{ArmPhysics, ArmState, GravityCompensation};
use crate::control::{POSITION_DAMPING, POSITION_STIFFNESS};
use crate::error::{Result, SimError};
use crate::options::{Colliders, SimOptions};
use dvrk_kin::{DynamicsData, DynamicsModel, Model, Pose};
use nalgebra::{DMatrix, DVector, Vector3};

/// One arm of a [`ReducedTree`], as the sim builds it.
#[derive(Debug, Clone)]
pub struct TreeArm {
    /// The scene arm's name (the prefix of its merged names).
    pub name: String,
    /// The mechanism on the true joints (a coupling error's map is the controller's business),
    /// its `base` the arm's world pose at the start.
    pub model: Model,
    /// The model whose effects hold its motors' inertia (the scene arm's).
    pub effects_model: Model,
    /// The arm carrying it, by position in the tree's arm list, and that arm's frame it sits on.
    pub parent: Option<(usize, usize)>,
    /// The arm's base in that frame (or the world) (m).
    pub mount: Pose,
    /// Body inertias, payloads included ([`Model::bodies`] order).
    pub inertias: Vec<dvrk_kin::BodyInertia>,
    /// The scene's drive armature per joint (kg m^2, kg).
    pub armature: Vec<f64>,
    /// Per joint: its motor sits behind a compliant transmission.
    pub transmission: Vec<bool>,
    /// Tree-joint damping (N·m s/rad, N s/m).
    pub damping: f64,
    /// Start positions (rad, m).
    pub start: Vec<f64>,
}

/// One tree of arms (an arm on the world and the arms it carries) in their actuated joints: the
/// merged model (immutable) and its workspace.
#[derive(Debug, Clone)]
pub struct ReducedTree {
    model: Model,
    dynamics: DynamicsModel,
    data: DynamicsData,
    /// World, m/s^2.
    gravity: Vector3<f64>,
    /// Drive inertia per joint (kg m^2, kg): the scene's armature with the motors' coupled
    /// inertia, cross terms included (`C^-T diag(I) C^-1`); zero on a joint whose motor sits
    /// behind a compliant transmission (the motor side holds it there).
    drive_inertia: DMatrix<f64>,
    /// Joint damping in the joints, `sum_i d_i c_i c_i^T` over the tree joints `phi_i = c_i . q`
    /// (N·m s/rad, N s/m): rapier damps every tree joint of the multibody.
    damping: DMatrix<f64>,
    /// `sum_i c_i c_i^T` (the damping per unit of a common `d`).
    unit_damping: DMatrix<f64>,
    /// `drive inertia + dt D` for the step `constant_dt` (s): the constant part of the step's
    /// matrix (NaN: to be formed).
    constant: DMatrix<f64>,
    constant_dt: f64,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// Link positions and velocities of every arm of the tree, arm after arm (rad, m; rad/s, m/s).
    /// Only [`ReducedTree::step`] moves them: it leaves the frames placed at `q`.
    pub(crate) q: Vec<f64>,
    pub(crate) qd: Vec<f64>,
    /// Per joint: a position-mode target (rad or m, rad/s or m/s), `None` when driven by effort.
    pub hold: Vec<Option<(f64, f64)>>,
    /// Joint efforts (N·m, N) for the next step, arm after arm.
    pub tau: Vec<f64>,
    /// Braked ([`crate::scene::Arm::braked`]): the tree stays where it started; a step does nothing.
    pub(crate) braked: bool,
    // Workspace.
    mass: DMatrix<f64>,
    bias: Vec<f64>,
    rhs: DVector<f64>,
    column: DVector<f64>,
}

/// Gauss-Seidel sweeps over the joint stops met in one step.
const LIMIT_SWEEPS: usize = 4;
/// How far past a stop a step may end before the stop acts (rad or m): rounding, not physics.
const LIMIT_SLOP: f64 = 1e-12;
/// Mass of the massless mount body of a tree's root (kg): dvrk-kin wants one per body; it never
/// moves, so it enters no equation of motion.
const MOUNT_MASS: f64 = 1e-9;

impl ReducedTree {
    /// The tree of `arms` (each carried one after its carrier) under `gravity` (m/s^2).
    pub fn new(name: &str, arms: &[TreeArm], gravity: [f64; 3]) -> Result<ReducedTree> {
        let mounted: Vec<dvrk_kin::compose::Mounted> = arms
            .iter()
            .map(|a| dvrk_kin::compose::Mounted { name: a.name.clone(), source: a.model.name.clone(), model: a.model.clone(), parent: a.parent, mount: a.mount, mount_body: None })
            .collect();
        let model = dvrk_kin::compose::merge(name, &mounted)?;
        let n = model.nq();
        // Each merged body is an arm's body (its first frame is that body's first frame), or a
        // root's fixed mount.
        let mut inertias = Vec::with_capacity(model.bodies.len());
        for b in &model.bodies {
            let first = b.frames[0];
            let found = model.parts.iter().zip(arms).find(|(p, _)| p.frames.contains(&first) && first > p.frames.start).and_then(|(p, a)| {
                let local = first - p.frames.start - 1;
                let body = a.model.frames[local].body;
                (a.model.bodies[body].frames[0] == local).then(|| a.inertias[body].clone())
            });
            inertias.push(found.unwrap_or_else(|| dvrk_kin::BodyInertia::new(MOUNT_MASS, [0.0; 3], [[0.0; 3]; 3])));
        }
        let dynamics = DynamicsModel::new(&model, inertias)?;
        let (mut drive_inertia, mut damping, mut unit) = (DMatrix::zeros(n, n), DMatrix::zeros(n, n), DMatrix::zeros(n, n));
        let mut q = Vec::with_capacity(n);
        for (a, p) in arms.iter().zip(&model.parts) {
            let (o, m) = (p.joints.start, p.joints.len());
            if a.start.len() != m || a.armature.len() < m {
                return Err(SimError::Build(format!("reduced engine: arm {}: {} start positions, {} armatures for {m} joints", a.name, a.start.len(), a.armature.len())));
            }
            let mut motor = DMatrix::zeros(m, m);
            dvrk_kin::effects::motor_inertia_matrix(&a.effects_model.effects, &mut motor);
            for k in 0..m {
                motor[(k, k)] += a.armature[k];
            }
            for (k, held) in a.transmission.iter().enumerate().take(m) {
                if *held {
                    motor.row_mut(k).fill(0.0);
                    motor.column_mut(k).fill(0.0);
                }
            }
            drive_inertia.view_mut((o, o), (m, m)).copy_from(&motor);
            for c in tree_joints(&model, p) {
                let cc = &c * c.transpose();
                damping += a.damping * &cc;
                unit += cc;
            }
            q.extend_from_slice(&a.start);
        }
        let (lower, upper) = model.joints.iter().map(|j| (j.lower, j.upper)).unzip();
        let mut tree = ReducedTree {
            data: DynamicsData::new(&model),
            model,
            dynamics,
            gravity: Vector3::from(gravity),
            drive_inertia,
            damping,
            unit_damping: unit,
            constant: DMatrix::zeros(n, n),
            constant_dt: f64::NAN,
            lower,
            upper,
            q,
            qd: vec![0.0; n],
            hold: vec![None; n],
            tau: vec![0.0; n],
            braked: false,
            mass: DMatrix::zeros(n, n),
            bias: vec![0.0; n],
            rhs: DVector::zeros(n),
            column: DVector::zeros(n),
        };
        dvrk_kin::compute_frame_placements(&tree.model, &mut tree.data.kin, &tree.q);
        Ok(tree)
    }

    /// Joints of arm `k` of the tree within `q`.
    pub fn joints(&self, k: usize) -> std::ops::Range<usize> {
        self.model.parts[k].joints.clone()
    }

    /// One step of `dt` (s) under the joint efforts in [`ReducedTree::tau`] (N·m, N; drives and
    /// effects summed). A non-finite state is left as it is (the caller checks).
    pub fn step(&mut self, dt: f64) {
        if self.braked {
            return;
        }
        let n = self.q.len();
        let (m, dm) = (&self.model, &self.dynamics);
        // The frames were placed at q at the end of the last step (or at the start).
        if self.q.iter().any(|x| !x.is_finite()) || dvrk_kin::mass_matrix_and_bias_placed(m, dm, &mut self.data, &self.qd, &self.gravity, &mut self.bias, &mut self.mass).is_err() {
            // dvrk-kin refuses only non-finite input: let it show in the state.
            self.qd.fill(f64::NAN);
            return;
        }
        // (M + dt D) q'' = tau - h - D q': the damping on the velocity the step ends with.
        if self.constant_dt != dt {
            self.constant.copy_from(&self.drive_inertia);
            for (c, d) in self.constant.iter_mut().zip(self.damping.iter()) {
                *c += dt * d;
            }
            self.constant_dt = dt;
        }
        self.mass += &self.constant;
        for i in 0..n {
            let damp: f64 = (0..n).map(|j| self.damping[(i, j)] * self.qd[j]).sum();
            self.rhs[i] = self.tau[i] - self.bias[i] - damp;
        }
        // A held joint: an implicit spring-damper to its target, scaled by its own inertia.
        for k in 0..n {
            if let Some((target, velocity)) = self.hold[k] {
                let mk = self.mass[(k, k)];
                self.rhs[k] += mk * (POSITION_STIFFNESS * (target - self.q[k] - dt * self.qd[k]) + POSITION_DAMPING * (velocity - self.qd[k]));
                self.mass[(k, k)] += mk * (POSITION_STIFFNESS * dt * dt + POSITION_DAMPING * dt);
            }
        }
        // The workspace goes through the factorisation and comes back (no allocation); a
        // non-positive pivot (a non-finite state) gives NaN, not a panic. (A hand-written kernel
        // for these dozen joints was measured 1-3% faster: not worth owning.)
        let a = std::mem::replace(&mut self.mass, DMatrix::zeros(0, 0));
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
        self.constant_dt = f64::NAN;
    }

    /// World pose of frame `frame` of arm `k` of the tree (the arm's own numbering) at the
    /// current positions.
    pub fn frame_pose(&self, k: usize, frame: usize) -> Pose {
        self.data.kin.frames[self.model.parts[k].frames.start + 1 + frame]
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

/// The coefficient vector `c` of every tree joint of `part` (`phi = c . q + b`; the first moving
/// frame of each of its bodies, as rapier's multibody has them).
fn tree_joints(model: &Model, part: &dvrk_kin::Part) -> Vec<DVector<f64>> {
    let n = model.nq();
    model
        .bodies
        .iter()
        .enumerate()
        .filter(|(_, b)| part.frames.contains(&b.frames[0]))
        .filter_map(|(bi, b)| {
            let f = b.frames.iter().find(|&&f| model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi))?;
            let var = model.frames[*f].variable().filter(|v| !v.is_constant())?;
            Some(DVector::from_iterator(n, (0..n).map(|k| var.coef.get(k).copied().unwrap_or(0.0))))
        })
        .collect()
}

/// The arms of `scene` for the reduced engine, one tree per arm on the world with the arms it
/// carries (no contacts); per scene arm its tree and place in that tree's arm list; the scene's
/// number of joints.
pub(crate) fn build(scene: &crate::scene::Scene, options: &SimOptions) -> Result<(Vec<ArmState>, Vec<ReducedTree>, Vec<(usize, usize)>, usize)> {
    if options.colliders == Colliders::Contacts {
        return Err(SimError::Build("the reduced engine has no contacts: use the rapier engine for --contacts".into()));
    }
    let g = if options.no_gravity { [0.0; 3] } else { scene.gravity };
    let mut arms = Vec::with_capacity(scene.arms.len());
    // Per scene arm: its tree and its place in that tree's arm list.
    let mut place: Vec<(usize, usize)> = Vec::with_capacity(scene.arms.len());
    let mut trees: Vec<(String, Vec<TreeArm>)> = Vec::new();
    let mut q_offset = 0;
    for arm in &scene.arms {
        // The mechanism on the true joints, as the rapier path builds it.
        let ArmPhysics { link_model, home: start, inertias, effects, .. } = ArmPhysics::new(arm, scene.dt)?;
        let transmission: Vec<bool> = effects.transmissions.iter().map(Option::is_some).collect();
        // On the world: the model's base is the mount. On an arm: the base relative to the
        // carrier's frame at the carrier's home, where the scene placed it.
        let (t, parent, mount) = match arm.parent {
            None => {
                trees.push((arm.name.clone(), Vec::new()));
                (trees.len() - 1, None, arm.model.base)
            }
            Some((pa, pf)) => {
                let carrier = &scene.arms[pa].model;
                let at = carrier.fk(&carrier.home())?[pf];
                (place[pa].0, Some((place[pa].1, pf)), at.inverse() * arm.model.base)
            }
        };
        let mut model = link_model;
        model.base = Pose::identity();
        place.push((t, trees[t].1.len()));
        trees[t].1.push(TreeArm { name: arm.name.clone(), model, effects_model: arm.model.clone(), parent, mount, inertias: inertias.clone(), armature: arm.armature.clone(), transmission, damping: arm.damping, start });
        let gravity_compensation = GravityCompensation::of(arm, scene, options, &inertias)?;
        arms.push(ArmState::without_rapier(arm, q_offset, effects, gravity_compensation));
        q_offset += arm.model.nq();
    }
    let mut reduced = trees.iter().map(|(name, a)| ReducedTree::new(name, a, g)).collect::<Result<Vec<_>>>()?;
    // A tree of braked setup joints alone does not move.
    for (t, tree) in reduced.iter_mut().enumerate() {
        tree.braked = scene.arms.iter().zip(&place).filter(|(_, p)| p.0 == t).all(|(a, _)| a.braked);
    }
    Ok((arms, reduced, place, q_offset))
}
