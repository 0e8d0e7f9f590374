//! MCAP recording of a run: 1 s of the psm scene at 100 Hz, read back with the mcap crate and
//! dvrk-sim's own CDR decoder, and with Python's `mcap` + `mcap-ros2-support` (skipped with a
//! printed reason when `python3 -c "import mcap_ros2"` fails).

use dvrk_sim::recording::ros_msgs::{JointState, PoseStamped};
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{RecordOptions, Recorder, Scene, Sim, SimOptions};
use nalgebra::{Translation3, UnitQuaternion};
use std::collections::BTreeMap;

/// What the sim held at each sample: time, q, qd, effort, target, tip in the base frame.
struct Expected {
    t: Vec<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    effort: Vec<Vec<f64>>,
    target: Vec<Vec<f64>>,
    tip: Vec<dvrk_kin::Pose>,
}

/// Run 1 s of the psm tracking test, recording at 100 Hz to `path`.
fn record_psm(path: &std::path::Path) -> (Sim, Expected) {
    let scene = Scene::load("psm").unwrap();
    let mut sim = Sim::new(&scene, &SimOptions::default()).unwrap();
    let mut rec = Recorder::create(&sim, &RecordOptions { path: path.into(), rate: 100.0 }).unwrap();
    let (traj, _) = Trajectory::tracking_test(&sim.arms[0].model);
    let n = sim.nq();
    let (mut q, mut qd) = (vec![0.0; n], vec![0.0; n]);
    let mut e = Expected { t: vec![], q: vec![], qd: vec![], effort: vec![], target: vec![], tip: vec![] };
    for step in 1..=1000u64 {
        traj.sample(sim.time + sim.dt, &mut q, &mut qd);
        for i in 0..n {
            sim.set_target(i, q[i], qd[i]).unwrap();
        }
        sim.step();
        let before = rec.samples();
        rec.after_step(&sim, step).unwrap();
        if rec.samples() > before {
            e.t.push(sim.time);
            e.q.push(sim.q().to_vec());
            e.qd.push(sim.qd().to_vec());
            e.effort.push(sim.arms[0].actuators.iter().map(|a| a.effort).collect());
            e.target.push(sim.arms[0].actuators.iter().map(|a| a.target).collect());
            e.tip.push(rec.tip_in_base(&sim, 0));
        }
    }
    assert!(!path.exists(), "the recording appears only when finished");
    rec.finish().unwrap();
    (sim, e)
}

fn messages(path: &std::path::Path) -> BTreeMap<String, Vec<(u64, Vec<u8>)>> {
    let bytes = std::fs::read(path).unwrap();
    let mut out: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        out.entry(m.channel.topic.clone()).or_default().push((m.log_time, m.data.to_vec()));
    }
    out
}

/// The joint names the dVRK publishes on `/PSM1/measured_js` (sawIntuitiveResearchKit's PSM; the
/// jaw goes on `/PSM1/jaw/measured_js` as `jaw`).
const DVRK_PSM_JOINTS: [&str; 6] = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"];

