//! Must-show 4: bad recordings (no motion, 2 degrees of motion, a single frame, NaN rows, a
//! missing topic, a wrong marker count, a truncated MCAP) give a clear error or a warning with
//! numbers: never a panic, never a silent result.

use crate::util::{config, psm, scenario};
use dvrk_sim::recording::{McapLayout, McapOptions};
use dvrk_calib::mocap::synth::{Scenario, SynthMotion, SynthOptions};
use dvrk_calib::{calibrate_axes, pivot_calibration, read_recording, AxesOptions, PivotOptions};
use std::path::Path;

fn with_amplitude(motion: SynthMotion, amplitude: [f64; 2]) -> Scenario {
    Scenario::new(&psm(), &SynthOptions { motion, amplitude, duration: 10.0, noise: 1e-4, occlusion: 0.0, ..Default::default() }).unwrap()
}

#[test]
fn no_motion_is_an_error_naming_the_ranges() {
    let s = with_amplitude(SynthMotion::Q1Q2Sweep, [0.0, 0.0]);
    let rec = s.record(1);
    let e = pivot_calibration(&rec.body("end").unwrap().poses, &PivotOptions::default()).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(e.starts_with("pivot calibration: the marker frame turned 0.") && e.contains("over 1200 samples") && e.contains("move q1 and q2"), "{e}");
    let e = calibrate_axes(&rec, &config(&s), &AxesOptions::default()).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(e.starts_with("axis 3 (yaw / back): the clusters turned 0.") && e.contains("needs at least 1.0 deg"), "{e}");
}

#[test]
fn two_degrees_of_motion_warns_with_the_range_and_the_uncertainty() {
    // Amplitude 1 degree: a 2 degree range of q1 and of q2.
    let s = with_amplitude(SynthMotion::Q1Q2Sweep, [1f64.to_radians(), 1f64.to_radians()]);
    let rec = s.record(2);
    let f = pivot_calibration(&rec.body("end").unwrap().poses, &PivotOptions::default()).unwrap();
    eprintln!("{:?}", f.warnings);
    assert_eq!(f.warnings.len(), 1);
    let w = &f.warnings[0];
    assert!(w.starts_with("motion range too small for a meaningful pivot: the marker frame turned "), "{w}");
    // The two ranges it names are those of the motion: about 2 degrees each.
    let nums: Vec<f64> = w.split(' ').filter_map(|t| t.parse().ok()).collect();
    assert!(nums[0] > 1.5 && nums[0] < 2.5 && nums[1] > 1.5 && nums[1] < 2.5, "{nums:?}");
    assert!(w.contains("pivot std ("), "{w}");
    // The uncertainty it reports is the one the result has: millimetres, not the 10 um of a full sweep.
    assert!(f.pivot_std().iter().any(|s| *s > 1e-4), "{:?}", f.pivot_std());
    let s = with_amplitude(SynthMotion::Q2Sweep, [0.0, 1f64.to_radians()]);
    let r = calibrate_axes(&s.record(3), &config(&s), &AxesOptions::default()).unwrap();
    let w: Vec<&String> = r.warnings.iter().filter(|w| w.contains("motion range too small")).collect();
    assert_eq!(w.len(), 7, "{:?}", r.warnings);
    // 2.0 degrees of motion, plus the tracker's rotation noise in quadrature.
    assert!(w[0].starts_with("axis 3 (yaw / back): motion range too small for a meaningful axis: the clusters turned 2.1 deg"), "{}", w[0]);
    assert!(w[0].contains("axis point std 0."), "{}", w[0]);
}

#[test]
fn a_single_frame_is_an_error() {
    let s = Scenario::new(&psm(), &SynthOptions { duration: 1.0 / 120.0, ..Default::default() }).unwrap();
    let rec = s.record(1);
    let poses = &rec.body("end").unwrap().poses;
    assert_eq!(poses.len(), 1);
    let e = pivot_calibration(poses, &PivotOptions::default()).unwrap_err().to_string();
    assert_eq!(e, "pivot calibration: 1 pose(s); it needs at least 10 spread over two joint motions");
    let e = calibrate_axes(&rec, &config(&s), &AxesOptions::default()).unwrap_err().to_string();
    assert_eq!(e, "axis 3 (yaw / back): 1 common sample(s) of the two clusters; an axis needs at least 10");
}

#[test]
fn nan_rows_are_dropped_with_a_count() {
    let s = scenario(&psm(), SynthMotion::Q1Q2Sweep, 1e-4, 10.0, 0.0);
    let mut rec = s.record(4);
    // Poison 25 rows of `end` in CSV and MCAP.
    rec.bodies.iter_mut().for_each(|b| {
        if b.name == "end" {
            for i in (0..250).step_by(10) {
                b.poses[i].translation.vector.x = f64::NAN;
            }
        }
    });
    let csv = dvrk_sim::recording::write_plain_csv(&rec);
    let back = dvrk_sim::recording::parse_plain_csv(&csv, Path::new("nan.csv")).unwrap();
    assert!(back.warnings.iter().any(|w| w == "nan.csv: rigid body `end`: 25 row(s) hold NaN; treated as occluded"), "{:?}", back.warnings);
    assert_eq!(back.body("end").unwrap().len(), 1200 - 25);
    let mcap = dvrk_sim::recording::write_mcap_poses(&rec, McapLayout::PoseStamped, "/js").unwrap();
    let back = dvrk_sim::recording::parse_mcap_poses(&mcap, Path::new("nan.mcap"), &McapOptions::default()).unwrap();
    assert!(back.warnings.iter().any(|w| w == "nan.mcap: /mocap/end/pose: 25 message(s) hold NaN; treated as occluded"), "{:?}", back.warnings);
    // The fit itself refuses a NaN pose rather than returning NaN.
    let e = pivot_calibration(&rec.body("end").unwrap().poses, &PivotOptions::default()).unwrap_err().to_string();
    assert_eq!(e, "pivot calibration: pose 0 is not finite");
}

