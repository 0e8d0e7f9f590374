//! MTM -> PSM follow mode (dvrk_sim::teleop) on the two arms' own kinematics: a synthetic MTM
//! motion from the MTM model's FK (a 5 cm square, a clutch in the middle, a 30 deg wrist turn,
//! a gripper closing) taken through the PSM's IK, with the camera posed away from the PSM's base.

use dvrk_kin::{inverse_kinematics, IkOptions, Pose};
use dvrk_sim::teleop::{angle_between, MtmSample, Teleop, TeleopConfig};
use nalgebra::{Rotation3, Translation3, Vector3};

#[test]
fn a_synthetic_mtm_motion_drives_the_psm_scaled_in_the_camera_frame() {
    let psm = dvrk_kin::load("psm", None).unwrap();
    let mtm = dvrk_kin::load("mtmr", None).unwrap();
    // The camera in the PSM's base frame: turned and shifted, as an ECM away from home sees it.
    let camera = Pose::from_parts(Translation3::new(0.05, -0.02, 0.03), Rotation3::from_euler_angles(0.4, -0.3, 0.9));
    let tip = |q: &[f64]| psm.fk(q).unwrap()[psm.tip];
    let mut q = psm.home().to_vec();
    let in_camera = |q: &[f64]| camera.inverse() * tip(q);
    // The MTM's start from its own FK; the console's display rotation makes it aligned.
    let mtm_start = mtm.fk(&[0.0, 0.2, 0.1, 0.5, 0.3, 0.1, 0.0]).unwrap()[mtm.tip];
    let display_from_mtm = in_camera(&q).rotation * mtm_start.rotation.inverse();
    let mut teleop = Teleop::new(TeleopConfig { display_from_mtm, ..TeleopConfig::default() });
    let to_mtm = |d: Vector3<f64>| display_from_mtm.inverse() * d; // a display displacement in MTM base axes
    // The script: (display displacement of the hand from its start, wrist turn about the display's
    // z, gripper, clutch), sampled every millimetre.
    let mut script: Vec<(Vector3<f64>, f64, f64, bool)> = Vec::new();
    let corners = [Vector3::zeros(), Vector3::new(0.05, 0.0, 0.0), Vector3::new(0.05, 0.05, 0.0), Vector3::new(0.0, 0.05, 0.0), Vector3::zeros()];
    let mut hand_offset = Vector3::zeros(); // the hand's motion while clutched, not followed
    for (leg, w) in corners.windows(2).enumerate() {
        if leg == 2 {
            // Clutch in the middle: the hand moves 3 cm along z, the PSM must not.
            for k in 0..=30 {
                script.push((w[0] + Vector3::new(0.0, 0.0, 0.001 * k as f64), 0.0, 0.8, true));
            }
            hand_offset = Vector3::new(0.0, 0.0, 0.03);
        }
        for k in 0..=50 {
            script.push((w[0] + (w[1] - w[0]) * (k as f64 / 50.0) + hand_offset, 0.0, 0.8, false));
        }
    }
    let last = script.last().unwrap().0;
    for k in 0..=30 {
        // The wrist turns 30 deg, then the gripper closes.
        script.push((last, (k as f64).to_radians(), 0.8, false));
    }
    for k in 0..=20 {
        script.push((last, 30f64.to_radians(), 0.8 * (1.0 - k as f64 / 20.0), false));
    }
    let ik = IkOptions { position_tolerance: 1e-9, orientation_tolerance: 1e-9, max_iterations: 100, restarts: 0, frame: None };
    let start = in_camera(&q);
    let (mut worst_position, mut worst_angle, mut jaw) = (0.0f64, 0.0f64, f64::NAN);
    for (d, turn, gripper, clutch) in &script {
        let rotation = display_from_mtm.inverse() * Rotation3::from_axis_angle(&Vector3::z_axis(), *turn) * display_from_mtm * mtm_start.rotation;
        let sample = MtmSample { pose: Pose::from_parts(Translation3::from(mtm_start.translation.vector + to_mtm(*d)), rotation), gripper: *gripper, clutch: *clutch };
        let before = q.clone();
        match teleop.step(&sample, &in_camera(&q)) {
            Some(c) => {
                q = inverse_kinematics(&psm, &(camera * c.tip_in_camera), &q, &ik).unwrap().q;
                jaw = c.jaw;
            }
            None => assert!(*clutch, "not following outside the clutch: {:?}", teleop.state),
        }
        if *clutch {
            assert_eq!(q, before, "the PSM moved while clutched");
            continue;
        }
        // The PSM tip's displacement in the camera frame is 0.2 times the hand's in the display
        // frame (the clutched motion excluded); its orientation is the hand's.
        let moved = in_camera(&q).translation.vector - start.translation.vector;
        // After the clutch the hand is 3 cm higher than the PSM follows.
        let hand_followed = d - if d.z > 0.0 { Vector3::new(0.0, 0.0, 0.03) } else { Vector3::zeros() };
        worst_position = worst_position.max((moved - 0.2 * hand_followed).norm());
        let want = Rotation3::from_axis_angle(&Vector3::z_axis(), *turn) * start.rotation;
        worst_angle = worst_angle.max(angle_between(&in_camera(&q).rotation, &want));
    }
    eprintln!("worst tip position error {:.3e} m, orientation {:.3e} deg over {} samples", worst_position, worst_angle.to_degrees(), script.len());
    assert!(worst_position < 0.5e-3 && worst_angle < 1f64.to_radians(), "{worst_position} m, {worst_angle} rad");
    assert!(jaw.abs() < 1e-12, "the jaw closes with the gripper: {jaw}");
}

