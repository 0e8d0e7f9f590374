//! The rapier side of the rapier engine: one world per independent arm group, the tree joints,
//! drives, loop closures and cables of an arm in it, pose conversions and the helpers that read
//! and load multibody coordinates.

use crate::error::{Result, SimError};
use crate::options::Colliders;
use crate::scene::Scene;
use dvrk_kin::{Model, Pose};
use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};
use rapier3d_f64::math::{Matrix as RMat, Pose as RPose, Rotation as RRot, Vector as RVec};
use rapier3d_f64::prelude::*;

/// The share of a drive's joint damping applied explicitly, on the velocity a step starts with.
/// rapier applies joint damping implicitly, on the velocity the step ends with, which leads the
/// positions by half a step: a recording of the sim reads the damping's share of the effort half
/// a step early (hidden-effect recordings at 0.125 ms: effect-free seed 1000 showed an apparent
/// latency of 38 us, 31.5 us with this; under seed 1031's 8 ms latency the wrist yaw's and wrist
/// pitch's own estimates, whose efforts are mostly damping, were 76 and 27 us late, now 42 and
/// 3). Half and half is the trapezoidal rule: the damping on the step's central velocity.
/// Drives only: their armature keeps the explicit half stable (`dt d / 2 I` = 0.0125 for the PSM
/// wrist at 1 ms); a passive joint's link can be light, and the passive joints' share changed the
/// apparent latency by 0.01 us.
const DRIVE_DAMPING_EXPLICIT: f64 = 0.5;
/// Natural frequency of a cable's mode on its follower's own inertia (rad/s), critically damped.
pub(crate) const CABLE_BANDWIDTH: f64 = 200.0;

/// A tree joint of the multibody: the joint that attaches one body to its parent.
#[derive(Debug, Clone)]
pub(crate) struct TreeDof {
    /// Rigid body of the child (and its parent; `None`: the ground).
    pub(crate) child: RigidBodyHandle,
    pub(crate) parent: Option<RigidBodyHandle>,
    pub(crate) handle: MultibodyJointHandle,
    pub(crate) revolute: bool,
    /// The child-side joint frame in the child body (x: the joint axis).
    pub(crate) frame2: RPose,
    /// The coordinate as `coef . q + offset` (the variable of dvrk-kin frame `frame`).
    pub(crate) coef: Vec<f64>,
    pub(crate) frame: usize,
    pub(crate) offset: f64,
}

/// One actuated joint: the tree joint that drives it (`coord = c q + b`).
#[derive(Debug, Clone)]
pub(crate) struct Drive {
    pub(crate) dof: usize,
    pub(crate) c: f64,
    pub(crate) b: f64,
}

/// A loop closure: the point on two bodies (body frames, m).
#[derive(Debug, Clone)]
pub(crate) struct ClosurePoints {
    pub(crate) a: RigidBodyHandle,
    pub(crate) pa: RVec,
    pub(crate) b: RigidBodyHandle,
    pub(crate) pb: RVec,
}

/// A passive joint tied to a driving joint like a cable: `follower = coeff * leader + offset`,
/// held by a stiff spring-damper whose tension acts on the follower and, through the ratio, back
/// on the leader (action and reaction equal, so the cable does no net work but what its damper
/// dissipates; the spring's energy is counted in [`Sim::energy`]). Explicit: a 200 rad/s mode at
/// dt = 1 ms is well inside symplectic Euler's limit (w dt < 2). (rapier 0.36's
/// `MultibodyDofCoupling` was tried first: with it the PSM yaw joint stops dead after a few
/// centimetres of motion anywhere in the arm, so it is not used.)
#[derive(Debug, Clone)]
pub(crate) struct Cable {
    pub(crate) leader: usize,
    pub(crate) follower: usize,
    pub(crate) coeff: f64,
    pub(crate) offset: f64,
    /// N/m or N·m/rad
    pub(crate) stiffness: f64,
    /// N s/m or N·m s/rad
    pub(crate) damping: f64,
    /// The damping it was built with (N s/m or N·m s/rad).
    pub(crate) built_damping: f64,
}

