//! The `dvrk` command line: output contracts other tools script against.

use crate::util::{dvrk_ok, tempdir};
use serde_json::Value;

#[test]
fn fk_json_lists_every_frame_with_the_papers_numbers() {
    let out = dvrk_ok(&["fk", "psm", "--q", "0.1,-0.2,0.12,0.3,0.2,-0.1,0.4", "--json"]);
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["model"], "psm");
    let frames = v["frames"].as_array().unwrap();
    let mut indices: Vec<i64> = frames.iter().map(|f| f["index"].as_i64().unwrap()).collect();
    indices.sort();
    assert_eq!(indices, (1..=17).collect::<Vec<_>>());
    let f6 = frames.iter().find(|f| f["index"] == 6).unwrap();
    assert_eq!(f6["parent"], 3);
    assert_eq!(f6["name"], "pitch_bottom");
    let t = f6["T"].as_array().unwrap();
    assert_eq!(t.len(), 4);
    assert_eq!(t[3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    // Frame 6 sits 0.150 m from frame 3 (Table 4).
    let p = |f: &Value| [0, 1, 2].map(|r| f["T"][r][3].as_f64().unwrap());
    let f3 = frames.iter().find(|f| f["index"] == 3).unwrap();
    let (a, b) = (p(f3), p(f6));
    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    assert!((d - 0.150).abs() < 1e-12);
    let closures = v["closures"].as_array().unwrap();
    assert_eq!(closures.len(), 2);
    assert!(closures.iter().all(|c| c["gap_m"].as_f64().unwrap() < 1e-12));
}

#[test]
fn fk_csv_batch_matches_single_evaluations() {
    let dir = tempdir();
    let input = dir.path().join("joints.csv");
    let output = dir.path().join("poses.csv");
    let rows = ["0.1,-0.2,0.12,0.3,0.2,-0.1,0.4", "-0.5,0.4,0.2,-1.0,0.5,0.3,0.0"];
    std::fs::write(&input, format!("time,q1,q2,q3,q4,q5,q6,q7\n0.0,{}\n0.1,{}\n", rows[0], rows[1])).unwrap();
    dvrk_ok(&["fk", "psm", "--input", input.to_str().unwrap(), "--output", output.to_str().unwrap()]);
    let text = std::fs::read_to_string(&output).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,qx,qy,qz,qw"));
    let m = dvrk_kin::load("psm", None).unwrap();
    for (row, line) in rows.iter().zip(lines) {
        let q: Vec<f64> = row.split(',').map(|s| s.parse().unwrap()).collect();
        let tip = m.fk(&q).unwrap()[m.tip];
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        assert!((tip.translation.vector - nalgebra::Vector3::new(v[0], v[1], v[2])).norm() < 1e-12);
        let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]));
        assert!(dvrk_kin::so3::angle(&(r.to_rotation_matrix().inverse() * tip.rotation)) < 1e-12);
    }
    // A chosen frame by paper number.
    dvrk_ok(&["fk", "psm", "--input", input.to_str().unwrap(), "--output", output.to_str().unwrap(), "--frame", "9"]);
    assert_eq!(std::fs::read_to_string(&output).unwrap().lines().count(), 3);
}

