"""The independent generator's effort cases (issue #62 item 5): a weight on the PSM, added to a
real robot's recording.

numpy only, no code and no model file of the project's: a point mass m at a point p fixed on one
of the pitch linkage's links loads the joints by virtual work, tau = J_p(q)^T m (a_p - g), with
the point's position from the paper's Table 4 (independent_psm.fk), its Jacobian by central
differences in q and its acceleration by second differences in time. That is added to the
efforts of a real dVRK recording without a weight (WPI's `one_no_weight_results.csv`: the real
arm's motion, friction, model error and noise), which is written as MCAP in the dVRK's CRTK
layout. Each seed draws the weight, its place and a 25 s window of the 30 s recording.

Cases (the truth: the first moment about the pitch's axis, what the pitch's gravity load fixes):
  payload_translating  on pitch_bottom (frame 6), which translates on its crank (Table 4's 0.150 m):
                       m x 0.150 wherever on the link it sits
  payload_turning      on pitch_end (frame 8), which turns about the remote centre: m times the
                       weight's distance from the pitch's axis through the remote centre
  none_efforts         the recording's window as it is

The WPI files hold the tool's last three channels in actuator space (positions M^-1 q, efforts
M^T tau, M from ../shared/data/external/README.md); the MCAP holds joints, as the dVRK publishes.
"""

import os

import numpy as np

import independent_psm as psm

CASES = ["payload_translating", "payload_turning", "none_efforts"]
HERE = os.path.dirname(os.path.abspath(__file__))
BASE = os.path.join(HERE, "..", "..", "..", "shared", "data", "external", "wpi-dvrk-dynamics",
                    "insertion-payload", "one_no_weight_results.csv")
RATE = 200.0        # Hz, the WPI recordings' rate
WINDOW = 25.0       # s of the 30 s recording per seed
GRAVITY = np.array([0.0, 0.0, -9.81])  # m/s^2 in the PSM base frame: the WPI arm stands upright
# Tool actuators 5..7 to joints (README): q_joint = M q_actuator, tau_joint = M^-T tau_actuator.
M_TOOL = np.array([[1.0186, 0.0, 0.0], [-0.8306, 0.6089, 0.6089], [0.0, -1.2177, 1.2177]])
PAYLOAD_FRAME = {"payload_translating": 6, "payload_turning": 8}


def read_wpi(path=BASE):
    """(q, qd, tau) in joint space, (N, 7) each, from a WPI 21-column CSV."""
    raw = np.loadtxt(path, delimiter=",")
    q, qd, tau = raw[:, 0:7].copy(), raw[:, 7:14].copy(), raw[:, 14:21].copy()
    q[:, 4:7] = q[:, 4:7] @ M_TOOL.T
    qd[:, 4:7] = qd[:, 4:7] @ M_TOOL.T
    tau[:, 4:7] = tau[:, 4:7] @ np.linalg.inv(M_TOOL)
    return q, qd, tau


def smooth(x, sigma_samples=2.0):
    """Zero-phase Gaussian smoothing along axis 0 (the encoder's quantisation out of a second
    difference), the ends held."""
    r = int(4 * sigma_samples)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma_samples) ** 2)
    k /= k.sum()
    pad = np.concatenate([np.repeat(x[:1], r, 0), x, np.repeat(x[-1:], r, 0)])
    return np.stack([np.convolve(pad[:, j], k, mode="valid") for j in range(x.shape[1])], 1)


def point(q, frame, p):
    """World position (N, 3) of point p (m, in paper frame `frame`) at joints q (N, >=4)."""
    T = psm.fk(q, frame)
    return T[:, :3, :3] @ p + T[:, :3, 3]


def payload_effort(q, frame, p, m, dt):
    """Joint efforts (N, 3) on yaw, pitch, insertion of mass m (kg) at p on `frame`."""
    qs = smooth(q[:, :4])
    x = point(qs, frame, p)
    a = np.zeros_like(x)
    a[1:-1] = (x[2:] - 2 * x[1:-1] + x[:-2]) / dt ** 2
    a[0], a[-1] = a[1], a[-2]
    h = 1e-6
    tau = np.zeros((len(q), 3))
    for j in range(3):
        up, down = qs.copy(), qs.copy()
        up[:, j] += h
        down[:, j] -= h
        dx = (point(up, frame, p) - point(down, frame, p)) / (2 * h)
        tau[:, j] = m * np.einsum("ij,ij->i", dx, a - GRAVITY)
    return tau


