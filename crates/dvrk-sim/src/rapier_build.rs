//! Building the rapier engine's worlds of a scene: one rigid body per dvrk-kin body, the frame
//! tree as one reduced-coordinate multibody per arm, each loop closed by a spherical impulse
//! joint, passive joints outside any loop tied to their driver by a cable.

use crate::arm_state::{actuators, ArmPhysics, ArmState, GravityCompensation};
use crate::error::{Result, SimError};
use crate::options::{ClosingLinks, Colliders, Coriolis, LoopMode, SimOptions};
use crate::rapier_world::*;
use crate::scene::Scene;
use dvrk_kin::Pose;
use nalgebra::{Rotation3, Translation3, Vector3};
use rapier3d_f64::prelude::*;

/// The arms of `scene` built in their rapier worlds, at their start positions, and the scene's
/// number of joints.
pub(crate) fn build(scene: &Scene, options: &SimOptions) -> Result<(Vec<ArmState>, Vec<World>, usize)> {
    let solver = scene.solver_settings(options);
    let mut params = IntegrationParameters { dt: scene.dt, ..IntegrationParameters::default() };
    params.num_solver_iterations = solver.iterations;
    params.num_internal_stabilization_iterations = solver.stabilization_iterations;
    params.warmstart_joints = solver.warmstart_joints;
    let mut worlds: Vec<World> = Vec::new();
    let mut arms: Vec<ArmState> = Vec::with_capacity(scene.arms.len());
    let mut q_offset = 0;
    for arm in &scene.arms {
        // An arm carried by another lives in its carrier's world; an arm on the fixed world
        // starts a world of its own.
        let world = match arm.parent {
            Some((pa, _)) => arms[pa].world,
            None => {
                worlds.push(World::new(params));
                worlds.len() - 1
            }
        };
        // Sweeps: an explicit option wins; else the most demanding arm of the group.
        let pgs = options.pgs_iterations.unwrap_or(arm.pgs_iterations.unwrap_or(scene.solver.pgs_iterations));
        let wp = &mut worlds[world].params;
        wp.num_internal_pgs_iterations = if arm.parent.is_some() { wp.num_internal_pgs_iterations.max(pgs) } else { pgs };
        let state = build_arm(scene, options, arm, &arms, &mut worlds[world], world, q_offset)?;
        q_offset += state.1;
        arms.push(state.0);
    }
    Ok((arms, worlds, q_offset))
}

/// Scene arm `arm` built in `world` (index `world_index`; `built`: the arms before it, its
/// carrier among them), its joints from `q_offset` on; with its number of joints.
fn build_arm(scene: &Scene, options: &SimOptions, arm: &crate::scene::Arm, built: &[ArmState], world: &mut World, world_index: usize, q_offset: usize) -> Result<(ArmState, usize)> {
    let ArmPhysics { link_model, home, inertias, armature, effects } = ArmPhysics::new(arm, scene.dt)?;
    let model = &link_model;
    let fk = model.fk(&home)?;
    // One rigid body per dvrk-kin body, placed at its first frame.
    let body_pose: Vec<Pose> = model.bodies.iter().map(|b| fk[b.frames[0]]).collect();
    let handles = add_bodies(world, model, &inertias, &body_pose, scene, options, built.len())?;
    let tree = tree_joints(world, model, arm, built, options, &fk, &body_pose, &handles)?;
    let drives = drives_of(model, &tree.dofs)?;
    let (closures, in_loop) = close_loops(world, model, options, &fk, &body_pose, &handles, &tree);
    let cables = cables_of(model, arm, options, &tree, &drives, &in_loop)?;
    let Tree { dofs, mb_index, .. } = tree;
    configure_multibody(world, model, arm, &home, &armature, &effects, &dofs, &drives, mb_index)?;
    let gravity_compensation = GravityCompensation::of(arm, scene, options, &inertias)?;
    let coriolis = match options.coriolis {
        Coriolis::Implicit => None,
        // On the links: the model the bodies were built from, payloads included.
        Coriolis::Explicit => Some(ExplicitCoriolis::new(model, inertias.clone(), dofs.len())?),
    };
    let actuators = actuators(arm);
    let state = ArmState {
        name: arm.name.clone(),
        model: arm.model.clone(),
        q_offset,
        bodies: handles,
        dofs,
        drives,
        closures,
        cables,
        actuators,
        tracking: arm.tracking,
        parent: arm.parent,
        world: world_index,
        effects,
        gravity_compensation,
        explicit_damping: explicit_share(arm.damping),
        coriolis,
    };
    Ok((state, model.nq()))
}