#[test]
fn ik_json_round_trips_through_fk() {
    let q = [0.2, -0.3, 0.15, 0.4, -0.2, 0.3, 0.2];
    let m = dvrk_kin::load("psm", None).unwrap();
    let tip = m.fk(&q).unwrap()[m.tip];
    let r = nalgebra::UnitQuaternion::from_rotation_matrix(&tip.rotation);
    let p = tip.translation.vector;
    let pose = format!("{},{},{},{},{},{},{}", p.x, p.y, p.z, r.i, r.j, r.k, r.w);
    let v: Value = serde_json::from_str(&dvrk_ok(&["ik", "psm", "--pose", &pose, "--json"])).unwrap();
    let sol: Vec<f64> = v["q"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    for k in 0..6 {
        assert!((sol[k] - q[k]).abs() < 1e-8, "joint {k}: {} vs {}", sol[k], q[k]);
    }
    assert!(v["position_error_m"].as_f64().unwrap() < 1e-9);
}

#[test]
fn model_check_reports_a_sound_psm() {
    let v: Value = serde_json::from_str(&dvrk_ok(&["model", "check", "psm", "--json", "--samples", "500"])).unwrap();
    assert_eq!(v["ok"], true);
    assert!(v["max_closure_residual_m"].as_f64().unwrap() < 1e-12);
    assert!(v["max_pivot_residual_m"].as_f64().unwrap() < 1e-12);
    assert!((v["rcm"][1].as_f64().unwrap() + 0.4864).abs() < 1e-12);
    assert!(v["conditioning"]["sigma_min_worst"].as_f64().unwrap() > 0.015);
    assert!(v["serial_equivalence"]["max_position_error_m"].as_f64().unwrap() < 1e-9);
}

#[test]
fn model_list_and_show_print_the_tables() {
    let list = dvrk_ok(&["model", "list"]);
    for name in ["psm", "ecm", "suj-psm1", "suj-psm2", "suj-psm3", "suj-ecm", "cart", "mtml", "mtmr", "psm-serial", "ecm-serial"] {
        assert!(list.lines().any(|l| l.starts_with(name)), "{name} listed");
    }
    let show = dvrk_ok(&["model", "show", "psm"]);
    assert!(show.contains("-q2 - beta1 - pi/2"));
    assert!(show.contains("pitch_back_link"));
    let line = show.lines().find(|l| l.trim_start().starts_with("11 ")).unwrap();
    assert!(line.contains("mu*q3") && line.contains("-0.1"), "{line}");
}

#[test]
fn sim_json_summary_of_the_psm_scene() {
    let v: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "1", "--json"])).unwrap();
    assert_eq!(v["scene"], "psm");
    assert_eq!(v["joints"].as_array().unwrap().len(), 7);
    assert!(v["real_time_factor"].as_f64().unwrap() > 1.0);
    // Loops closed to well under a micrometre, the insertion axis on the kinematic RCM.
    assert!(v["max_closure_error"].as_f64().unwrap() < 1e-6, "{}", v["max_closure_error"]);
    assert!(v["max_rcm_error"].as_f64().unwrap() < 1e-6, "{}", v["max_rcm_error"]);
    let yaw = &v["joints"][0];
    assert_eq!(yaw["joint"], "outer_yaw");
    assert!(yaw["rms_error"].as_f64().unwrap() < 0.05);
    // The default engine is the reduced one; a rapier option (or the flag) picks rapier, and the
    // reduced engine refuses contacts in one line.
    assert_eq!(v["engine"], "reduced");
    let rapier: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "0.2", "--contacts", "--json"])).unwrap();
    assert_eq!(rapier["engine"], "rapier");
    let e = crate::util::dvrk_err(&["sim", "--scene", "psm", "--duration", "0.2", "--engine", "reduced", "--contacts"]);
    assert!(e.contains("contacts") && e.contains("rapier") && e.trim().lines().count() == 1, "{e}");
    // --brake-suj: the full cart's setup joints held still; a scene without them is refused.
    let braked: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "full", "--duration", "0.5", "--brake-suj", "--json"])).unwrap();
    let suj = braked["joints"].as_array().unwrap().iter().filter(|j| j["arm"].as_str().unwrap().starts_with("SUJ")).collect::<Vec<_>>();
    assert!(suj.len() == 22 && suj.iter().all(|j| j["max_error"].as_f64() == Some(0.0)), "{suj:?}");
    let e = crate::util::dvrk_err(&["sim", "--scene", "psm", "--duration", "0.2", "--brake-suj"]);
    assert!(e.contains("--brake-suj") && e.contains("no setup joints"), "{e}");
}

#[test]
fn synthetic_tracker_to_calibrated_model() {
    let dir = tempdir();
    let d = |f: &str| dir.path().join(f).to_str().unwrap().to_string();
    // Pivot (RCM) from markers on link 8 while q1 and q2 sweep, noise-free.
    dvrk_ok(&["synth", "mocap", "--model", "psm", "--motion", "q1q2-sweep", "--noise-mm", "0", "--rate", "120", "-o", &d("piv.mcap")]);
    let p: Value = serde_json::from_str(&dvrk_ok(&["calib", "pivot", "--recording", &d("piv.mcap"), "--topic", "end", "--json"])).unwrap();
    for key in ["tip", "pivot", "rms_per_axis", "rms", "tip_std", "pivot_std", "samples", "method"] {
        assert!(p.get(key).is_some(), "pivot JSON has {key}");
    }
    assert_eq!(p["method"], "one-step");
    assert!(p["rms"].as_f64().unwrap() < 1e-9, "{}", p["rms"]);
    // Axes -> distance table -> an updated model that is still sound.
    dvrk_ok(&["synth", "mocap", "--model", "psm", "--motion", "q2-sweep", "--noise-mm", "0", "-o", &d("axes.mcap"), "--config-out", &d("markers.toml")]);
    let axes = dvrk_ok(&["calib", "axes", "--recording", &d("axes.mcap"), "--config", &d("markers.toml"), "--json"]);
    std::fs::write(d("axes.json"), &axes).unwrap();
    dvrk_ok(&["calib", "apply", "--axes", &d("axes.json"), "--model", "psm", "-o", &d("my-psm.toml")]);
    let check: Value = serde_json::from_str(&dvrk_ok(&["model", "check", &d("my-psm.toml"), "--json", "--samples", "200"])).unwrap();
    assert_eq!(check["ok"], true, "{check}");
    // Noise-free: the calibrated model's RCM is the shipped one's.
    assert!((check["rcm"][1].as_f64().unwrap() + 0.4864).abs() < 1e-6, "{}", check["rcm"]);
}

