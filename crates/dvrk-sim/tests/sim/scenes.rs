//! The multi-arm scenes of Table 9 (2psm-ecm, 3psm, full): they build, run 1 s of the tracking
//! test with finite state and closed loops, and stand where the cart (dvrk-kin's `cart` system)
//! puts the arms.

use dvrk_sim::run::{run, RunOptions, TrajectoryKind};
use dvrk_sim::{Mode, Scene, SimOptions};

fn one_second(name: &str) -> dvrk_sim::Summary {
    let scene = Scene::load(name).unwrap();
    run(&scene, &RunOptions { duration: 1.0, trajectory: TrajectoryKind::Sine, sim: SimOptions::default() }, |_| {}).unwrap()
}

/// 1 s of the tracking test: finite, every loop closed to 1e-5 m, the PSMs following their sines.
#[test]
fn cart_scenes_step_one_second_with_closed_loops() {
    for name in ["2psm-ecm", "3psm", "full"] {
        let s = one_second(name);
        println!("{name}: max gap {:.3e} m at {:.3} s, RCM {:.3e} m", s.max_closure_error, s.max_closure_time, s.max_rcm_error);
        assert!(s.finite, "{name}");
        assert!(s.max_closure_error < 1e-5, "{name}: gap {} m", s.max_closure_error);
        assert!(s.max_rcm_error < 1e-4, "{name}: RCM {} m", s.max_rcm_error);
        for j in s.joints.iter().filter(|j| j.arm.starts_with("PSM") && j.joint == "outer_yaw") {
            // The yaw's 1 rad, 0.1 Hz sine (0.63 rad/s peak): tracked within 0.05 rad.
            assert!(j.max_error < 0.05, "{name}: {j:?}");
        }
    }
}

/// The setup joints are held in position mode at home while the PSMs move: each SUJ joint within
/// 1e-4 rad (m) of home after 1 s.
#[test]
fn full_scene_holds_the_setup_joints() {
    let scene = Scene::load("full").unwrap();
    let s = one_second("full");
    let mut suj = 0;
    for (arm, j) in scene.arms.iter().flat_map(|a| a.model.joints.iter().map(move |j| (a, j))) {
        if arm.name.starts_with("SUJ") {
            assert_eq!(arm.mode, Mode::Position);
            let js = s.joints.iter().find(|x| x.arm == arm.name && x.joint == j.name).unwrap();
            println!("{} {}: max {:.3e} {}", arm.name, j.name, js.max_error, js.unit);
            assert!(js.max_error < 1e-4, "{} {}: {js:?}", arm.name, j.name);
            suj += 1;
        }
    }
    assert_eq!(suj, 4 + 3 * 6);
    assert_eq!(scene.arms.len(), 8);
}

/// Every PSM and the ECM stand where dvrk-kin's cart puts their frame 0 at the SUJ home: in the
/// full scene (SUJ bodies) and in the fixed-base scenes (mounts copied from it), to 1e-9 m / rad.
#[test]
fn arms_stand_where_the_cart_puts_them() {
    let cart = dvrk_kin::load("cart", None).unwrap();
    let fk = cart.fk(&cart.home()).unwrap();
    for name in ["2psm-ecm", "3psm", "full"] {
        let scene = Scene::load(name).unwrap();
        for arm in scene.arms.iter().filter(|a| !a.name.starts_with("SUJ")) {
            let f = cart.frames.iter().position(|f| f.name == format!("{}/mount", arm.name)).unwrap();
            let d = fk[f].inverse() * arm.model.base;
            assert!(d.translation.vector.norm() < 1e-9, "{name} {}: {:?}", arm.name, d.translation);
            let r = (d.rotation.matrix() - nalgebra::Matrix3::identity()).norm();
            assert!(r < 1e-9, "{name} {}: rotation off by {r}", arm.name);
        }
    }
}

/// A carried arm must name an arm listed before it; the error names the field and the value.
#[test]
fn unknown_parent_arm_is_rejected() {
    let text = include_str!("../../../../models/scenes/full.toml").replace("parent = \"SUJ-PSM3\"", "parent = \"SUJ-PSM9\"");
    let e = Scene::parse(&text, "full.toml", None).unwrap_err().to_string();
    assert!(e.contains("parent") && e.contains("SUJ-PSM9"), "{e}");
}

/// Stepping the independent arm groups on separate threads gives the same state, bit for bit.
#[test]
fn parallel_step_matches_sequential() {
    use dvrk_sim::Sim;
    for name in ["3psm", "full"] {
        let scene = Scene::load(name).unwrap();
        let mut seq = Sim::new(&scene, &SimOptions::default()).unwrap();
        let mut par = Sim::new(&scene, &SimOptions { parallel: true, ..SimOptions::default() }).unwrap();
        for s in 0..200 {
            for i in 0..seq.nq() {
                let target = seq.actuator(i).unwrap().target + 1e-3 * ((s + i) as f64 * 0.05).sin();
                seq.set_target(i, target, 0.0).unwrap();
                par.set_target(i, target, 0.0).unwrap();
            }
            seq.step();
            par.step();
        }
        assert_eq!(seq.q(), par.q(), "{name}");
        assert_eq!(seq.closure_error(), par.closure_error(), "{name}");
    }
}

