//! The dVRK's own recordings, written by other people's code (`writers/dvrk_layouts.py`: the
//! Python `mcap-ros2-support` and `rosbags` packages) from a real WPI recording taken to joint
//! space: all joints on one topic, the dVRK's CRTK layout (the jaw on `/PSM1/jaw/measured_js`),
//! and the same as ROS 1 bags (uncompressed, bz2, lz4). Every reader must give the same numbers
//! from each, and identify, discrepancy and the pivot calibration the same results.
//!
//! Skipped, with a message, where Python lacks `mcap_ros2` or `rosbags` (`bash scripts/test.sh`
//! installs both) or the external data is absent.

use dvrk_calib::discrepancy::{discrepancy, scene_for_arm, Options};
use dvrk_calib::identify::{summary, IdentifyOptions};
use dvrk_calib::identify;
use dvrk_sim::recording::McapOptions;
use dvrk_calib::{pivot_calibration, read_recording, PivotOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The fixtures, written once per test binary run into a temporary directory that lives as
/// long as the process.
fn fixtures() -> Option<&'static Path> {
    static DIR: std::sync::OnceLock<Option<tempfile::TempDir>> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let wpi = crate::identify::wpi("insertion-payload/one_no_weight_results.csv")?;
        let ok = Command::new("python3").args(["-c", "import mcap_ros2, rosbags, numpy"]).output().map(|o| o.status.success()).unwrap_or(false);
        if !ok {
            eprintln!("SKIPPED: python3 with mcap-ros2-support, rosbags and numpy is not available (bash scripts/test.sh installs them)");
            return None;
        }
        let dir = tempfile::tempdir().unwrap();
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("calib/writers/dvrk_layouts.py");
        let out = Command::new("python3").arg(&script).arg(&wpi).arg(dir.path()).arg("12").output().expect("python3 runs");
        assert!(out.status.success(), "the fixture writer failed: {}", String::from_utf8_lossy(&out.stderr));
        Some(dir)
    })
    .as_ref()
    .map(|d| d.path())
}

fn file(dir: &Path, name: &str) -> PathBuf {
    dir.join(name)
}

/// Every layout and container reads to the same joint-space recording, bit for bit.
#[test]
fn one_topic_crtk_layout_and_bags_read_the_same() {
    let Some(dir) = fixtures() else { return };
    let psm = dvrk_kin::load("psm", None).unwrap();
    let (base, _) = identify::read_log(&file(dir, "one_topic.mcap"), "auto", &psm, "PSM1").unwrap();
    assert_eq!(base.len(), 2400);
    for name in ["dvrk.mcap", "dvrk.bag", "dvrk_bz2.bag", "dvrk_lz4.bag"] {
        let (rec, notes) = identify::read_log(&file(dir, name), "auto", &psm, "PSM1").unwrap();
        assert_eq!((&rec.t, &rec.position, &rec.velocity, &rec.effort), (&base.t, &base.position, &base.velocity, &base.effort), "{name}");
        let told = if name.ends_with(".bag") { "read as bag" } else { "read as mcap" };
        assert!(notes.iter().any(|n| n.contains(told)), "{name}: {notes:?}");
    }
    // The jaw (joint 7) came from its own topic: the real recording's jaw moves.
    let jaw: Vec<f64> = base.position.iter().map(|q| q[6]).collect();
    let span = jaw.iter().cloned().fold(f64::MIN, f64::max) - jaw.iter().cloned().fold(f64::MAX, f64::min);
    assert!(span > 0.1, "jaw span {span} rad");
    let (one, _) = dvrk_calib::discrepancy::read_log(&file(dir, "one_topic.mcap"), "auto", &psm, "PSM1").unwrap();
    for name in ["dvrk.mcap", "dvrk_bz2.bag"] {
        let (log, _) = dvrk_calib::discrepancy::read_log(&file(dir, name), "auto", &psm, "PSM1").unwrap();
        // The same log but for where it was read from.
        assert_eq!(dvrk_sim::recording::JointLog { source: one.source.clone(), ..log }, one, "{name}");
    }
}

