"""Independent writers for the dVRK-layout tests (crates/dvrk-calib/tests/calib/dvrk_layout.rs).

usage: dvrk_layouts.py WPI_CSV OUTDIR SECONDS

From a WPI recording (no header; q, qd, tau of 7 channels at 200 Hz, channels 5..7 in the tool's
actuator space) the first SECONDS are taken to joint space with the coupling the recording's
README gives, and written with other people's code:
- one_topic.mcap (mcap-ros2-support): all 7 joints on /PSM1/measured_js and /PSM1/setpoint_js;
- dvrk.mcap: the dVRK's layout, 6 arm joints on /PSM1/measured_js, the jaw on
  /PSM1/jaw/measured_js, likewise setpoint_js;
- dvrk.bag, dvrk_bz2.bag, dvrk_lz4.bag (rosbags): dvrk.mcap's content as ROS 1 bags;
- jaw_only.bag: the jaw's topics without the arm's (a damaged recording);
- pivot.mcap and pivot_lz4.bag: a marker turning about a fixed point as PoseStamped on
  /vrpn/end/pose (the pivot calibration's input); pivot_tf.bag: the same poses as the TF child
  frame `end` on /tf (tf2_msgs/TFMessage, bz2 chunks).
"""
import math
import sys
from pathlib import Path

import numpy as np
from mcap_ros2.writer import Writer as Ros2Writer
from rosbags.rosbag1 import Writer as BagWriter
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

ARM = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"]
# Tool actuators 5..7 -> joints (the WPI README's M).
M = np.array([[1.0186, 0, 0], [-0.8306, 0.6089, 0.6089], [0, -1.2177, 1.2177]])
T0_NS = 1_700_000_000_000_000_000

SEP = "=" * 80 + "\n"
HEADER = SEP + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + SEP + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
JS = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + HEADER
POSE = ("std_msgs/Header header\nPose pose\n" + HEADER + SEP + "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n"
        + SEP + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n")


def joint_space(path, seconds):
    rows = np.loadtxt(path, delimiter=",")[: int(seconds * 200)]
    q, qd, tau = rows[:, 0:7].copy(), rows[:, 7:14].copy(), rows[:, 14:21].copy()
    q[:, 4:7] = q[:, 4:7] @ M.T
    qd[:, 4:7] = qd[:, 4:7] @ M.T
    tau[:, 4:7] = tau[:, 4:7] @ np.linalg.inv(M)
    return q, qd, tau


def stamp_ns(i):
    return T0_NS + i * 5_000_000


def messages(q, qd, tau, layout):
    """(topic, stamp ns, names, position, velocity, effort) in time order."""
    for i in range(len(q)):
        ns = stamp_ns(i)
        if layout == "one":
            yield "/PSM1/setpoint_js", ns, ARM + ["jaw"], q[i], [], []
            yield "/PSM1/measured_js", ns, ARM + ["jaw"], q[i], qd[i], tau[i]
        else:
            yield "/PSM1/setpoint_js", ns, ARM, q[i, :6], [], []
            yield "/PSM1/jaw/setpoint_js", ns, ["jaw"], q[i, 6:], [], []
            yield "/PSM1/measured_js", ns, ARM, q[i, :6], qd[i, :6], tau[i, :6]
            yield "/PSM1/jaw/measured_js", ns, ["jaw"], q[i, 6:], qd[i, 6:], tau[i, 6:]


def write_mcap(path, q, qd, tau, layout):
    with open(path, "wb") as f:
        w = Ros2Writer(output=f)
        schema = w.register_msgdef("sensor_msgs/msg/JointState", JS)
        for seq, (topic, ns, names, p, v, e) in enumerate(messages(q, qd, tau, layout)):
            header = {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": ""}
            msg = {"header": header, "name": names, "position": [float(x) for x in p], "velocity": [float(x) for x in v], "effort": [float(x) for x in e]}
            w.write_message(topic, schema, msg, log_time=ns, publish_time=ns, sequence=seq)
        w.finish()


def write_bag(path, items, compression=None):
    """items: (topic, msgtype, stamp ns, message object) in time order."""
    path.unlink(missing_ok=True)
    writer = BagWriter(path)
    if compression:
        writer.set_compression(compression)
    with writer:
        conns = {}
        for topic, msgtype, ns, msg in items:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=TS)
            writer.write(conns[topic], ns, TS.serialize_ros1(msg, msgtype))


TS = get_typestore(Stores.ROS1_NOETIC)
# tf2_msgs is not in the Noetic store's defaults: its one-line definition, registered.
TS.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))