/// One dynamic rigid body per body of `model` at `body_pose`, with its inertials; its link
/// geometry as massless colliders unless they are off (`arm`: the arm's index in the scene).
#[allow(clippy::too_many_arguments)]
fn add_bodies(world: &mut World, model: &dvrk_kin::Model, inertias: &[dvrk_kin::BodyInertia], body_pose: &[Pose], scene: &Scene, options: &SimOptions, arm: usize) -> Result<Vec<RigidBodyHandle>> {
    let World { bodies, colliders, .. } = world;
    let mut handles = Vec::with_capacity(model.bodies.len());
    for (bi, ine) in inertias.iter().enumerate() {
        let mp = mass_properties(ine.mass, &ine.com, &ine.inertia);
        let rb = RigidBodyBuilder::dynamic().pose(to_rapier(&body_pose[bi])).additional_mass_properties(mp).can_sleep(false);
        handles.push(bodies.insert(rb));
    }
    if options.colliders != Colliders::Off {
        let geometry = crate::geometry::ArmGeometry::new(model)?;
        let groups = collision_groups(scene, arm, options.colliders);
        for (bi, solids) in geometry.bodies.iter().enumerate() {
            for s in solids {
                // Massless, and exactly: the CAD inertials stay the bodies' only mass.
                let shape = crate::geometry::in_body_frame(s)?;
                let c = ColliderBuilder::new(shape).mass_properties(MassProperties::default()).collision_groups(groups).solver_groups(groups);
                colliders.insert_with_parent(c, handles[bi], bodies);
            }
        }
    }
    Ok(handles)
}

/// An arm's tree: its multibody joints, and the impulse-jointed pivots of free closing links.
struct Tree {
    dofs: Vec<TreeDof>,
    /// Two points on each free closing link's pivot axis (part of its loop).
    pivots: Vec<ClosurePoints>,
    /// Each body's tree joint (`usize::MAX`: none).
    dof_of_body: Vec<usize>,
    mb_index: MultibodyIndex,
}

