"""`dvrk teleop`: a recorded MTM driving a simulated PSM through the console's follow mode.

The MTM recordings are written here with mcap-ros2-support and rosbags (not our writers), the
run is read back with the mcap reader; the expected PSM motion is computed here from the script
(`teleop_script.py`), not by our follow mode. The binary is DVRK_BIN (default
target/release/dvrk); without it these tests skip, saying so."""

import json
import os
import subprocess

import numpy as np
import pytest

import teleop_script as ts

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DVRK = os.path.abspath(os.environ.get("DVRK_BIN", os.path.join(ROOT, "target", "release", "dvrk")))
pytestmark = pytest.mark.skipif(not os.path.isfile(DVRK), reason=f"no dvrk binary at {DVRK} (set DVRK_BIN)")


def angle_deg(a, b):
    return np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1.0) / 2.0, -1.0, 1.0)))


def read(path, topic):
    """(log time s, message) of one topic, decoded by mcap-ros2-support."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, "rb") as f:
        return [(m.log_time * 1e-9, msg) for _, _, m, msg in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=[topic])]


def pose_of(msg):
    p, o = msg.pose.position, msg.pose.orientation
    return np.array([p.x, p.y, p.z]), ts.matrix([o.x, o.y, o.z, o.w])


def dvrk(*args):
    return subprocess.run([DVRK, *map(str, args)], capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def psm_start(tmp_path_factory):
    """The simulated PSM's tip at its start in PSM1_base, as `dvrk sim` publishes setpoint_cp."""
    pytest.importorskip("mcap_ros2")
    out = tmp_path_factory.mktemp("start") / "hold.mcap"
    r = dvrk("sim", "--scene", "psm", "--trajectory", "hold", "--duration", "0.02", "--out", out, "--json")
    assert r.returncode == 0, r.stderr
    return out, pose_of(read(out, "/PSM1/setpoint_cp")[0][1])


def mtm_start():
    """A reachable MTM tip position: the MTMR model's FK at home (m, MTMR base)."""
    import dvrk_twin
    m = dvrk_twin.Model.load("mtmr")
    return m.fk(m.home)[-1][:3, 3]


def followed(rows):
    """The hand's displacement the PSM follows at each sample: increments while not clutched,
    none across a clutch release (the console re-anchors there)."""
    f = np.zeros((len(rows), 3))
    for i in range(1, len(rows)):
        moving = not rows[i][4] and not rows[i - 1][4]
        f[i] = f[i - 1] + (rows[i][1] - rows[i - 1][1] if moving else 0.0)
    return f