def ros1_header(ns, frame=""):
    Header, Time = TS.types["std_msgs/msg/Header"], TS.types["builtin_interfaces/msg/Time"]
    return Header(seq=0, stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id=frame)


def joint_items(q, qd, tau):
    JointState = TS.types["sensor_msgs/msg/JointState"]
    for topic, ns, names, p, v, e in messages(q, qd, tau, "dvrk"):
        arr = lambda x: np.asarray(x, dtype=np.float64)
        yield topic, "sensor_msgs/msg/JointState", ns, JointState(header=ros1_header(ns), name=list(names), position=arr(p), velocity=arr(v), effort=arr(e))


def pivot_poses():
    """A marker frame that turns about two axes while its point TIP stays at PIVOT."""
    pivot, tip = np.array([0.3, -0.2, 1.1]), np.array([0.02, -0.1, 0.05])
    for i in range(400):
        t = i / 200.0 * 2 * math.pi
        a, b = 0.5 * math.sin(t), 0.4 * math.cos(3 * t)
        rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
        r = rz @ rx
        # Quaternion (x, y, z, w) of r.
        w = math.sqrt(max(0.0, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
        quat = ((r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w), w)
        yield stamp_ns(i), pivot - r @ tip, quat


def main():
    wpi, out, seconds = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
    q, qd, tau = joint_space(wpi, seconds)
    write_mcap(out / "one_topic.mcap", q, qd, tau, "one")
    write_mcap(out / "dvrk.mcap", q, qd, tau, "dvrk")
    items = list(joint_items(q, qd, tau))
    write_bag(out / "dvrk.bag", items)
    write_bag(out / "dvrk_bz2.bag", items, BagWriter.CompressionFormat.BZ2)
    write_bag(out / "dvrk_lz4.bag", items, BagWriter.CompressionFormat.LZ4)
    write_bag(out / "jaw_only.bag", [i for i in items if "/jaw/" in i[0]])

    poses = list(pivot_poses())
    with open(out / "pivot.mcap", "wb") as f:
        w = Ros2Writer(output=f)
        schema = w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE)
        for seq, (ns, p, quat) in enumerate(poses):
            header = {"stamp": {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}, "frame_id": "optitrack"}
            msg = {"header": header, "pose": {"position": dict(zip("xyz", map(float, p))), "orientation": dict(zip("xyzw", quat))}}
            w.write_message("/vrpn/end/pose", schema, msg, log_time=ns, publish_time=ns, sequence=seq)
        w.finish()
    PoseStamped, Pose = TS.types["geometry_msgs/msg/PoseStamped"], TS.types["geometry_msgs/msg/Pose"]
    Point, Quaternion = TS.types["geometry_msgs/msg/Point"], TS.types["geometry_msgs/msg/Quaternion"]
    pose_items = [
        ("/vrpn/end/pose", "geometry_msgs/msg/PoseStamped", ns, PoseStamped(header=ros1_header(ns, "optitrack"), pose=Pose(position=Point(*map(float, p)), orientation=Quaternion(*quat))))
        for ns, p, quat in poses
    ]
    write_bag(out / "pivot_lz4.bag", pose_items, BagWriter.CompressionFormat.LZ4)
    TFMessage, TransformStamped = TS.types["tf2_msgs/msg/TFMessage"], TS.types["geometry_msgs/msg/TransformStamped"]
    Transform, Vector3 = TS.types["geometry_msgs/msg/Transform"], TS.types["geometry_msgs/msg/Vector3"]
    tf_items = [
        ("/tf", "tf2_msgs/msg/TFMessage", ns, TFMessage(transforms=[TransformStamped(header=ros1_header(ns, "optitrack"), child_frame_id="end", transform=Transform(translation=Vector3(*map(float, p)), rotation=Quaternion(*quat)))]))
        for ns, p, quat in poses
    ]
    write_bag(out / "pivot_tf.bag", tf_items, BagWriter.CompressionFormat.BZ2)


if __name__ == "__main__":
    main()