/// An inertials file labelled for another model whose bodies all match is loaded with a note
/// (#45: `model = "ecm"` in a PSM inertials file was accepted without a word); the arm's own
/// label gives none.
#[test]
fn an_inertials_file_labelled_for_another_model_is_noted() {
    let dir = std::env::temp_dir().join(format!("dvrk-scene-label-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let psm = include_str!("../../../../models/inertials/psm.toml");
    let scene = include_str!("../../../../models/scenes/psm.toml").replace("inertials = \"psm\"", "inertials = \"labelled.toml\"");
    for (label, noted) in [("ecm", true), ("psm", false)] {
        std::fs::write(dir.join("labelled.toml"), psm.replace("model = \"psm\"", &format!("model = \"{label}\""))).unwrap();
        let s = Scene::parse(&scene, "psm.toml", Some(&dir)).unwrap();
        assert_eq!(s.notes.len(), usize::from(noted), "{label}: {:?}", s.notes);
        if noted {
            assert!(s.notes[0].contains("labelled.toml") && s.notes[0].contains("model = \"ecm\"") && s.notes[0].contains("PSM1"), "{}", s.notes[0]);
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Braked setup joints (`Scene::brake_setup_joints`, `dvrk sim --brake-suj`): on the reduced
/// engine every setup joint stays exactly where it starts, each arm stands where its setup joints
/// put it (its tip's pose at the start equal to the carried scene's to 1e-12 m), and the PSMs
/// track their sines as when carried (per-joint RMS within 1% of it: the held setup joints
/// moved by at most 1e-4 rad or m there).
#[test]
fn braked_setup_joints_hold_each_arm_where_they_put_it() {
    let reduced = SimOptions { engine: Some(dvrk_sim::Engine::Reduced), ..Default::default() };
    let carried = Scene::load("full").unwrap();
    let mut braked = carried.clone();
    assert_eq!(braked.brake_setup_joints(), 4);
    assert_eq!(braked.clone().brake_setup_joints(), 0, "nothing carried any more");
    assert!(braked.arms.iter().all(|a| a.parent.is_none()));
    // The scene file's flag does the same.
    let text = include_str!("../../../../models/scenes/full.toml").replace("gravity = [0.0, 0.0, -9.81]", "gravity = [0.0, 0.0, -9.81]\nbrake_setup_joints = true");
    let from_file = Scene::parse(&text, "full.toml", None).unwrap();
    assert_eq!(from_file.arms.iter().map(|a| (a.parent, a.braked)).collect::<Vec<_>>(), braked.arms.iter().map(|a| (a.parent, a.braked)).collect::<Vec<_>>());
    assert_eq!(from_file.arms.iter().filter(|a| a.braked).count(), 4);
    let (a, b) = (dvrk_sim::Sim::new(&carried, &reduced).unwrap(), dvrk_sim::Sim::new(&braked, &reduced).unwrap());
    for (k, arm) in carried.arms.iter().enumerate().filter(|(_, a)| !a.name.starts_with("SUJ")) {
        let tip = arm.model.frames.len() - 1;
        let rel = dvrk_kin::Pose::identity();
        let d = a.frame_pose(k, tip, &rel).inverse() * b.frame_pose(k, tip, &rel);
        assert!(d.translation.vector.norm() < 1e-12, "{}: {:?}", arm.name, d.translation);
    }
    let opts = RunOptions { duration: 2.0, trajectory: TrajectoryKind::Sine, sim: reduced };
    let (sa, sb) = (run(&carried, &opts, |_| {}).unwrap(), run(&braked, &opts, |_| {}).unwrap());
    assert!(sb.finite && sb.max_closure_error < 1e-9 && sb.max_rcm_error < 1e-9, "{} {}", sb.max_closure_error, sb.max_rcm_error);
    for (x, y) in sa.joints.iter().zip(&sb.joints) {
        assert_eq!((&x.arm, &x.joint), (&y.arm, &y.joint));
        if x.arm.starts_with("SUJ") {
            assert_eq!(y.max_error, 0.0, "{} {} braked moved", y.arm, y.joint);
            assert!(x.max_error < 1e-4, "{} {} carried: {}", x.arm, x.joint, x.max_error);
        } else if x.rms_error > 1e-4 {
            assert!((y.rms_error / x.rms_error - 1.0).abs() < 0.01, "{} {}: {} carried, {} braked", x.arm, x.joint, x.rms_error, y.rms_error);
        }
    }
}
