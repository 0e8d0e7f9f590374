//! MJCF (MuJoCo XML) export of a scene: the same mechanism [`crate::Sim`] builds on rapier, so
//! anyone can run our dynamics in a second engine.
//!
//! What maps to what (units SI; MuJoCo's `qpos` of every joint is the dvrk-kin frame variable,
//! `theta` or `d`, exactly like the rapier coordinate, so `q = (qpos - b) / c` for a drive):
//! - one `<body>` per dvrk-kin body, nested along the frame tree and placed at the home
//!   configuration (arms carried by another arm nest in the carrier's body, as the scene mounts
//!   them); `<inertial>` mass, centre of mass and `fullinertia` (about the COM, body axes) from
//!   the scene's inertials;
//! - one hinge/slide per tree joint (the body's first frame whose parent is in another body),
//!   `ref` = its home value, `damping` = the arm's damping; the drive of each actuated joint also
//!   has its `armature` (per unit of `q`, reflected to the coordinate by `1/c^2`) and its range;
//! - each loop closure (c1, c2) an `<equality connect>` between two sites at the closure points;
//! - each passive joint outside a loop (PSM counterweight `mu*q3`, second jaw blade) a fixed
//!   `<tendon>` spring-damper `follower - coeff * leader` with the rapier cable's stiffness,
//!   damping and rest offset: the generalised forces are the same (tension on the follower, its
//!   reaction times `-coeff` on the leader), where an `<equality joint>` would be a constraint;
//! - each actuated joint a `<motor>` with `gear = 1/c` (ctrl is the effort in N·m or N of `q`) and
//!   `ctrlrange` = the effort limit; the PID runs outside MuJoCo, as `control.rs` runs it outside
//!   rapier. Joints the scene holds in position mode (setup joints) are also held by an
//!   `<equality joint>` at home (`polycoef` 0: MuJoCo counts joint equalities from `ref`).
//! - an arm whose scene turns on the gravity feed-forward (`gravity_compensation`) has
//!   `gravcomp="1"` on its bodies: MuJoCo then applies the opposite of each body's weight, whose
//!   generalised force is the feed-forward `g(q)` the dVRK controller adds to the PID (the same
//!   virtual work through the loops). One difference: our drive clamps PID plus feed-forward at
//!   the effort limit, MuJoCo clamps the PID alone; no built-in scene's feed-forward comes near it.
//! - `<custom>` numerics `dvrk:ARM/joint` carry per actuated joint the drive map, gains, limits
//!   and tracking-test sine ([`DRIVE_FIELDS`]), so a controller needs nothing but the file.
//!
//! - the model's effects (an identified model's friction, springs, offsets: `dvrk_kin::effects`)
//!   are not exported: an XML comment per arm says which ([`unexported_effects`]).
//!
//! Stiff constraints: every equality (connect and hold) gets `solref = (2 dt, 1)`, the shortest
//! time constant MuJoCo accepts without `refsafe` lengthening it (a critically damped constraint
//! mode of 1/(2 dt) rad/s), and `solimp = (0.9999, 0.9999, 1e-3)`, MuJoCo's largest impedance: the
//! PSM's loops then open by at most 1.4e-3 mm in the tracking test (0.99 left 1.3e-2 mm).
//!
//! Integrator: `Euler`, MuJoCo's semi-implicit Euler with implicit joint damping, the scheme rapier
//! steps (symplectic Euler, implicit joint damping). The cables are explicit spring-dampers in
//! both (dvrk-sim applies tension and reaction itself; MuJoCo's tendon under `Euler`), so every
//! joint of every built-in scene agrees within 2% (cable-driven PSM insertion 0.3%, jaw 1.8%, the
//! rest 0.1%; `tests/python/test_mujoco.py`).

use crate::error::{Result, SimError};
use crate::scene::{Arm, Scene, Tracking};
use crate::trajectory::Trajectory;
use crate::Mode;
use dvrk_kin::{FrameJoint, Model, Pose};
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use std::fmt::Write as _;

