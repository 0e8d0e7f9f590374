//! Link geometry of every model: simple solids sized from the kinematics, or the meshes a model
//! file names (`[[meshes]]`, STL or OBJ). Used by the camera's renderer and attached to the rapier
//! bodies as colliders (contacts off unless asked for).
//!
//! The solids follow the frame tree, so no size is written per model: on each body, a capsule
//! from every frame's origin to the point where each child joint sits on the body (a revolute
//! child's origin on its axis, a prismatic child's point before its slide) and to each loop-closure
//! point on the body. The radius is one number per part class ([`Part`]). Bodies with no segment
//! (a counterweight, the wrist's yaw link) get a ball; the leaf bodies beyond an RCM arm's tip
//! (the jaw blades) get a small box along the tip's approach axis (z of the tip frame).

use crate::error::{Result, SimError};
use dvrk_kin::{FrameJoint, Model, Pose};
use nalgebra::{Point3, Rotation3, Translation3, Unit, Vector3};
use rapier3d_f64::math::Vector as RVec;
use rapier3d_f64::parry::shape::{Ball, Capsule, Cuboid, SharedShape, TriMesh};
use std::path::Path;

/// Radius of the links of an arm with an RCM (PSM, ECM) before its tool (m).
pub const LINK_RADIUS_M: f64 = 0.012;
/// Radius of the links of models without an RCM (setup joints, MTMs) (m).
pub const SETUP_RADIUS_M: f64 = 0.025;
/// Radius of the tool: the instrument shaft and wrist beyond the RCM frame (an 8 mm dVRK
/// instrument; the ECM's endoscope uses the same) (m).
pub const TOOL_RADIUS_M: f64 = 0.004;
/// Jaw blade (m): length along the tip's approach axis, width and thickness (a needle driver's).
pub const JAW_SIZE_M: [f64; 3] = [0.0095, 0.003, 0.0015];
/// Segments shorter than this are not drawn (m).
const MIN_SEGMENT_M: f64 = 1e-6;

/// Colours of the arms with an RCM, in scene order (RGB, 0-1; camera images and the live view's 3D scene): PSM1 orange, PSM2 blue,
/// PSM3 green, ... so a person can tell the arms apart. The ECM is not in view of itself.
pub const ARM_COLORS: [[f32; 3]; 5] = [[0.95, 0.55, 0.15], [0.25, 0.55, 0.95], [0.35, 0.8, 0.35], [0.85, 0.3, 0.75], [0.9, 0.85, 0.3]];
/// Setup joints: grey.
pub const SETUP_COLOR: [f32; 3] = [0.6, 0.6, 0.62];
/// Jaw blades: steel.
pub const JAW_COLOR: [f32; 3] = [0.85, 0.87, 0.9];

/// What a solid is part of: sets its radius and its colour in camera images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// A link of an arm with an RCM (PSM, ECM).
    Link,
    /// A link of a model without an RCM (setup joints, MTM).
    Setup,
    /// The tool beyond the RCM frame: shaft and wrist.
    Tool,
    /// A jaw blade.
    Jaw,
    /// A mesh from the model file.
    Mesh,
}

impl Part {
    /// Its colour on an arm coloured `arm` (RGB, 0-1): the setup joints grey, a jaw blade steel,
    /// the tool shaft a darker shade of its arm's colour, links and meshes the arm's.
    pub fn color(self, arm: [f32; 3]) -> [f32; 3] {
        match self {
            Part::Setup => SETUP_COLOR,
            Part::Jaw => JAW_COLOR,
            Part::Tool => arm.map(|c| 0.75 * c),
            Part::Link | Part::Mesh => arm,
        }
    }
}

/// The colour of arm `a` of a scene whose arms have an RCM or not (`has_rcm`): the arms with an
/// RCM take [`ARM_COLORS`] in scene order, the others the setup joints' grey.
pub fn arm_color(has_rcm: &[bool], a: usize) -> [f32; 3] {
    if !has_rcm[a] {
        return SETUP_COLOR;
    }
    let k = has_rcm[..=a].iter().filter(|r| **r).count();
    ARM_COLORS[(k - 1) % ARM_COLORS.len()]
}

