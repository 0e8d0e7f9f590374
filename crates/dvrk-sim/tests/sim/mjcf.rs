//! The MJCF export (`dvrk export mjcf`): the XML parses and holds the scene's bodies, joints,
//! loop closures, cables, holds and motors, with the inertials' masses; and the cable fix it
//! uncovered. MuJoCo itself runs the file in `tests/python/test_mujoco.py`.

use dvrk_sim::mjcf::{export_mjcf, resolve, DRIVE_FIELDS};
use dvrk_sim::run::TrajectoryKind;
use dvrk_sim::{run, Mode, RunOptions, Scene};

/// Elements of the parsed document by tag name.
fn count(doc: &roxmltree::Document, tag: &str) -> usize {
    doc.descendants().filter(|n| n.has_tag_name(tag)).count()
}

fn num(n: roxmltree::Node, attr: &str) -> f64 {
    n.attribute(attr).unwrap_or_else(|| panic!("{attr} missing on {n:?}")).parse().unwrap()
}

fn nums(n: roxmltree::Node, attr: &str) -> Vec<f64> {
    n.attribute(attr).unwrap_or_else(|| panic!("{attr} missing on {n:?}")).split_whitespace().map(|x| x.parse().unwrap()).collect()
}

#[test]
fn every_scene_exports_its_bodies_joints_closures_cables_and_motors() {
    // Expected per scene (bodies = joints, closures, cables, held joints, actuated joints),
    // counted from the model files: PSM 13 bodies, 2 loops, 2 cables (counterweight, second
    // jaw blade), 7 joints; ECM 8 bodies, 2 loops, 4 joints; SUJ-PSM 6 bodies, SUJ-ECM 4.
    let expect = [("psm", 13, 2, 2, 0, 7), ("ecm", 8, 2, 0, 0, 4), ("2psm-ecm", 34, 6, 4, 0, 18), ("3psm", 39, 6, 6, 0, 21), ("full", 69, 8, 6, 22, 47)];
    for (name, bodies, closures, cables, held, nq) in expect {
        let scene = Scene::load(name).unwrap();
        let xml = export_mjcf(&scene).unwrap();
        let doc = roxmltree::Document::parse(&xml).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(count(&doc, "body"), bodies, "{name} bodies");
        assert_eq!(count(&doc, "joint") - count(&doc, "fixed") * 2 - held, bodies, "{name} tree joints");
        assert_eq!(count(&doc, "connect"), closures, "{name} loop closures");
        assert_eq!(count(&doc, "fixed"), cables, "{name} cables");
        let holds = doc.descendants().filter(|n| n.has_tag_name("joint") && n.attribute("joint1").is_some()).count();
        assert_eq!(holds, held, "{name} position-mode holds");
        assert_eq!(count(&doc, "motor"), nq, "{name} motors");
        assert_eq!(count(&doc, "numeric"), nq, "{name} drive data");
        let nq_scene: usize = scene.arms.iter().map(|a| a.model.nq()).sum();
        assert_eq!(nq, nq_scene);
        let bodies_scene: usize = scene.arms.iter().map(|a| a.model.bodies.len()).sum();
        assert_eq!(bodies, bodies_scene);
        // Masses: the inertials' total (kg).
        let total: f64 = doc.descendants().filter(|n| n.has_tag_name("inertial")).map(|n| num(n, "mass")).sum();
        let want: f64 = scene.arms.iter().flat_map(|a| a.inertials.bodies.iter().map(|b| b.mass)).sum();
        assert!((total - want).abs() < 1e-9 * want, "{name}: {total} kg vs {want} kg");
        // Every name is unique (MuJoCo refuses duplicates within a kind).
        let mut names: Vec<(String, &str)> = doc.descendants().filter_map(|n| n.attribute("name").map(|a| (n.tag_name().name().to_string(), a))).collect();
        let n = names.len();
        names.sort();
        names.dedup();
        assert_eq!(names.len(), n, "{name}: duplicate names");
        let opt = doc.descendants().find(|n| n.has_tag_name("option")).unwrap();
        assert_eq!(num(opt, "timestep"), scene.dt);
        assert_eq!(nums(opt, "gravity"), scene.gravity.to_vec());
    }
}