/// The tree joints: for each body, the first moving frame whose parent lies in another body.
#[allow(clippy::too_many_arguments)]
fn tree_joints(world: &mut World, model: &dvrk_kin::Model, arm: &crate::scene::Arm, built: &[ArmState], options: &SimOptions, fk: &[Pose], body_pose: &[Pose], handles: &[RigidBodyHandle]) -> Result<Tree> {
    let World { bodies, impulse_joints, multibody_joints, ground, .. } = world;
    let ground = *ground;
    let ry = Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::y_axis(), -std::f64::consts::FRAC_PI_2));
    let mut dofs: Vec<TreeDof> = Vec::new();
    let mut pivots: Vec<ClosurePoints> = Vec::new();
    let mut dof_of_body = vec![usize::MAX; model.bodies.len()];
    // The closing link of each loop (a leaf body on a closure's `frame` side) is a multibody
    // link by default, and the closure an impulse joint between two links of the multibody
    // (rapier solves it on the relative jacobian J2 - J1). `ClosingLinks::FreeBodies`
    // keeps the first design for comparison: a free body on two impulse joints (its pivot
    // and the closure), whose gap stays at 0.1-0.5 mm (PSM) however many iterations run,
    // because the light free link is pulled between two stiff, heavy multibodies. The
    // same-multibody closure needs enough Gauss-Seidel sweeps per substep (scene
    // `pgs_iterations`): under-converged, it can lock the yaw joint.
    let has_child = |bi: usize| model.frames.iter().any(|f| f.body != bi && f.parent.is_some_and(|p| model.frames[p].body == bi));
    let free_body: Vec<bool> = (0..model.bodies.len())
        .map(|bi| options.loops == LoopMode::ImpulseJoints && options.closing_links == ClosingLinks::FreeBodies && !has_child(bi) && model.closures.iter().any(|c| model.frames[c.frame].body == bi))
        .collect();
    for (bi, b) in model.bodies.iter().enumerate() {
        let Some(&f) = b.frames.iter().find(|&&f| model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi)) else {
            continue;
        };
        let frame = &model.frames[f];
        let Some(var) = frame.variable().filter(|v| !v.is_constant()) else {
            return Err(SimError::Build(format!("body {} is fixed to its parent: fixed joints are not supported yet", b.name)));
        };
        let revolute = frame.joint == dvrk_kin::FrameJoint::Revolute;
        let (parent_pose, parent_handle) = match (frame.parent, arm.parent) {
            (Some(p), _) => (body_pose[model.frames[p].body], Some(handles[model.frames[p].body])),
            // The root of an arm carried by another (a PSM on its SUJ): jointed to the
            // parent arm's body, so both are one multibody and the SUJ feels the arm.
            (None, Some((pa, pf))) => {
                let parent_arm: &ArmState = &built[pa];
                let h = parent_arm.bodies[parent_arm.model.frames[pf].body];
                (from_rapier(bodies[h].position()), Some(h))
            }
            (None, None) => (Pose::identity(), None),
        };
        let parent_frame = match frame.parent {
            Some(p) => fk[p],
            None => model.base,
        };
        let j1 = parent_pose.inverse() * parent_frame * frame.pre() * ry;
        let post_inv = frame.post().map(|p| p.inverse()).unwrap_or_else(Pose::identity);
        let along = if revolute { var_d0(frame, model) } else { 0.0 };
        let j2 = body_pose[bi].inverse() * fk[f] * post_inv * Translation3::new(0.0, 0.0, -along) * ry;
        let mask = if revolute { JointAxesMask::LOCKED_REVOLUTE_AXES } else { JointAxesMask::LOCKED_PRISMATIC_AXES };
        let joint = GenericJointBuilder::new(mask).local_frame1(to_rapier(&j1)).local_frame2(to_rapier(&j2)).build();
        let parent_rb = parent_handle.unwrap_or(ground);
        if free_body[bi] {
            impulse_joints.insert(parent_rb, handles[bi], joint, true);
            // Its pivot is part of the loop: watch two points on the axis (origin and
            // 50 mm along it), so axis tilt counts in the loop-closure error too.
            let parent_pose_w = parent_pose;
            for along_axis in [0.0, 0.05] {
                let p_world = parent_pose_w * j1 * nalgebra::Point3::new(along_axis, 0.0, 0.0);
                let pa = parent_pose_w.inverse() * p_world;
                let pb = body_pose[bi].inverse() * p_world;
                pivots.push(ClosurePoints { a: parent_rb, pa: rv(&pa.coords), b: handles[bi], pb: rv(&pb.coords) });
            }
            continue;
        }
        let handle = multibody_joints
            .insert(parent_rb, handles[bi], joint, true)
            .ok_or_else(|| SimError::Build(format!("rapier refused the joint of body {}", b.name)))?;
        dof_of_body[bi] = dofs.len();
        dofs.push(TreeDof { child: handles[bi], parent: parent_handle, handle, revolute, frame2: to_rapier(&j2), coef: var.coef.clone(), frame: f, offset: var.offset });
    }
    let mb_index = multibody_index(multibody_joints, dofs[0].handle)?.0;
    Ok(Tree { dofs, pivots, dof_of_body, mb_index })
}