/// The generalised force that moves rapier's Coriolis and gyroscopic forces from the velocity a
/// step ends with back to the one it starts with ([`Coriolis::Explicit`]).
#[derive(Debug, Clone)]
pub(crate) struct ExplicitCoriolis {
    /// The mechanism's model (on the true joints, without a coupling error).
    pub(crate) model: Model,
    pub(crate) dynamics: dvrk_kin::DynamicsModel,
    pub(crate) data: dvrk_kin::DynamicsData,
    /// Frame rates `v + dt a`, `v - dt a` (one per dvrk-kin frame; rad/s, m/s), and the frames'
    /// bias forces at each (N·m, N).
    pub(crate) plus: Vec<f64>,
    pub(crate) minus: Vec<f64>,
    pub(crate) bias_plus: Vec<f64>,
    pub(crate) bias_minus: Vec<f64>,
    /// The force on each tree joint of the arm (N·m, N per unit of its coordinate).
    pub(crate) force: Vec<f64>,
}

impl ExplicitCoriolis {
    pub(crate) fn new(model: &Model, inertias: Vec<dvrk_kin::BodyInertia>, ndofs: usize) -> Result<ExplicitCoriolis> {
        let nf = model.frames.len();
        let dynamics = dvrk_kin::DynamicsModel::new(model, inertias)?;
        Ok(ExplicitCoriolis { model: model.clone(), dynamics, data: dvrk_kin::DynamicsData::new(model), plus: vec![0.0; nf], minus: vec![0.0; nf], bias_plus: vec![0.0; nf], bias_minus: vec![0.0; nf], force: vec![0.0; ndofs] })
    }

    /// `force = dt dc/dv a` on each of `dofs` at the links' positions `q` (rad, m), from the
    /// multibody's velocities and last free accelerations. `c` is quadratic in the rates, so
    /// `dc/dv x = (c(v + x) - c(v - x)) / 2` exactly. A q outside the model's checks (never from
    /// the sim) leaves it at zero.
    pub(crate) fn update(&mut self, q: &[f64], mbs: &MultibodyJointSet, dofs: &[TreeDof], dt: f64) {
        self.force.fill(0.0);
        let Some((mb, _)) = dofs.first().and_then(|d| mbs.get(d.handle)) else { return };
        let (v, a) = (mb.generalized_velocity(), mb.generalized_acceleration());
        if a.len() != v.len() {
            return;
        }
        self.plus.fill(0.0);
        self.minus.fill(0.0);
        for d in dofs {
            let Some(l) = mbs.get(d.handle).and_then(|(mb, link)| mb.link(link)) else { return };
            let (vi, xi) = (v[l.assembly_id()], dt * a[l.assembly_id()]);
            (self.plus[d.frame], self.minus[d.frame]) = (vi + xi, vi - xi);
        }
        let (m, dm) = (&self.model, &self.dynamics);
        if dvrk_kin::frame_bias_forces(m, dm, &mut self.data, q, &self.plus, &mut self.bias_plus).is_err()
            || dvrk_kin::frame_bias_forces(m, dm, &mut self.data, q, &self.minus, &mut self.bias_minus).is_err()
        {
            return;
        }
        for (f, d) in self.force.iter_mut().zip(dofs) {
            *f = 0.5 * (self.bias_plus[d.frame] - self.bias_minus[d.frame]);
        }
    }
}

/// One rapier world: an arm mounted on the fixed world and every arm it carries. Arms in
/// different groups share no body, joint or contact, so each group is a world of its own. In one
/// shared world every arm's root joint hangs off the same fixed ground body, and rapier's
/// `MultibodyJointSet::insert` adds a joint to the multibody its first body already belongs to:
/// all arms became ONE multibody (dense mass matrix factored every substep, every loop, limit and
/// motor row spanning all its DoFs), costing ~3x the sum of the separate groups for 3 PSMs and
/// ~6x for the full cart (rapier3d-f64 0.36.1). Separate worlds make the cost linear in the
/// number of groups and let the groups step in parallel (`SimOptions::parallel`).
pub(crate) struct World {
    pub(crate) bodies: RigidBodySet,
    pub(crate) colliders: ColliderSet,
    pub(crate) impulse_joints: ImpulseJointSet,
    pub(crate) multibody_joints: MultibodyJointSet,
    pub(crate) soft_bodies: SoftBodySet,
    pub(crate) pipeline: PhysicsPipeline,
    pub(crate) islands: IslandManager,
    pub(crate) broad_phase: DefaultBroadPhase,
    pub(crate) narrow_phase: NarrowPhase,
    pub(crate) ccd: CCDSolver,
    pub(crate) ground: RigidBodyHandle,
    /// Solver settings of this group: the sweeps its most demanding arm needs.
    pub(crate) params: IntegrationParameters,
}