#[test]
fn a_missing_topic_names_the_ones_there_are() {
    let s = scenario(&psm(), SynthMotion::Q1Q2Sweep, 1e-4, 1.0, 0.0);
    let mcap = dvrk_sim::recording::write_mcap_poses(&s.record(1), McapLayout::PoseStamped, "/PSM1/measured_js").unwrap();
    let e = dvrk_sim::recording::parse_mcap_poses(&mcap, Path::new("r.mcap"), &McapOptions { topics: vec!["/vrpn/PSM/pose".into()], joint_topic: None })
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("r.mcap: no topic or TF child frame `/vrpn/PSM/pose`; topics: /PSM1/measured_js (sensor_msgs/msg/JointState, cdr), /mocap/back/pose"), "{e}");
    let e = dvrk_sim::recording::parse_mcap_poses(&mcap, Path::new("r.mcap"), &McapOptions { topics: vec![], joint_topic: Some("/PSM2/measured_js".into()) }).unwrap_err().to_string();
    assert!(e.starts_with("r.mcap: no JointState topic `/PSM2/measured_js`"), "{e}");
    let rec = dvrk_sim::recording::parse_mcap_poses(&mcap, Path::new("r.mcap"), &McapOptions::default()).unwrap();
    let e = rec.body("tool").unwrap_err().to_string();
    assert_eq!(e, "rigid body or topic `tool`: not in the recording; available: /mocap/back/pose, /mocap/bottom/pose, /mocap/end/pose, /mocap/front/pose, /mocap/top/pose, /mocap/yaw/pose");
    let mut cfg = config(&s);
    cfg.bodies[1].recording = Some("/mocap/pitch_back/pose".into());
    let e = calibrate_axes(&rec, &cfg, &AxesOptions::default()).unwrap_err().to_string();
    assert!(e.starts_with("body `back` (rigid body or topic `/mocap/pitch_back/pose`): not in the recording; available:"), "{e}");
}

#[test]
fn a_wrong_marker_count_is_an_error() {
    let s = scenario(&psm(), SynthMotion::Q1Q2Sweep, 1e-4, 1.0, 0.0);
    let mut rec = s.record(5);
    rec.bodies.clear();
    // A cluster that lost a marker in every frame of the file: two columns groups only.
    let end = rec.markers.iter_mut().find(|m| m.body == "end").unwrap();
    let n = end.t.len();
    end.xyz = (0..n).flat_map(|i| end.xyz[i * 9..i * 9 + 6].to_vec()).collect();
    end.names.truncate(2);
    let csv = dvrk_sim::recording::write_plain_csv(&rec);
    let back = dvrk_sim::recording::parse_plain_csv(&csv, Path::new("m.csv")).unwrap();
    let e = back.poses("end", None, true).unwrap_err().to_string();
    assert_eq!(e, "rigid body `end`: has 2 marker(s); a pose needs 3 or more");
    // A layout of four markers for a three-marker cluster.
    let four = [nalgebra::Vector3::x(), nalgebra::Vector3::y(), nalgebra::Vector3::z(), -nalgebra::Vector3::x()];
    let e = back.poses("top", Some(&four), true).unwrap_err().to_string();
    assert_eq!(e, "rigid body `top`: the recording has 3 markers for it, its definition has 4");
}

#[test]
fn a_truncated_mcap_is_an_error_with_the_message_count() {
    let s = scenario(&psm(), SynthMotion::Q1Q2Sweep, 1e-4, 5.0, 0.0);
    let mcap = dvrk_sim::recording::write_mcap_poses(&s.record(6), McapLayout::PoseStamped, "/PSM1/measured_js").unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.mcap");
    std::fs::write(&path, &mcap[..mcap.len() * 2 / 3]).unwrap();
    let e = read_recording(&path, &McapOptions::default()).unwrap_err().to_string();
    eprintln!("{e}");
    assert!(e.contains("cut.mcap: truncated or damaged after ") && e.contains("nothing was fitted"), "{e}");
    std::fs::write(&path, b"not an mcap").unwrap();
    let e = read_recording(&path, &McapOptions::default()).unwrap_err().to_string();
    assert!(e.contains("cut.mcap: not an MCAP file"), "{e}");
    let e = read_recording(&dir.path().join("absent.mcap"), &McapOptions::default()).unwrap_err().to_string();
    assert!(e.ends_with("absent.mcap: no such file"), "{e}");
}
