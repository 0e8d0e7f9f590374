//! URDF and SDF interchange: export -> import reproduces FK; the exported files say what the
//! paper's files say (mimic joints, loop-closing joints at the closure points); bad input gives
//! errors that name the file and the joint.

use dvrk_kin::sdf::export_sdf;
use dvrk_kin::urdf::{export_urdf, export_urdf_file, import_urdf_file, import_urdf_str, link_name};
use dvrk_kin::{KinError, Model, ModelSpec, Pose};
use nalgebra::{Point3, Rotation3, Translation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Largest position (m) and rotation-matrix entry difference (~rad) between two poses.
fn pose_error(a: &Pose, b: &Pose) -> (f64, f64) {
    ((a.translation.vector - b.translation.vector).norm(), (a.rotation.matrix() - b.rotation.matrix()).abs().max())
}

/// Export `name` to URDF, import it, and compare FK of every frame (by name) over 200 random
/// configurations within the limits.
fn urdf_round_trip(name: &str) {
    let m = dvrk_kin::load(name, None).unwrap();
    let text = export_urdf(&m).unwrap();
    let imp = import_urdf_str(&text, &format!("{name}.urdf")).unwrap();
    assert_eq!(imp.nq(), m.nq(), "{name}: actuated joints");
    // The imported joint order may differ: map by name.
    let map: Vec<usize> = imp.joints.iter().map(|j| m.joint_id(&j.name).unwrap()).collect();
    for (a, &k) in map.iter().enumerate() {
        let (ji, jo) = (&imp.joints[a], &m.joints[k]);
        assert_eq!(
            (ji.kind, ji.lower, ji.upper, ji.effort_limit),
            (jo.kind, jo.lower, jo.upper, jo.effort_limit),
            "{name}: joint {}",
            jo.name
        );
    }
    let frame_of: Vec<usize> = m
        .frames
        .iter()
        .map(|f| {
            imp.frames
                .iter()
                .position(|g| g.name == link_name(&f.name))
                .unwrap_or_else(|| panic!("{name}: frame {} lost", f.name))
        })
        .collect();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed ^ name.len() as u64);
    let mut worst = (0.0_f64, 0.0_f64);
    for _ in 0..200 {
        let q: Vec<f64> = m.joints.iter().map(|j| rng.random_range(j.lower..=j.upper)).collect();
        let qi: Vec<f64> = map.iter().map(|&k| q[k]).collect();
        let (a, b) = (m.fk(&q).unwrap(), imp.fk(&qi).unwrap());
        for (i, f) in m.frames.iter().enumerate() {
            let (dp, dr) = pose_error(&a[i], &b[frame_of[i]]);
            assert!(dp < 1e-12 && dr < 1e-12, "{name}: frame {} off by {dp:.2e} m, {dr:.2e} rad at q = {q:?}", f.name);
            worst = (worst.0.max(dp), worst.1.max(dr));
        }
        let (dp, dr) = pose_error(&a[m.tip], &b[frame_of[m.tip]]);
        assert!(dp < 1e-12 && dr < 1e-12, "{name}: tip");
    }
    eprintln!("{name}: {} frames, worst {:.1e} m, {:.1e} rad", m.frames.len(), worst.0, worst.1);
}

#[test]
fn urdf_round_trip_psm() {
    urdf_round_trip("psm");
}

#[test]
fn urdf_round_trip_ecm() {
    urdf_round_trip("ecm");
}

#[test]
fn urdf_round_trip_mtmr_standard_dh() {
    // Standard DH puts a constant transform after the joint motion: the `__post` joints.
    urdf_round_trip("mtmr");
}

#[test]
fn urdf_round_trip_cart() {
    urdf_round_trip("cart");
}

