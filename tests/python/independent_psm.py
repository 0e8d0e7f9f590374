"""An independent generator of dVRK PSM recordings with one hidden effect (issue #62 item 5).

numpy only for the physics; MCAP (ROS 2 CDR) through the PyPI package `mcap-ros2-support`. It
shares no code and no model file with the project (`dvrk synth`, `dvrk_twin`, `models/`): the
PSM's serial chain up to the insertion stage (paper frame 9) and the tool roll (frame 12) is
computed here from Gondokaryono et al., Table 4, as printed (modified DH, Craig:
T = RotX(alpha) TransX(a) RotZ(theta) TransZ(d), a row's a and alpha taken from its parent),
with one convention of the dVRK's: q2 enters with the opposite sign (the dVRK's outer_pitch
tilts the insertion axis the other way; see test_independent_generator.py).

What a motion-capture user records, in the dVRK's CRTK layout:
  /PSM1/measured_js, /PSM1/setpoint_js         six arm joints (position, velocity; no effort)
  /PSM1/jaw/measured_js, /PSM1/jaw/setpoint_js the jaw
  MARKER_TOPIC (geometry_msgs/PoseStamped)      a rigid body on the link, in the tracker's frame

  python tests/python/independent_psm.py --case CASE --seed N -o out.mcap   # prints the truth (JSON)
"""

import argparse
import json
import math
import sys

import numpy as np

# ---------------------------------------------------------------- kinematics (paper, Table 4)
BETA1 = 0.2908          # rad, Table 4 as printed
INSERTION_OFFSET = 0.2881  # m, frame 9: d = q3 - 0.2881
TOOL_LENGTH = 0.4162    # m, frame 12: d
Q2_SIGN = -1.0          # the dVRK's outer_pitch is the paper's -q2
PI2 = math.pi / 2

# frame: (parent, a, alpha, d(q), theta(q)); q = the dVRK joints (yaw, pitch, insertion, roll, ...)
TABLE4 = {
    1: (0, 0.0, PI2, lambda q: 0.0 * q[0], lambda q: q[0] + PI2),
    2: (1, 0.0, PI2, lambda q: 0.0 * q[0], lambda q: PI2 + 0.0 * q[0]),
    3: (2, -0.0296, 0.0, lambda q: 0.0 * q[0], lambda q: Q2_SIGN * q[1] - BETA1 - PI2),
    6: (3, 0.150, 0.0, lambda q: 0.0 * q[0], lambda q: -Q2_SIGN * q[1] + BETA1 + PI2),
    8: (6, 0.516, 0.0, lambda q: 0.0 * q[0], lambda q: Q2_SIGN * q[1]),
    9: (8, 0.043, -PI2, lambda q: q[2] - INSERTION_OFFSET, lambda q: PI2 + 0.0 * q[0]),
    12: (9, 0.0, 0.0, lambda q: TOOL_LENGTH + 0.0 * q[0], lambda q: q[3] - PI2),
}
FRAME_NAMES = {1: "yaw", 2: "pitch_base", 3: "pitch_back", 6: "pitch_bottom", 8: "pitch_end",
               9: "main_insertion", 12: "tool_roll"}


def mdh(a, alpha, d, theta):
    """Modified DH transforms, (N, 4, 4): RotX(alpha) TransX(a) RotZ(theta) TransZ(d)."""
    theta = np.asarray(theta, float)
    d = np.broadcast_to(np.asarray(d, float), theta.shape)
    ct, st, ca, sa = np.cos(theta), np.sin(theta), math.cos(alpha), math.sin(alpha)
    T = np.zeros(theta.shape + (4, 4))
    T[..., 0, 0], T[..., 0, 1], T[..., 0, 3] = ct, -st, a
    T[..., 1, 0], T[..., 1, 1], T[..., 1, 2], T[..., 1, 3] = st * ca, ct * ca, -sa, -sa * d
    T[..., 2, 0], T[..., 2, 1], T[..., 2, 2], T[..., 2, 3] = st * sa, ct * sa, ca, ca * d
    T[..., 3, 3] = 1.0
    return T


