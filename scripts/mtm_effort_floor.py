#!/usr/bin/env python3
"""How much of the real MTM's measured effort the recorded motion does not carry (issue #58).

The WPI protocol compares efforts through a 6th-order Butterworth acting at 5.65 Hz (docs/mtm.md);
the excitation's harmonics end near 1 Hz. Per joint on `two`: the share of the compared effort
(the filter's squared magnitude, zero phase, the first 10 s after the 200-sample trim) that lies
at 2.5 Hz and up, and how much of that band a linear fit of every joint's velocity and
acceleration in the band explains (fitted on `one`, tested on `two`): what any model driven by the
recorded motion, rigid or not, could predict of it. Numpy only (bands cut in the Fourier domain).

  .venv/bin/python scripts/mtm_effort_floor.py [path/to/mtm]
"""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT = os.path.join(HERE, "..", "..", "shared", "data", "external", "wpi-dvrk-dynamics", "mtm")
RATE = 200.0  # Hz, the WPI recordings' rate
PROTOCOL_CUTOFF = 5.65  # Hz
BAND = (2.5, 6.5)  # Hz
JOINTS = ["outer_yaw", "shoulder_pitch", "elbow_pitch"]


def masked(x, gain):
    """`x` (mean removed) through the zero-phase frequency response `gain(f)`."""
    spectrum = np.fft.rfft(x - x.mean())
    return np.fft.irfft(spectrum * gain(np.fft.rfftfreq(len(x), 1.0 / RATE)), len(x))


def protocol(f):
    return 1.0 / (1.0 + (f / PROTOCOL_CUTOFF) ** 12)  # |H|^2 of the 6th-order filter, run twice


def in_band(f):
    return ((f >= BAND[0]) & (f < BAND[1])).astype(float)


def load(folder, name):
    a = np.loadtxt(os.path.join(folder, f"{name}_results.csv"), delimiter=",")
    return a[:, 7:14], a[:, 14:21]


def motion_columns(qd):
    """Every joint's velocity and acceleration in the band."""
    cols = []
    for k in range(qd.shape[1]):
        cols.append(masked(qd[:, k], in_band))
        cols.append(masked(qd[:, k], lambda f: in_band(f) * 2j * np.pi * f))
    return np.column_stack(cols)


def two_mass_columns(qd, joints=(1, 2), resonances=(5.0, 7.0, 9.0, 12.0), damping=(0.1, 0.3)):
    """A compliant drive's extra effort: the motor's jerk through the drive's resonance (a
    second-order low-pass at `fn` Hz, damping `z`), in the band, for the shoulder and elbow."""
    cols = []
    for k in joints:
        for fn in resonances:
            for z in damping:
                w = 2 * np.pi * fn
                cols.append(masked(qd[:, k], lambda f: in_band(f) * (2j * np.pi * f) ** 2 * w * w / ((2j * np.pi * f) ** 2 + 2 * z * w * 2j * np.pi * f + w * w)))
    return np.column_stack(cols)


def power(x, lo, hi):
    """Mean power of `x` per frequency bin in [lo, hi) Hz."""
    spectrum = np.abs(np.fft.rfft(x - x.mean())) ** 2
    f = np.fft.rfftfreq(len(x), 1.0 / RATE)
    return spectrum[(f >= lo) & (f < hi)].mean()


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else DEFAULT
    qd1, tau1 = load(folder, "one")
    qd2, tau2 = load(folder, "two")
    window = slice(200, 200 + int(10 * RATE))
    a1, a2 = motion_columns(qd1), motion_columns(qd2)
    print(f"band {BAND[0]}-{BAND[1]} Hz; compared through the protocol's filter (5.65 Hz), WPI two")
    print("joint | band's share of the compared effort | of the band, explained by the motion: fit on one / on two | floor: the share the motion leaves | on two with a compliant drive's columns too | effort/velocity power, 4.4-7 Hz over 1.8-2.3 Hz")
    for j, name in enumerate(JOINTS):
        compared = masked(tau2[:, j], protocol)[window]
        band2 = masked(tau2[:, j], lambda f: protocol(f) * in_band(f))
        share = np.linalg.norm(band2[window]) / np.linalg.norm(compared)
        y1, y2 = masked(tau1[:, j], in_band), masked(tau2[:, j], in_band)
        theta, *_ = np.linalg.lstsq(a1, y1, rcond=None)
        train = 1 - np.linalg.norm(y1 - a1 @ theta) / np.linalg.norm(y1)
        test = 1 - np.linalg.norm(y2 - a2 @ theta) / np.linalg.norm(y2)
        b1, b2 = np.column_stack([a1, two_mass_columns(qd1)]), np.column_stack([a2, two_mass_columns(qd2)])
        theta2, *_ = np.linalg.lstsq(b1, y1, rcond=None)
        compliant = 1 - np.linalg.norm(y2 - b2 @ theta2) / np.linalg.norm(y2)
        # An inertia's effort over its velocity grows as f^2: (5.7 / 2.05)^2 = 7.7 between the bands.
        growth = (power(tau2[:, j], 4.4, 7.0) / power(qd2[:, j], 4.4, 7.0)) / (power(tau2[:, j], 1.8, 2.3) / power(qd2[:, j], 1.8, 2.3))
        print(f"{name} | {share:.3f} | {train:.2f} / {test:.2f} | {share * (1 - max(test, 0.0)):.3f} | {compliant:.2f} | {growth:.1f}")


if __name__ == "__main__":
    main()