#[test]
fn psm_urdf_has_mimic_joints_and_the_dvrk_joint_names() {
    let m = dvrk_kin::load("psm", None).unwrap();
    let text = export_urdf(&m).unwrap();
    let robot = urdf_rs::read_from_string(&text).unwrap();
    let moving: Vec<&urdf_rs::Joint> =
        robot.joints.iter().filter(|j| j.joint_type != urdf_rs::JointType::Fixed).collect();
    let mut mimic: Vec<&str> = moving.iter().filter(|j| j.mimic.is_some()).map(|j| j.name.as_str()).collect();
    mimic.sort();
    // Every moving frame but the first `1*q_k` one of each joint (the parallelograms, the
    // counterweight, the jaw blades).
    assert_eq!(
        mimic,
        ["counterweight", "jaw_1", "jaw_2", "pitch_back", "pitch_end", "pitch_front", "pitch_top", "pitch_top_pivot"]
    );
    let actuated: Vec<&str> = moving.iter().filter(|j| j.mimic.is_none()).map(|j| j.name.as_str()).collect();
    assert_eq!(
        actuated,
        ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw", "jaw"]
    );
    let find = |n: &str| robot.joints.iter().find(|j| j.name == n).unwrap();
    let cw = find("counterweight").mimic.clone().unwrap();
    assert_eq!((cw.joint.as_str(), cw.multiplier, cw.offset), ("outer_insertion", Some(0.6025), Some(0.0)));
    let jaw = find("jaw_1").mimic.clone().unwrap();
    assert_eq!((jaw.joint.as_str(), jaw.multiplier), ("jaw", Some(0.5)));
    // The mimic's limits are the actuated joint's mapped through c*q + b, in order.
    let back = find("pitch_back");
    let b = back.mimic.as_ref().unwrap().offset.unwrap();
    assert!((back.limit.lower - (-0.925025 + b)).abs() < 1e-15 && (back.limit.upper - (0.925025 + b)).abs() < 1e-15);
    // The jaw has no frame moving as 1*q7: a stand-in link carries its value.
    assert_eq!(find("jaw").child.link, "jaw__actuator");
    // The tree drops the loops, so the file says so.
    assert!(
        text.contains("closure c1: frame pitch_front point [0.15, 0, 0] == frame pitch_bottom point [0.096, 0, 0]"),
        "{text}"
    );
    assert!(text.contains("closure c2: frame pitch_top"));
}

#[test]
fn urdf_file_round_trip_through_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ecm.urdf");
    let m = dvrk_kin::load("ecm", None).unwrap();
    export_urdf_file(&m, &path).unwrap();
    // No temporary file is left beside it.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let imp = dvrk_kin::load(path.to_str().unwrap(), None).unwrap();
    assert_eq!(imp.origin.as_deref(), Some(path.as_path()));
    let q = m.home();
    let tip_name = &m.frames[m.tip].name;
    let tip = imp.frame_id(&dvrk_kin::FrameRef::Name(tip_name.clone())).unwrap();
    let (dp, dr) = pose_error(&m.fk(&q).unwrap()[m.tip], &imp.fk(&q).unwrap()[tip]);
    assert!(dp < 1e-12 && dr < 1e-12);
}

const TWO_LINKS: &str = r#"<?xml version="1.0"?>
<robot name="bad">
  <link name="base"/>
  <link name="a"/>
  <link name="b"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    MIMIC
  </joint>
</robot>
"#;

/// Import `text` from a file and return the error message.
fn import_error(text: &str) -> (String, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken_arm.urdf");
    std::fs::write(&path, text).unwrap();
    let e = import_urdf_file(&path).unwrap_err();
    (e.to_string(), path.display().to_string())
}