/// One solid of a body: a parry shape placed in the body frame (the body's first frame).
#[derive(Clone)]
pub struct Solid {
    pub shape: SharedShape,
    /// Placement in the body frame (m).
    pub pose: Pose,
    pub part: Part,
}

impl std::fmt::Debug for Solid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Solid").field("shape", &self.shape.shape_type()).field("pose", &self.pose).field("part", &self.part).finish()
    }
}

/// The solids of every body of one model (`bodies[b]`: body `b` of [`Model::bodies`]).
#[derive(Debug, Clone)]
pub struct ArmGeometry {
    pub bodies: Vec<Vec<Solid>>,
}

impl ArmGeometry {
    /// Geometry of `model`: the meshes its file names, solids from the kinematics elsewhere.
    pub fn new(model: &Model) -> Result<ArmGeometry> {
        let mut bodies = kinematic_solids(model)?;
        let file = model.origin.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| format!("model {}", model.name));
        let dir = model.origin.as_deref().and_then(Path::parent).map(Path::to_path_buf).unwrap_or_default();
        let mut meshed = vec![false; bodies.len()];
        for (i, m) in model.spec.meshes.iter().enumerate() {
            let field = |f: &str| format!("meshes[{i}].{f}");
            let Some(b) = model.bodies.iter().position(|b| b.name == m.body) else {
                let valid: Vec<&str> = model.bodies.iter().map(|b| b.name.as_str()).collect();
                return Err(SimError::field(&file, field("body"), format!("`{}` is not a body of {} (valid: {})", m.body, model.name, valid.join(", "))));
            };
            if !(m.scale.is_finite() && m.scale > 0.0) {
                return Err(SimError::field(&file, field("scale"), format!("{} is not a positive number of metres per file unit", m.scale)));
            }
            let pose = match &m.transform {
                Some(t) => dvrk_kin::pose_from_rows(t, "transform").map_err(|e| SimError::field(&file, field("transform"), e.to_string()))?,
                None => Pose::identity(),
            };
            let path = dir.join(&m.file);
            let mesh = load_mesh(&path, m.scale).map_err(|e| SimError::field(&file, field("file"), format!("{}: {e}", path.display())))?;
            if !meshed[b] {
                bodies[b].clear();
                meshed[b] = true;
            }
            bodies[b].push(Solid { shape: SharedShape::new(mesh), pose, part: Part::Mesh });
        }
        Ok(ArmGeometry { bodies })
    }
}

/// The largest mesh file read (bytes): the dVRK's STL meshes are a few MB each.
pub const MAX_MESH_BYTES: u64 = 256 << 20;