def fk(q, frame=9, da=None):
    """Pose of paper frame `frame` in the PSM base (frame 0) for joints q (N, >=4): (N, 4, 4).
    da: {frame: change of its DH length a (m)} (the link_length effect)."""
    q = np.atleast_2d(np.asarray(q, float)).T  # (nq, N)
    chain = []
    f = frame
    while f != 0:
        chain.append(f)
        f = TABLE4[f][0]
    T = np.broadcast_to(np.eye(4), (q.shape[1], 4, 4)).copy()
    for f in reversed(chain):
        _, a, alpha, d, theta = TABLE4[f]
        T = T @ mdh(a + (da or {}).get(f, 0.0), alpha, d(q), theta(q))
    return T


# ---------------------------------------------------------------- the recording's conventions
JOINTS = ["outer_yaw", "outer_pitch", "outer_insertion", "outer_roll",
          "outer_wrist_pitch", "outer_wrist_yaw"]
JAW = "jaw"
# dVRK limits (PSM.json, large needle driver); the motion stays well inside them.
LIMITS = np.array([[-1.588, 1.588], [-0.925, 0.925], [0.0, 0.24], [-4.538, 4.538],
                   [-1.396, 1.396], [-1.396, 1.396], [-0.698, 1.396]])
# (centre, half swing, max speed) per joint, yaw .. jaw: rad, m, rad/s, m/s
MOTION = np.array([[0.0, 0.70, 0.8], [0.0, 0.50, 0.8], [0.13, 0.07, 0.04], [0.0, 1.2, 1.5],
                   [0.0, 0.8, 1.5], [0.0, 0.8, 1.5], [0.45, 0.35, 1.0]])
# Encoder resolution (rad or m) per joint: quantised, with a little edge jitter.
RESOLUTION = np.array([2e-5, 2e-5, 2e-6, 5e-5, 5e-5, 5e-5, 5e-5])
TRACKING_LAG = 0.003    # s: the PID's motor lags the setpoint
JOINT_INDEX = {n: i for i, n in enumerate(JOINTS)}

CASES = ["none", "clock_offset_late", "clock_offset_early", "motion_play_yaw",
         "motion_play_pitch", "joint_offset", "link_length"]
# Effort cases (payload on a translating / a turning link) will join here: they need efforts on
# measured_js and the dynamics, which this generator does not compute yet.

# What a tracker on the insertion stage (frame 9) or the tool shaft (frame 12) can see of a joint
# offset: yaw turns the whole arm about the base (the tracker's unknown placement takes it),
# insertion slides both frames along their own z (the marker's placement takes it), and roll is
# frame 12's last joint (the marker's placement again) and moves nothing up to frame 9. Only the
# pitch is left.
OFFSET_JOINTS = {9: ["outer_pitch"], 12: ["outer_pitch"]}
# The DH lengths the analysis offers (`kinematic.candidates` of a `none` recording's report): none
# for a marker on frame 9 (the parallelogram's lengths would open its loops; frame 9's own `a` is
# the marker's placement), main_insertion's a (0.043) for a marker on frame 12, where the roll
# turns it.
LENGTH_FRAMES = {9: [], 12: [9]}
# The marker's link per case: frame 9 (main_insertion) as the issue asks, frame 12 (tool_roll,
# the instrument's shaft) where only there the effect can be seen.
MARKER_LINK = {"link_length": 12}