/// The driving tree joint of each actuated joint: the first that depends on it alone.
fn drives_of(model: &dvrk_kin::Model, dofs: &[TreeDof]) -> Result<Vec<Drive>> {
    let mut drives = Vec::with_capacity(model.nq());
    for (k, j) in model.joints.iter().enumerate() {
        let d = dofs
            .iter()
            .position(|d| d.coef[k] != 0.0 && d.coef.iter().enumerate().all(|(i, c)| i == k || *c == 0.0))
            .ok_or_else(|| SimError::Build(format!("joint {} drives no tree joint on its own", j.name)))?;
        drives.push(Drive { dof: d, c: dofs[d].coef[k], b: dofs[d].offset });
    }
    Ok(drives)
}

/// Each loop closed (the closure's two points watched; an impulse joint between them in
/// [`LoopMode::ImpulseJoints`]), the free links' pivots first; and which tree joints lie inside a
/// loop (on the tree path between a closure's two bodies).
fn close_loops(world: &mut World, model: &dvrk_kin::Model, options: &SimOptions, fk: &[Pose], body_pose: &[Pose], handles: &[RigidBodyHandle], tree: &Tree) -> (Vec<ClosurePoints>, Vec<bool>) {
    let impulse_joints = &mut world.impulse_joints;
    let dof_of_body = &tree.dof_of_body;
    let mut in_loop = vec![false; tree.dofs.len()];
    let body_parent = |bi: usize| -> Option<usize> {
        let f = model.bodies[bi].frames.iter().find(|&&f| model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi))?;
        model.frames[*f].parent.map(|p| model.frames[p].body)
    };
    let chain = |mut bi: usize| -> Vec<usize> {
        let mut v = vec![bi];
        while let Some(p) = body_parent(bi) {
            v.push(p);
            bi = p;
        }
        v
    };
    let mut closures = tree.pivots.clone();
    for c in &model.closures {
        let (ba, bb) = (model.frames[c.frame].body, model.frames[c.partner].body);
        let (ca, cb) = (chain(ba), chain(bb));
        for &x in ca.iter().filter(|x| !cb.contains(x)).chain(cb.iter().filter(|x| !ca.contains(x))) {
            if dof_of_body[x] != usize::MAX {
                in_loop[dof_of_body[x]] = true;
            }
        }
        let pa = body_pose[ba].inverse() * (fk[c.frame] * nalgebra::Point3::from(c.point));
        let pb = body_pose[bb].inverse() * (fk[c.partner] * nalgebra::Point3::from(c.partner_point));
        closures.push(ClosurePoints { a: handles[ba], pa: rv(&pa.coords), b: handles[bb], pb: rv(&pb.coords) });
        if options.loops == LoopMode::ImpulseJoints {
            let joint = SphericalJointBuilder::new().local_anchor1(rv(&pa.coords)).local_anchor2(rv(&pb.coords)).contacts_enabled(false);
            impulse_joints.insert(handles[ba], handles[bb], joint, true);
        }
    }
    (closures, in_loop)
}

