//! A robot description for the panels that want one (Foxglove's and RViz's URDF displays): one
//! URDF per arm whose links are the arm's bodies, named as their `/tf` frames (`PSM1/yaw_link`),
//! each with the link geometry of [`crate::geometry`] as its visuals (a capsule as a cylinder and
//! two spheres), attached to `world` by floating joints. A display then places every link from
//! `/tf` as the simulation moves it: the loops need no mimic joints, which a URDF cannot close.
//!
//! The kinematic URDF of a model (links per frame, mimic joints; `dvrk export urdf`) is the
//! other description: it answers joint values, this one answers poses.

use crate::geometry::{ArmGeometry, Part, Solid};
use dvrk_kin::Pose;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use std::fmt::Write;

/// XML attribute text.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn origin(p: &Vector3<f64>, r: &UnitQuaternion<f64>) -> String {
    let (roll, pitch, yaw) = r.euler_angles();
    format!("<origin xyz=\"{} {} {}\" rpy=\"{roll} {pitch} {yaw}\"/>", p.x, p.y, p.z)
}

/// The visuals of one solid (m, in the body frame), in `material`.
fn visuals(s: &Solid, material: &str, out: &mut String) {
    let rot = |p: &Pose| UnitQuaternion::from_rotation_matrix(&p.rotation);
    let mut visual = |o: String, g: String| {
        let _ = writeln!(out, "    <visual>{o}<geometry>{g}</geometry><material name=\"{material}\"/></visual>");
    };
    let shape = &s.shape;
    if let Some(c) = shape.as_capsule() {
        let (a, b) = (s.pose * Point3::new(c.segment.a.x, c.segment.a.y, c.segment.a.z), s.pose * Point3::new(c.segment.b.x, c.segment.b.y, c.segment.b.z));
        let d = b - a;
        let along = UnitQuaternion::rotation_between(&Vector3::z(), &d).unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        if d.norm() > 0.0 {
            visual(origin(&nalgebra::center(&a, &b).coords, &along), format!("<cylinder radius=\"{}\" length=\"{}\"/>", c.radius, d.norm()));
        }
        for end in [a, b] {
            visual(origin(&end.coords, &UnitQuaternion::identity()), format!("<sphere radius=\"{}\"/>", c.radius));
        }
    } else if let Some(ball) = shape.as_ball() {
        visual(origin(&s.pose.translation.vector, &UnitQuaternion::identity()), format!("<sphere radius=\"{}\"/>", ball.radius));
    } else if let Some(c) = shape.as_cuboid() {
        let e = c.half_extents * 2.0;
        visual(origin(&s.pose.translation.vector, &rot(&s.pose)), format!("<box size=\"{} {} {}\"/>", e.x, e.y, e.z));
    }
    // A model file's mesh: its triangles are in `/scene`; a URDF would need the file on the
    // viewer's machine.
}

/// The URDF of arm `arm` (its `/tf` prefix) with geometry `geometry` and body names `bodies`,
/// coloured `color` (RGB, 0-1) as in the camera images.
pub fn arm_urdf(arm: &str, geometry: &ArmGeometry, bodies: &[String], color: [f32; 3]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "<?xml version=\"1.0\"?>");
    let _ = writeln!(out, "<!-- dvrk-twin: the bodies of {} as their /tf frames (m, rad); floating joints: place them from /tf. -->", esc(arm));
    let _ = writeln!(out, "<robot name=\"{}\">", esc(arm));
    for (name, part) in [("link", Part::Link), ("setup", Part::Setup), ("tool", Part::Tool), ("jaw", Part::Jaw)] {
        let c = part.color(color);
        let _ = writeln!(out, "  <material name=\"{name}\"><color rgba=\"{} {} {} 1\"/></material>", c[0], c[1], c[2]);
    }
    let _ = writeln!(out, "  <link name=\"world\"/>");
    for (b, solids) in geometry.bodies.iter().enumerate() {
        let name = esc(&bodies[b]);
        let _ = writeln!(out, "  <link name=\"{name}\">");
        for s in solids {
            let material = match s.part {
                Part::Setup => "setup",
                Part::Tool => "tool",
                Part::Jaw => "jaw",
                Part::Link | Part::Mesh => "link",
            };
            visuals(s, material, &mut out);
        }
        let _ = writeln!(out, "  </link>");
        let _ = writeln!(out, "  <joint name=\"{name}\" type=\"floating\"><parent link=\"world\"/><child link=\"{name}\"/></joint>");
    }
    let _ = writeln!(out, "</robot>");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::ARM_COLORS;

    #[test]
    fn the_psm_description_has_a_link_per_body_with_its_visuals() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let geometry = ArmGeometry::new(&model).unwrap();
        let names: Vec<String> = model.bodies.iter().map(|b| format!("PSM1/{}", b.name)).collect();
        let text = arm_urdf("PSM1", &geometry, &names, ARM_COLORS[0]);
        // urdf-rs, the reader dvrk-kin imports URDF with, reads it back.
        let robot = urdf_rs::read_from_string(&text).unwrap();
        assert_eq!(robot.links.len(), model.bodies.len() + 1);
        for (b, solids) in geometry.bodies.iter().enumerate() {
            let link = robot.links.iter().find(|l| l.name == names[b]).unwrap();
            let capsules = solids.iter().filter(|s| s.shape.as_capsule().is_some()).count();
            assert!(link.visual.len() >= solids.len() && link.visual.len() <= solids.len() + 2 * capsules, "{}", link.name);
        }
        assert!(robot.joints.iter().all(|j| matches!(j.joint_type, urdf_rs::JointType::Floating) && j.parent.link == "world"));
        // A capsule's cylinder joins its two spheres: its origin midway, its length their distance.
        let link = robot.links.iter().find(|l| l.visual.iter().any(|v| matches!(v.geometry, urdf_rs::Geometry::Cylinder { .. }))).unwrap();
        let v = &link.visual;
        let i = v.iter().position(|x| matches!(x.geometry, urdf_rs::Geometry::Cylinder { .. })).unwrap();
        let (c, s1, s2) = (v[i].origin.xyz.0, v[i + 1].origin.xyz.0, v[i + 2].origin.xyz.0);
        let length = match v[i].geometry {
            urdf_rs::Geometry::Cylinder { length, .. } => length,
            _ => unreachable!(),
        };
        let (a, b) = (Vector3::from(s1), Vector3::from(s2));
        assert!((Vector3::from(c) - (a + b) / 2.0).norm() < 1e-12 && ((b - a).norm() - length).abs() < 1e-12);
        // Its axis (the origin's z) along the segment.
        let [r, p, y] = v[i].origin.rpy.0;
        let z = UnitQuaternion::from_euler_angles(r, p, y) * Vector3::z();
        assert!((z - (b - a).normalize()).norm() < 1e-9, "{z:?}");
    }
}