#[test]
fn sim_and_calib_reject_bad_flags() {
    crate::util::dvrk_err(&["sim", "--scene", "psm", "--duration", "nan"]);
    crate::util::dvrk_err(&["sim", "--scene", "no-such-scene", "--duration", "1"]);
    crate::util::dvrk_err(&["calib", "pivot", "--recording", "/nonexistent.mcap"]);
}

#[test]
fn sim_writes_an_mcap_recording_whole() {
    let dir = tempdir();
    let out = dir.path().join("run.mcap");
    let v: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "0.5", "--out", out.to_str().unwrap(), "--json"])).unwrap();
    assert_eq!(v["scene"], "psm");
    // The calibration reader takes the simulator's recording: measured_js and measured_cp.
    let rec = dvrk_calib::read_recording(&out, &dvrk_calib::McapOptions { topics: vec!["/PSM1/measured_cp".into()], joint_topic: Some("/PSM1/measured_js".into()) }).unwrap();
    let tip = rec.body("/PSM1/measured_cp").unwrap();
    assert!(tip.len() >= 45, "about 100 Hz for 0.5 s: {}", tip.len());
    let joints = rec.joints.as_ref().unwrap();
    assert_eq!(joints.names[0], "outer_yaw");
    assert_eq!(joints.q.len(), tip.len());
    // Nothing but the recording is left in the directory (written via a temporary file).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// A recorded run replayed through `--trajectory replay:FILE` tracks like the original: the
/// setpoints come back from /PSM1/setpoint_js (100 Hz, linearly interpolated), so each joint's
/// tracking RMS matches the sine run's to 2% (measured: 0.04-1.1%).
#[test]
fn sim_replays_its_own_recording() {
    let dir = tempdir();
    let rec = dir.path().join("run.mcap");
    let rec = rec.to_str().unwrap();
    let sine: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "4", "--out", rec, "--json"])).unwrap();
    let replay_arg = format!("replay:{rec}");
    let replay: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "4", "--trajectory", &replay_arg, "--json"])).unwrap();
    assert_eq!(replay["trajectory"], replay_arg.as_str());
    // The jaw holds still in both (its error is ~1e-6 rad of noise): compare the six tracked joints.
    for (a, b) in sine["joints"].as_array().unwrap().iter().zip(replay["joints"].as_array().unwrap()).take(6) {
        let (x, y) = (a["rms_error"].as_f64().unwrap(), b["rms_error"].as_f64().unwrap());
        eprintln!("{}: sine {x:.4e}, replay {y:.4e}", a["joint"]);
        assert!((y / x - 1.0).abs() < 0.02, "{}: sine {x}, replay {y}", a["joint"]);
    }
    // A CSV replays into the scene's tracked arm; the arm starts on the first sample.
    let csv = dir.path().join("q.csv");
    std::fs::write(&csv, "time,q1,q2,q3,q4,q5,q6,q7\n0.0,0.2,0.1,0.12,0,0,0,0\n1.0,0.3,0.1,0.12,0,0,0,0\n").unwrap();
    let v: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--duration", "1", "--trajectory", &format!("replay:{}", csv.display()), "--json"])).unwrap();
    assert!(v["joints"][0]["max_error"].as_f64().unwrap() < 0.01, "{}", v["joints"][0]);
    // Bad replays: a missing file, a CSV for a scene with several tracked arms, the wrong joint count.
    let e = crate::util::dvrk_err(&["sim", "--scene", "psm", "--trajectory", "replay:/nonexistent.mcap"]);
    assert!(e.contains("/nonexistent.mcap: no such file"), "{e}");
    let e = crate::util::dvrk_err(&["sim", "--scene", "3psm", "--trajectory", &format!("replay:{}", csv.display())]);
    assert!(e.contains("tracks 3 arms (PSM1, PSM2, PSM3)"), "{e}");
    std::fs::write(&csv, "time,q1,q2\n0.0,0.2,0.1\n1.0,0.3,0.1\n").unwrap();
    let e = crate::util::dvrk_err(&["sim", "--scene", "psm", "--trajectory", &format!("replay:{}", csv.display())]);
    assert!(e.contains("2 joint columns, arm PSM1 has 7 joints"), "{e}");
}