/// identify and the discrepancy workflow give identical results on the one-topic MCAP and on
/// the dVRK-layout compressed bag.
#[test]
fn identify_and_discrepancy_agree_across_layouts_and_containers() {
    let Some(dir) = fixtures() else { return };
    let psm = dvrk_kin::load("psm", None).unwrap();
    let prior = dvrk_sim::scene::builtin_inertials("psm", &psm).unwrap().body_inertias(&psm).unwrap();
    let options = IdentifyOptions::for_recording(&psm, "mcap");
    let summary = |name: &str| {
        let (rec, _) = identify::read_log(&file(dir, name), "auto", &psm, "PSM1").unwrap();
        summary::run(&psm, &prior, &rec, None, &options, "r", "mcap").unwrap().summary
    };
    let (a, b) = (summary("one_topic.mcap"), summary("dvrk_lz4.bag"));
    assert_eq!(a["relative_error"], b["relative_error"]);
    assert_eq!(a["effects"], b["effects"]);
    // A real arm: the fit explains its yaw and pitch to about 10%.
    let yaw = a["relative_error"][0].as_f64().unwrap();
    assert!(yaw > 0.02 && yaw < 0.2, "yaw relative error {yaw}");
    let report = |name: &str| {
        let (log, _) = dvrk_calib::discrepancy::read_log(&file(dir, name), "auto", &psm, "PSM1").unwrap();
        let r = discrepancy(&psm, &scene_for_arm("PSM1").unwrap(), "PSM1", &log, &Options { tracking: false, ..Default::default() }).unwrap().report;
        serde_json::to_value(&r).unwrap()
    };
    let (a, b) = (report("one_topic.mcap"), report("dvrk.bag"));
    for key in ["verdict", "effects", "rms_before", "rms_after", "noise_floor", "candidates"] {
        assert_eq!(a[key], b[key], "{key}");
    }
}

/// The pivot calibration from a PoseStamped topic in an MCAP and in an lz4 bag, and from a TF
/// child frame in a bz2 bag.
#[test]
fn pivot_from_a_bag_equals_pivot_from_mcap() {
    let Some(dir) = fixtures() else { return };
    let fit = |name: &str| {
        let rec = read_recording(&file(dir, name), &McapOptions::default()).unwrap();
        assert_eq!(rec.bodies.len(), 1, "{name}");
        assert_eq!(rec.bodies[0].name, "/vrpn/end/pose");
        pivot_calibration(&rec.bodies[0].poses, &PivotOptions::default()).unwrap()
    };
    let (m, b) = (fit("pivot.mcap"), fit("pivot_lz4.bag"));
    assert_eq!((m.pivot, m.tip, m.rms), (b.pivot, b.tip, b.rms));
    // The same poses as a TF child frame in a bz2 bag.
    let rec = read_recording(&file(dir, "pivot_tf.bag"), &McapOptions::default()).unwrap();
    let end = rec.body("end").unwrap();
    assert_eq!(end.frame_id, "optitrack");
    let tf = pivot_calibration(&end.poses, &PivotOptions::default()).unwrap();
    assert_eq!((tf.pivot, tf.tip, tf.rms), (m.pivot, m.tip, m.rms));
    assert!((b.pivot - nalgebra::Vector3::new(0.3, -0.2, 1.1)).norm() < 1e-9, "{:?}", b.pivot);
}

/// A damaged or incomplete bag is one line naming the file, the topic and what is missing.
#[test]
fn bad_bags_are_named() {
    let Some(dir) = fixtures() else { return };
    let psm = dvrk_kin::load("psm", None).unwrap();
    let e = identify::read_log(&file(dir, "dvrk.bag"), "auto", &psm, "PSM2").unwrap_err().to_string();
    assert!(e.contains("dvrk.bag") && e.contains("no topic /PSM2/measured_js") && e.contains("/PSM1/jaw/measured_js"), "{e}");
    let e = identify::read_log(&file(dir, "jaw_only.bag"), "auto", &psm, "PSM1").unwrap_err().to_string();
    assert!(e.contains("jaw_only.bag") && e.contains("/PSM1/jaw/measured_js is there but its arm topic /PSM1/measured_js is not"), "{e}");
    let bytes = std::fs::read(file(dir, "dvrk_bz2.bag")).unwrap();
    let cut = file(dir, "cut.bag");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let e = identify::read_log(&cut, "auto", &psm, "PSM1").unwrap_err().to_string();
    assert!(e.contains("cut.bag") && e.contains("truncated ROS 1 bag") && !e.contains('\n'), "{e}");
}

/// The real WPI arm's jaw goes up to 4.3 mrad past the limit the model holds (1.39626 rad) on
/// 509 of the 5999 samples of `one`: the recording is identified as measured, and the notes
/// count it (measured: jaw, 509 samples, at most 4.252e-3 rad).
#[test]
fn a_real_recording_past_a_limit_is_fitted_and_counted() {
    let Some(one) = crate::identify::wpi("psm_one_results.csv") else { return };
    let psm = dvrk_kin::load("psm", None).unwrap();
    let (rec, notes) = identify::read_log(&one, "auto", &psm, "PSM1").unwrap();
    assert_eq!(rec.len(), 5999);
    let note = notes.iter().find(|n| n.contains("outside the limits")).unwrap_or_else(|| panic!("{notes:?}"));
    assert!(note.contains("509 of 5999 measured configuration(s)") && note.contains("jaw: 509 of 5999 sample(s) outside [-0.698132, 1.39626] rad, at most 4.252e-3 rad past"), "{note}");
}