class Motion:
    """The commanded multi-sine per joint; the motor follows it TRACKING_LAG behind."""

    def __init__(self, rng):
        n = len(MOTION)
        k = 4
        self.f = rng.uniform(0.04, 0.35, (n, k))
        self.phase = rng.uniform(0, 2 * math.pi, (n, k))
        w = rng.uniform(0.3, 1.0, (n, k))
        amp = w / w.sum(1, keepdims=True) * MOTION[:, 1:2]
        speed = (amp * 2 * math.pi * self.f).sum(1)
        self.amp = amp * np.minimum(1.0, MOTION[:, 2] / speed)[:, None]
        self.centre = MOTION[:, 0] + rng.uniform(-0.2, 0.2, n) * MOTION[:, 1] * 0.3

    def command(self, t):
        """(N, 7) positions and velocities at times t (s from the start)."""
        arg = 2 * math.pi * self.f[None] * np.asarray(t)[:, None, None] + self.phase[None]
        q = self.centre + (self.amp[None] * np.sin(arg)).sum(-1)
        v = (self.amp[None] * 2 * math.pi * self.f[None] * np.cos(arg)).sum(-1)
        return q, v

    def motor(self, t):
        return self.command(np.asarray(t) - TRACKING_LAG)


def play(x, b, y0):
    """The play (backlash) operator: the output follows x with a dead band of half width b."""
    y = np.empty_like(x)
    cur = y0
    for i, xi in enumerate(x):
        if xi > cur + b:
            cur = xi - b
        elif xi < cur - b:
            cur = xi + b
        y[i] = cur
    return y


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return quat_to_matrix(q)


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(R):
    """(N, 3, 3) -> (N, 4) x, y, z, w with w >= 0."""
    R = np.asarray(R)
    tr = np.trace(R, axis1=-2, axis2=-1)
    q = np.empty(R.shape[:-2] + (4,))
    # Pick per sample the largest of w, x, y, z to divide by (stable everywhere).
    cand = np.stack([tr, R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], -1)
    k = cand.argmax(-1)
    for i in range(4):
        m = k == i
        Rm = R[m]
        if i == 0:
            s = np.sqrt(1 + tr[m]) * 2
            q[m] = np.stack([(Rm[:, 2, 1] - Rm[:, 1, 2]) / s, (Rm[:, 0, 2] - Rm[:, 2, 0]) / s,
                             (Rm[:, 1, 0] - Rm[:, 0, 1]) / s, 0.25 * s], -1)
        else:
            a, b, c = i - 1, i % 3, (i + 1) % 3
            s = np.sqrt(1 + Rm[:, a, a] - Rm[:, b, b] - Rm[:, c, c]) * 2
            v = np.empty((m.sum(), 4))
            v[:, a] = 0.25 * s
            v[:, b] = (Rm[:, b, a] + Rm[:, a, b]) / s
            v[:, c] = (Rm[:, c, a] + Rm[:, a, c]) / s
            v[:, 3] = (Rm[:, c, b] - Rm[:, b, c]) / s
            q[m] = v
    q *= np.where(q[:, 3:4] < 0, -1.0, 1.0)
    return q


def small_rotations(rng, n, sigma):
    """(n, 3, 3) rotations by vectors with per-axis standard deviation sigma (rad)."""
    v = rng.normal(0, sigma, (n, 3))
    th = np.linalg.norm(v, axis=1)
    k = v / np.maximum(th, 1e-300)[:, None]
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K -= K.transpose(0, 2, 1)
    s, c = np.sin(th)[:, None, None], np.cos(th)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * K @ K