#[test]
fn export_mjcf_writes_a_scene_or_a_model_and_names_bad_input() {
    let dir = tempdir();
    let out = dir.path().join("psm.xml");
    dvrk_ok(&["export", "mjcf", "psm", "-o", out.to_str().unwrap()]);
    let xml = std::fs::read_to_string(&out).unwrap();
    assert!(xml.starts_with("<mujoco model=\"psm\">") && xml.contains("<connect name=\"PSM1/c1\""), "{}", &xml[..200]);
    // A model (no scene of that name): its built-in inertials, its scene arm's mode.
    let out = dir.path().join("suj.xml");
    dvrk_ok(&["export", "mjcf", "suj-ecm", "-o", out.to_str().unwrap()]);
    assert_eq!(std::fs::read_to_string(&out).unwrap().matches("polycoef").count(), 4);
    let err = crate::util::dvrk_err(&["export", "mjcf", "cart", "-o", out.to_str().unwrap()]);
    assert!(err.contains("cart") && err.contains("no built-in inertials"), "{err}");
    let err = crate::util::dvrk_err(&["export", "mjcf", "psm", "--q", "0", "-o", out.to_str().unwrap()]);
    assert!(err.contains("--q"), "{err}");
}

/// `dvrk identify` on the real WPI recordings (skipped when ../shared is absent): the JSON
/// contract, the validation block and the identified model file, which `dvrk sim --model` runs.
#[test]
fn identify_json_and_output_file() {
    let (Some(one), Some(two)) = (crate::util::external("wpi-dvrk-dynamics/psm_one_results.csv"), crate::util::external("wpi-dvrk-dynamics/psm_two_results.csv")) else { return };
    let dir = tempdir();
    let out = dir.path().join("psm-identified.toml");
    let v: Value = serde_json::from_str(&dvrk_ok(&[
        "identify", "--recording", one.to_str().unwrap(), "--format", "wpi-csv", "--model", "psm", "--validate", two.to_str().unwrap(), "-o", out.to_str().unwrap(), "--json",
    ]))
    .unwrap();
    for key in ["relative_error", "rigid_body_only", "validation", "effects", "bodies", "physically_consistent", "unidentifiable", "base_parameters", "ablation"] {
        assert!(v.get(key).is_some(), "identify JSON has {key}");
    }
    assert_eq!(v["physically_consistent"], true);
    assert_eq!(v["validation"]["relative_error"].as_array().unwrap().len(), 7);
    // The WPI authors' protocol: one period of `two`'s excitation (6.48 s) after 1 s trimmed.
    let published = &v["validation"]["as_published"];
    assert_eq!(published["relative_error"].as_array().unwrap().len(), 7);
    assert!((published["period_s"].as_f64().unwrap() - 6.48).abs() < 0.01, "{published}");
    assert!((published["window_s"][0].as_f64().unwrap() - 1.0).abs() < 1e-9, "{published}");
    // The ablation: eleven rows from the rigid body alone to the chosen options, each validated
    // on `two`, the last with the summary's own figures.
    let ablation = v["ablation"].as_array().unwrap();
    assert_eq!(ablation.len(), 11);
    assert_eq!(ablation[0]["effects"], "rigid body only (CAD prior, one cut-off)");
    assert_eq!(ablation[0]["validation"].as_array().unwrap().len(), 7);
    assert_eq!(ablation.last().unwrap()["validation"], v["validation"]["relative_error"]);
    // The output is a model file with the identified inertials and effects, which the simulator runs.
    let model = dvrk_kin::load(out.to_str().unwrap(), None).unwrap();
    assert_eq!(model.spec.inertials.len(), model.bodies.len());
    assert!(model.spec.inertials.iter().all(|b| b.source.starts_with("dvrk identify from")));
    assert!(model.spec.effects.iter().any(|e| e.name == "coulomb_friction" && e.joint.as_deref() == Some("outer_yaw")));
    // The tool's actuator channels' terms are actuator effects (issue 40 item 4): the jaw
    // actuator's viscous friction as identified, on actuator 7; what is left unexpressed names
    // no actuator friction, spring or motor inertia.
    let fitted = v["effects"].as_array().unwrap().iter().find(|e| e["name"] == "viscous_friction" && e["joint"] == "jaw actuator").unwrap()["parameters"]["fv"].as_f64().unwrap();
    let written = model.spec.effects.iter().find(|e| e.name == "actuator_viscous_friction" && e.actuator == Some(7)).unwrap().parameters["fv"];
    assert!((written - fitted).abs() <= 1e-12 * fitted.abs(), "{written} vs {fitted}");
    assert!(model.spec.effects.iter().any(|e| e.name == "motor_inertia" && e.actuator == Some(5)));
    let left = v["not_expressed_as_effects"].as_array().unwrap();
    assert!(left.iter().all(|s| !s.as_str().unwrap().contains("actuator.fv =") && !s.as_str().unwrap().contains("actuator.im =")), "{left:?}");
    // The winding terms are effects too (issue 62 item 4): what is left is the presliding
    // levels' transition and the cross springs fitted next to it.
    assert!(left.iter().all(|s| s.as_str().unwrap().contains(".fd = ") || s.as_str().unwrap().contains(".k from ")), "{left:?}");
    assert!(model.spec.effects.iter().any(|e| e.name == "coulomb_friction" && e.parameters.get("fq").is_some_and(|x| *x != 0.0)));
    let sim: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "psm", "--model", &format!("PSM1={}", out.display()), "--duration", "0.5", "--json"])).unwrap();
    assert!(sim.is_object(), "{sim}");
    // Without the ablation (most of the time): the same summary and model file, no
    // `ablation`.
    let quick = dir.path().join("quick.toml");
    let mut w: Value = serde_json::from_str(&dvrk_ok(&[
        "identify", "--recording", one.to_str().unwrap(), "--format", "wpi-csv", "--model", "psm", "--validate", two.to_str().unwrap(), "-o", quick.to_str().unwrap(), "--json", "--no-ablation",
    ]))
    .unwrap();
    assert!(w.get("ablation").is_none());
    let (mut v, text) = (v, std::fs::read_to_string(&out).unwrap());
    v.as_object_mut().unwrap().remove("ablation");
    for s in [&mut v, &mut w] {
        s.as_object_mut().unwrap().remove("output");
    }
    assert_eq!(v, w);
    assert_eq!(std::fs::read_to_string(&quick).unwrap(), text);
    // A CSV given as MCAP, and an unknown format, are named.
    let e = crate::util::dvrk_err(&["identify", "--recording", one.to_str().unwrap(), "--format", "mcap"]);
    assert!(e.contains("psm_one_results.csv: not an MCAP file"), "{e}");
    // (`bag` is a format since ROS 1 bags are read: issue 41.)
    let e = crate::util::dvrk_err(&["identify", "--recording", one.to_str().unwrap(), "--format", "rosbag"]);
    assert!(e.contains("--format") && e.contains("`rosbag` is not a format; valid: auto, mcap, bag, wpi-csv, csv"), "{e}");
}

