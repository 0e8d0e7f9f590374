"""dvrk_twin.pivot / axis / read_recording: closed-form recoveries and bad input."""

import numpy as np
import pytest

import dvrk_twin


def rot(axis, angle):
    """Rotation matrix about a unit axis (Rodrigues)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def pose(r, p):
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = p
    return t


def pivot_poses(tip, post, n=200, seed=3):
    """Marker poses rotating about a fixed point: p_i = post - R_i tip (paper eq. 3)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        r = rot([1, 0, 0], rng.uniform(-0.6, 0.6)) @ rot([0, 1, 0], rng.uniform(-0.6, 0.6))
        out.append(pose(r, post - r @ tip))
    return np.array(out)


def test_pivot_recovers_tip_and_pivot_with_every_method():
    tip, post = np.array([0.01, -0.02, 0.15]), np.array([0.3, -0.516, 0.02])
    poses = pivot_poses(tip, post)
    for method in ["one-step", "two-step", "sphere"]:
        fit = dvrk_twin.pivot(poses, method=method)
        assert fit["method"] == method
        assert np.linalg.norm(np.array(fit["pivot"]) - post) < 1e-9
        assert np.linalg.norm(np.array(fit["tip"]) - tip) < 1e-9
        assert fit["samples"] == 200 and fit["rms"] < 1e-9


def test_pivot_uncertainty_follows_the_noise():
    tip, post = np.array([0.0, 0.0, 0.2]), np.array([0.1, 0.2, 0.3])
    poses = pivot_poses(tip, post, n=500)
    rng = np.random.default_rng(1)
    poses[:, :3, 3] += rng.normal(0.0, 1e-4, (500, 3))
    fit = dvrk_twin.pivot(poses)
    err = np.linalg.norm(np.array(fit["pivot"]) - post)
    std = np.linalg.norm(fit["pivot_std"])
    assert 0.0 < std < 5e-5 and err < 5 * std
    assert abs(fit["rms"] - 1e-4) < 2e-5


def test_axis_recovers_a_hinge():
    rng = np.random.default_rng(7)
    g, h = np.array([0.05, -0.02, 0.1]), np.array([0.2, 0.3, 0.93])
    h = h / np.linalg.norm(h)
    ref, mov = [], []
    for _ in range(150):
        a = pose(rot(rng.normal(size=3), rng.uniform(0, 0.5)), rng.normal(size=3) * 0.1)
        th = rng.uniform(-1.0, 1.0)
        hinge = pose(rot(h, th), g - rot(h, th) @ g)  # rotation about the line (g, h)
        ref.append(a)
        mov.append(a @ hinge @ pose(np.eye(3), [0.1, 0.0, 0.0]))
    fit = dvrk_twin.axis(np.array(ref), np.array(mov))
    d = np.array(fit["direction"])
    assert abs(abs(d @ h) - 1.0) < 1e-9
    p = np.array(fit["point"])
    off = (p - g) - h * ((p - g) @ h)  # distance of the fitted point from the true line
    assert np.linalg.norm(off) < 1e-9


def test_read_recording_plain_csv(tmp_path):
    path = tmp_path / "rec.csv"
    rows = ["time,end.x,end.y,end.z,end.qx,end.qy,end.qz,end.qw,q1,q2"]
    for i in range(20):
        rows.append(f"{i / 120},{0.1 * i},0.2,0.3,0,0,0,1,{0.01 * i},-0.1")
    path.write_text("\n".join(rows) + "\n")
    rec = dvrk_twin.read_recording(path)
    end = rec["bodies"]["end"]
    assert end["poses"].shape == (20, 4, 4) and end["t"].shape == (20,)
    assert np.allclose(end["poses"][5, :3, 3], [0.5, 0.2, 0.3])
    assert rec["joints"]["q"].shape == (20, 2)


def test_bad_calibration_input():
    with pytest.raises(dvrk_twin.InputError, match=r"\(N, 4, 4\)"):
        dvrk_twin.pivot(np.zeros((10, 3, 3)))
    poses = pivot_poses(np.zeros(3), np.ones(3), n=20)
    poses[4, 0, 3] = np.nan
    with pytest.raises(ValueError, match=r"poses\[4\]"):
        dvrk_twin.pivot(poses)
    with pytest.raises(dvrk_twin.DvrkError, match="at least"):
        dvrk_twin.pivot(pivot_poses(np.zeros(3), np.ones(3), n=3))
    still = np.array([np.eye(4)] * 50)
    with pytest.raises(dvrk_twin.DvrkError):
        dvrk_twin.pivot(still)
    with pytest.raises(ValueError, match="method"):
        dvrk_twin.pivot(poses, method="magic")
    with pytest.raises(FileNotFoundError):
        dvrk_twin.read_recording("/nonexistent/rec.mcap")


def test_read_recording_takes_the_dvrk_layout(tmp_path):
    """A PSM as the dVRK publishes it, written by mcap-ros2-support: six arm joints on
    /PSM1/measured_js at 200 Hz, the jaw on /PSM1/jaw/measured_js at 100 Hz. The jaw comes back
    merged onto the arm's time stamps, interpolated."""
    mcap_ros2_writer = pytest.importorskip("mcap_ros2.writer")
    sep = "=" * 80 + "\n"
    header = sep + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + sep + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
    js = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + header
    arm = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw"]
    path = tmp_path / "dvrk.mcap"
    t0 = 1_700_000_000 * 10**9
    with open(path, "wb") as f:
        w = mcap_ros2_writer.Writer(output=f)
        schema = w.register_msgdef("sensor_msgs/msg/JointState", js)
        for i in range(201):
            ns = t0 + i * 5_000_000
            stamp = {"sec": ns // 10**9, "nanosec": ns % 10**9}
            q = [0.01 * i, -0.1, 0.12, 0.0, 0.0, 0.0]
            w.write_message("/PSM1/measured_js", schema, {"header": {"stamp": stamp, "frame_id": ""}, "name": arm, "position": q, "velocity": [], "effort": []}, log_time=ns, publish_time=ns)
            if i % 2 == 0:
                jaw = {"header": {"stamp": stamp, "frame_id": ""}, "name": ["jaw"], "position": [0.5 + 0.002 * i], "velocity": [], "effort": []}
                w.write_message("/PSM1/jaw/measured_js", schema, jaw, log_time=ns, publish_time=ns)
        w.finish()
    rec = dvrk_twin.read_recording(path)
    joints = rec["joints"]
    assert joints["names"] == arm + ["jaw"]
    assert joints["q"].shape == (201, 7)
    # The jaw at the arm's odd samples, between two of its own messages: interpolated.
    assert np.allclose(joints["q"][:, 6], 0.5 + 0.002 * np.arange(201), atol=1e-12)
    assert np.allclose(joints["q"][:, 0], 0.01 * np.arange(201))