#[test]
fn urdf_errors_name_the_file_and_the_joint() {
    let (e, path) = import_error(&TWO_LINKS.replace("MIMIC", r#"<mimic joint="ghost" multiplier="2"/>"#));
    assert!(e.contains(&path) && e.contains("j2") && e.contains("ghost") && e.contains("j1"), "{e}");

    let (e, path) = import_error(&TWO_LINKS.replace("MIMIC", "").replace("</robot>", "<joint name=\"j3\""));
    assert!(e.contains(&path), "{e}");

    let (e, _) = import_error("this is not XML at all <<<");
    assert!(e.contains("broken_arm.urdf"), "{e}");

    // A mimic of a mimic.
    let text = TWO_LINKS.replace("MIMIC", r#"<mimic joint="j1"/>"#).replace(
        "</robot>",
        r#"<link name="c"/><joint name="j3" type="revolute"><parent link="b"/><child link="c"/>
           <limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j2"/></joint></robot>"#,
    );
    let (e, _) = import_error(&text);
    assert!(e.contains("j3") && e.contains("j2") && e.contains("mimic"), "{e}");

    // Two roots.
    let (e, _) = import_error(&TWO_LINKS.replace("MIMIC", "").replace("</robot>", "<link name=\"loose\"/></robot>"));
    assert!(e.contains("root") && e.contains("loose"), "{e}");

    // NaN in an origin.
    let (e, _) = import_error(
        &TWO_LINKS
            .replace("MIMIC", "")
            .replace("<parent link=\"a\"/>", "<origin xyz=\"0 NaN 0\" rpy=\"0 0 0\"/><parent link=\"a\"/>"),
    );
    assert!(e.contains("j2") && e.contains("NaN"), "{e}");

    // A missing file.
    let e = import_urdf_file(std::path::Path::new("/nonexistent/arm.urdf")).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/arm.urdf"), "{e}");
}

#[test]
fn urdf_import_turns_z_onto_the_joint_axis() {
    // Axes y, -z and a slanted one, with origins: FK must be origin * Rot(axis, q) per joint.
    let text = r#"<robot name="axes">
      <link name="base"/><link name="a"/><link name="b"/><link name="c"/>
      <joint name="ja" type="revolute"><origin xyz="0.1 0 0.2" rpy="0.3 0 0"/>
        <parent link="base"/><child link="a"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="jb" type="prismatic"><origin xyz="0 0.05 0" rpy="0 0 0.4"/>
        <parent link="a"/><child link="b"/><axis xyz="0 0 -1"/><limit lower="0" upper="0.2" effort="1" velocity="1"/></joint>
      <joint name="jc" type="continuous"><origin xyz="0 0 0.3"/>
        <parent link="b"/><child link="c"/><axis xyz="1 1 1"/><mimic joint="ja" multiplier="-2" offset="0.1"/></joint>
    </robot>"#;
    let m = import_urdf_str(text, "axes.urdf").unwrap();
    assert_eq!(m.joints.iter().map(|j| j.name.as_str()).collect::<Vec<_>>(), ["ja", "jb"]);
    let q = [0.7, 0.13];
    let fk = m.fk(&q).unwrap();
    let o = |x: f64, y: f64, z: f64, r: f64, p: f64, yaw: f64| {
        Pose::from_parts(Translation3::new(x, y, z), Rotation3::from_euler_angles(r, p, yaw))
    };
    let rot = |axis: Vector3<f64>, a: f64| {
        Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), a))
    };
    let a = o(0.1, 0.0, 0.2, 0.3, 0.0, 0.0) * rot(Vector3::y(), 0.7);
    let b = a
        * o(0.0, 0.05, 0.0, 0.0, 0.0, 0.4)
        * Pose::from_parts(Translation3::new(0.0, 0.0, -0.13), Rotation3::identity());
    let c = b * o(0.0, 0.0, 0.3, 0.0, 0.0, 0.0) * rot(Vector3::new(1.0, 1.0, 1.0), -2.0 * 0.7 + 0.1);
    for (i, want) in [a, b, c].iter().enumerate() {
        let (dp, dr) = pose_error(&fk[i], want);
        assert!(dp < 1e-14 && dr < 1e-14, "frame {}: {dp:e} {dr:e}", m.frames[i].name);
    }
}

#[test]
fn urdf_export_refuses_a_frame_moved_by_two_joints() {
    let text = r#"
name = "two"
[[joints]]
name = "j1"
type = "revolute"
lower = -1.0
upper = 1.0
[[joints]]
name = "j2"
type = "revolute"
lower = -1.0
upper = 1.0
[[frames]]
name = "f1"
parent = 0
joint = "revolute"
theta = "j1"
[[frames]]
name = "both"
parent = 1
joint = "revolute"
theta = "j1 + j2"
"#;
    let m = Model::compile(ModelSpec::from_toml(text, std::path::Path::new("two.toml")).unwrap()).unwrap();
    match export_urdf(&m) {
        Err(KinError::Export(e)) => assert!(e.contains("both") && e.contains("j1") && e.contains("j2"), "{e}"),
        other => panic!("expected an export error, got {other:?}"),
    }
}

/// `<pose>` text of an SDF element: x y z roll pitch yaw.
fn sdf_pose(node: roxmltree::Node) -> Pose {
    let text = node.children().find(|c| c.has_tag_name("pose")).and_then(|p| p.text()).unwrap_or("0 0 0 0 0 0");
    let v: Vec<f64> = text.split_whitespace().map(|x| x.parse().unwrap()).collect();
    assert_eq!(v.len(), 6, "{text}");
    Pose::from_parts(Translation3::new(v[0], v[1], v[2]), Rotation3::from_euler_angles(v[3], v[4], v[5]))
}

fn child_text<'a>(node: roxmltree::Node<'a, 'a>, tag: &str) -> &'a str {
    node.children().find(|c| c.has_tag_name(tag)).and_then(|c| c.text()).unwrap_or("")
}