#[test]
fn sim_full_camera_writes_the_frames_as_png_files() {
    let dir = tempdir();
    let frames = dir.path().join("frames");
    let v: Value = serde_json::from_str(&dvrk_ok(&["sim", "--scene", "full-camera", "--duration", "0.04", "--frames-dir", frames.to_str().unwrap(), "--json"])).unwrap();
    // Frames at the first step and at 1/30 s.
    assert_eq!(v["camera"]["frames"], 2);
    assert_eq!(v["camera"]["rate_hz"], 30.0);
    let mut names: Vec<String> = std::fs::read_dir(&frames).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    names.sort();
    assert_eq!(names, ["left_000001.png", "left_000002.png", "left_depth_000001.png", "left_depth_000002.png", "right_000001.png", "right_000002.png", "right_depth_000001.png", "right_depth_000002.png"]);
    let png = std::fs::read(frames.join("left_000001.png")).unwrap();
    assert_eq!(&png[..8], &[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]);
    // IHDR: 800 x 800.
    assert_eq!(&png[16..24], &[0, 0, 3, 32, 0, 0, 3, 32]);
    let err = crate::util::dvrk_err(&["sim", "--scene", "psm", "--duration", "0.01", "--frames-dir", frames.to_str().unwrap()]);
    assert!(err.contains("--frames-dir") && err.contains("scene psm has no camera (full-camera has one)"), "{err}");
}

