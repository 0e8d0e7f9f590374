//! Writers and readers agree: the three MCAP layouts and the plain CSV carry the synthetic
//! tracker's poses and joint states unchanged, and raw markers give back the tracker's poses.

use crate::util::{psm, scenario};
use dvrk_sim::recording::{McapLayout, McapOptions};
use dvrk_calib::mocap::synth::SynthMotion;
use std::path::Path;

fn max_pose_difference(a: &[dvrk_kin::Pose], b: &[dvrk_kin::Pose]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x.to_homogeneous() - y.to_homogeneous()).abs().max()).fold(0.0, f64::max)
}

#[test]
fn every_mcap_layout_round_trips() {
    let s = scenario(&psm(), SynthMotion::Q1Q2Sweep, 1e-4, 2.0, 0.05);
    let rec = s.record(9);
    for layout in [McapLayout::PoseStamped, McapLayout::Tf, McapLayout::FoxgloveJson, McapLayout::Foxglove] {
        let bytes = dvrk_sim::recording::write_mcap_poses(&rec, layout, "/PSM1/measured_js").unwrap();
        let back = dvrk_sim::recording::parse_mcap_poses(&bytes, Path::new("r.mcap"), &McapOptions::default()).unwrap();
        assert!(back.warnings.is_empty(), "{layout:?}: {:?}", back.warnings);
        for b in &rec.bodies {
            let got = back.body(&b.name).unwrap();
            // Times pass through sec + nanosec: 1 ns.
            assert!(got.t.iter().zip(&b.t).all(|(x, y)| (x - y).abs() < 1e-9), "{layout:?}");
            let d = max_pose_difference(&got.poses, &b.poses);
            assert!(d < 1e-14, "{layout:?} {}: {d:e}", b.name);
        }
        let j = back.joints.as_ref().unwrap();
        assert_eq!(j.source, "/PSM1/measured_js");
        assert_eq!(j.names[..2], ["outer_yaw".to_string(), "outer_pitch".to_string()]);
        assert_eq!(j.q, rec.joints.as_ref().unwrap().q);
    }
    // A topic filter keeps the named body only.
    let bytes = dvrk_sim::recording::write_mcap_poses(&rec, McapLayout::PoseStamped, "/js").unwrap();
    let one = dvrk_sim::recording::parse_mcap_poses(&bytes, Path::new("r.mcap"), &McapOptions { topics: vec!["/mocap/end/pose".into()], joint_topic: None }).unwrap();
    assert_eq!(one.body_names(), vec!["/mocap/end/pose".to_string()]);
}

#[test]
fn raw_markers_give_the_trackers_poses_and_drop_ghost_frames() {
    let model = psm();
    let s = dvrk_calib::mocap::synth::Scenario::new(
        &model,
        &dvrk_calib::mocap::synth::SynthOptions { noise: 1e-4, duration: 10.0, occlusion: 0.01, outliers: 0.01, ..Default::default() },
    )
    .unwrap();
    let rec = s.record(21);
    let csv = dvrk_sim::recording::write_plain_csv(&rec);
    let back = dvrk_sim::recording::parse_plain_csv(&csv, Path::new("m.csv")).unwrap();
    // The layout estimated from the markers (first complete frame, refined) is the cluster's up
    // to a rotation: the pose track it gives moves exactly as the tracker's.
    let fitted = back.poses("end", None, true).unwrap();
    let tracker = rec.body("end").unwrap();
    // About 1200 * 3 * 1% occluded frames and 1200 * 1% ghost frames, all counted.
    eprintln!("end: {} fitted, {} occluded, {} outliers; tracker {} poses", fitted.len(), fitted.occluded, fitted.outliers, tracker.len());
    assert_eq!(fitted.len() + fitted.occluded + fitted.outliers, 1200);
    assert!(fitted.occluded > 15 && fitted.occluded < 60, "{}", fitted.occluded);
    assert!(fitted.outliers > 4 && fitted.outliers < 25, "{}", fitted.outliers);
    let p_fit = dvrk_calib::pivot_calibration(&fitted.poses, &Default::default()).unwrap();
    let p_trk = dvrk_calib::pivot_calibration(&tracker.poses, &Default::default()).unwrap();
    eprintln!("pivot from raw markers vs tracker poses: {:.4} mm apart", (p_fit.pivot - p_trk.pivot).norm() * 1e3);
    assert!((p_fit.pivot - s.rcm.unwrap()).norm() < 5e-5);
}
