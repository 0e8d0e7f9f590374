//! Inertial parameters of a model's rigid bodies (mass, centre of mass, inertia), stored per body
//! in the body's first DH frame, and their conversion from the paper's CAD/SDF figures.
//!
//! The SDF gives each link's pose in its model frame at the zero configuration; dvrk-kin gives
//! each body's first frame at `q = 0` in its own base frame. One constant `base_transform` maps
//! the dvrk-kin base frame onto the SDF model frame; with it, each link's inertial is re-expressed
//! in the body frame (`com_b = B^-1 L c`, `I_b = R I R^T` with `R` the rotation of `B^-1 L C`).

use crate::error::{Result, SimError};
use dvrk_kin::{pose_from_rows, pose_to_rows, Model, Pose};
use nalgebra::{Matrix3, Point3, Rotation3, Translation3, Vector3};
use serde::{Deserialize, Serialize};

/// Inertial parameters of one rigid body.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BodyInertial {
    /// dvrk-kin body name (the SDF link name where there is one).
    pub name: String,
    /// Paper frame number of the body's first frame, in which `com` and `inertia` are given.
    pub frame: i64,
    /// kg
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    #[serde(deserialize_with = "dvrk_kin::exact::vec3")]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, body-frame axes (kg m^2), row-major.
    #[serde(deserialize_with = "dvrk_kin::exact::mat3")]
    pub inertia: [[f64; 3]; 3],
    /// Where the figures come from (SDF link, or how they were derived).
    pub provenance: String,
}

/// Inertial parameters of every body of a model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Inertials {
    /// The dvrk-kin model these belong to.
    pub model: String,
    pub source: String,
    /// Row-major 4x4 map from the dvrk-kin base frame to the SDF model frame (m).
    #[serde(deserialize_with = "dvrk_kin::exact::mat4")]
    pub base_transform: [[f64; 4]; 4],
    pub notes: String,
    pub bodies: Vec<BodyInertial>,
}

/// The SDF extract `dvrk-env-inertials/*.json` (see `../shared/data/external/README.md`).
#[derive(Debug, Deserialize)]
pub struct SdfExtract {
    pub source: String,
    pub links: Vec<SdfLink>,
    #[serde(default)]
    pub joints: Vec<SdfJoint>,
}

#[derive(Debug, Deserialize)]
pub struct SdfLink {
    pub link: String,
    /// x, y, z (m), roll, pitch, yaw (rad): the link frame in the model frame at zero configuration.
    pub link_pose_in_model_xyz_rpy: [f64; 6],
    pub mass_kg: f64,
    /// The inertial frame in the link frame.
    pub com_pose_in_link_xyz_rpy: [f64; 6],
    pub inertia_about_com_kg_m2: SdfInertia,
}

#[derive(Debug, Deserialize)]
pub struct SdfInertia {
    pub ixx: f64,
    pub ixy: f64,
    pub ixz: f64,
    pub iyy: f64,
    pub iyz: f64,
    pub izz: f64,
}

#[derive(Debug, Deserialize)]
pub struct SdfJoint {
    pub joint: String,
    #[serde(rename = "type")]
    pub kind: String,
    pub parent: String,
    pub child: String,
    /// The joint frame in the child link frame (`None`: at the link origin).
    pub pose_in_child_xyz_rpy: Option<[f64; 6]>,
    /// Axis in the model frame (the SDF was written with `use_parent_model_frame`).
    pub axis_xyz: Option<[f64; 3]>,
}

/// An SDF `x y z roll pitch yaw` pose (fixed-axis roll-pitch-yaw, as SDF defines it).
pub fn sdf_pose(p: &[f64; 6]) -> Pose {
    Pose::from_parts(Translation3::new(p[0], p[1], p[2]), Rotation3::from_euler_angles(p[3], p[4], p[5]))
}

impl SdfInertia {
    fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(self.ixx, self.ixy, self.ixz, self.ixy, self.iyy, self.iyz, self.ixz, self.iyz, self.izz)
    }
}