/// `dvrk discrepancy --format wpi-csv` on the WPI recording: a report with the contract's keys
/// and one step per round; a bad prior is refused with the flag and value.
#[test]
fn discrepancy_reads_the_wpi_recording() {
    let Some(rec) = crate::util::external("wpi-dvrk-dynamics/psm_one_results.csv") else { return };
    let dir = tempdir();
    let (report, updated) = (dir.path().join("r.json"), dir.path().join("m.toml"));
    let rec = rec.to_str().unwrap();
    // The updated model must load: an unbounded fit once named a coupling error (d44 = 0.74)
    // beyond the model file's range.
    dvrk_ok(&["discrepancy", "--model", "psm", "--recording", rec, "--format", "wpi-csv", "--report", report.to_str().unwrap(), "--no-tracking", "--max-rounds", "2", "-o", updated.to_str().unwrap()]);
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    for key in ["verdict", "channel", "effects", "candidates", "rms_before", "rms_after", "rms_heldout_before", "rms_heldout_after", "noise_floor", "steps"] {
        assert!(r.get(key).is_some(), "{key} missing");
    }
    let steps = r["steps"].as_array().unwrap();
    assert!(!steps.is_empty() && steps.len() <= 2);
    // The CAD model misses the real robot by far more than the sensor noise.
    assert!(r["rms_heldout_before"].as_f64().unwrap() > 10.0);
    if r["verdict"] == "named" {
        dvrk_kin::load(updated.to_str().unwrap(), None).unwrap();
    }
    let e = crate::util::dvrk_err(&["discrepancy", "--model", "psm", "--recording", rec, "--format", "wpi-csv", "--report", report.to_str().unwrap(), "--inertia-prior", "x"]);
    assert!(e.contains("--inertia-prior x"), "{e}");
}

/// The kinematic channel from the command line: `dvrk synth hidden-effect --marker-link` adds a
/// tracked marker on the tool shaft; `dvrk discrepancy --marker-topic T --marker-link 12` (the
/// paper's frame number of tool_roll) reads it, joins its evidence to the torque channel's and
/// names the hidden play with the tracker's figures in the report. Bad marker flags are refused
/// with the flag and value. (The truth on the reduced engine, as in `hidden_viscous_friction`.)
#[test]
fn discrepancy_reads_a_tracked_marker() {
    let dir = tempdir();
    let (rec, answer, report) = (dir.path().join("rec.mcap"), dir.path().join("a.json"), dir.path().join("r.json"));
    let p = |x: &std::path::Path| x.to_str().unwrap().to_string();
    dvrk_ok(&["synth", "hidden-effect", "--effect", "backlash", "--seed", "11", "--enr", "5", "--duration", "20", "--engine", "reduced", "--marker-link", "tool_roll", "-o", &p(&rec), "--answer", &p(&answer)]);
    let a: Value = serde_json::from_slice(&std::fs::read(&answer).unwrap()).unwrap();
    let topic = a["marker_topic"].as_str().unwrap().to_string();
    let text = dvrk_ok(&["discrepancy", "--model", "psm", "--recording", &p(&rec), "--marker-topic", &topic, "--marker-link", "12", "--report", &p(&report), "--no-tracking", "--max-rounds", "1"]);
    // The tracker's figures on the command line too (a recording without efforts has no others).
    assert!(text.lines().any(|l| l.trim_start().starts_with("marker on tool_roll") && l.contains("of the tracker's noise")), "{text}");
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["channel"], "torque+kinematic");
    assert_eq!(r["verdict"], "named");
    assert_eq!(r["effects"][0]["name"], "backlash");
    assert_eq!(r["effects"][0]["joint"], a["effects"][0]["joint"]);
    let k = &r["kinematic"];
    assert_eq!(k["link"], "tool_roll");
    // Measured 3.83 -> 1.32: what is left is the play profile's bias, not the tracker's noise.
    assert!(k["rms_heldout_before"].as_f64().unwrap() > 3.0 && k["rms_heldout_after"].as_f64().unwrap() < 1.4, "{k}");
    let e = crate::util::dvrk_err(&["discrepancy", "--model", "psm", "--recording", &p(&rec), "--marker-topic", &topic, "--marker-link", "99", "--report", &p(&report)]);
    assert!(e.contains("--marker-link") && e.contains("99"), "{e}");
    let e = crate::util::dvrk_err(&["discrepancy", "--model", "psm", "--recording", &p(&rec), "--marker-topic", "/nope", "--marker-link", "12", "--report", &p(&report)]);
    assert!(e.contains("/nope") && e.contains("rec.mcap"), "{e}");
    // The same recording as a CSV with the marker's pose columns: the same named effect.
    let (csv, report2) = (dir.path().join("rec.csv"), dir.path().join("r2.json"));
    dvrk_ok(&["synth", "hidden-effect", "--effect", "backlash", "--seed", "11", "--enr", "5", "--duration", "20", "--engine", "reduced", "--marker-link", "tool_roll", "-o", &p(&csv), "--answer", &p(&answer)]);
    assert!(std::fs::read_to_string(&csv).unwrap().lines().nth(2).unwrap().ends_with("marker_tool_roll.qw"));
    dvrk_ok(&["discrepancy", "--model", "psm", "--recording", &p(&csv), "--format", "csv", "--marker-topic", "marker_tool_roll", "--marker-link", "tool_roll", "--report", &p(&report2), "--no-tracking", "--max-rounds", "1"]);
    let r2: Value = serde_json::from_slice(&std::fs::read(&report2).unwrap()).unwrap();
    assert_eq!((&r2["verdict"], &r2["effects"][0]["name"], &r2["effects"][0]["joint"]), (&r["verdict"], &r["effects"][0]["name"], &r["effects"][0]["joint"]));
    let (b1, b2) = (r["effects"][0]["parameters"]["b"].as_f64().unwrap(), r2["effects"][0]["parameters"]["b"].as_f64().unwrap());
    assert!((b1 - b2).abs() < 1e-6 * b1, "{b1} {b2}");
}