impl World {
    pub(crate) fn new(params: IntegrationParameters) -> World {
        let mut bodies = RigidBodySet::new();
        let ground = bodies.insert(RigidBodyBuilder::fixed());
        World {
            bodies,
            colliders: ColliderSet::new(),
            impulse_joints: ImpulseJointSet::new(),
            multibody_joints: MultibodyJointSet::new(),
            soft_bodies: SoftBodySet::new(),
            pipeline: PhysicsPipeline::new(),
            islands: IslandManager::new(),
            broad_phase: DefaultBroadPhase::new(),
            narrow_phase: NarrowPhase::new(),
            ccd: CCDSolver::new(),
            ground,
            params,
        }
    }

    pub(crate) fn step(&mut self, gravity: RVec) {
        self.pipeline.step(
            gravity,
            &self.params,
            &mut self.islands,
            &mut self.broad_phase,
            &mut self.narrow_phase,
            &mut self.bodies,
            &mut self.colliders,
            &mut self.impulse_joints,
            &mut self.multibody_joints,
            &mut self.soft_bodies,
            &mut self.ccd,
            &(),
            &(),
        );
    }
}

/// nalgebra pose to rapier pose.
pub fn to_rapier(p: &Pose) -> RPose {
    let r = p.rotation.matrix();
    let m = RMat::from_cols(
        RVec::new(r[(0, 0)], r[(1, 0)], r[(2, 0)]),
        RVec::new(r[(0, 1)], r[(1, 1)], r[(2, 1)]),
        RVec::new(r[(0, 2)], r[(1, 2)], r[(2, 2)]),
    );
    let t = p.translation.vector;
    RPose::from_parts(RVec::new(t.x, t.y, t.z), RRot::from_mat3(&m).normalize())
}

/// rapier pose to nalgebra pose.
pub fn from_rapier(p: &RPose) -> Pose {
    let q = p.rotation;
    let uq = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
    Pose::from_parts(Translation3::new(p.translation.x, p.translation.y, p.translation.z), uq.to_rotation_matrix())
}

/// rapier mass properties of a body: `mass` (kg), centre `com` (m) and `inertia` about it
/// (kg m^2), both in the body's frame. The principal axes come from nalgebra's iterative
/// eigensolver: parry's closed-form one (`MassProperties::with_inertia_matrix`) returns wrong
/// axes when two principal moments are equal, and the PSM tool's near-isotropic 0.001 kg m^2
/// links came back 1e-5 kg m^2 off in every entry (all of their products of inertia), which an
/// effect-free recording showed as a wrist residual above its noise floor.
pub fn mass_properties(mass: f64, com: &Vector3<f64>, inertia: &nalgebra::Matrix3<f64>) -> MassProperties {
    let eig = inertia.symmetric_eigen();
    let mut axes = eig.eigenvectors;
    // A right-handed frame: flipping one axis keeps it an eigenvector.
    if axes.determinant() < 0.0 {
        axes.column_mut(2).neg_mut();
    }
    let frame = to_rapier(&Pose::from_parts(Translation3::identity(), Rotation3::from_matrix_unchecked(axes))).rotation;
    let moments = eig.eigenvalues.map(|e| e.max(0.0));
    MassProperties::with_principal_inertia_frame(rv(com), mass, rv(&moments), frame)
}

pub(crate) fn rv(v: &Vector3<f64>) -> RVec {
    RVec::new(v.x, v.y, v.z)
}

/// The explicit share of a drive's joint damping `d` (N·m s/rad, N s/m; [`DRIVE_DAMPING_EXPLICIT`]).
pub(crate) fn explicit_share(d: f64) -> f64 {
    d * DRIVE_DAMPING_EXPLICIT
}

