"""`dvrk gc --console-file`: the dVRK console's MTM gravity-compensation file (gc-MTMR.json,
version 2.0), read here as the console reads it and evaluated with the console's regressor
(sawIntuitiveResearchKit robGravityCompensationMTM, written out below from its source, not from
our code), against the model's holding torque that `dvrk gc --q` prints."""

import json
import os
import subprocess

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DVRK = os.path.abspath(os.environ.get("DVRK_BIN", os.path.join(ROOT, "target", "release", "dvrk")))
pytestmark = pytest.mark.skipif(not os.path.isfile(DVRK), reason=f"no dvrk binary at {DVRK} (set DVRK_BIN)")


def console_torque(gc, q, qd):
    """What the console's compute() adds to the MTM's efforts (N·m, 7 joints)."""
    g = 9.81
    s, c = np.sin, np.cos
    q1, q2, q3, q4, q5, q6 = q[:6]
    s2, c2, s23, c23 = s(q2), c(q2), s(q2 + q3), c(q2 + q3)
    s4, c4, s5, c5, s6, c6 = s(q4), c(q4), s(q5), c(q5), s(q6), c(q6)
    R = np.zeros((7, 40))
    R[1, 0], R[1, 1] = g * s2, g * c2
    block = [g * c23, -g * s23, g * c23 * c4, -g * c23 * s4, -g * (c23 * c4 * s5 + s23 * c5), g * (c23 * c4 * c5 - s23 * s5),
             g * (s23 * s5 * c6 + c23 * (s4 * s6 - c4 * c5 * c6)), g * (c23 * (s4 * c6 + c4 * c5 * s6) - s23 * s5 * s6)]
    R[1, 2:10] = block
    R[2, 2:10] = block
    R[3, 4:10] = [-g * s23 * s4, -g * s23 * c4, g * s23 * s4 * s5, -g * s23 * s4 * c5, g * s23 * (c4 * s6 + s4 * c5 * c6), g * s23 * (c4 * c6 - s4 * c5 * s6)]
    R[4, 6:10] = [-g * (c23 * s5 + s23 * c4 * c5), g * (c23 * c5 - s23 * c4 * s5), g * c6 * (s23 * c4 * s5 - c23 * c5), g * s6 * (c23 * c5 - s23 * c4 * s5)]
    R[5, 8:10] = [g * (s23 * s4 * c6 + c23 * s5 * s6 + s23 * c4 * c5 * s6), g * (c23 * s5 * c6 - s23 * s4 * s6 + s23 * c4 * c5 * c6)]
    for j in range(6):
        R[j, 10 + 5 * j:15 + 5 * j] = [q[j] ** k for k in range(5)]
    c_ = gc["GC_controller"]
    pos, neg = R @ np.array(c_["gc_dynamic_params_pos"]), R @ np.array(c_["gc_dynamic_params_neg"])
    tau = np.zeros(7)
    for j in range(7):
        db, sat, r, v = c_["db_vel_vec"][j], c_["sat_vec_vec"][j], c_["fric_comp_ratio_vec"][j], qd[j]
        if v >= sat:
            w = 0.5 + 0.5 * r
        elif v <= -sat:
            w = 0.5 - 0.5 * r
        elif abs(v) <= db:
            w = 0.5
        elif v > 0:
            w = 0.5 + 0.5 * r * (v - db) / (sat - db)
        else:
            w = 0.5 - 0.5 * r * (-v - db) / (sat - db)
        t = w * pos[j] + (1 - w) * neg[j]
        tau[j] = min(max(t, c_["safe_lower_torque_limit"][j]), c_["safe_upper_torque_limit"][j])
    return tau


def test_the_console_file_reproduces_the_identified_mtms_holding_torque(tmp_path):
    path = tmp_path / "gc-MTMR.json"
    r = subprocess.run([DVRK, "gc", "--model", "mtmr-wpi", "--console-file", str(path), "--json"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    gc = json.loads(path.read_text())
    # What the console checks: the version, and non-empty number arrays of the sizes its code
    # indexes (40 parameters, 7 joints).
    assert gc["version"] == "2.0" and gc["ARM_NAME"] == "MTMR"
    c_ = gc["GC_controller"]
    assert len(c_["gc_dynamic_params_pos"]) == len(c_["gc_dynamic_params_neg"]) == 40
    for key in ("safe_upper_torque_limit", "safe_lower_torque_limit", "db_vel_vec", "sat_vec_vec", "fric_comp_ratio_vec"):
        assert len(c_[key]) == 7 and all(isinstance(x, float) for x in c_[key]), key
    assert all(s > d for s, d in zip(c_["sat_vec_vec"], c_["db_vel_vec"]))
    fit = out["console_file"]["fit"]
    # At poses the fit never saw, the console's torque is the model's within the fit's largest
    # residual (the springs between channels the console's form has no term for).
    rng = np.random.default_rng(5)
    worst = np.zeros(7)
    for _ in range(12):
        q = rng.uniform(-0.5, 0.5, 7) + np.array([0.0, 0.1, 0.1, 0.5, 0.3, 0.0, 0.0])
        r = subprocess.run([DVRK, "gc", "--model", "mtmr-wpi", "--q", ",".join(f"{x:.17g}" for x in q), "--json"], capture_output=True, text=True, timeout=60)
        model = np.array(json.loads(r.stdout)["holding_torque"])
        for qd in (np.zeros(7), np.full(7, 0.5)):  # pos = neg: the velocity changes nothing
            worst = np.maximum(worst, abs(console_torque(gc, q, qd) - model))
    print("console vs model, worst per joint (N·m):", np.round(worst, 5), "fit residual max:", np.round(fit["residual_max"], 5))
    assert np.all(worst[:6] <= 1.5 * np.array(fit["residual_max"][:6]) + 1e-9)
    assert np.all(worst[:6] < 0.02)