def test_a_recorded_mtm_drives_the_psm_scaled_in_its_frame(tmp_path, psm_start):
    _, (p0, r0) = psm_start
    rec = tmp_path / "mtm.mcap"
    rows = ts.write(rec, mtm_start(), r0)
    run = tmp_path / "run.mcap"
    r = dvrk("teleop", "--mtm", rec, "--scene", "psm", "--out", run, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    follow = out["follow"]
    assert out["mtm"]["arm"] == "MTMR" and out["mtm"]["samples"] == len(rows)
    assert out["mtm"]["topics"] == {"pose": "/MTMR/measured_cp", "gripper": "/MTMR/gripper/measured_js", "clutch": "/footpedals/clutch"}
    assert follow["following_from"] == 0.0 and follow["clutch_presses"] == 1 and follow["ik_misses"] == 0
    assert follow["clutched_s"] == pytest.approx(2.0, abs=0.01)

    # Commanded (setpoint_cp): every sample, 0.2 x the followed hand motion, the hand's orientation.
    f = followed(rows)
    sp = read(run, "/PSM1/setpoint_cp")
    t_first = sp[0][0] - 0.01  # the recorder's first sample is after the first 10 ms
    worst_p, worst_r = 0.0, 0.0
    for t, msg in sp:
        i = int(round((t - t_first) * ts.RATE))
        if i >= len(rows):
            break
        p, rm = pose_of(msg)
        worst_p = max(worst_p, np.linalg.norm((p - p0) - 0.2 * f[i]))
        worst_r = max(worst_r, angle_deg(rm, rows[i][2]))
    print(f"setpoint_cp: worst position {worst_p * 1e3:.4f} mm, orientation {worst_r:.4f} deg over {len(sp)} samples")
    assert worst_p < 0.5e-3 and worst_r < 1.0

    # Measured (measured_cp) at the end of each window: the PID's gravity sag (the scene's Table 8
    # gains, no gravity compensation) changes with the pose by up to 0.6 mm, so from the settled
    # start within 1 mm and 1 deg; nothing moves while clutched.
    ms = read(run, "/PSM1/measured_cp")
    times = np.array([t - t_first for t, _ in ms])
    ends = np.cumsum([w[1] for w in ts.SCRIPT])
    at = lambda te: pose_of(ms[int(np.argmin(abs(times - te)))][1])
    (ps, rs) = at(ends[0])
    for (name, *_), te in zip(ts.SCRIPT, ends):
        i = min(int(round(te * ts.RATE)) - 1, len(rows) - 1)
        p, rm = at(te)
        assert np.linalg.norm((p - ps) - 0.2 * (f[i] - f[int(round(ends[0] * ts.RATE)) - 1])) < 1e-3, name
        assert angle_deg(rm, rows[i][2] @ rows[0][2].T @ rs) < 1.0, name
    names = [w[0] for w in ts.SCRIPT]
    a, b = ends[names.index("hold 2")], ends[names.index("clutch up")]
    clutched = np.array([pose_of(m)[0] for (t, m), x in zip(ms, times) if a <= x <= b])
    assert np.ptp(clutched, axis=0).max() < 0.05e-3

    # The jaw: opened by the gripper (0.8 rad x 4/3), closed with it.
    jaw = read(run, "/PSM1/jaw/setpoint_js")
    assert max(m.position[0] for _, m in jaw) == pytest.approx(ts.OPEN * 4 / 3, abs=1e-9)
    assert abs(jaw[-1][1].position[0]) < 1e-9
    assert abs(read(run, "/PSM1/jaw/measured_js")[-1][1].position[0]) < 0.02


def test_a_ros1_bag_with_transform_stamped_poses_reads_the_same(tmp_path, psm_start):
    """The same motion as a ROS 1 bag written by rosbags, measured_cp as TransformStamped (later
    dVRK releases), the 1.x clutch topic: the same follow report."""
    rosbags = pytest.importorskip("rosbags")
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore
    _, (p0, r0) = psm_start
    store = get_typestore(Stores.ROS1_NOETIC)
    T = store.types
    Header, Time = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    rows = ts.samples(mtm_start(), r0)
    bag = tmp_path / "mtm.bag"
    with Writer(bag) as w:
        cp = w.add_connection("/MTMR/measured_cp", "geometry_msgs/msg/TransformStamped", typestore=store)
        gr = w.add_connection("/MTMR/gripper/measured_js", "sensor_msgs/msg/JointState", typestore=store)
        cl = w.add_connection("/dvrk/footpedals/clutch", "sensor_msgs/msg/Joy", typestore=store)
        pressed = None
        for t, p, r, g, clutch, _ in rows:
            ns = int(round((1_700_000_000.0 + t) * 1e9))
            h = Header(seq=0, stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="MTMR_base")
            x, y, z, wq = ts.quat(r)
            msg = T["geometry_msgs/msg/TransformStamped"](header=h, child_frame_id="MTMR", transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]), rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=wq)))
            w.write(cp, ns, store.serialize_ros1(msg, "geometry_msgs/msg/TransformStamped"))
            js = T["sensor_msgs/msg/JointState"](header=h, name=["gripper"], position=np.array([g]), velocity=np.array([], dtype=float), effort=np.array([], dtype=float))
            w.write(gr, ns, store.serialize_ros1(js, "sensor_msgs/msg/JointState"))
            if clutch != pressed:
                joy = T["sensor_msgs/msg/Joy"](header=h, axes=np.array([], dtype=np.float32), buttons=np.array([1 if clutch else 0], dtype=np.int32))
                w.write(cl, ns, store.serialize_ros1(joy, "sensor_msgs/msg/Joy"))
                pressed = clutch
    r = dvrk("teleop", "--mtm", bag, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["mtm"]["topics"]["clutch"] == "/dvrk/footpedals/clutch"
    assert out["mtm"]["samples"] == len(rows)
    f = out["follow"]
    assert f["following_from"] == 0.0 and f["clutch_presses"] == 1 and f["ik_misses"] == 0
    # The tip's commanded path: the square's four 1 cm sides (0.2 x 5 cm).
    assert f["tip_path_m"] == pytest.approx(0.04, abs=1e-4)


def one_error_line(r, *fragments):
    assert r.returncode == 1, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for frag in fragments:
        assert frag in lines[0], lines[0]
    return lines[0]


def test_bad_mtm_recordings_get_one_clear_line(tmp_path, psm_start):
    hold, (p0, r0) = psm_start
    # A PSM's recording is not an MTM's: the line lists what it holds.
    print(one_error_line(dvrk("teleop", "--mtm", hold), "no MTM's pose", "/PSM1/measured_cp"))
    # The wrong arm: the line names the one there.
    rec = tmp_path / "mtmr.mcap"
    ts.write(rec, mtm_start(), r0)
    print(one_error_line(dvrk("teleop", "--mtm", rec, "--arm", "MTML"), "no pose of MTML", "--arm MTMR"))
    # A start 30 deg off the PSM's orientation: refused as the console does, with the way out.
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.5236), -np.sin(0.5236)], [0.0, np.sin(0.5236), np.cos(0.5236)]])
    off = tmp_path / "misaligned.mcap"
    ts.write(off, mtm_start(), r0 @ tilt)
    print(one_error_line(dvrk("teleop", "--mtm", off), "never comes within 5 deg", "30.0 deg", "--align offset"))
    r = dvrk("teleop", "--mtm", off, "--align", "offset", "--json")
    assert r.returncode == 0, r.stderr
    f = json.loads(r.stdout)["follow"]
    assert f["misalignment_at_start_deg"] == pytest.approx(30.0, abs=0.01) and f["following_from"] == 0.0
    # No file, and an output over the input.
    one_error_line(dvrk("teleop", "--mtm", tmp_path / "none.mcap"), "--mtm")
    one_error_line(dvrk("teleop", "--mtm", rec, "--out", rec), "--out")
    one_error_line(dvrk("teleop", "--mtm", rec, "--realtime", "0"), "--realtime 0")
    one_error_line(dvrk("teleop", "--mtm", rec, "--scale", "0"), "--scale 0")