/// Every sample on every topic, values equal to the simulated ones, and the tip pose equal to the
/// model's FK of the recorded joints (the loops closed to 1e-7 m, so to 1e-6 m).
#[test]
fn psm_recording_holds_the_simulated_values() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let (sim, e) = record_psm(&path);
    assert_eq!(e.t.len(), 100);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left");
    let m = messages(&path);
    let topics: Vec<&str> = m.keys().map(|s| s.as_str()).collect();
    // The dVRK's CRTK layout: the jaw on its own topics.
    assert_eq!(
        topics,
        ["/PSM1/jaw/measured_js", "/PSM1/jaw/setpoint_js", "/PSM1/measured_cp", "/PSM1/measured_cv", "/PSM1/measured_js", "/PSM1/operating_state", "/PSM1/robot_description", "/PSM1/setpoint_cp", "/PSM1/setpoint_js", "/scene", "/tf"]
    );
    assert_eq!(m["/PSM1/operating_state"].len(), 1);
    // What does not change, once: the link geometry and the robot description.
    assert_eq!((m["/scene"].len(), m["/PSM1/robot_description"].len()), (1, 1));
    let model = &sim.arms[0].model;
    // One foxglove.FrameTransforms per sample, every body in it, at the sample's time.
    assert_eq!(m["/tf"].len(), 100);
    for (k, (ns, bytes)) in m["/tf"].iter().enumerate() {
        let tf = <foxglove::messages::FrameTransforms as foxglove::Decode>::decode(bytes.as_slice()).unwrap();
        assert_eq!(*ns, (e.t[k] * 1e9).round() as u64);
        let children: Vec<String> = tf.transforms.iter().map(|t| t.child_frame_id.clone()).collect();
        assert_eq!(children, model.bodies.iter().map(|b| format!("PSM1/{}", b.name)).collect::<Vec<_>>());
        assert!(tf.transforms.iter().all(|t| t.parent_frame_id == "world" && t.timestamp.unwrap().total_nanos() == *ns));
    }
    let mut unplaced = model.clone();
    unplaced.base = dvrk_kin::Pose::identity();
    let serial = dvrk_kin::compose::serial_base_transform(&unplaced).unwrap();
    for (k, t) in e.t.iter().enumerate() {
        let js = JointState::decode(&m["/PSM1/measured_js"][k].1).unwrap();
        assert_eq!(m["/PSM1/measured_js"][k].0, (t * 1e9).round() as u64);
        assert!((js.header.time() - t).abs() < 1e-9);
        assert_eq!(js.name, DVRK_PSM_JOINTS);
        let jaw = JointState::decode(&m["/PSM1/jaw/measured_js"][k].1).unwrap();
        assert_eq!(jaw.name, ["jaw"]);
        assert_eq!(m["/PSM1/jaw/measured_js"][k].0, m["/PSM1/measured_js"][k].0);
        let joined = |a: &[f64], b: &[f64]| [a, b].concat();
        assert_eq!(joined(&js.position, &jaw.position), e.q[k]);
        assert_eq!(joined(&js.velocity, &jaw.velocity), e.qd[k]);
        assert_eq!(joined(&js.effort, &jaw.effort), e.effort[k]);
        let sp = JointState::decode(&m["/PSM1/setpoint_js"][k].1).unwrap();
        let jaw_sp = JointState::decode(&m["/PSM1/jaw/setpoint_js"][k].1).unwrap();
        assert_eq!(joined(&sp.position, &jaw_sp.position), e.target[k]);
        let js = JointState { position: joined(&js.position, &jaw.position), ..js };
        let cp = PoseStamped::decode(&m["/PSM1/measured_cp"][k].1).unwrap();
        assert_eq!(cp.header.frame_id, "PSM1_base");
        let [x, y, z, w] = cp.orientation;
        let rot = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)).to_rotation_matrix();
        let pose = dvrk_kin::Pose::from_parts(Translation3::new(cp.position[0], cp.position[1], cp.position[2]), rot);
        let d = e.tip[k].inverse() * pose;
        assert!(d.translation.vector.norm() < 1e-12 && (d.rotation.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-12, "sample {k}: {d:?}");
        // Independently: FK of the recorded joints, in the serial base (the RCM frame).
        let fk = unplaced.fk(&js.position).unwrap();
        let want = serial.inverse() * fk[model.tip];
        let gap = (want.translation.vector - pose.translation.vector).norm();
        assert!(gap < 1e-6, "sample {k}: tip {gap} m from FK");
        // setpoint_cp: FK of the recorded setpoints, in the same frame.
        let scp = PoseStamped::decode(&m["/PSM1/setpoint_cp"][k].1).unwrap();
        assert_eq!(scp.header.frame_id, "PSM1_base");
        let want = serial.inverse() * unplaced.fk(&joined(&sp.position, &jaw_sp.position)).unwrap()[model.tip];
        let gap = (want.translation.vector - nalgebra::Vector3::from(scp.position)).norm();
        assert!(gap < 1e-9, "sample {k}: setpoint_cp {gap} m from FK of setpoint_js");
        // measured_cv: the tip's twist in the base's axes, J(q) qd of the unplaced model turned
        // by the serial base (an independent path: no scene placement, no body poses).
        let cv = &m["/PSM1/measured_cv"][k].1;
        let mut r = dvrk_sim::recording::cdr::CdrReader::new(cv).unwrap();
        let (_, _, frame) = (r.i32("sec").unwrap(), r.u32("nanosec").unwrap(), r.string("frame_id").unwrap());
        assert_eq!(frame, "PSM1_base");
        let twist: Vec<f64> = (0..6).map(|_| r.f64("twist").unwrap()).collect();
        let qd = joined(&js.velocity, &jaw.velocity);
        let jt = unplaced.jacobian(&js.position, model.tip).unwrap() * nalgebra::DVector::from_vec(qd);
        let rt = serial.rotation.inverse();
        let (v, w) = (rt * nalgebra::Vector3::new(jt[0], jt[1], jt[2]), rt * nalgebra::Vector3::new(jt[3], jt[4], jt[5]));
        let got = (nalgebra::Vector3::new(twist[0], twist[1], twist[2]), nalgebra::Vector3::new(twist[3], twist[4], twist[5]));
        assert!((got.0 - v).norm() < 1e-6 && (got.1 - w).norm() < 1e-6, "sample {k}: measured_cv {got:?} vs J qd {v:?} {w:?}");
    }
    // The tip moved: the sine is running (the yaw's 1 rad sine reaches 0.59 rad at 1 s).
    let yaw_last = e.q.last().unwrap()[0];
    assert!((yaw_last - 0.5878).abs() < 0.05, "{yaw_last}");
}

