#!/usr/bin/env python3
"""A payload from the effort difference of two recordings of the same trajectory, without the
discrepancy workflow: an independent check of what the WPI insertion-payload recordings can fix.

    python scripts/paired_payload.py --reference one_no_weight_results.csv \
        one_results_1.0_scale_205_grams_insertion.csv [--body pitch_end] [--distance 0.535]

The weighted recording's yaw, pitch and insertion efforts minus the weightless one's, sample by
sample (the model and its identification cancel), are fitted with a point mass on `--body`:
its effort is J(p)^T m (a(p) + g), `a` the point's acceleration along the weighted recording's
joints (differentiated twice, zero-phase low-passed). Printed: the free fit (mass and place) on
the whole recording and on each half, then the mass with the place held at `--distance` metres
from the remote centre, back along the insertion axis (`--offset` m beside it), with the RMS of
what each leaves. Needs numpy and the dvrk_twin wheel (FK and Jacobians of the closed-loop PSM).
"""
import argparse
import numpy as np
import dvrk_twin

RATE = 200.0  # Hz, the WPI recordings'
GRAVITY = np.array([0.0, 0.0, 9.81])  # m/s^2, the model's world: z up


def lowpass(x, cutoff_hz):
    """Zero-phase low-pass: the spectrum cut at `cutoff_hz` (a smooth cosine edge)."""
    n = x.shape[0]
    f = np.fft.rfftfreq(n, 1.0 / RATE)
    w = np.clip((2 * cutoff_hz - f) / cutoff_hz, 0.0, 1.0)
    w = 0.5 - 0.5 * np.cos(np.pi * w)
    return np.fft.irfft(np.fft.rfft(x, axis=0) * w[:, None], n, axis=0)


class Signature:
    def __init__(self, model, q, body, cutoff):
        self.T = model.fk(q, body)
        self.J = model.jacobian(q, body)
        self.cutoff = cutoff

    def effort(self, m, p):
        """Yaw, pitch, insertion effort (N·m, N) of mass m (kg) at p (m, body frame)."""
        P = self.T[:, :3, 3] + np.einsum("nij,j->ni", self.T[:, :3, :3], p)
        acc = lowpass(np.gradient(np.gradient(P, 1 / RATE, axis=0), 1 / RATE, axis=0), self.cutoff)
        r = P - self.T[:, :3, 3]
        jv = self.J[:, :3, :3] + np.cross(self.J[:, 3:, :3].transpose(0, 2, 1), r[:, None, :]).transpose(0, 2, 1)
        return np.einsum("nij,ni->nj", jv, m * (acc + GRAVITY))


def gauss_newton(f, x0, iterations=50):
    x = np.array(x0, float)
    for _ in range(iterations):
        r = f(x)
        jac = np.stack([(f(x + h) - r) / 1e-6 for h in np.eye(len(x)) * 1e-6], axis=1)
        step = np.linalg.lstsq(jac, -r, rcond=None)[0]
        x = x + step
        if np.abs(step).max() < 1e-9:
            break
    return x


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("weighted", help="wpi-csv recording with the weight")
    ap.add_argument("--reference", required=True, help="wpi-csv recording of the same trajectory without it")
    ap.add_argument("--body", default="pitch_end", help="the body carrying the weight (frame name)")
    ap.add_argument("--distance", type=float, default=0.535, help="held place: metres from the RCM along the stage")
    ap.add_argument("--offset", type=float, default=0.028, help="held place: metres beside the axis")
    ap.add_argument("--cutoff", type=float, default=10.0, help="low-pass of the efforts and accelerations (Hz)")
    a = ap.parse_args()
    ref = np.loadtxt(a.reference, delimiter=",")
    rec = np.loadtxt(a.weighted, delimiter=",")
    n = min(len(ref), len(rec))
    model = dvrk_twin.Model.load("psm")
    q = rec[:n, :7].copy()
    q[:, 3:] = 0.0  # the wrist (actuator columns) moves no body of the arm
    sig = Signature(model, q, a.body, a.cutoff)
    dtau = lowpass(rec[:n, 14:17] - ref[:n, 14:17], a.cutoff)
    # The remote centre in the body's frame, and the stage's axis (back from the RCM) in it.
    t0 = np.linalg.inv(model.fk(np.zeros(7), a.body))
    rcm = (t0 @ np.append(model.rcm, 1.0))[:3]
    back = t0[:3, :3] @ model.fk(np.zeros(7), "main_insertion")[:3, 2] * -1.0
    side = t0[:3, :3] @ np.array([0.0, -1.0, 0.0])
    trim = 100
    rms = lambda r: np.sqrt((r**2).mean(axis=0))
    print(f"effort difference RMS (yaw N·m, pitch N·m, insertion N): {np.round(rms(dtau[trim:n - trim]), 4)}")
    for name, rows in (("whole", slice(trim, n - trim)), ("first half", slice(trim, n // 2)), ("second half", slice(n // 2, n - trim))):
        f = lambda x: (sig.effort(x[0], x[1:]) - dtau)[rows].ravel()
        x = gauss_newton(f, np.r_[0.2, rcm + 0.5 * back])
        left = rms(f(x).reshape(-1, 3))
        print(f"free place, {name}: {x[0]:.3f} kg at {np.linalg.norm(x[1:] - rcm):.3f} m from the RCM; left {np.round(left, 4)}")
    p = rcm + a.distance * back + a.offset * side
    rows = slice(trim, n - trim)
    for j, label in ((None, "all"), (0, "yaw alone"), (1, "pitch alone")):
        cols = [0, 1, 2] if j is None else [j]
        f = lambda x: (sig.effort(x[0], p) - dtau)[rows][:, cols].ravel()
        m = gauss_newton(f, [0.2])[0]
        print(f"held at {a.distance:.3f} m ({label}): {m:.3f} kg; left {np.round(rms((sig.effort(m, p) - dtau)[rows]), 4)}")


if __name__ == "__main__":
    main()