/// `dvrk synth hidden-effect` (viscous friction, 12 s, the truth on the reduced engine: 16x
/// rapier's speed; `tests/outputs.rs` runs the default) to `rec.<ext>`; its path.
fn hidden_viscous_friction(dir: &std::path::Path, ext: &str) -> String {
    let rec = dir.join(format!("rec.{ext}"));
    let answer = dir.join(format!("answer-{ext}.json"));
    dvrk_ok(&["synth", "hidden-effect", "--effect", "viscous_friction", "--seed", "3", "--duration", "12", "--engine", "reduced", "-o", rec.to_str().unwrap(), "--answer", answer.to_str().unwrap()]);
    rec.to_str().unwrap().to_string()
}

/// `dvrk discrepancy --plot out.png`: a row of four panels per moving joint (residual against
/// time, velocity, load, position), the residual before and after in their colours; a bad
/// extension is refused before the analysis, naming the flag and the path, writing nothing.
#[test]
fn discrepancy_plots_the_residual_before_and_after() {
    use dvrk_calib::discrepancy::plot::{AFTER, BEFORE, COLUMNS, PANEL};
    use dvrk_calib::plot::{Figure, Panel};
    let dir = tempdir();
    let rec = hidden_viscous_friction(dir.path(), "mcap");
    let (report, plot) = (dir.path().join("r.json"), dir.path().join("out.png"));
    dvrk_ok(&["discrepancy", "--model", "psm", "--recording", &rec, "--report", report.to_str().unwrap(), "--plot", plot.to_str().unwrap(), "--no-tracking", "--max-rounds", "2"]);
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(r["verdict"], "named");
    // The report's keys are those of a run without --plot.
    assert!(r.get("residuals").is_none());
    let moving = r["joints"].as_array().unwrap().len();
    assert!(moving >= 6, "{moving} moving joints");
    let like = Figure { title: String::new(), panels: vec![Panel::default(); COLUMNS * moving], columns: COLUMNS, panel_size: PANEL };
    let decoder = png::Decoder::new(std::io::Cursor::new(std::fs::read(&plot).unwrap()));
    let mut d = decoder.read_info().unwrap();
    let mut px = vec![0; d.output_buffer_size().unwrap()];
    let info = d.next_frame(&mut px).unwrap();
    assert_eq!((info.width as usize, info.height as usize), like.size());
    assert_eq!(like.size(), (4 * 320, 20 + moving * 250));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let count = |c: [u8; 3]| px.chunks(3).filter(|p| *p == c).count();
    assert!(count(BEFORE) > 1000 && count(AFTER) > 1000, "before {} px, after {} px", count(BEFORE), count(AFTER));
    assert!(std::fs::metadata(&plot).unwrap().len() < 1_000_000);
    let (report2, bad) = (dir.path().join("r2.json"), dir.path().join("out.txt"));
    let e = crate::util::dvrk_err(&["discrepancy", "--model", "psm", "--recording", &rec, "--report", report2.to_str().unwrap(), "--plot", bad.to_str().unwrap()]);
    assert!(e.contains("--plot") && e.contains("out.txt") && e.contains(".png, .svg"), "{e}");
    assert!(!report2.exists() && !bad.exists());
}

