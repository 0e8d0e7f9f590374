//! MCAP files written by other tools: the Python `mcap` and `mcap-ros2-support` packages write
//! ROS 2 PoseStamped, TFMessage and JointState (zstd chunks, their own CDR encoder and message
//! definitions), Foxglove JSON, and Foxglove protobuf (`foxglove-schemas-protobuf`'s classes,
//! `mcap-protobuf-support`'s writer); our reader must give back their numbers. And the reverse:
//! Python decodes the MCAP our synthetic tracker writes.
//!
//! Skipped, with a message, where Python lacks those packages (`scripts/test.sh` installs them).

use dvrk_sim::recording::{McapLayout, McapOptions};
use dvrk_calib::{pivot_calibration, read_recording, PivotOptions};
use nalgebra::Vector3;
use std::path::Path;
use std::process::Command;

fn python_ready() -> bool {
    let ok = Command::new("python3").args(["-c", "import mcap, mcap_ros2, mcap_protobuf, foxglove_schemas_protobuf"]).output().map(|o| o.status.success()).unwrap_or(false);
    if !ok {
        eprintln!("skipped: python3 with mcap, mcap-ros2-support, mcap-protobuf-support and foxglove-schemas-protobuf is not available (scripts/test.sh installs them)");
    }
    ok
}

fn run_python(script: &str, args: &[&Path]) -> String {
    let out = Command::new("python3").arg("-c").arg(script).args(args).output().expect("python3 runs");
    assert!(out.status.success(), "python failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8")
}

/// Writes ros2.mcap (PoseStamped on /vrpn/end/pose, TFMessage on /tf with two bodies, JointState
/// on /PSM1/measured_js), foxglove.mcap (foxglove.PoseInFrame in JSON) and protobuf.mcap
/// (foxglove.PoseInFrame on /end and foxglove.FrameTransforms on /tf, two children, protobuf): a
/// marker frame that turns about two axes while its point TIP stays at PIVOT.
const WRITER: &str = r#"
import json, math, sys
from mcap.writer import Writer as McapWriter
from mcap_ros2.writer import Writer as Ros2Writer

PIVOT = (0.3, -0.2, 1.1)
TIP = (0.02, -0.1, 0.05)

def quat_mul(a, b):
    ax, ay, az, aw = a; bx, by, bz, bw = b
    return (aw*bx + ax*bw + ay*bz - az*by, aw*by - ax*bz + ay*bw + az*bx, aw*bz + ax*by - ay*bx + az*bw, aw*bw - ax*bx - ay*by - az*bz)

def axis_angle(axis, angle):
    n = math.sqrt(sum(c*c for c in axis)); s = math.sin(angle/2)
    return (axis[0]/n*s, axis[1]/n*s, axis[2]/n*s, math.cos(angle/2))

def rotate(q, v):
    x, y, z, w = q
    r = [[1-2*(y*y+z*z), 2*(x*y-z*w), 2*(x*z+y*w)], [2*(x*y+z*w), 1-2*(x*x+z*z), 2*(y*z-x*w)], [2*(x*z-y*w), 2*(y*z+x*w), 1-2*(x*x+y*y)]]
    return [sum(r[i][j]*v[j] for j in range(3)) for i in range(3)]

def pose(i):
    t = i / 200.0 * 2 * math.pi
    q = quat_mul(axis_angle((0, 0, 1), 0.5*math.sin(t)), axis_angle((1, 0.2, 0), 0.4*math.cos(3*t)))
    r = rotate(q, TIP)
    return [PIVOT[k] - r[k] for k in range(3)], q

TIME = "int32 sec\nuint32 nanosec\n"
SEP = "=" * 80 + "\n"
HEADER = SEP + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + SEP + "MSG: builtin_interfaces/Time\n" + TIME
QUAT = SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
POSE = ("std_msgs/Header header\nPose pose\n" + HEADER + SEP + "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n"
        + SEP + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + QUAT)
TF = ("geometry_msgs/TransformStamped[] transforms\n" + SEP + "MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\nTransform transform\n"
      + HEADER + SEP + "MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n" + SEP + "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n" + QUAT)
JS = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + HEADER

def stamp(i):
    ns = 1_700_000_000_000_000_000 + i * 5_000_000
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, ns