/// A rate the time step cannot give, and a directory that does not exist, are errors naming them.
#[test]
fn bad_rate_and_path_are_rejected() {
    let sim = Sim::new(&Scene::load("psm").unwrap(), &SimOptions::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    for rate in [0.0, -1.0, f64::NAN, 5000.0] {
        let e = Recorder::create(&sim, &RecordOptions { path: dir.path().join("x.mcap"), rate }).err().unwrap().to_string();
        assert!(e.contains("recording rate"), "{e}");
    }
    let e = Recorder::create(&sim, &RecordOptions { path: dir.path().join("no/such/x.mcap"), rate: 100.0 }).err().unwrap().to_string();
    assert!(e.contains("no/such"), "{e}");
}

const PY: &str = r#"
import json, sys
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoders
out = {"js": [], "jaw": [], "cp": [], "tf": 0, "tf_messages": 0, "frame_id": None, "topics": [], "names": None, "jaw_names": None, "state": None, "description": None}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f, decoder_factories=[ProtobufDecoders()])
    out["topics"] = sorted((c.topic, reader.get_summary().schemas[c.schema_id].name) for c in reader.get_summary().channels.values())
    for schema, channel, message, tf in reader.iter_decoded_messages(topics=["/tf"]):
        out["tf_messages"] += 1
        for t in tf.transforms:
            out["tf"] += 1
            assert t.parent_frame_id == "world" and t.child_frame_id.startswith("PSM1/")
            assert t.timestamp.seconds * 10**9 + t.timestamp.nanos == message.log_time
    f.seek(0)
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    for schema, channel, message, msg in reader.iter_decoded_messages(topics=["/PSM1/measured_js", "/PSM1/jaw/measured_js", "/PSM1/measured_cp", "/PSM1/operating_state", "/PSM1/robot_description"]):
        if channel.topic == "/PSM1/robot_description":
            out["description"] = msg.data
        elif channel.topic == "/PSM1/operating_state":
            out["state"] = [msg.state, msg.is_homed, msg.is_busy]
        elif channel.topic == "/PSM1/measured_js":
            out["names"] = list(msg.name)
            out["js"].append([msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9] + list(msg.position) + list(msg.velocity) + list(msg.effort))
        elif channel.topic == "/PSM1/jaw/measured_js":
            out["jaw_names"] = list(msg.name)
            out["jaw"].append(list(msg.position) + list(msg.velocity) + list(msg.effort))
        else:
            p = msg.pose
            out["frame_id"] = msg.header.frame_id
            out["cp"].append([p.position.x, p.position.y, p.position.z, p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w])
