"""A synthetic MTM recording for `dvrk teleop`, written with mcap-ros2-support (not our writer):
the MTM's start position from the MTM model's FK, its orientation the PSM's at the start (an
operator who aligned), then a 5 cm square in the display frame with a clutch in the middle (the
hand moves 3 cm up while clutched), a 30 deg wrist turn about the display's z and a gripper
closing. Holds between moves let the simulated PSM settle; `SCRIPT` says what each window is."""

import numpy as np

SEP = "=" * 80 + "\n"
HEADER = SEP + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + SEP + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
POSE = ("std_msgs/Header header\ngeometry_msgs/Pose pose\n" + HEADER + SEP + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"
        + SEP + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + SEP + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n")
JS = "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + HEADER
JOY = "std_msgs/Header header\nfloat32[] axes\nint32[] buttons\n" + HEADER

RATE = 200.0  # Hz, the MTM's topics
OPEN = 0.8  # rad, the gripper before it closes
# (name, seconds, hand displacement at the end of the window in the display frame (m), wrist turn
# (deg), gripper (rad), clutch). Moves are cosine-smoothed between the windows' ends.
SCRIPT = [
    ("start", 0.5, (0.0, 0.0, 0.0), 0.0, OPEN, False),
    ("leg x", 2.0, (0.05, 0.0, 0.0), 0.0, OPEN, False),
    ("hold 1", 1.0, (0.05, 0.0, 0.0), 0.0, OPEN, False),
    ("leg y", 2.0, (0.05, 0.05, 0.0), 0.0, OPEN, False),
    ("hold 2", 1.0, (0.05, 0.05, 0.0), 0.0, OPEN, False),
    ("clutch down", 0.5, (0.05, 0.05, 0.0), 0.0, OPEN, True),
    ("clutched move", 1.0, (0.05, 0.05, 0.03), 0.0, OPEN, True),
    ("clutch up", 0.5, (0.05, 0.05, 0.03), 0.0, OPEN, True),
    ("leg -x", 2.0, (0.0, 0.05, 0.03), 0.0, OPEN, False),
    ("hold 3", 1.0, (0.0, 0.05, 0.03), 0.0, OPEN, False),
    ("leg -y", 2.0, (0.0, 0.0, 0.03), 0.0, OPEN, False),
    ("hold 4", 1.0, (0.0, 0.0, 0.03), 0.0, OPEN, False),
    ("turn", 1.5, (0.0, 0.0, 0.03), 30.0, OPEN, False),
    ("hold 5", 1.0, (0.0, 0.0, 0.03), 30.0, OPEN, False),
    ("close", 1.0, (0.0, 0.0, 0.03), 30.0, 0.0, False),
    ("hold 6", 1.5, (0.0, 0.0, 0.03), 30.0, 0.0, False),
]
CLUTCHED_Z = 0.03  # m the hand moved while clutched


def rot_z(deg):
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def quat(r):
    """x, y, z, w of a rotation matrix."""
    w = np.sqrt(max(0.0, 1.0 + np.trace(r))) / 2.0
    if w > 1e-6:
        return [(r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w), w]
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    v = np.sqrt(max(0.0, 1.0 + r[i, i] - r[j, j] - r[k, k])) / 2.0
    q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / (4 * v)]
    q[i] = v
    q[j] = (r[j, i] + r[i, j]) / (4 * v)
    q[k] = (r[k, i] + r[i, k]) / (4 * v)
    return q


# The same moves, shorter, for a live twin (real time).
SHORT = [
    ("start", 0.5, (0.0, 0.0, 0.0), 0.0, OPEN, False),
    ("leg x", 1.0, (0.05, 0.0, 0.0), 0.0, OPEN, False),
    ("hold 1", 0.6, (0.05, 0.0, 0.0), 0.0, OPEN, False),
    ("clutch down", 0.3, (0.05, 0.0, 0.0), 0.0, OPEN, True),
    ("clutched move", 0.5, (0.05, 0.0, 0.03), 0.0, OPEN, True),
    ("clutch up", 0.3, (0.05, 0.0, 0.03), 0.0, OPEN, True),
    ("leg y", 1.0, (0.05, 0.05, 0.03), 0.0, OPEN, False),
    ("hold 2", 0.6, (0.05, 0.05, 0.03), 0.0, OPEN, False),
    ("turn", 0.8, (0.05, 0.05, 0.03), 30.0, OPEN, False),
    ("hold 3", 0.6, (0.05, 0.05, 0.03), 30.0, OPEN, False),
    ("close", 0.5, (0.05, 0.05, 0.03), 30.0, 0.0, False),
    ("hold 4", 0.6, (0.05, 0.05, 0.03), 30.0, 0.0, False),
]


def matrix(q):
    """The rotation matrix of quaternion x, y, z, w (unit)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def samples(start_position, start_rotation, script=SCRIPT):
    """(t, position, rotation, gripper, clutch, window name) at RATE over `script`."""
    out, t = [], 0.0
    prev = (np.zeros(3), 0.0, OPEN)
    for name, seconds, d, turn, grip, clutch in script:
        n = int(round(seconds * RATE))
        for k in range(n):
            s = 0.5 - 0.5 * np.cos(np.pi * (k + 1) / n)
            disp = prev[0] + s * (np.array(d) - prev[0])
            ang = prev[1] + s * (turn - prev[1])
            g = prev[2] + s * (grip - prev[2])
            out.append((t, start_position + disp, rot_z(ang) @ start_rotation, g, clutch, name))
            t += 1.0 / RATE
        prev = (np.array(d), turn, grip)
    return out


def write(path, start_position, start_rotation, arm="MTMR", t0=1_700_000_000.0, clutch_topic="/footpedals/clutch"):
    """Write the script as the dVRK publishes it; returns the samples."""
    from mcap_ros2.writer import Writer

    rows = samples(start_position, start_rotation)
    with open(path, "wb") as f:
        w = Writer(output=f)
        pose_s = w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE)
        js_s = w.register_msgdef("sensor_msgs/msg/JointState", JS)
        joy_s = w.register_msgdef("sensor_msgs/msg/Joy", JOY)
        pressed = None
        for t, p, r, g, clutch, _ in rows:
            ns = int(round((t0 + t) * 1e9))
            header = {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": f"{arm}_base"}
            q = quat(r)
            w.write_message(f"/{arm}/measured_cp", pose_s, {"header": header, "pose": {"position": dict(zip("xyz", p)), "orientation": dict(zip("xyzw", q))}}, log_time=ns, publish_time=ns)
            w.write_message(f"/{arm}/gripper/measured_js", js_s, {"header": header, "name": ["gripper"], "position": [g], "velocity": [], "effort": []}, log_time=ns, publish_time=ns)
            if clutch != pressed and clutch_topic:
                # The console publishes the pedal when it changes.
                w.write_message(clutch_topic, joy_s, {"header": header, "axes": [], "buttons": [1 if clutch else 0]}, log_time=ns, publish_time=ns)
                pressed = clutch
        w.finish()
    return rows