with open(sys.argv[1], "wb") as f:
    w = Ros2Writer(output=f)
    sp, st, sj = w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE), w.register_msgdef("tf2_msgs/msg/TFMessage", TF), w.register_msgdef("sensor_msgs/msg/JointState", JS)
    for i in range(200):
        s, ns = stamp(i)
        p, q = pose(i)
        header = {"stamp": s, "frame_id": "optitrack"}
        w.write_message("/vrpn/end/pose", sp, {"header": header, "pose": {"position": dict(zip("xyz", p)), "orientation": dict(zip("xyzw", q))}}, log_time=ns, publish_time=ns, sequence=i)
        tfs = [{"header": header, "child_frame_id": c, "transform": {"translation": dict(zip("xyz", [p[0] + d, p[1], p[2]])), "rotation": dict(zip("xyzw", q))}} for c, d in (("end_tf", 0.0), ("shifted", 0.25))]
        w.write_message("/tf", st, {"transforms": tfs}, log_time=ns, publish_time=ns, sequence=i)
        w.write_message("/PSM1/measured_js", sj, {"header": header, "name": ["outer_yaw", "outer_pitch"], "position": [0.001 * i, -0.002 * i], "velocity": [], "effort": []}, log_time=ns, publish_time=ns, sequence=i)
    w.finish()

with open(sys.argv[2], "wb") as f:
    w = McapWriter(f)
    w.start(profile="", library="python-test")
    sid = w.register_schema(name="foxglove.PoseInFrame", encoding="jsonschema", data=b'{"type":"object"}')
    cid = w.register_channel(topic="/end", message_encoding="json", schema_id=sid)
    for i in range(200):
        s, ns = stamp(i)
        p, q = pose(i)
        msg = {"timestamp": {"sec": s["sec"], "nsec": s["nanosec"]}, "frame_id": "optitrack", "pose": {"position": dict(zip("xyz", p)), "orientation": dict(zip("xyzw", q))}}
        w.add_message(channel_id=cid, log_time=ns, data=json.dumps(msg).encode(), publish_time=ns)
    w.finish()

from mcap_protobuf.writer import Writer as ProtobufWriter
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
with open(sys.argv[3], "wb") as f:
    w = ProtobufWriter(f)
    for i in range(200):
        s, ns = stamp(i)
        p, q = pose(i)
        m = PoseInFrame(frame_id="optitrack")
        m.timestamp.FromNanoseconds(ns)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = p
        m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z, m.pose.orientation.w = q
        w.write_message(topic="/end", message=m, log_time=ns, publish_time=ns)
        tfs = FrameTransforms()
        for c, d in (("end_tf", 0.0), ("shifted", 0.25)):
            t = tfs.transforms.add(parent_frame_id="optitrack", child_frame_id=c)
            t.timestamp.FromNanoseconds(ns)
            t.translation.x, t.translation.y, t.translation.z = p[0] + d, p[1], p[2]
            t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w = q
        w.write_message(topic="/tf", message=tfs, log_time=ns, publish_time=ns)
    w.finish()
"#;

#[test]
fn python_written_ros2_and_foxglove_mcap_read_back() {
    if !python_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (ros2, fox, proto) = (dir.path().join("ros2.mcap"), dir.path().join("foxglove.mcap"), dir.path().join("protobuf.mcap"));
    run_python(WRITER, &[&ros2, &fox, &proto]);
    let pivot = Vector3::new(0.3, -0.2, 1.1);
    let tip = Vector3::new(0.02, -0.1, 0.05);
    let rec = read_recording(&ros2, &McapOptions::default()).unwrap();
    assert!(rec.warnings.is_empty(), "{:?}", rec.warnings);
    for name in ["/vrpn/end/pose", "end_tf"] {
        let b = rec.body(name).unwrap();
        assert_eq!((b.len(), b.frame_id.as_str()), (200, "optitrack"), "{name}");
        assert!((b.t[1] - b.t[0] - 0.005).abs() < 1e-6);
        let f = pivot_calibration(&b.poses, &PivotOptions::default()).unwrap();
        eprintln!("{name}: pivot {:.2e} m from Python's, tip {:.2e} m", (f.pivot - pivot).norm(), (f.tip - tip).norm());
        assert!((f.pivot - pivot).norm() < 1e-9 && (f.tip - tip).norm() < 1e-9, "{name}");
    }
    // The second TF child is 0.25 m along x of the first at every sample.
    let (a, b) = (rec.body("end_tf").unwrap(), rec.body("shifted").unwrap());
    assert!(a.poses.iter().zip(&b.poses).all(|(p, q)| ((q.translation.vector - p.translation.vector) - Vector3::new(0.25, 0.0, 0.0)).norm() < 1e-15));
    let j = rec.joints.as_ref().unwrap();
    assert_eq!((j.source.as_str(), j.names.len(), j.q.len()), ("/PSM1/measured_js", 2, 200));
    assert_eq!(j.q[100], vec![0.1, -0.2]);
    let rec = read_recording(&fox, &McapOptions::default()).unwrap();
    let f = pivot_calibration(&rec.body("/end").unwrap().poses, &PivotOptions::default()).unwrap();
    assert!((f.pivot - pivot).norm() < 1e-9);
    // Foxglove's protobuf schemas, as Foxglove's own Python classes write them.
    let rec = read_recording(&proto, &McapOptions::default()).unwrap();
    assert!(rec.warnings.is_empty(), "{:?}", rec.warnings);
    for name in ["/end", "end_tf"] {
        let b = rec.body(name).unwrap();
        assert_eq!((b.len(), b.frame_id.as_str()), (200, "optitrack"), "{name}");
        assert!((b.t[1] - b.t[0] - 0.005).abs() < 1e-6, "{name}");
        let f = pivot_calibration(&b.poses, &PivotOptions::default()).unwrap();
        assert!((f.pivot - pivot).norm() < 1e-9 && (f.tip - tip).norm() < 1e-9, "{name}");
    }
    let (a, b) = (rec.body("end_tf").unwrap(), rec.body("shifted").unwrap());
    assert!(a.poses.iter().zip(&b.poses).all(|(p, q)| ((q.translation.vector - p.translation.vector) - Vector3::new(0.25, 0.0, 0.0)).norm() < 1e-15));
}