/// Passive tree joints not held by a loop follow their driving joint by a cable (a coupling).
fn cables_of(model: &dvrk_kin::Model, arm: &crate::scene::Arm, options: &SimOptions, tree: &Tree, drives: &[Drive], in_loop: &[bool]) -> Result<Vec<Cable>> {
    let (dofs, dof_of_body) = (&tree.dofs, &tree.dof_of_body);
    let mut cables = Vec::new();
    for (i, d) in dofs.iter().enumerate() {
        if drives.iter().any(|dr| dr.dof == i) || (in_loop[i] && options.loops == LoopMode::ImpulseJoints) {
            continue;
        }
        let terms: Vec<(usize, f64)> = d.coef.iter().copied().enumerate().filter(|(_, c)| *c != 0.0).collect();
        let [(k, ci)] = terms.as_slice() else {
            return Err(SimError::Build(format!("passive joint of body {} depends on several joints", model.bodies[dof_body(dof_of_body, i)].name)));
        };
        let dr = &drives[*k];
        let coeff = ci / dr.c;
        // Stiffness for a CABLE_BANDWIDTH cable mode on the follower's own inertia, critically damped.
        let inertia = axis_inertia(&arm.inertials, model, dof_body(dof_of_body, i), &d.frame2, d.revolute);
        let w = CABLE_BANDWIDTH;
        cables.push(Cable { leader: dr.dof, follower: i, coeff, offset: d.offset - coeff * dr.b, stiffness: inertia * w * w, damping: 2.0 * inertia * w, built_damping: 2.0 * inertia * w });
    }
    Ok(cables)
}

/// The multibody at `home`: its coordinates, damping on every tree joint, the drives' armature
/// (none where a transmission's motor carries it) and joint limits.
#[allow(clippy::too_many_arguments)]
fn configure_multibody(world: &mut World, model: &dvrk_kin::Model, arm: &crate::scene::Arm, home: &[f64], armature: &[f64], effects: &crate::effects::ArmEffects, dofs: &[TreeDof], drives: &[Drive], mb_index: MultibodyIndex) -> Result<()> {
    let World { bodies, multibody_joints, .. } = world;
    let link_ids: Vec<usize> = dofs.iter().map(|d| multibody_joints.get(d.handle).map(|(_, l)| l).unwrap_or(0)).collect();
    let mb = multibody_joints.get_multibody_mut(mb_index).ok_or_else(|| SimError::Build("multibody vanished".into()))?;
    // Coordinates at home, damping on every tree joint, armature on the drives.
    let mut disp = vec![0.0; mb.ndofs()];
    for (i, d) in dofs.iter().enumerate() {
        let assembly = mb.link(link_ids[i]).map(|l| l.assembly_id()).unwrap_or(0);
        disp[assembly] = d.coef.iter().zip(home).map(|(c, q)| c * q).sum::<f64>() + d.offset;
        mb.damping_mut()[assembly] = arm.damping;
        mb.armature_mut()[assembly] = 0.0;
    }
    for (k, dr) in drives.iter().enumerate() {
        let assembly = mb.link(link_ids[dr.dof]).map(|l| l.assembly_id()).unwrap_or(0);
        split_drive_damping(mb, assembly, arm.damping);
        // Reflected through the drive's ratio: armature is per unit of q.
        mb.armature_mut()[assembly] = armature[k] / (dr.c * dr.c);
    }
    // Joint limits on the drives, in coordinate units (coord = c q + b).
    for (k, dr) in drives.iter().enumerate() {
        let j = &model.joints[k];
        let (a, b) = (dr.c * j.lower + dr.b, dr.c * j.upper + dr.b);
        let axis = if dofs[dr.dof].revolute { JointAxis::AngX } else { JointAxis::LinX };
        if let Some(l) = mb.link_mut(link_ids[dr.dof]) {
            l.joint.data.set_limits(axis, [a.min(b), a.max(b)]);
        }
    }
    mb.apply_displacements(&disp);
    mb.forward_kinematics(bodies, true);
    mb.update_rigid_bodies(bodies, true);
    {
        let mb = multibody_joints.get_multibody_mut(mb_index).ok_or_else(|| SimError::Build("multibody vanished".into()))?;
        for (k, t) in effects.transmissions.iter().enumerate() {
            if t.is_some() {
                // The motor inertia lives on the motor side of the transmission.
                let assembly = mb.link(link_ids[drives[k].dof]).map(|l| l.assembly_id()).unwrap_or(0);
                mb.armature_mut()[assembly] = 0.0;
            }
        }
    }
    Ok(())
}
