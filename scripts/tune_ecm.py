"""Step-response tuning of the ECM's PID gains (issue 42, "ECM tracking"), as the paper tuned the
PSM's (section 4.3: "tuned individually for all joints for a step response").

Method (reduced engine, dt 1 ms, the ECM of ``models/scenes/ecm.toml`` with its gravity
feed-forward on, the armature held at the scene's values: it stands for the drives' inertia and
does not follow the gains):

- each joint alone: the arm settles at home for 2 s, then that joint's target steps by a small
  amount (0.05 rad, 5 mm for the insertion) while the others hold;
- a candidate (kp, kd) is admissible when the drive never reaches its effort limit during the step
  (a linear response: a criterion that allowed saturation would reward bang-bang gains), the
  overshoot is at most 5%, and the closed loop stays slower than ``OMEGA_MAX`` (a natural
  frequency estimated as sqrt(kp / m), m the joint's inertia seen by the drive at home:
  about 125 steps per period at 1 ms);
- among admissible candidates the fastest 2% settling wins (ties: the smaller kp);
- ki = kp / 10 (a 10 s integral time: it removes what the feed-forward leaves, slowly enough not
  to wind up on a step).

Usage (after building and installing the wheel)::

    .venv/bin/python scripts/tune_ecm.py [--scene models/scenes/ecm.toml]

Prints per joint the chosen gains and the step figures of today's and the chosen gains.
"""

from __future__ import annotations

import argparse
import itertools
import math
import re
import tempfile
from pathlib import Path

import dvrk_twin

ROOT = Path(__file__).resolve().parent.parent
STEPS = [0.05, 0.05, 0.005, 0.05]  # rad, rad, m, rad
OMEGA_MAX = 50.0  # rad/s
SETTLE_S, RESPONSE_S = 2.0, 1.5
KP_GRID = [10.0 * 1.25**k for k in range(40)]
ZETA_GRID = [0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.2, 1.5]


def scene_with(text: str, gains: list[tuple[float, float, float]]) -> str:
    """The scene text with the ECM's gains replaced and its gravity feed-forward on."""
    kp, ki, kd = ([g[i] for g in gains] for i in range(3))
    for key, vals in (("kp", kp), ("ki", ki), ("kd", kd)):
        text = re.sub(rf"^{key} = \[.*\]$", f"{key} = [{', '.join(repr(v) for v in vals)}]", text, count=1, flags=re.M)
    if "gravity_compensation" not in text:
        text = text.replace('model = "ecm"\n', 'model = "ecm"\ngravity_compensation = true\n', 1)
    return text


def step_response(path: Path, joint: int, step: float) -> dict:
    sim = dvrk_twin.Sim.from_scene(str(path), engine="reduced")
    dt = sim.dt
    sim.step(int(SETTLE_S / dt))
    q0 = list(sim.q)
    start = q0[joint]
    target = start + step
    sim.set_target(joint, target, 0.0)
    ys, efforts = [], []
    for _ in range(int(RESPONSE_S / dt)):
        sim.step(1)
        ys.append(sim.q[joint])
        efforts.append(abs(sim.effort(joint)))
    rel = [(y - start) / step for y in ys]
    overshoot = max(0.0, max(rel) - 1.0)
    settle = RESPONSE_S
    for k in range(len(rel) - 1, -1, -1):
        if abs(rel[k] - 1.0) > 0.02:
            settle = (k + 1) * dt
            break
    else:
        settle = 0.0
    return {"overshoot": overshoot, "settle": settle, "peak_effort": max(efforts), "final": rel[-1]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=str(ROOT / "models/scenes/ecm.toml"))
    args = ap.parse_args()
    text = Path(args.scene).read_text()
    today = [tuple(float(x) for x in re.search(rf"^{k} = \[(.*)\]$", text, re.M).group(1).split(",")) for k in ("kp", "ki", "kd")]
    today = [tuple(today[i][j] for i in range(3)) for j in range(4)]
    limits = [26.93208, 26.93208, 80.6589483, 0.87658808]
    tmp = Path(tempfile.mkdtemp())
    chosen = list(today)
    print("joint | gains (kp, ki, kd) | overshoot | 2% settle (s) | peak effort / limit")
    for j in range(4):
        path = tmp / "s.toml"
        path.write_text(scene_with(text, chosen))
        base = step_response(path, j, STEPS[j])
        # The inertia the drive sees at home (link and drive), from a P loop's period.
        probe = list(chosen)
        probe[j] = (today[j][0], 0.0, 0.0)
        path.write_text(scene_with(text, probe))
        m = inertia_from_period(path, j, STEPS[j], today[j][0])
        best = None
        for kp, zeta in itertools.product(KP_GRID, ZETA_GRID):
            if math.sqrt(kp / m) > OMEGA_MAX:
                continue
            kd = 2.0 * zeta * math.sqrt(kp * m)
            trial = list(chosen)
            trial[j] = (kp, kp / 10.0, kd)
            path.write_text(scene_with(text, trial))
            try:
                r = step_response(path, j, STEPS[j])
            except dvrk_twin.DvrkError:
                continue
            if r["peak_effort"] >= 0.999 * limits[j] or r["overshoot"] > 0.05:
                continue
            key = (r["settle"], kp)
            if best is None or key < best[0]:
                best = (key, trial[j], r)
        name = ["yaw", "pitch", "insertion", "roll"][j]
        print(f"{name} today | {fmt(today[j])} | {base['overshoot']:.1%} | {base['settle']:.3f} | {base['peak_effort'] / limits[j]:.2f}")
        if best is None:
            print(f"{name}: no admissible gains (m = {m:.4g})")
            continue
        chosen[j] = best[1]
        r = best[2]
        print(f"{name} chosen (m = {m:.4g}) | {fmt(best[1])} | {r['overshoot']:.1%} | {r['settle']:.3f} | {r['peak_effort'] / limits[j]:.2f}")
    print("kp =", [round(g[0], 3) for g in chosen])
    print("ki =", [round(g[1], 3) for g in chosen])
    print("kd =", [round(g[2], 3) for g in chosen])


def inertia_from_period(path: Path, joint: int, step: float, kp: float) -> float:
    """The inertia (kg m^2, kg) a P-only drive sees, from its oscillation period after a step."""
    sim = dvrk_twin.Sim.from_scene(str(path), engine="reduced")
    dt = sim.dt
    sim.step(int(SETTLE_S / dt))
    start = sim.q[joint]
    sim.set_target(joint, start + step, 0.0)
    ys = []
    for _ in range(int(3.0 / dt)):
        sim.step(1)
        ys.append(sim.q[joint] - start - step)
    # Zero crossings of the error, upward and downward alike: half a period apart.
    crossings = [k for k in range(1, len(ys)) if (ys[k - 1] < 0.0) != (ys[k] < 0.0)]
    if len(crossings) < 3:
        raise SystemExit(f"joint {joint}: a P loop with kp {kp} did not oscillate: cannot read its inertia")
    half = (crossings[-1] - crossings[0]) / (len(crossings) - 1) * dt
    period = 2.0 * half
    return kp * (period / (2.0 * math.pi)) ** 2


def fmt(g) -> str:
    return f"{g[0]:.4g}, {g[1]:.4g}, {g[2]:.4g}"


if __name__ == "__main__":
    main()