/// A triangle mesh from an STL (binary or ASCII) or OBJ file, scaled to metres.
pub fn load_mesh(path: &Path, scale: f64) -> std::result::Result<TriMesh, String> {
    // Only a regular file of a mesh's size is parsed (a FIFO would wait, a device never end).
    let file = dvrk_kin::text_file::open_input(path).map_err(|e| match e {
        dvrk_kin::KinError::File { message, .. } => message,
        e => e.to_string(),
    })?;
    let size = file.metadata().map_err(|e| format!("cannot read: {e}"))?.len();
    if size > MAX_MESH_BYTES {
        return Err(format!("{size} bytes: a mesh file is at most {MAX_MESH_BYTES} bytes"));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let (vertices, indices): (Vec<RVec>, Vec<[u32; 3]>) = match ext.as_deref() {
        Some("stl") => {
            let mut f = std::fs::File::open(path).map_err(|e| e.to_string())?;
            let m = stl_io::read_stl(&mut f).map_err(|e| format!("not a readable STL file ({e})"))?;
            let v = m.vertices.iter().map(|p| RVec::new(p.0[0] as f64, p.0[1] as f64, p.0[2] as f64) * scale).collect();
            let i = m.faces.iter().map(|t| [t.vertices[0] as u32, t.vertices[1] as u32, t.vertices[2] as u32]).collect();
            (v, i)
        }
        Some("obj") => {
            let (models, _) = tobj::load_obj(path, &tobj::GPU_LOAD_OPTIONS).map_err(|e| format!("not a readable OBJ file ({e})"))?;
            let (mut v, mut i) = (Vec::new(), Vec::new());
            for m in &models {
                let base = v.len() as u32;
                v.extend(m.mesh.positions.chunks_exact(3).map(|p| RVec::new(p[0] as f64, p[1] as f64, p[2] as f64) * scale));
                i.extend(m.mesh.indices.chunks_exact(3).map(|t| [base + t[0], base + t[1], base + t[2]]));
            }
            (v, i)
        }
        _ => return Err("unknown mesh format (valid: .stl, .obj)".into()),
    };
    if indices.is_empty() {
        return Err("the mesh has no triangles".into());
    }
    TriMesh::new(vertices, indices).map_err(|e| format!("not a valid triangle mesh ({e:?})"))
}

/// The frames beyond (and including) the RCM frame: the tool.
fn tool_frames(model: &Model) -> Vec<bool> {
    let mut tool = vec![false; model.frames.len()];
    if let Some(r) = &model.rcm {
        tool[r.frame] = true;
        // Depth-first order: a frame's parent comes first.
        for i in 0..model.frames.len() {
            if let Some(p) = model.frames[i].parent {
                if tool[p] {
                    tool[i] = true;
                }
            }
        }
    }
    tool
}

/// Where joint frame `f` sits on its parent's body (world, m): on the axis for a revolute joint,
/// before the slide for a prismatic one, the origin for a fixed frame.
fn joint_point(model: &Model, fk: &[Pose], f: usize) -> Point3<f64> {
    let frame = &model.frames[f];
    match frame.joint {
        FrameJoint::Revolute => {
            // Modified DH: the origin is on the axis. Standard DH: the axis point is before `post`.
            let post = frame.post().copied().unwrap_or_else(Pose::identity);
            fk[f] * post.inverse() * Point3::origin()
        }
        FrameJoint::Prismatic => {
            let parent = frame.parent.map(|p| fk[p]).unwrap_or(model.base);
            parent * frame.pre() * Point3::origin()
        }
        FrameJoint::Fixed => fk[f] * Point3::origin(),
    }
}

/// A capsule's axis (world, m) and its part.
type Segment = (Point3<f64>, Point3<f64>, Part);

/// Solids from the kinematics (see the module documentation), per body, in body frames.
fn kinematic_solids(model: &Model) -> Result<Vec<Vec<Solid>>> {
    let fk = model.fk(&model.home())?;
    let tool = tool_frames(model);
    let has_rcm = model.rcm.is_some();
    let nb = model.bodies.len();
    // Segments per body in world coordinates at home, with the part they belong to.
    let mut segments: Vec<Vec<Segment>> = vec![Vec::new(); nb];
    let part_of = |f: usize| match (has_rcm, tool[f]) {
        (false, _) => Part::Setup,
        (true, true) => Part::Tool,
        (true, false) => Part::Link,
    };
    for (f, frame) in model.frames.iter().enumerate() {
        let Some(p) = frame.parent else { continue };
        let pb = model.frames[p].body;
        let j = joint_point(model, &fk, f);
        segments[pb].push((fk[p] * Point3::origin(), j, part_of(p)));
        if frame.body != pb {
            // A standard-DH link runs from the axis to the frame origin on the child body.
            segments[frame.body].push((j, fk[f] * Point3::origin(), part_of(f)));
        }
    }
    for c in &model.closures {
        let a = fk[c.frame];
        segments[model.frames[c.frame].body].push((a * Point3::origin(), a * Point3::from(c.point), part_of(c.frame)));
        let b = fk[c.partner];
        segments[model.frames[c.partner].body].push((b * Point3::origin(), b * Point3::from(c.partner_point), part_of(c.partner)));
    }
    let approach = fk[model.tip].rotation * Vector3::z();
    let mut out = Vec::with_capacity(nb);
    for (b, body) in model.bodies.iter().enumerate() {
        let to_body = fk[body.frames[0]].inverse();
        let mut solids = Vec::new();
        for (a, c, part) in &segments[b] {
            if (c - a).norm() < MIN_SEGMENT_M {
                continue;
            }
            let (a, c) = (to_body * a, to_body * c);
            let r = radius(*part);
            solids.push(Solid { shape: SharedShape::new(Capsule::new(rv(&a.coords), rv(&c.coords), r)), pose: Pose::identity(), part: *part });
        }
        if solids.is_empty() {
            let f0 = body.frames[0];
            let leaf = !model.frames.iter().any(|f| f.parent.is_some_and(|p| model.frames[p].body == b) && f.body != b);
            if tool[f0] && leaf && model.frames[model.tip].body != b {
                // A jaw blade: a box along the tip's approach axis from the blade's pivot.
                let [l, w, t] = JAW_SIZE_M;
                let dir = to_body.rotation * approach;
                let centre = to_body * (fk[f0] * Point3::origin()) + dir * (l / 2.0);
                let rot = Rotation3::rotation_between(&Vector3::x(), &dir).unwrap_or_else(|| Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::y()), std::f64::consts::PI));
                let pose = Pose::from_parts(Translation3::from(centre.coords), rot);
                solids.push(Solid { shape: SharedShape::new(Cuboid::new(RVec::new(l / 2.0, w / 2.0, t / 2.0))), pose, part: Part::Jaw });
            } else {
                let part = part_of(f0);
                let r = if part == Part::Tool { radius(part) } else { 1.5 * radius(part) };
                solids.push(Solid { shape: SharedShape::new(Ball::new(r)), pose: Pose::identity(), part });
            }
        }
        out.push(solids);
    }
    Ok(out)
}