/// Give rapier the implicit share of a drive's joint damping `d` on its DoF `assembly`; the
/// explicit share ([`explicit_share`]) is applied with the drive's effort.
pub(crate) fn split_drive_damping(mb: &mut Multibody, assembly: usize, d: f64) {
    mb.damping_mut()[assembly] = d - explicit_share(d);
}

/// Coordinate (rad or m) and velocity of tree joint `dof`.
pub(crate) fn coordinate(mbs: &MultibodyJointSet, dof: &TreeDof) -> Option<(f64, f64)> {
    let (mb, link) = mbs.get(dof.handle)?;
    let l = mb.link(link)?;
    Some((l.joint().coords()[if dof.revolute { 3 } else { 0 }], mb.joint_velocity(l)[0]))
}

/// Apply generalised force `f` (N·m or N) on tree joint `dof`: a torque (force) on the child
/// about (along) the joint axis and its reaction on the parent.
pub(crate) fn apply_generalized(bodies: &mut RigidBodySet, dof: &TreeDof, f: f64) {
    let child_pose = *bodies[dof.child].position();
    let axis = (child_pose * dof.frame2).rotation * RVec::X;
    if dof.revolute {
        bodies[dof.child].add_torque(axis * f, false);
        if let Some(p) = dof.parent {
            bodies[p].add_torque(-axis * f, false);
        }
    } else {
        let at = bodies[dof.child].center_of_mass();
        bodies[dof.child].add_force(axis * f, false);
        if let Some(p) = dof.parent {
            bodies[p].add_force_at_point(-axis * f, at, false);
        }
    }
}

/// Collision groups of arm `a`'s colliders: none for [`Colliders::NoContacts`]; otherwise its own
/// group, filtering out itself and the arms it carries or is carried by.
pub(crate) fn collision_groups(scene: &Scene, a: usize, mode: Colliders) -> InteractionGroups {
    if mode != Colliders::Contacts {
        return InteractionGroups::none();
    }
    let bit = |i: usize| Group::from_bits_truncate(1u32 << (i % 32));
    let mut filter = Group::ALL.difference(bit(a));
    for (i, arm) in scene.arms.iter().enumerate() {
        let carries = arm.parent.is_some_and(|(p, _)| p == a);
        let carried = scene.arms[a].parent.is_some_and(|(p, _)| p == i);
        if carries || carried {
            filter = filter.difference(bit(i));
        }
    }
    InteractionGroups::new(bit(a), filter, InteractionTestMode::And)
}

pub(crate) fn dof_body(dof_of_body: &[usize], dof: usize) -> usize {
    dof_of_body.iter().position(|&d| d == dof).unwrap_or(0)
}

/// Inertia of body `body` about (mass along) the joint axis of `frame2` (x axis, body frame):
/// kg m^2 or kg.
pub(crate) fn axis_inertia(ine: &crate::inertials::Inertials, model: &Model, body: usize, frame2: &RPose, revolute: bool) -> f64 {
    let Some(b) = ine.body(model, body) else { return 1e-3 };
    if !revolute {
        return b.mass;
    }
    let a = frame2.rotation * RVec::X;
    let a = Vector3::new(a.x, a.y, a.z);
    let r = Vector3::new(b.com[0] - frame2.translation.x, b.com[1] - frame2.translation.y, b.com[2] - frame2.translation.z);
    let i = crate::inertials::matrix3(&b.inertia);
    (a.transpose() * i * a)[0] + b.mass * a.cross(&r).norm_squared()
}

/// The revolute frame's constant offset along its axis (`Tz(d0)` after the rotation), m.
pub(crate) fn var_d0(frame: &dvrk_kin::Frame, _model: &Model) -> f64 {
    frame.d.offset
}

pub(crate) fn multibody_index(mbs: &MultibodyJointSet, h: MultibodyJointHandle) -> Result<(MultibodyIndex, usize)> {
    let (_, link) = mbs.get(h).ok_or_else(|| SimError::Build("joint not in a multibody".into()))?;
    let id = mbs
        .rigid_body_link(RigidBodyHandle(h.0))
        .ok_or_else(|| SimError::Build("body not in a multibody".into()))?;
    Ok((id.multibody, link))
}