/// Why an inertia matrix is not physical, if it is not: symmetric, positive principal moments
/// obeying the triangle inequality (kg m^2).
pub fn inertia_problem(i: &Matrix3<f64>) -> Option<String> {
    if i.iter().any(|x| !x.is_finite()) {
        return Some("has a non-finite entry".into());
    }
    if (i - i.transpose()).abs().max() > 1e-12 * i.abs().max().max(1e-300) {
        return Some("is not symmetric".into());
    }
    let e = i.symmetric_eigenvalues();
    let tol = 1e-12 * e.abs().max().max(1e-300);
    if e.iter().any(|x| *x <= 0.0) {
        return Some(format!("principal moments {:?} are not all positive", e.as_slice()));
    }
    for k in 0..3 {
        if e[k] > e[(k + 1) % 3] + e[(k + 2) % 3] + tol {
            return Some(format!("principal moments {:?} break the triangle inequality", e.as_slice()));
        }
    }
    None
}

/// The nearest physical inertia with the same principal axes: each principal moment raised to
/// at least the difference of the other two, and to `floor` (kg m^2). Returns the matrix and
/// whether it changed.
fn make_physical(i: &Matrix3<f64>, floor: f64) -> (Matrix3<f64>, bool) {
    if inertia_problem(i).is_none() {
        return (*i, false);
    }
    let eig = i.symmetric_eigen();
    let mut e = eig.eigenvalues;
    for x in e.iter_mut() {
        *x = x.max(floor);
    }
    for k in 0..3 {
        let need = (e[(k + 1) % 3] - e[(k + 2) % 3]).abs();
        e[k] = e[k].max(need);
    }
    let v = eig.eigenvectors;
    (v * Matrix3::from_diagonal(&e) * v.transpose(), true)
}

impl Inertials {
    /// Parse an inertials file (`file` names it in errors) and check it against `model`: every
    /// body present once, finite positive masses, physical inertias.
    pub fn parse(text: &str, file: &str, model: &Model) -> Result<Inertials> {
        let ine: Inertials = toml::from_str(text).map_err(|e| SimError::field(file, "(syntax)", dvrk_kin::spec::toml_message(&e, text)))?;
        ine.check(file, model)?;
        Ok(ine)
    }

    /// See [`Inertials::parse`].
    pub fn check(&self, file: &str, model: &Model) -> Result<()> {
        pose_from_rows(&self.base_transform, "base_transform").map_err(|e| SimError::field(file, "base_transform", e.to_string()))?;
        for (i, b) in self.bodies.iter().enumerate() {
            let field = |f: &str| format!("bodies[{i}] ({}).{f}", b.name);
            let Some(body) = model.bodies.iter().position(|mb| mb.name == b.name) else {
                let valid: Vec<&str> = model.bodies.iter().map(|mb| mb.name.as_str()).collect();
                return Err(SimError::field(file, field("name"), format!("model {} has no body `{}` (valid: {})", model.name, b.name, valid.join(", "))));
            };
            if model.frames[model.bodies[body].frames[0]].index != b.frame {
                return Err(SimError::field(file, field("frame"), format!("{} is not the body's first frame ({})", b.frame, model.frames[model.bodies[body].frames[0]].index)));
            }
            if !(b.mass.is_finite() && b.mass > 0.0) {
                return Err(SimError::field(file, field("mass"), format!("{} kg is not a positive finite mass", b.mass)));
            }
            if b.com.iter().any(|x| !x.is_finite()) {
                return Err(SimError::field(file, field("com"), format!("{:?} has a non-finite entry", b.com)));
            }
            if let Some(p) = inertia_problem(&matrix3(&b.inertia)) {
                return Err(SimError::field(file, field("inertia"), format!("{:?} {p}", b.inertia)));
            }
            if self.bodies[..i].iter().any(|c| c.name == b.name) {
                return Err(SimError::field(file, field("name"), "body appears twice"));
            }
        }
        if let Some(missing) = model.bodies.iter().find(|mb| !self.bodies.iter().any(|b| b.name == mb.name)) {
            return Err(SimError::field(file, "bodies", format!("no entry for body `{}` of model {}", missing.name, model.name)));
        }
        Ok(())
    }