#[test]
fn drive_data_maps_each_motor_joint_back_to_q() {
    let scene = Scene::load("psm").unwrap();
    let xml = export_mjcf(&scene).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    let model = &scene.arms[0].model;
    let home = model.home();
    for (k, j) in model.joints.iter().enumerate() {
        let name = format!("PSM1/{}", j.name);
        let motor = doc.descendants().find(|n| n.has_tag_name("motor") && n.attribute("name") == Some(&name)).unwrap();
        let joint_name = motor.attribute("joint").unwrap();
        let joint = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(joint_name)).unwrap();
        let data = nums(doc.descendants().find(|n| n.has_tag_name("numeric") && n.attribute("name") == Some(&format!("dvrk:{name}"))).unwrap(), "data");
        assert_eq!(data.len(), DRIVE_FIELDS.len());
        let (c, b) = (data[0], data[1]);
        // qpos = ref at home, and q = (qpos - b) / c is the joint's home.
        assert!(((num(joint, "ref") - b) / c - home[k]).abs() < 1e-12, "{name}");
        // The motor's effort is per unit of q: gear 1/c; ctrlrange the effort limit.
        assert!((num(motor, "gear") * c - 1.0).abs() < 1e-12, "{name}");
        assert_eq!(nums(motor, "ctrlrange"), vec![-j.effort_limit, j.effort_limit], "{name}");
        // The range is the joint limits in coordinate units; armature reflected by 1/c^2.
        let mut lim = [c * j.lower + b, c * j.upper + b];
        lim.sort_by(f64::total_cmp);
        let range = nums(joint, "range");
        assert!((range[0] - lim[0]).abs() < 1e-12 && (range[1] - lim[1]).abs() < 1e-12, "{name}: {range:?} vs {lim:?}");
        assert!((num(joint, "armature") - scene.arms[0].armature[k] / (c * c)).abs() < 1e-12, "{name}");
        assert_eq!(&data[2..5], &[scene.arms[0].gains[k].kp, scene.arms[0].gains[k].ki, scene.arms[0].gains[k].kd]);
    }
    // The jaw drives one blade (half the jaw angle): gear 2 on it, the other blade on a cable.
    let jaw = doc.descendants().find(|n| n.has_tag_name("motor") && n.attribute("name") == Some("PSM1/jaw")).unwrap();
    assert_eq!(num(jaw, "gear"), 2.0);
    // The counterweight cable: follower - mu * insertion, mu = 0.6025 (Table 4).
    let cw = doc.descendants().find(|n| n.has_tag_name("fixed") && n.attribute("name") == Some("PSM1/cable:counterweight_link")).unwrap();
    let coefs: Vec<f64> = cw.children().filter(|n| n.has_tag_name("joint")).map(|n| num(n, "coef")).collect();
    assert_eq!(coefs, vec![1.0, -0.6025]);
}

#[test]
fn a_model_exports_with_the_inertials_and_mode_of_its_scene_arm() {
    let s = resolve("suj-psm1").unwrap();
    assert_eq!(s.arms.len(), 1);
    assert_eq!(s.arms[0].mode, Mode::Position);
    let xml = export_mjcf(&s).unwrap();
    let doc = roxmltree::Document::parse(&xml).unwrap();
    // Every setup joint held by an equality, at its home: MuJoCo counts a joint equality from
    // the joint's `ref`, so the polynomial is 0 (the absolute home coordinate flung the SUJ away).
    let holds: Vec<_> = doc.descendants().filter(|n| n.has_tag_name("joint") && n.attribute("joint1").is_some()).collect();
    assert_eq!(holds.len(), 6);
    assert!(holds.iter().all(|h| nums(*h, "polycoef") == vec![0.0; 5]));
    // A built-in scene name wins over the model of the same name.
    assert_eq!(resolve("psm").unwrap().arms[0].name, "PSM1");
    let e = resolve("mtml").unwrap_err().to_string();
    assert!(e.contains("mtml") && e.contains("no built-in inertials") && e.contains("suj-psm1"), "{e}");
    let e = resolve("no-such-scene").unwrap_err().to_string();
    assert!(e.contains("no-such-scene") && e.contains("2psm-ecm") && e.contains("psm-serial"), "{e}");
}

/// Regression: rapier's implicit joint spring is backward Euler about a fixed rest, so a cable
/// whose rest moves with its leader dragged the follower by k dt times its velocity. The PSM
/// counterweight lagged and held the insertion ~1 mm behind its target (0.73 mm RMS), which
/// MuJoCo on the exported model did not reproduce (0.10 mm). With the feed-forward: 0.083 mm.
#[test]
fn the_counterweight_cable_does_not_drag_the_insertion() {
    let scene = Scene::load("psm").unwrap();
    let opts = RunOptions { duration: 10.0, trajectory: TrajectoryKind::Sine, sim: Default::default() };
    let s = run(&scene, &opts, |_| {}).unwrap();
    let ins = s.joints.iter().find(|j| j.joint == "outer_insertion").unwrap();
    assert!(ins.rms_error < 1.5e-4, "insertion RMS {} m", ins.rms_error);
}

/// A model file with its own `[[inertials]]` and `[drive]` (what `dvrk identify -o` writes)
/// exports with them, as `dvrk sim --model ARM=FILE` (`Scene::set_model`) runs it: the body's
/// mass, the drive's damping (replacing the scene's 0.1), and the armature raised to the
/// drive's where it is larger (insertion) but kept as the PID's floor where it is smaller (yaw).
#[test]
fn a_model_file_exports_with_its_own_inertials_and_drive() {
    let own = "\n[drive]\ndamping = 0.0\narmature = [1e-6, 0.0, 0.128, 0.0, 3e-4, 1e-4, 2.5e-5]\n\n[[inertials]]\nbody = \"yaw_link\"\nmass = 1.5\ncom = [0.01, 0.0, -0.04]\ninertia = [[0.018, 0.0, 0.0], [0.0, 0.016, 0.0], [0.0, 0.0, 0.008]]\n";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("psm-own.toml");
    std::fs::write(&path, format!("{}{own}", dvrk_kin::load::builtin_text("psm").unwrap())).unwrap();
    let s = resolve(path.to_str().unwrap()).unwrap();
    let template = &Scene::load("psm").unwrap().arms[0];
    let a = &s.arms[0];
    assert_eq!(a.inertials.bodies.iter().find(|b| b.name == "yaw_link").unwrap().mass, 1.5);
    assert_eq!((a.damping, template.damping), (0.0, 0.1));
    assert_eq!((a.armature[0], a.armature[2]), (template.armature[0], 0.128));
    let mut set = Scene::load("psm").unwrap();
    set.set_model(0, a.model.clone()).unwrap();
    assert_eq!((set.arms[0].damping, &set.arms[0].armature), (a.damping, &a.armature));
}