/// The fields of each `dvrk:ARM/joint` custom numeric, in order: drive map `qpos = c q + b`
/// (c, b), PID gains (kp, ki, kd), effort limit (N·m or N, 0: none), `position_mode` (1: held by
/// an equality, 0: PID), home (rad or m), tracking-test sine amplitude (rad or m, 0: holds) and
/// frequency (Hz), joint limits (rad or m).
pub const DRIVE_FIELDS: [&str; 12] = ["c", "b", "kp", "ki", "kd", "effort_limit", "position_mode", "home", "amplitude", "frequency", "lower", "upper"];

/// Closure-gap time constant, in time steps (see the module doc).
const STIFF_TIMECONST_STEPS: f64 = 2.0;
/// `solimp` of every stiff equality: dmin, dmax, width (m or rad).
const STIFF_SOLIMP: [f64; 3] = [0.9999, 0.9999, 1e-3];

/// One tree joint of an arm.
struct TreeJoint {
    /// MuJoCo joint name (`ARM/frame`).
    name: String,
    revolute: bool,
    /// Joint origin and axis in the child body frame (m, unit).
    pos: Vector3<f64>,
    axis: Vector3<f64>,
    /// The coordinate as `coef . q + offset`.
    coef: Vec<f64>,
    offset: f64,
    /// Coordinate at home (rad or m).
    home: f64,
    damping: f64,
    armature: f64,
    range: Option<[f64; 2]>,
}

/// One body of the exported tree.
struct MjBody {
    name: String,
    /// Parent in the exported body list (`None`: the world).
    parent: Option<usize>,
    /// World pose at home.
    pose: Pose,
    mass: f64,
    com: [f64; 3],
    inertia: [[f64; 3]; 3],
    joint: Option<TreeJoint>,
    sites: Vec<(String, Vector3<f64>)>,
    /// Its arm's controller cancels gravity (the scene's `gravity_compensation`).
    gravcomp: bool,
}

/// Everything but the bodies, as XML lines.
#[derive(Default)]
struct Extras {
    tendons: Vec<String>,
    equalities: Vec<String>,
    actuators: Vec<String>,
    custom: Vec<String>,
}