# ---------------------------------------------------------------- one recording
def generate(case, seed, duration=60.0, js_rate=200.0, tracker_rate=100.0, marker_link=None,
             arm="PSM1", marker_topic="/vrpn_client_node/PSM1_shaft/pose",
             pos_noise=1e-4, rot_noise_deg=0.03):
    """Simulate one recording; returns (streams, truth). Times are Unix-like seconds."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; cases: {', '.join(CASES)}")
    marker_link = marker_link or MARKER_LINK.get(case, 9)
    rng = np.random.default_rng([seed, CASES.index(case)])
    motion = Motion(rng)
    t0 = 1.7e9 + float(rng.integers(0, 10**7))  # the dVRK stamps wall-clock time
    effect = None
    # The hidden effect.
    d_clock, play_b, play_joint, offset, da = 0.0, 0.0, None, np.zeros(len(JOINTS)), {}
    if case.startswith("clock_offset"):
        d_clock = rng.uniform(0.005, 0.030) * (1 if case.endswith("late") else -1)
        effect = {"name": "clock_offset", "joint": None, "link": None,
                  "parameters": {"seconds": d_clock}}
    elif case.startswith("motion_play"):
        play_joint = "outer_yaw" if case.endswith("yaw") else "outer_pitch"
        play_b = math.radians(rng.uniform(0.1, 0.3))
        effect = {"name": "motion_play", "joint": play_joint, "link": None,
                  "parameters": {"b": play_b}}
    elif case == "joint_offset":
        j = str(rng.choice(OFFSET_JOINTS[marker_link]))
        size = rng.uniform(0.5e-3, 2e-3) if j == "outer_insertion" else math.radians(rng.uniform(0.2, 1.0))
        offset[JOINT_INDEX[j]] = size * rng.choice([-1, 1])
        effect = {"name": "joint_offset", "joint": j, "link": None,
                  "parameters": {"offset": float(offset[JOINT_INDEX[j]])}}
    elif case == "link_length":
        if not LENGTH_FRAMES[marker_link]:
            raise ValueError(f"no DH length is visible to a marker on frame {marker_link}")
        f = int(rng.choice(LENGTH_FRAMES[marker_link]))
        da[f] = rng.uniform(2e-3, 5e-3) * rng.choice([-1, 1])
        # The analysis' convention: `a` is the change of the frame's DH a (m).
        effect = {"name": "link_length", "joint": None, "link": FRAME_NAMES[f],
                  "parameters": {"a": da[f]}, "a_nominal": TABLE4[f][1]}

    # The joint stream: setpoints, encoders (the motors), quantised.
    n = int(round(duration * js_rate))
    t = np.arange(n) / js_rate
    q_set, v_set = motion.command(t)
    q_mot, v_mot = motion.motor(t)
    res = RESOLUTION
    q_enc = np.round((q_mot + rng.normal(0, 0.3, q_mot.shape) * res) / res) * res
    v_enc = v_mot + rng.normal(0, 1, v_mot.shape) * res * js_rate / 4

    # The link's true joints at any time: the motor through play, plus the offset.
    if play_joint is not None:
        fine_dt = 2.5e-4
        tf = np.arange(-0.2, duration + 0.2, fine_dt)
        jm = JOINT_INDEX[play_joint]
        xm = motion.motor(tf)[0][:, jm]
        link_fine = play(xm, play_b, xm[0] + rng.uniform(-play_b, play_b))

    def link_joints(ts):
        q = motion.motor(ts)[0][:, :len(JOINTS)] + offset
        if play_joint is not None:
            q[:, jm] = np.interp(ts, tf, link_fine)
        return q

    # The tracker: its own 100 Hz clock, stamped on the joint stream's; a pose stamped s shows
    # the link at s - d_clock.
    first = rng.uniform(0.05, 0.15)
    ts = np.arange(first, duration - 0.05, 1.0 / tracker_rate)
    q_link = link_joints(ts - d_clock)
    T_link = fk(q_link, marker_link, da)
    # Unknown placements: the tracker 1-2 m from the base, any orientation; the marker a few cm
    # from the link's frame, any orientation.
    R_tb = random_rotation(rng)
    u = rng.normal(size=3)
    p_tb = u / np.linalg.norm(u) * rng.uniform(1.0, 2.0)
    T_tb = np.eye(4)
    T_tb[:3, :3], T_tb[:3, 3] = R_tb, p_tb
    T_lm = np.eye(4)
    T_lm[:3, :3] = random_rotation(rng)
    T_lm[:3, 3] = rng.uniform(-0.05, 0.05, 3)
    T_tm = T_tb @ T_link @ T_lm
    pos = T_tm[:, :3, 3] + rng.normal(0, pos_noise, (len(ts), 3))
    rot = small_rotations(rng, len(ts), math.radians(rot_noise_deg)) @ T_tm[:, :3, :3]

    streams = {
        "t_js": t0 + t, "q_set": q_set, "v_set": v_set, "q_enc": q_enc, "v_enc": v_enc,
        "t_marker": t0 + ts, "marker_pos": pos, "marker_quat": matrix_to_quat(rot),
        "arm": arm, "marker_topic": marker_topic,
    }
    truth = {"case": case, "seed": seed, "effect": effect,
             "effects": [effect] if effect else [],
             "marker_topic": marker_topic, "marker_link": marker_link,
             "marker_frame": FRAME_NAMES[marker_link], "duration": duration,
             "js_rate": js_rate, "tracker_rate": tracker_rate,
             "tracker_to_base_m": float(np.linalg.norm(p_tb)),
             "marker_offset_m": float(np.linalg.norm(T_lm[:3, 3]))}
    return streams, truth


# ---------------------------------------------------------------- MCAP (ROS 2)
TIME = "int32 sec\nuint32 nanosec\n"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
SEP = "=" * 80 + "\n"
JOINT_STATE = ("std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
               "float64[] effort\n" + SEP + "MSG: std_msgs/Header\n" + HEADER + SEP
               + "MSG: builtin_interfaces/Time\n" + TIME)
POSE_STAMPED = ("std_msgs/Header header\ngeometry_msgs/Pose pose\n" + SEP + "MSG: std_msgs/Header\n"
                + HEADER + SEP + "MSG: builtin_interfaces/Time\n" + TIME + SEP
                + "MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n" + SEP
                + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + SEP
                + "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n")


def _stamp(t):
    ns = int(round(t * 1e9))
    return ns, {"sec": ns // 10**9, "nanosec": ns % 10**9}


def write_mcap(path, streams):
    from mcap_ros2.writer import Writer

    arm = streams["arm"]
    events = []  # (ns, order, topic, kind, message)
    # Efforts on measured_js where the streams have them (e_enc); no setpoint_js without q_set.
    effort = streams.get("e_enc")
    kinds = [("measured_js", streams["q_enc"], streams["v_enc"], effort)]
    if streams["q_set"] is not None:
        kinds.insert(0, ("setpoint_js", streams["q_set"], streams["v_set"], None))
    for i, t in enumerate(streams["t_js"]):
        ns, stamp = _stamp(t)
        for kind, q, v, e in kinds:
            hdr = {"stamp": stamp, "frame_id": ""}
            events.append((ns, 0, f"/{arm}/{kind}", "js",
                           {"header": hdr, "name": JOINTS, "position": q[i, :6].tolist(),
                            "velocity": v[i, :6].tolist(), "effort": [] if e is None else e[i, :6].tolist()}))
            events.append((ns, 1, f"/{arm}/jaw/{kind}", "js",
                           {"header": hdr, "name": [JAW], "position": [float(q[i, 6])],
                            "velocity": [float(v[i, 6])], "effort": [] if e is None else [float(e[i, 6])]}))
    for i, t in enumerate(streams["t_marker"]):
        ns, stamp = _stamp(t)
        p, qq = streams["marker_pos"][i], streams["marker_quat"][i]
        events.append((ns, 2, streams["marker_topic"], "pose",
                       {"header": {"stamp": stamp, "frame_id": "world"},
                        "pose": {"position": dict(zip("xyz", map(float, p))),
                                 "orientation": dict(zip("xyzw", map(float, qq)))}}))
    events.sort(key=lambda e: (e[0], e[1]))
    with open(path, "wb") as f:
        w = Writer(f)
        schemas = {"js": w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE),
                   "pose": w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED)}
        for ns, _, topic, kind, msg in events:
            w.write_message(topic, schemas[kind], msg, log_time=ns, publish_time=ns)
        w.finish()


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--case", required=True, choices=CASES)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--js-rate", type=float, default=200.0, help="joint stream rate (Hz)")
    p.add_argument("--marker-link", type=int, choices=[9, 12],
                   help="the marker's frame (default 9; 12 for link_length)")
    a = p.parse_args(argv)
    streams, truth = generate(a.case, a.seed, a.duration, a.js_rate, marker_link=a.marker_link)
    write_mcap(a.output, streams)
    print(json.dumps(truth))


if __name__ == "__main__":
    sys.exit(main())