def remote_centre_in(frame):
    """The point of `frame` that stays put while yaw and pitch move (m, in the frame): the
    remote centre, by least squares over random yaw and pitch."""
    rng = np.random.default_rng(0)
    q = np.zeros((40, 4))
    q[:, 0], q[:, 1], q[:, 2] = rng.uniform(-1, 1, 40), rng.uniform(-0.8, 0.8, 40), 0.1
    T = psm.fk(q, frame)
    # R_i p + t_i = c for all i: unknowns p (3) and c (3).
    A = np.concatenate([T[:, :3, :3], -np.broadcast_to(np.eye(3), (40, 3, 3))], 2).reshape(-1, 6)
    b = -T[:, :3, 3].reshape(-1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    return sol[:3]


def pitch_axis_in(frame):
    """The axis (unit, in `frame`) the frame turns about when the pitch moves: by the rotation
    between two pitch angles."""
    q = np.zeros((2, 4))
    q[:, 2] = 0.1
    q[1, 1] = 0.01
    T = psm.fk(q, frame)
    R = T[0, :3, :3].T @ T[1, :3, :3]
    axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return axis / np.linalg.norm(axis)


def generate(case, seed, base=BASE):
    """One recording: (streams for independent_psm.write_mcap, truth)."""
    if case not in CASES:
        raise ValueError(f"unknown case {case!r}; cases: {', '.join(CASES)}")
    rng = np.random.default_rng([seed, 100 + CASES.index(case)])
    q, qd, tau = read_wpi(base)
    n = int(WINDOW * RATE)
    start = int(rng.integers(0, len(q) - n + 1))
    q, qd, tau = q[start:start + n], qd[start:start + n], tau[start:start + n].copy()
    effect = None
    if case in PAYLOAD_FRAME:
        frame = PAYLOAD_FRAME[case]
        m = rng.uniform(0.08, 0.3)
        if frame == 6:
            # Anywhere along the bottom link (frame 6's x runs to frame 8 at Table 4's 0.516 m),
            # a few cm off its line.
            p = np.array([rng.uniform(0.05, 0.45), rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03)])
            first_moment = m * psm.TABLE4[6][1]  # the crank: frame 6's a
            axis_first_moment = first_moment
        else:
            c = remote_centre_in(frame)
            # On pitch_end, 0.2-0.45 m from the remote centre along the link (frame 8's x), a few cm off.
            p = c + np.array([-rng.uniform(0.2, 0.45), rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03)])
            first_moment = m * float(np.linalg.norm(p - c))
            # About the pitch's axis through the remote centre: what the pitch's gravity load fixes.
            a = pitch_axis_in(frame)
            axis_first_moment = m * float(np.linalg.norm((p - c) - a * a.dot(p - c)))
        tau[:, :3] += payload_effort(q, frame, p, m, 1.0 / RATE)
        # The graded value: the first moment about the pitch's axis (the report's
        # axis_first_moment); first_moment_rcm: about the remote centre (its first_moment).
        effect = {"name": "payload_mass", "joint": None, "link": psm.FRAME_NAMES[frame],
                  "parameters": {"axis_first_moment": axis_first_moment},
                  "first_moment_rcm": first_moment,
                  "mass": m, "place": p.tolist()}
    t0 = 1.7e9 + float(rng.integers(0, 10**7))
    t = np.arange(n) / RATE
    streams = {"t_js": t0 + t, "q_set": None, "v_set": None, "q_enc": q, "v_enc": qd, "e_enc": tau,
               "t_marker": np.zeros(0), "marker_pos": np.zeros((0, 3)), "marker_quat": np.zeros((0, 4)),
               "arm": "PSM1", "marker_topic": None}
    truth = {"case": case, "seed": seed, "effect": effect, "effects": [effect] if effect else [],
             "window_start_s": start / RATE, "duration": WINDOW, "base": os.path.basename(base)}
    return streams, truth


if __name__ == "__main__":
    import json
    import sys

    # python tests/python/independent_payload.py CASE SEED out.mcap   (prints the truth, JSON)
    case, seed, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    s, truth = generate(case, seed)
    psm.write_mcap(out, s)
    print(json.dumps(truth))