    /// Every body's inertia in [`Model::bodies`] order, for dvrk-kin's dynamics.
    /// `model`'s counterweight travel ratio `mu` and the counterweight's mass here (kg); `None`
    /// when the model has no counterweight (or these inertials do not cover it).
    pub fn counterweight(&self, model: &Model) -> Option<[f64; 2]> {
        let mu = model.spec.parameters.get("mu")?.value;
        let frame = model.counterweight_frame()?;
        Some([mu, self.body_inertias(model).ok()?[model.frames[frame].body].mass])
    }

    pub fn body_inertias(&self, model: &Model) -> Result<Vec<dvrk_kin::BodyInertia>> {
        (0..model.bodies.len())
            .map(|b| {
                let e = self.body(model, b).ok_or_else(|| SimError::field(&self.model, "bodies", format!("no entry for body `{}`", model.bodies[b].name)))?;
                Ok(dvrk_kin::BodyInertia::new(e.mass, e.com, e.inertia))
            })
            .collect()
    }

    /// These inertials with every body that `model`'s file carries (`[[inertials]]`, e.g. an
    /// identified model's) in place of this file's entry: the model file wins.
    pub fn with_model(&self, model: &Model) -> Inertials {
        let mut out = self.clone();
        for e in &model.spec.inertials {
            let Some(b) = model.bodies.iter().position(|mb| mb.name == e.body) else { continue };
            let entry = BodyInertial {
                name: e.body.clone(),
                frame: model.frames[model.bodies[b].frames[0]].index,
                mass: e.mass,
                com: e.com,
                inertia: e.inertia,
                provenance: if e.source.is_empty() { format!("model {}", model.name) } else { e.source.clone() },
            };
            match out.bodies.iter_mut().find(|x| x.name == e.body) {
                Some(x) => *x = entry,
                None => out.bodies.push(entry),
            }
        }
        out
    }

    /// The entry of `body` (a position in `model.bodies`).
    pub fn body(&self, model: &Model, body: usize) -> Option<&BodyInertial> {
        self.bodies.iter().find(|b| b.name == model.bodies[body].name)
    }

    /// The file text (TOML), with a header saying how it was made.
    pub fn to_toml(&self, header: &str) -> String {
        let body = toml::to_string(self).unwrap_or_default();
        let mut out = String::new();
        for line in header.lines() {
            out += "# ";
            out += line;
            out += "\n";
        }
        out + &body
    }
}

/// Row-major 3x3 to a matrix.
pub fn matrix3(m: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    // Rounded to 1e-12 so regenerated files compare equal across platforms.
    let r = |x: f64| (x * 1e12).round() / 1e12;
    [[r(m[(0, 0)]), r(m[(0, 1)]), r(m[(0, 2)])], [r(m[(1, 0)]), r(m[(1, 1)]), r(m[(1, 2)])], [r(m[(2, 0)]), r(m[(2, 1)]), r(m[(2, 2)])]]
}

/// A body without an SDF link (e.g. the PSM counterweight): its figures and their provenance.
#[derive(Debug, Clone)]
pub struct ExtraBody {
    pub name: String,
    pub inertial: BodyInertial,
}

