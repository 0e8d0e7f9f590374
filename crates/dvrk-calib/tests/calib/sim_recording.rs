//! A run recorded by dvrk-sim (1 s of the psm scene at 100 Hz) read with dvrk-calib's reader: the
//! JointState positions and the PoseStamped tool tip equal the simulated ones.

use dvrk_calib::dvrk_kin::Pose;
use dvrk_calib::{read_recording, McapOptions};
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{RecordOptions, Recorder, Scene, Sim, SimOptions};

#[test]
fn sim_recording_reads_back_with_the_simulated_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let mut sim = Sim::new(&Scene::load("psm").unwrap(), &SimOptions::default()).unwrap();
    let mut rec = Recorder::create(&sim, &RecordOptions { path: path.clone(), rate: 100.0 }).unwrap();
    let (traj, _) = Trajectory::tracking_test(&sim.arms[0].model);
    let n = sim.nq();
    let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
    let (mut times, mut qs, mut tips): (Vec<f64>, Vec<Vec<f64>>, Vec<Pose>) = (vec![], vec![], vec![]);
    for step in 1..=1000u64 {
        traj.sample(sim.time + sim.dt, &mut q, &mut qd);
        for i in 0..n {
            sim.set_target(i, q[i], qd[i]).unwrap();
        }
        sim.step();
        if step % 10 == 0 {
            times.push(sim.time);
            qs.push(sim.q().to_vec());
            tips.push(rec.tip_in_base(&sim, 0));
        }
        rec.after_step(&sim, step).unwrap();
    }
    rec.finish().unwrap();
    let options = McapOptions { topics: vec!["/PSM1/measured_cp".into()], joint_topic: Some("/PSM1/measured_js".into()) };
    let r = read_recording(&path, &options).unwrap();
    let j = r.joints.as_ref().unwrap();
    // The dVRK layout: the jaw from its own topic, merged by time.
    assert_eq!(j.source, "/PSM1/measured_js + /PSM1/jaw/measured_js");
    assert_eq!(j.names.len(), 7);
    assert_eq!(j.names[0], "outer_yaw");
    assert_eq!(j.t.len(), 100);
    for k in 0..100 {
        assert!((j.t[k] - times[k]).abs() < 1e-9, "{} vs {}", j.t[k], times[k]);
        assert_eq!(j.q[k], qs[k], "sample {k}");
    }
    let cp = r.body("/PSM1/measured_cp").unwrap();
    assert_eq!(cp.frame_id, "PSM1_base");
    assert_eq!(cp.poses.len(), 100);
    for k in 0..100 {
        let d = tips[k].inverse() * cp.poses[k];
        // Through a unit quaternion and back: equal to rounding (1e-12 m, 1e-12 rad).
        assert!(d.translation.vector.norm() < 1e-12, "sample {k}: {:?}", d.translation);
        assert!((d.rotation.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-12, "sample {k}");
    }
    // The whole arm's bodies are there too, as Foxglove transforms in `world`.
    let all = read_recording(&path, &McapOptions::default()).unwrap();
    assert!(all.bodies.iter().any(|b| b.name == "PSM1/yaw_link" && b.frame_id == "world" && b.t.len() == 100));
}