/// The replay ([`dvrk_sim::teleop_replay`]) in a scene with an ECM follows in the ECM's camera
/// frame: a hand motion along the display's x moves PSM1's commanded tip 0.2 times as far along
/// the camera's x in the world, whatever the PSM's own base; the clutch holds it; an MTM that
/// starts misaligned waits.
#[test]
fn a_replay_in_a_scene_with_an_ecm_moves_the_tip_along_the_cameras_axes() {
    use dvrk_sim::teleop_replay::{camera_frame, plan, MtmMotion};
    let scene = dvrk_sim::Scene::load("2psm-ecm").unwrap();
    let (psm, ecm) = (scene.arm_index("PSM1").unwrap(), scene.arm_index("ECM").unwrap());
    let (camera, name) = camera_frame(&scene, psm, Some(ecm)).unwrap();
    assert!(name.starts_with("ECM's camera"), "{name}");
    // Independently: the ECM model placed by the scene's mount, at home.
    let ecm_model = &scene.arms[ecm].model;
    let cam = ecm_model.fk(&ecm_model.home()).unwrap()[ecm_model.tip];
    assert!((cam.translation.vector - camera.translation.vector).norm() < 1e-12);
    let psm_model = &scene.arms[psm].model;
    let tip = |q: &[f64]| psm_model.fk(q).unwrap()[psm_model.tip];
    let start = tip(&scene.arms[psm].start);
    // The MTM aligned with the PSM in the camera frame (display = MTM base).
    let r = camera.rotation.inverse() * start.rotation;
    let n = 201;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.005).collect();
    let poses: Vec<Pose> = (0..n).map(|k| Pose::from_parts(Translation3::new(0.05 * (k.min(100) as f64 / 100.0), 0.0, 0.0), r)).collect();
    // The clutch over the last 100 samples, while the hand goes on along y.
    let poses: Vec<Pose> = poses.iter().enumerate().map(|(k, p)| if k > 100 { Pose::from_parts(Translation3::new(0.05, 0.001 * (k - 100) as f64, 0.0), r) } else { *p }).collect();
    let clutch: Vec<bool> = (0..n).map(|k| k > 100).collect();
    let motion = MtmMotion { t: &t, poses: &poses, gripper: None, clutch: &clutch };
    let out = plan(&scene, psm, &camera, &name, &motion, &TeleopConfig::default()).unwrap();
    let dvrk_sim::trajectory::Trajectory::Samples { q, .. } = &out.trajectory else { panic!() };
    let moved = tip(&q[100]).translation.vector - start.translation.vector;
    let want = camera.rotation * Vector3::new(0.01, 0.0, 0.0);
    assert!((moved - want).norm() < 1e-6, "moved {moved:?} m in the world, want {want:?}");
    assert_eq!(q[200], q[100], "the clutch holds the PSM");
    assert_eq!((out.report.following_from, out.report.clutch_presses, out.report.ik_misses), (Some(0.0), 1, 0));
    // 20 deg off: the console waits, and says how far off.
    let turned: Vec<Pose> = poses.iter().map(|p| Pose::from_parts(p.translation, p.rotation * Rotation3::from_axis_angle(&Vector3::y_axis(), 20f64.to_radians()))).collect();
    let out = plan(&scene, psm, &camera, &name, &MtmMotion { poses: &turned, ..motion }, &TeleopConfig::default()).unwrap();
    assert_eq!(out.report.following_from, None);
    assert!((out.report.misalignment_at_start_deg - 20.0).abs() < 1e-9);
}