/// Check the SDF of `name` at home: links = bodies, and each closure joint (child link pose *
/// joint pose) sits at the closure point of FK.
fn check_sdf(name: &str) -> (Model, String) {
    let m = dvrk_kin::load(name, None).unwrap();
    let q = m.home();
    let text = export_sdf(&m, &q).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let sdf = doc.root_element();
    assert_eq!(sdf.attribute("version"), Some("1.6"));
    let model = sdf.children().find(|c| c.has_tag_name("model")).unwrap();
    let links: Vec<_> = model.children().filter(|c| c.has_tag_name("link")).collect();
    assert_eq!(links.len(), m.bodies.len(), "{name}: one link per body");
    let fk = m.fk(&q).unwrap();
    let link_pose = |n: &str| {
        sdf_pose(*links.iter().find(|l| l.attribute("name") == Some(n)).unwrap_or_else(|| panic!("link {n}")))
    };
    for b in &m.bodies {
        let (dp, dr) = pose_error(&link_pose(&b.name), &fk[b.frames[0]]);
        assert!(dp < 1e-12 && dr < 1e-12, "{name}: link {}", b.name);
    }
    let joints: Vec<_> = model.children().filter(|c| c.has_tag_name("joint")).collect();
    for c in &m.closures {
        let j = joints
            .iter()
            .find(|j| j.attribute("name") == Some(c.name.as_str()))
            .unwrap_or_else(|| panic!("{name}: closure joint {}", c.name));
        assert_eq!(j.attribute("type"), Some("revolute"));
        let child = child_text(*j, "child");
        assert_eq!(child, m.bodies[m.frames[c.frame].body].name);
        assert_eq!(child_text(*j, "parent"), m.bodies[m.frames[c.partner].body].name);
        let world = link_pose(child) * sdf_pose(*j);
        let want = fk[c.frame] * Point3::from(c.point);
        let err = (world.translation.vector - want.coords).norm();
        assert!(err < 1e-9, "{name}: closure {} joint {err:e} m from the closure point", c.name);
        // The pivot axis is z of the closure's frame.
        let z = world.rotation.matrix().column(2).into_owned();
        assert!((z - fk[c.frame].rotation.matrix().column(2)).norm() < 1e-9);
    }
    (m, text)
}

#[test]
fn psm_sdf_has_bodies_tree_pivots_and_two_loop_joints() {
    let (m, text) = check_sdf("psm");
    let doc = roxmltree::Document::parse(&text).unwrap();
    let joints: Vec<_> = doc.descendants().filter(|c| c.has_tag_name("joint")).collect();
    assert!(
        joints.iter().any(|j| j.attribute("name") == Some("c1"))
            && joints.iter().any(|j| j.attribute("name") == Some("c2"))
    );
    // Frames 3 and 5 turn one body (the back link) about one axis: one joint, not two.
    let back: Vec<_> = joints
        .iter()
        .filter(|j| child_text(**j, "parent") == "yaw_link" && child_text(**j, "child") == "pitch_back_link")
        .collect();
    assert_eq!(back.len(), 1, "{text}");
    assert!(!joints.iter().any(|j| j.attribute("name") == Some("pitch_top_pivot")));
    // 14 moving frames, 3 and 5 merged: 13 tree joints, plus the 2 loop-closing joints.
    assert_eq!(joints.len(), 13 + 2);
    // Joint positions count from the exported configuration: insertion home is 0.12 m.
    let ins = joints.iter().find(|j| j.attribute("name") == Some("outer_insertion")).unwrap();
    let lower: f64 = ins.descendants().find(|c| c.has_tag_name("lower")).unwrap().text().unwrap().parse().unwrap();
    let upper: f64 = ins.descendants().find(|c| c.has_tag_name("upper")).unwrap().text().unwrap().parse().unwrap();
    assert!((lower + 0.12).abs() < 1e-15 && (upper - 0.12).abs() < 1e-15, "{lower} {upper}");
    // The yaw joint's frame is frame 1 itself (no post transform, base = identity).
    let yaw = joints.iter().find(|j| j.attribute("name") == Some("outer_yaw")).unwrap();
    assert_eq!(child_text(*yaw, "parent"), "world");
    let fk = m.fk(&m.home()).unwrap();
    let yaw_link =
        doc.descendants().find(|l| l.has_tag_name("link") && l.attribute("name") == Some("yaw_link")).unwrap();
    let (dp, dr) = pose_error(&(sdf_pose(yaw_link) * sdf_pose(*yaw)), &fk[0]);
    assert!(dp < 1e-12 && dr < 1e-12);
}

#[test]
fn ecm_and_cart_sdf_close_their_loops() {
    check_sdf("ecm");
    let (m, _) = check_sdf("cart");
    assert_eq!(m.closures.len(), 8, "three PSMs and the ECM, two loops each");
}