/// The same hidden-effect recording as MCAP and as plain CSV (`synth hidden-effect -o rec.csv`,
/// `discrepancy --format csv`): the same verdict, effect and parameter; the CSV run's SVG plot
/// holds both colours.
#[test]
fn discrepancy_reads_a_csv_joint_log_as_it_reads_mcap() {
    let dir = tempdir();
    let mut reports = Vec::new();
    for (ext, format) in [("mcap", "mcap"), ("csv", "csv")] {
        let rec = hidden_viscous_friction(dir.path(), ext);
        let report = dir.path().join(format!("r-{ext}.json"));
        let plot = dir.path().join(format!("p-{ext}.svg"));
        dvrk_ok(&["discrepancy", "--model", "psm", "--recording", &rec, "--format", format, "--report", report.to_str().unwrap(), "--plot", plot.to_str().unwrap(), "--no-tracking", "--max-rounds", "2"]);
        let svg = std::fs::read_to_string(&plot).unwrap();
        // The residual before (orange) and after (blue) drawn as dots (plotters writes colours in capitals).
        assert!(svg.contains("fill=\"#E6550D\"") && svg.contains("fill=\"#1F77B4\""));
        reports.push(serde_json::from_slice::<Value>(&std::fs::read(&report).unwrap()).unwrap());
    }
    let (m, c) = (&reports[0], &reports[1]);
    assert_eq!(m["verdict"], "named");
    assert_eq!(c["verdict"], m["verdict"]);
    assert_eq!(c["effects"][0]["name"], "viscous_friction");
    assert_eq!(c["effects"][0]["joint"], m["effects"][0]["joint"]);
    let fv = |r: &Value| r["effects"][0]["parameters"]["fv"].as_f64().unwrap();
    assert!((fv(c) - fv(m)).abs() < 1e-9 * fv(m), "{} vs {}", fv(c), fv(m));
    // A CSV joint log that lacks a column is refused with its name.
    let text = std::fs::read_to_string(dir.path().join("rec.csv")).unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, text.replacen(",tau3,", ",torque3,", 1)).unwrap();
    let e = crate::util::dvrk_err(&["discrepancy", "--model", "psm", "--recording", bad.to_str().unwrap(), "--format", "csv", "--report", dir.path().join("rb.json").to_str().unwrap()]);
    assert!(e.contains("bad.csv") && e.contains("tau3"), "{e}");
}

/// `dvrk identify --plot`: per channel, the measured efforts against the identified model's
/// prediction, titled with the channel's relative error in the band (the summary's figure), and
/// committed with the model file (`-o`) or neither.
#[test]
fn identify_plots_measured_against_predicted_per_channel() {
    let dir = tempdir();
    let rec = hidden_viscous_friction(dir.path(), "mcap");
    let (out, plot) = (dir.path().join("id.toml"), dir.path().join("id.svg"));
    let text = dvrk_ok(&["identify", "--recording", &rec, "--model", "psm", "-o", out.to_str().unwrap(), "--plot", plot.to_str().unwrap()]);
    assert!(text.contains("wrote") && out.exists());
    let svg = std::fs::read_to_string(&plot).unwrap();
    for joint in ["outer_yaw", "outer_pitch", "outer_insertion", "jaw"] {
        assert!(svg.contains(&format!("{joint}: relative error 0.")), "{joint}");
    }
    for text in ["effort (N)", "effort (N·m)", "time (s)", "measured (in band)", "identified model"] {
        assert!(svg.contains(text), "{text}");
    }
    // The prediction drawn in blue, the measurement in orange, once per channel (and its legend).
    let stroke = |c: [u8; 3]| svg.matches(&format!("stroke=\"#{:02X}{:02X}{:02X}\"", c[0], c[1], c[2])).count();
    assert!(stroke(dvrk_calib::plot::BLUE) >= 7 && stroke(dvrk_calib::plot::ORANGE) >= 7);
    // A bad plot path fails before any work, leaving no model file.
    let (out2, bad) = (dir.path().join("id2.toml"), dir.path().join("id.jpg"));
    let e = crate::util::dvrk_err(&["identify", "--recording", &rec, "--model", "psm", "-o", out2.to_str().unwrap(), "--plot", bad.to_str().unwrap()]);
    assert!(e.contains("--plot") && e.contains(".png, .svg"), "{e}");
    assert!(!out2.exists());
}