/// Decodes our PoseStamped and JointState with mcap_ros2 and prints count, first position, names.
const READER: &str = r#"
import sys
from mcap_ros2.reader import read_ros2_messages
n, first, names = 0, None, None
for m in read_ros2_messages(sys.argv[1]):
    if m.channel.topic == "/mocap/end/pose":
        n += 1
        if first is None:
            p = m.ros_msg.pose.position
            first = (p.x, p.y, p.z, m.ros_msg.header.stamp.sec, m.ros_msg.header.stamp.nanosec, m.ros_msg.header.frame_id)
    if m.channel.topic == "/PSM1/measured_js" and names is None:
        names = ",".join(m.ros_msg.name)
print(n)
print(repr(first[0]), repr(first[1]), repr(first[2]), first[3], first[4], first[5])
print(names)
"#;

#[test]
fn python_reads_the_synthetic_trackers_mcap() {
    if !python_ready() {
        return;
    }
    let s = crate::util::scenario(&crate::util::psm(), dvrk_calib::mocap::synth::SynthMotion::Q1Q2Sweep, 1e-4, 2.0, 0.02);
    let rec = s.record(4);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("synth.mcap");
    std::fs::write(&path, dvrk_sim::recording::write_mcap_poses(&rec, McapLayout::PoseStamped, "/PSM1/measured_js").unwrap()).unwrap();
    let out = run_python(READER, &[&path]);
    let lines: Vec<&str> = out.lines().collect();
    let end = rec.body("end").unwrap();
    assert_eq!(lines[0].parse::<usize>().unwrap(), end.len());
    let v: Vec<&str> = lines[1].split(' ').collect();
    let p = end.poses[0].translation.vector;
    let xyz: Vec<f64> = v[..3].iter().map(|x| x.parse().unwrap()).collect();
    assert_eq!(xyz, vec![p.x, p.y, p.z], "bit-exact through CDR");
    assert_eq!((v[3], v[5]), ("0", "tracker"));
    assert_eq!(v[4].parse::<u32>().unwrap(), (end.t[0] * 1e9).round() as u32);
    assert!(lines[2].starts_with("outer_yaw,outer_pitch,outer_insertion"), "{}", lines[2]);
}

/// A JointState written in JSON (Python's `mcap`, a Foxglove-style channel) is refused naming its
/// encoding: the message read "carries sensor_msgs/msg/JointState; expected
/// sensor_msgs/msg/JointState" (issue 63 item 6).
#[test]
fn a_joint_state_in_json_is_refused_naming_its_encoding() {
    if !python_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("json-joints.mcap");
    run_python(
        r#"
import json, sys
from mcap.writer import Writer
with open(sys.argv[1], "wb") as f:
    w = Writer(f)
    w.start(profile="", library="python-test")
    sid = w.register_schema(name="sensor_msgs/msg/JointState", encoding="jsonschema", data=b'{"type":"object"}')
    cid = w.register_channel(topic="/PSM1/measured_js", message_encoding="json", schema_id=sid)
    for i in range(10):
        msg = {"name": ["outer_yaw"], "position": [0.001 * i], "velocity": [], "effort": []}
        w.add_message(channel_id=cid, log_time=i * 1000000, data=json.dumps(msg).encode(), publish_time=i * 1000000)
    w.finish()
"#,
        &[&path],
    );
    let e = dvrk_sim::recording::read_arm(&path, "PSM1", &["measured_js"]).unwrap_err().to_string();
    assert!(e.contains("json-joints.mcap") && e.contains("carries sensor_msgs/msg/JointState (json); expected sensor_msgs/msg/JointState (cdr or ros1)"), "{e}");
}