/// A number for XML: the shortest text that reads back to the same f64, in exponent form below
/// 1e-4; rounding noise below 1e-14 (in m, rad or SI) written as 0.
fn num(x: f64) -> String {
    if x.abs() < 1e-14 {
        "0".into()
    } else if x.abs() < 1e-4 || x.abs() >= 1e15 {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Every number the MJCF holds is finite: a figure no robot has (a mass of 1e306 kg) made a
/// cable's stiffness `inf`, which MuJoCo then simulates as nothing sensible. The error names the
/// element and attribute.
fn check_finite(xml: &str, scene: &str) -> Result<()> {
    for line in xml.lines() {
        let parts: Vec<&str> = line.split('"').collect();
        for k in (1..parts.len()).step_by(2) {
            let attr = parts[k - 1].trim_end().trim_end_matches('=').rsplit([' ', '<']).next().unwrap_or("");
            // Names are words, whatever they spell.
            if attr == "name" || attr == "joint" || attr == "body" || attr == "tendon" || attr == "model" || attr == "file" || attr == "mesh" {
                continue;
            }
            if parts[k].split_whitespace().any(|t| t.parse::<f64>().is_ok_and(|x| !x.is_finite())) {
                let element = line.trim().split([' ', '>']).next().unwrap_or("");
                let named = line.split("name=\"").nth(1).and_then(|r| r.split('"').next()).map(|n| format!(" `{n}`")).unwrap_or_default();
                return Err(SimError::field(
                    format!("scene {scene}"),
                    "MJCF export",
                    format!("{attr}=\"{}\" in {element}>{named}: a figure of the model or scene overflows (a mass, inertia or length no robot has)", parts[k]),
                ));
            }
        }
    }
    Ok(())
}

fn nums(xs: &[f64]) -> String {
    xs.iter().map(|x| num(*x)).collect::<Vec<_>>().join(" ")
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The MJCF text of `scene` (see the module doc for the mapping).
pub fn export_mjcf(scene: &Scene) -> Result<String> {
    let mut bodies: Vec<MjBody> = Vec::new();
    let mut extras = Extras::default();
    // Exported index of each arm's dvrk-kin bodies.
    let mut arm_bodies: Vec<Vec<usize>> = Vec::with_capacity(scene.arms.len());
    let solref = format!("{} 1", num(STIFF_TIMECONST_STEPS * scene.dt));
    let solimp = nums(&STIFF_SOLIMP);
    for arm in &scene.arms {
        let ids = add_arm(scene, arm, &arm_bodies, &mut bodies, &mut extras, &solref, &solimp)?;
        arm_bodies.push(ids);
    }
    let mut out = String::new();
    let _ = writeln!(out, "<mujoco model=\"{}\">", esc(&scene.name));
    let _ = writeln!(
        out,
        "  <!-- Generated by dvrk-sim from scene `{}` ({}). Units: m, rad, s, kg, N, N·m.\n       \
         See crates/dvrk-sim/src/mjcf.rs for the mapping; custom numerics dvrk:ARM/joint hold: {}. -->",
        esc(&scene.name),
        esc(&scene.title),
        DRIVE_FIELDS.join(" ")
    );
    let _ = writeln!(out, "  <compiler angle=\"radian\" autolimits=\"true\" inertiafromgeom=\"false\"/>");
    let g = scene.gravity;
    let _ = writeln!(
        out,
        "  <option timestep=\"{}\" gravity=\"{}\" integrator=\"Euler\" solver=\"Newton\" iterations=\"100\" tolerance=\"1e-10\">\n    <flag contact=\"disable\"/>\n  </option>",
        num(scene.dt),
        nums(&g)
    );
    for line in unexported_effects(scene) {
        let _ = writeln!(out, "  <!-- not exported: {} -->", esc(&line));
    }
    out += "  <worldbody>\n";
    write_children(&mut out, &bodies, None, &Pose::identity(), 2)?;
    out += "  </worldbody>\n";
    for (tag, lines) in [("tendon", &extras.tendons), ("equality", &extras.equalities), ("actuator", &extras.actuators), ("custom", &extras.custom)] {
        if lines.is_empty() {
            continue;
        }
        let _ = writeln!(out, "  <{tag}>");
        for l in lines {
            let _ = writeln!(out, "    {l}");
        }
        let _ = writeln!(out, "  </{tag}>");
    }
    out += "</mujoco>\n";
    check_finite(&out, &scene.name)?;
    Ok(out)
}

/// Per arm whose model carries effects (an identified model's friction, springs, offsets...):
/// a line naming them. The export has no MuJoCo counterpart for them, so MuJoCo runs the arm
/// without: said in the file (an XML comment) and by `dvrk export` on stderr.
pub fn unexported_effects(scene: &Scene) -> Vec<String> {
    scene
        .arms
        .iter()
        .filter_map(|a| {
            // Motor inertias go in as the drives' armature (their joint-space diagonal).
            let motor = dvrk_kin::effects::EffectKind::MotorInertia;
            let left: Vec<_> = a.model.effects.iter().filter(|e| e.kind != motor).collect();
            let kinds: std::collections::BTreeSet<String> = left.iter().map(|e| format!("{:?}", e.kind)).collect();
            let armature = if left.len() < a.model.effects.len() { " (its motor inertias are in the drives' armature, their diagonal)" } else { "" };
            (!left.is_empty()).then(|| format!("{}: {} effects of its model ({}); MuJoCo runs the arm without them{armature}", a.name, left.len(), kinds.into_iter().collect::<Vec<_>>().join(", ")))
        })
        .collect()
}

/// Write the bodies whose parent is `parent` (placed relative to `parent_pose`), recursively.
fn write_children(out: &mut String, bodies: &[MjBody], parent: Option<usize>, parent_pose: &Pose, depth: usize) -> Result<()> {
    let pad = "  ".repeat(depth);
    for (i, b) in bodies.iter().enumerate().filter(|(_, b)| b.parent == parent) {
        let rel = parent_pose.inverse() * b.pose;
        let t = rel.translation.vector;
        let q = UnitQuaternion::from_rotation_matrix(&rel.rotation);
        let v = [t.x, t.y, t.z, q.w, q.i, q.j, q.k];
        if v.iter().any(|x| !x.is_finite()) {
            return Err(SimError::Build(format!("body {}: non-finite home pose", b.name)));
        }
        let gravcomp = if b.gravcomp { " gravcomp=\"1\"" } else { "" };
        let _ = writeln!(out, "{pad}<body name=\"{}\" pos=\"{}\" quat=\"{}\"{gravcomp}>", esc(&b.name), nums(&v[..3]), nums(&v[3..]));
        let i3 = &strict_triangle(&b.inertia);
        let _ = writeln!(
            out,
            "{pad}  <inertial pos=\"{}\" mass=\"{}\" fullinertia=\"{}\"/>",
            nums(&b.com),
            num(b.mass),
            nums(&[i3[0][0], i3[1][1], i3[2][2], i3[0][1], i3[0][2], i3[1][2]])
        );
        if let Some(j) = &b.joint {
            let kind = if j.revolute { "hinge" } else { "slide" };
            let mut attrs = format!(
                "name=\"{}\" type=\"{kind}\" pos=\"{}\" axis=\"{}\" ref=\"{}\" damping=\"{}\"",
                esc(&j.name),
                nums(&[j.pos.x, j.pos.y, j.pos.z]),
                nums(&[j.axis.x, j.axis.y, j.axis.z]),
                num(j.home),
                num(j.damping)
            );
            if j.armature > 0.0 {
                let _ = write!(attrs, " armature=\"{}\"", num(j.armature));
            }
            if let Some([lo, hi]) = j.range {
                let _ = write!(attrs, " range=\"{} {}\"", num(lo), num(hi));
            }
            let _ = writeln!(out, "{pad}  <joint {attrs}/>");
        }
        for (name, p) in &b.sites {
            let _ = writeln!(out, "{pad}  <site name=\"{}\" pos=\"{}\"/>", esc(name), nums(&[p.x, p.y, p.z]));
        }
        write_children(out, bodies, Some(i), &b.pose, depth + 1)?;
        let _ = writeln!(out, "{pad}</body>");
    }
    Ok(())
}

/// `inertia` (kg m^2) with `delta * I` added when its principal moments break MuJoCo's strict
/// `A + B >= C` check by rounding noise: the inertials files hold moments made physical exactly at
/// the boundary (`A + B = C`) and rounded to 1e-12, which can leave them 4e-14 below it. `delta` is
/// the shortfall plus 1e-12 of the largest moment, far below any dynamic effect.
fn strict_triangle(inertia: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let e = crate::inertials::matrix3(inertia).symmetric_eigenvalues();
    let mut e = [e[0], e[1], e[2]];
    e.sort_by(f64::total_cmp);
    let shortfall = e[2] - e[0] - e[1];
    if shortfall < -1e-12 * e[2] {
        return *inertia;
    }
    let delta = shortfall.max(0.0) + 1e-12 * e[2];
    let mut out = *inertia;
    for (k, row) in out.iter_mut().enumerate() {
        row[k] += delta;
    }
    out
}

/// The revolute frame's constant offset along its axis (`Tz(d0)` after the rotation), m.
fn along(frame: &dvrk_kin::Frame) -> f64 {
    if frame.joint == FrameJoint::Revolute {
        frame.d.offset
    } else {
        0.0
    }
}

/// Add arm `arm` of `scene`: its bodies (appended to `bodies`) and its tendons, equalities,
/// actuators and drive data. Returns the exported index of each of its dvrk-kin bodies.
fn add_arm(scene: &Scene, arm: &Arm, arm_bodies: &[Vec<usize>], bodies: &mut Vec<MjBody>, extras: &mut Extras, solref: &str, solimp: &str) -> Result<Vec<usize>> {
    let model: &Model = &arm.model;
    let home = model.home();
    let fk = model.fk(&home)?;
    let body_pose: Vec<Pose> = model.bodies.iter().map(|b| fk[b.frames[0]]).collect();
    let first = bodies.len();
    let ids: Vec<usize> = (first..first + model.bodies.len()).collect();
    let named = |s: &str| format!("{}/{}", arm.name, s);
    // The tree joint of each body, as Sim::new picks it: the first frame whose parent lies in
    // another body.
    let mut tree_frame = vec![None; model.bodies.len()];
    for (bi, b) in model.bodies.iter().enumerate() {
        let f = b.frames.iter().copied().find(|&f| model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi));
        tree_frame[bi] = f;
        let ine = arm.inertials.body(model, bi).ok_or_else(|| SimError::Build(format!("{}: no inertials for body {}", arm.name, b.name)))?;
        let parent = match f.and_then(|f| model.frames[f].parent) {
            Some(p) => Some(ids[model.frames[p].body]),
            None => arm.parent.map(|(pa, pf)| arm_bodies[pa][scene.arms[pa].model.frames[pf].body]),
        };
        let joint = f.and_then(|f| {
            let frame = &model.frames[f];
            let var = frame.variable().filter(|v| !v.is_constant())?;
            let post_inv = frame.post().map(|p| p.inverse()).unwrap_or_else(Pose::identity);
            let axis_frame = body_pose[bi].inverse() * fk[f] * post_inv * Translation3::new(0.0, 0.0, -along(frame));
            Some(TreeJoint {
                name: named(&frame.name),
                revolute: frame.joint == FrameJoint::Revolute,
                pos: axis_frame.translation.vector,
                axis: axis_frame.rotation * Vector3::z(),
                coef: var.coef.clone(),
                offset: var.offset,
                home: var.coef.iter().zip(&home).map(|(c, q)| c * q).sum::<f64>() + var.offset,
                damping: arm.damping,
                armature: 0.0,
                range: None,
            })
        });
        bodies.push(MjBody { name: named(&b.name), parent, pose: body_pose[bi], mass: ine.mass, com: ine.com, inertia: ine.inertia, joint, sites: Vec::new(), gravcomp: arm.gravity_compensation });
    }
    // Drives: the first tree joint that depends on the actuated joint alone (as Sim::new).
    let mut drives: Vec<(usize, f64, f64)> = Vec::with_capacity(model.nq()); // (body, c, b)
    for (k, j) in model.joints.iter().enumerate() {
        let d = ids
            .iter()
            .position(|&id| bodies[id].joint.as_ref().is_some_and(|t| t.coef[k] != 0.0 && t.coef.iter().enumerate().all(|(i, c)| i == k || *c == 0.0)))
            .ok_or_else(|| SimError::Build(format!("{}: joint {} drives no tree joint on its own", arm.name, j.name)))?;
        let t = bodies[ids[d]].joint.as_ref().map(|t| (t.coef[k], t.offset)).unwrap_or((1.0, 0.0));
        drives.push((d, t.0, t.1));
    }
    // Loop closures: sites at both points, a stiff connect; the tree joints between them are in a loop.
    let body_parent = |bi: usize| tree_frame[bi].and_then(|f| model.frames[f].parent).map(|p| model.frames[p].body);
    let chain = |mut bi: usize| {
        let mut v = vec![bi];
        while let Some(p) = body_parent(bi) {
            v.push(p);
            bi = p;
        }
        v
    };
    let mut in_loop = vec![false; model.bodies.len()];
    for c in &model.closures {
        let (ba, bb) = (model.frames[c.frame].body, model.frames[c.partner].body);
        let (ca, cb) = (chain(ba), chain(bb));
        for &x in ca.iter().filter(|x| !cb.contains(x)).chain(cb.iter().filter(|x| !ca.contains(x))) {
            in_loop[x] = true;
        }
        let pa = body_pose[ba].inverse() * (fk[c.frame] * Point3::from(c.point));
        let pb = body_pose[bb].inverse() * (fk[c.partner] * Point3::from(c.partner_point));
        let (sa, sb) = (named(&format!("{}:a", c.name)), named(&format!("{}:b", c.name)));
        bodies[ids[ba]].sites.push((sa.clone(), pa.coords));
        bodies[ids[bb]].sites.push((sb.clone(), pb.coords));
        extras.equalities.push(format!(
            "<connect name=\"{}\" site1=\"{}\" site2=\"{}\" solref=\"{solref}\" solimp=\"{solimp}\"/>",
            esc(&named(&c.name)),
            esc(&sa),
            esc(&sb)
        ));
    }
    // Passive tree joints outside every loop follow their driver through a cable (tendon spring).
    for bi in 0..model.bodies.len() {
        let Some(t) = bodies[ids[bi]].joint.as_ref() else { continue };
        if drives.iter().any(|d| d.0 == bi) || in_loop[bi] {
            continue;
        }
        let terms: Vec<(usize, f64)> = t.coef.iter().copied().enumerate().filter(|(_, c)| *c != 0.0).collect();
        let [(k, ci)] = terms.as_slice() else {
            return Err(SimError::Build(format!("{}: passive joint of body {} depends on several joints", arm.name, model.bodies[bi].name)));
        };
        let (lead_body, c, b) = drives[*k];
        let coeff = ci / c;
        let frame2 = rapier_axis_frame(t);
        let inertia = crate::rapier_world::axis_inertia(&arm.inertials, model, bi, &frame2, t.revolute);
        let w = crate::rapier_world::CABLE_BANDWIDTH;
        let lead = bodies[ids[lead_body]].joint.as_ref().map(|l| l.name.clone()).unwrap_or_default();
        extras.tendons.push(format!(
            "<fixed name=\"{}\" stiffness=\"{}\" damping=\"{}\" springlength=\"{}\"><joint joint=\"{}\" coef=\"1\"/><joint joint=\"{}\" coef=\"{}\"/></fixed>",
            esc(&named(&format!("cable:{}", model.bodies[bi].name))),
            num(inertia * w * w),
            num(2.0 * inertia * w),
            num(t.offset - coeff * b),
            esc(&t.name),
            esc(&lead),
            num(-coeff)
        ));
    }
    // Drives: armature, limits, motor, hold, controller data.
    let (traj, _) = Trajectory::tracking_test(model);
    let armature = crate::effects::drive_armature(&arm.model, &arm.armature);
    for (k, j) in model.joints.iter().enumerate() {
        let (bi, c, b) = drives[k];
        let t = bodies[ids[bi]].joint.as_mut().ok_or_else(|| SimError::Build(format!("{}: drive of {} has no joint", arm.name, j.name)))?;
        t.armature = armature[k] / (c * c);
        let (lo, hi) = (c * j.lower + b, c * j.upper + b);
        t.range = Some([lo.min(hi), lo.max(hi)]);
        let jname = t.name.clone();
        let aname = named(&j.name);
        let ctrl = if j.effort_limit > 0.0 { format!(" ctrlrange=\"{} {}\"", num(-j.effort_limit), num(j.effort_limit)) } else { String::new() };
        extras.actuators.push(format!("<motor name=\"{}\" joint=\"{}\" gear=\"{}\"{ctrl}/>", esc(&aname), esc(&jname), num(1.0 / c)));
        let held = arm.mode == Mode::Position;
        if held {
            // MuJoCo's joint equality acts on the offset from `ref` (home): hold it at 0.
            extras.equalities.push(format!(
                "<joint name=\"{}\" joint1=\"{}\" polycoef=\"0 0 0 0 0\" solref=\"{solref}\" solimp=\"{solimp}\"/>",
                esc(&named(&format!("hold:{}", j.name))),
                esc(&jname)
            ));
        }
        let (amplitude, frequency) = match (&traj, arm.tracking) {
            (Trajectory::Sine { amplitude, frequency, .. }, Tracking::Sine) => (amplitude[k], *frequency),
            _ => (0.0, 0.0),
        };
        let g = arm.gains[k];
        let data = [c, b, g.kp, g.ki, g.kd, j.effort_limit, if held { 1.0 } else { 0.0 }, home[k], amplitude, frequency, j.lower, j.upper];
        extras.custom.push(format!("<numeric name=\"dvrk:{}\" data=\"{}\"/>", esc(&aname), nums(&data)));
    }
    Ok(ids)
}

/// The rapier joint frame (x: the axis) of a tree joint, for [`crate::sim::axis_inertia`].
fn rapier_axis_frame(t: &TreeJoint) -> rapier3d_f64::math::Pose {
    let rot = nalgebra::Rotation3::rotation_between(&Vector3::x(), &t.axis).unwrap_or_else(|| nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI));
    crate::sim::to_rapier(&Pose::from_parts(Translation3::from(t.pos), rot))
}

/// The scene `dvrk export mjcf NAME` exports: a built-in scene name or a scene file (a TOML with
/// `[[arms]]`), else a model (built-in name or file) mounted at its own base, with the inertials,
/// gains, armature, damping and drive mode the built-in scenes give an arm of that model.
pub fn resolve(name_or_path: &str) -> Result<Scene> {
    if crate::scene::builtin_scenes().contains(&name_or_path) {
        return Scene::load(name_or_path);
    }
    let path = std::path::Path::new(name_or_path);
    if path.is_file() && path.extension().is_some_and(|e| e == "toml") {
        let text = dvrk_kin::load::read_text(path)?;
        let is_scene = toml::from_str::<toml::Table>(&text).is_ok_and(|t| t.contains_key("arms"));
        if is_scene {
            return Scene::load(name_or_path);
        }
    }
    let model = dvrk_kin::load(name_or_path, None).map_err(|e| {
        SimError::field(name_or_path, "scene or model", format!("not a built-in scene ({}) or scene file, and not a model: {e}", crate::scene::builtin_scenes().join(", ")))
    })?;
    single_model(model, name_or_path)
}

/// A one-arm scene of `model` (mounted at `model.base`), taking the first built-in scene arm of
/// the same model name as the template for everything but the mount.
fn single_model(model: Model, what: &str) -> Result<Scene> {
    let mut with: Vec<String> = Vec::new();
    for s in crate::scene::builtin_scenes() {
        let scene = Scene::load(s)?;
        for arm in &scene.arms {
            if arm.model.name == model.name {
                arm.inertials.check(&format!("built-in inertials of {}", model.name), &model)?;
                let mut a = arm.clone();
                a.name = model.name.clone();
                a.model = model;
                a.parent = None;
                // An identified model file's own inertials and drive, as `Scene::set_model` takes them.
                a.take_model_file(scene.solver.pgs_iterations);
                a.inertials.check(&format!("{} inertials", a.model.name), &a.model)?;
                return Ok(Scene { name: a.name.clone(), title: format!("{} alone ({})", a.name, model_title(&a.model)), dt: scene.dt, engine: scene.engine, solver: scene.solver, gravity: scene.gravity, arms: vec![a], camera: None, file: scene.file.clone(), notes: scene.notes.clone() });
            }
            if !with.contains(&arm.model.name) {
                with.push(arm.model.name.clone());
            }
        }
    }
    Err(SimError::field(what, "model", format!("model {} has no built-in inertials and gains (models with them: {})", model.name, with.join(", "))))
}

fn model_title(m: &Model) -> &str {
    if m.title.is_empty() {
        &m.name
    } else {
        &m.title
    }
}

/// [`export_mjcf`] of [`resolve`]`(name_or_path)`.
pub fn export_named(name_or_path: &str) -> Result<String> {
    export_mjcf(&resolve(name_or_path)?)
}