print(json.dumps(out))
"#;

/// Python's mcap + mcap-ros2-support decode the recording to the same numbers.
#[test]
fn python_mcap_ros2_reads_the_recording() {
    let ok = std::process::Command::new("python3").args(["-c", "import mcap_ros2, mcap_protobuf, mcap"]).output().map(|o| o.status.success()).unwrap_or(false);
    if !ok {
        println!("SKIPPED: python3 cannot import mcap_ros2 or mcap_protobuf (scripts/test.sh puts a venv with mcap, mcap-ros2-support and mcap-protobuf-support on PATH)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let (sim, e) = record_psm(&path);
    let out = std::process::Command::new("python3").args(["-c", PY, path.to_str().unwrap()]).output().unwrap();
    assert!(out.status.success(), "python: {}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let nb = sim.arms[0].model.bodies.len();
    assert_eq!((v["tf_messages"].as_u64().unwrap(), v["tf"].as_u64().unwrap() as usize), (100, 100 * nb));
    // Topic names, types, joint names and frames as the dVRK publishes them.
    assert_eq!(v["frame_id"], "PSM1_base");
    assert_eq!(v["names"], serde_json::json!(DVRK_PSM_JOINTS));
    assert_eq!(v["jaw_names"], serde_json::json!(["jaw"]));
    let js_type = "sensor_msgs/msg/JointState";
    let want = serde_json::json!([
        ["/PSM1/jaw/measured_js", js_type],
        ["/PSM1/jaw/setpoint_js", js_type],
        ["/PSM1/measured_cp", "geometry_msgs/msg/PoseStamped"],
        ["/PSM1/measured_cv", "geometry_msgs/msg/TwistStamped"],
        ["/PSM1/measured_js", js_type],
        ["/PSM1/operating_state", "crtk_msgs/msg/OperatingState"],
        ["/PSM1/robot_description", "std_msgs/msg/String"],
        ["/PSM1/setpoint_cp", "geometry_msgs/msg/PoseStamped"],
        ["/PSM1/setpoint_js", js_type],
        ["/scene", "foxglove.SceneUpdate"],
        ["/tf", "foxglove.FrameTransforms"]
    ]);
    // mcap-ros2-support decodes the description: a URDF.
    assert!(v["description"].as_str().unwrap().contains("<robot name=\"PSM1\">"), "{}", v["description"]);
    assert_eq!(v["topics"], want);
    assert_eq!(v["state"], serde_json::json!(["ENABLED", true, false]));
    let js = v["js"].as_array().unwrap();
    let jaw = v["jaw"].as_array().unwrap();
    let cp = v["cp"].as_array().unwrap();
    assert_eq!((js.len(), jaw.len(), cp.len()), (100, 100, 100));
    let n = sim.nq();
    for k in 0..100 {
        // Time, then position, velocity and effort of the six arm joints and the jaw, joined.
        let arm: Vec<f64> = js[k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let j: Vec<f64> = jaw[k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let row: Vec<f64> = [&arm[..1], &arm[1..7], &j[0..1], &arm[7..13], &j[1..2], &arm[13..19], &j[2..3]].concat();
        assert!((row[0] - e.t[k]).abs() < 1e-9);
        // serde_json's default float parser may miss the last bit of Python's shortest repr:
        // equal to 1e-15 relative, not bitwise.
        let close = |a: &[f64], b: &[f64]| a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-15 * x.abs().max(1.0));
        assert!(close(&row[1..1 + n], &e.q[k]), "q {k}: {row:?} vs {:?}", e.q[k]);
        assert!(close(&row[1 + n..1 + 2 * n], &e.qd[k]), "qd {k}");
        assert!(close(&row[1 + 2 * n..], &e.effort[k]), "effort {k}");
        let c: Vec<f64> = cp[k].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        let v = e.tip[k].translation.vector;
        assert!(close(&c[..3], &[v.x, v.y, v.z]), "tip {k}");
    }
}