/// Convert an SDF extract to inertials in the model's body frames. `base` maps the dvrk-kin base
/// frame onto the SDF model frame; links the model has no body for (the SDF `base_link`, the ECM
/// `camera_link`) are skipped and listed in the notes; `extra` supplies bodies the SDF lacks.
/// Non-physical inertias are replaced by the nearest physical one and the change is noted.
pub fn from_sdf(model: &Model, sdf: &SdfExtract, base: &Pose, extra: &[ExtraBody], notes: &str) -> Result<Inertials> {
    let q0 = vec![0.0; model.nq()];
    let fk = model.fk(&q0)?;
    let mut bodies = Vec::new();
    let mut skipped = Vec::new();
    let mut fixed = Vec::new();
    for link in &sdf.links {
        let Some(bi) = model.bodies.iter().position(|b| b.name == link.link) else {
            skipped.push(link.link.clone());
            continue;
        };
        let f0 = model.bodies[bi].frames[0];
        let body_in_sdf = base * fk[f0];
        let link_pose = sdf_pose(&link.link_pose_in_model_xyz_rpy);
        let com_frame = body_in_sdf.inverse() * link_pose * sdf_pose(&link.com_pose_in_link_xyz_rpy);
        let r = com_frame.rotation.matrix();
        let i_body = r * link.inertia_about_com_kg_m2.matrix() * r.transpose();
        let (i_phys, changed) = make_physical(&i_body, 1e-9);
        let mut provenance = format!("SDF link {} (mass, inertial pose, inertia), re-expressed in frame {}", link.link, model.frames[f0].index);
        if changed {
            provenance += "; SDF inertia is not physical, principal moments raised to the triangle inequality";
            fixed.push(link.link.clone());
        }
        let c = com_frame.translation.vector;
        let r12 = |x: f64| (x * 1e12).round() / 1e12;
        bodies.push(BodyInertial {
            name: link.link.clone(),
            frame: model.frames[f0].index,
            mass: link.mass_kg,
            com: [r12(c.x), r12(c.y), r12(c.z)],
            inertia: rows3(&i_phys),
            provenance,
        });
    }
    for e in extra {
        bodies.push(e.inertial.clone());
    }
    // Model order, so the file reads like the DH table.
    bodies.sort_by_key(|b| model.bodies.iter().position(|mb| mb.name == b.name).unwrap_or(usize::MAX));
    let mut all_notes = notes.trim().to_string();
    if !skipped.is_empty() {
        all_notes += &format!("\nSDF links without a body in the model (not used): {}.", skipped.join(", "));
    }
    if !fixed.is_empty() {
        all_notes += &format!("\nNon-physical SDF inertias made physical (nearest, same principal axes): {}.", fixed.join(", "));
    }
    let mut bt = pose_to_rows(base);
    for x in bt.iter_mut().flatten() {
        *x = (*x * 1e12).round() / 1e12 + 0.0; // + 0.0 turns -0.0 into 0.0
    }
    let out = Inertials { model: model.name.clone(), source: sdf.source.clone(), base_transform: bt, notes: all_notes, bodies };
    out.check(&format!("inertials of {}", model.name), model)?;
    Ok(out)
}

/// How well the SDF's joints at zero configuration sit on the model's joint axes after `base`:
/// per SDF joint whose child link is a model body, the angle between the axes (rad) and, for
/// revolute joints, the distance from the SDF joint origin to the model axis line (m).
pub fn axis_agreement(model: &Model, sdf: &SdfExtract, base: &Pose) -> Result<Vec<(String, f64, f64)>> {
    let fk = model.fk(&vec![0.0; model.nq()])?;
    let mut out = Vec::new();
    for j in &sdf.joints {
        let (Some(axis), Some(link)) = (j.axis_xyz, sdf.links.iter().find(|l| l.link == j.child)) else { continue };
        let Some(bi) = model.bodies.iter().position(|b| b.name == j.child) else { continue };
        // The body's tree joint: its first frame whose parent lies in another body.
        let Some(&f) = model.bodies[bi].frames.iter().find(|&&f| {
            model.frames[f].is_moving() && model.frames[f].parent.is_none_or(|p| model.frames[p].body != bi)
        }) else {
            continue;
        };
        // A loop-closing SDF joint also has this child: only the tree joint (from the parent body) counts.
        let parent_body = model.frames[f].parent.map(|p| model.bodies[model.frames[p].body].name.clone());
        if parent_body.as_deref().is_some_and(|p| p != j.parent) && j.parent != "base_link" {
            continue;
        }
        let axis_frame = base * fk[f] * model.frames[f].post().map(|p| p.inverse()).unwrap_or_else(Pose::identity);
        let z = axis_frame.rotation.matrix().column(2).into_owned();
        let a = Vector3::from(axis).normalize();
        let angle = z.cross(&a).norm().asin();
        let origin = sdf_pose(&link.link_pose_in_model_xyz_rpy)
            * Point3::from(j.pose_in_child_xyz_rpy.map(|p| Vector3::new(p[0], p[1], p[2])).unwrap_or_else(Vector3::zeros));
        let distance = if j.kind == "revolute" {
            let v = origin.coords - axis_frame.translation.vector;
            (v - z * z.dot(&v)).norm()
        } else {
            0.0
        };
        out.push((j.joint.clone(), angle, distance));
    }
    Ok(out)
}