fn radius(part: Part) -> f64 {
    match part {
        Part::Link | Part::Mesh => LINK_RADIUS_M,
        Part::Setup => SETUP_RADIUS_M,
        Part::Tool | Part::Jaw => TOOL_RADIUS_M,
    }
}

fn rv(v: &Vector3<f64>) -> RVec {
    RVec::new(v.x, v.y, v.z)
}

/// Triangles of a solid's surface in its body frame: (vertices in m, triangles).
pub fn tessellate(solid: &Solid) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    // 16 around, 8 from pole to pole: round enough at 800 px for a 24 mm link at 0.2 m.
    const AROUND: u32 = 16;
    const POLES: u32 = 8;
    let s = &solid.shape;
    let (v, i) = if let Some(c) = s.as_capsule() {
        c.to_trimesh(AROUND, POLES)
    } else if let Some(b) = s.as_ball() {
        b.to_trimesh(AROUND, POLES)
    } else if let Some(c) = s.as_cuboid() {
        c.to_trimesh()
    } else if let Some(c) = s.as_cylinder() {
        c.to_trimesh(AROUND)
    } else if let Some(m) = s.as_trimesh() {
        (m.vertices().to_vec(), m.indices().to_vec())
    } else {
        (Vec::new(), Vec::new())
    };
    let v = v.iter().map(|p| (solid.pose * Point3::new(p.x, p.y, p.z)).coords).collect();
    (v, i)
}

/// A solid's shape placed at its body's frame (a collider at the identity pose): as it is where
/// its pose is the identity, else its surface moved into the body frame (a box: the hull of its
/// corners). A collider at the identity with zero mass properties adds exactly nothing to its
/// body's: rapier then keeps the body's own (see [`crate::sim::mass_properties`] for why that
/// matters), where any other collider re-derives them through parry's principal axes.
pub fn in_body_frame(solid: &Solid) -> Result<SharedShape> {
    if solid.pose == Pose::identity() {
        return Ok(solid.shape.clone());
    }
    let (v, i) = tessellate(solid);
    let points: Vec<RVec> = v.iter().map(rv).collect();
    let shape = if solid.shape.as_cuboid().is_some() {
        SharedShape::convex_hull(&points)
    } else {
        SharedShape::trimesh(points, i).ok()
    };
    shape.ok_or_else(|| SimError::Build(format!("the {:?} solid could not be moved into its body frame", solid.part)))
}
