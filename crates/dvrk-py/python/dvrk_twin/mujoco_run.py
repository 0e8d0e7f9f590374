"""Run an exported MJCF (:func:`dvrk_twin.export_mjcf`) in MuJoCo under our controller.

The cross-check of our dynamics in a second engine: the same mechanism (``dvrk export mjcf``) on
the same tracking test (section 4.3 sines, Table 8 PID), with the PID of ``control.rs``
reproduced here step for step (position error against the target at the end of the step,
velocity feed-forward, conditional integration, integral cap ``effort_limit / ki``, effort clamp)
since MuJoCo's actuators cannot express its anti-windup. Joints the scene holds in position mode
are held by the MJCF's equality constraints and get no effort.

Needs the PyPI package ``mujoco`` (imported when called). Units: m, rad, s, N, N·m.
"""

from __future__ import annotations

import time
from typing import Any, Dict, List

import numpy as np

#: Layout of the ``dvrk:ARM/joint`` custom numerics written by the exporter.
DRIVE_FIELDS = ["c", "b", "kp", "ki", "kd", "effort_limit", "position_mode", "home", "amplitude", "frequency", "lower", "upper"]


class Drives:
    """The actuated joints of an exported model: names, drive maps and controller data, as
    arrays in actuator order (one entry per actuated joint of the scene)."""

    def __init__(self, model: Any) -> None:
        import mujoco

        self.names: List[str] = []
        rows = []
        for i in range(model.nu):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i)
            nid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, "dvrk:" + name)
            if nid < 0:
                raise ValueError(f"actuator {name}: no custom numeric dvrk:{name} (not a dvrk_twin export?)")
            adr, size = model.numeric_adr[nid], model.numeric_size[nid]
            if size != len(DRIVE_FIELDS):
                raise ValueError(f"custom numeric dvrk:{name} has {size} values, expected {len(DRIVE_FIELDS)}")
            rows.append(model.numeric_data[adr : adr + size])
            self.names.append(name)
        data = np.array(rows).reshape(-1, len(DRIVE_FIELDS))
        for k, f in enumerate(DRIVE_FIELDS):
            setattr(self, f, data[:, k].copy())
        jnt = model.actuator_trnid[:, 0]
        #: qpos and qvel address of each drive's joint.
        self.qadr = model.jnt_qposadr[jnt].copy()
        self.vadr = model.jnt_dofadr[jnt].copy()
        self.pid = self.position_mode == 0.0

    def q(self, data: Any) -> np.ndarray:
        """Joint positions (rad, m) from the MuJoCo coordinates."""
        return (data.qpos[self.qadr] - self.b) / self.c

    def targets(self, t: float) -> tuple:
        """Target position and velocity of every joint at time ``t`` (s)."""
        w = 2.0 * np.pi * self.frequency
        q = self.home + self.amplitude * np.sin(w * t)
        qd = self.amplitude * w * np.cos(w * t)
        return np.clip(q, self.lower, self.upper), qd


def closure_sites(model: Any) -> List[tuple]:
    """Site id pairs ``(ARM/c:a, ARM/c:b)`` of every loop closure."""
    import mujoco

    pairs = []
    for i in range(model.nsite):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, i)
        if name and name.endswith(":a"):
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name[:-2] + ":b")
            if j >= 0:
                pairs.append((i, j))
    return pairs


def run_tracking(xml: str, duration: float, record: bool = False) -> Dict[str, Any]:
    """Run the exported scene ``xml`` for ``duration`` s of the tracking test in MuJoCo (Python
    step loop, one ``mj_step`` per time step). Returns ``joints`` (name, rms_error, max_error per
    actuated joint), ``max_closure_error`` (m), ``final_closure_error`` (m, last tenth),
    ``wall_time`` (s, the step loop with the controller), ``real_time_factor``, ``steps``,
    ``dt``, and with ``record`` the measured ``q`` (steps, nq)."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    d = Drives(model)
    sites = closure_sites(model)
    sa = np.array([a for a, _ in sites], dtype=int)
    sb = np.array([b for _, b in sites], dtype=int)
    dt = model.opt.timestep
    steps = max(1, int(round(duration / dt)))
    n = len(d.names)
    integral = np.zeros(n)
    q_prev = d.q(data)
    qd = np.zeros(n)
    kp, ki, kd, lim = d.kp, d.ki, d.kd, d.effort_limit
    limited = lim > 0.0
    cap = np.where(limited & (ki > 0.0), lim / np.where(ki > 0.0, ki, 1.0), np.inf)
    sum_sq = np.zeros(n)
    max_err = np.zeros(n)
    max_closure = final_closure = 0.0
    qs = np.zeros((steps, n)) if record else None
    mujoco.mj_forward(model, data)
    start = time.perf_counter()
    for s in range(steps):
        t = (s + 1) * dt
        qr, qdr = d.targets(t)
        q = d.q(data)
        # control.rs: PID on the error, clamped; conditional integration (anti-windup).
        e = qr - q
        unsat = kp * e + ki * (integral + e * dt) + kd * (qdr - qd)
        tau = np.where(limited, np.clip(unsat, -lim, lim), unsat)
        saturated = (tau != unsat) & (np.sign(unsat) == np.sign(e))
        integral = np.where(saturated, integral, np.clip(integral + e * dt, -cap, cap))
        data.ctrl[:] = np.where(d.pid, tau, 0.0)
        mujoco.mj_step(model, data)
        # The velocity the sim measures: the coordinate's change over the step.
        q = d.q(data)
        qd = (q - q_prev) / dt
        q_prev = q
        err = q - qr
        sum_sq += err * err
        np.maximum(max_err, np.abs(err), out=max_err)
        # mj_step computes positions before it integrates: site_xpos lags qpos by one step.
        if len(sites):
            gap = float(np.max(np.linalg.norm(data.site_xpos[sa] - data.site_xpos[sb], axis=1)))
            max_closure = max(max_closure, gap)
            if s >= steps - steps // 10:
                final_closure = max(final_closure, gap)
        if qs is not None:
            qs[s] = q
    wall = time.perf_counter() - start
    rms = np.sqrt(sum_sq / steps)
    out: Dict[str, Any] = {
        "joints": [{"name": nm, "rms_error": float(r), "max_error": float(m)} for nm, r, m in zip(d.names, rms, max_err)],
        "max_closure_error": max_closure,
        "final_closure_error": final_closure,
        "wall_time": wall,
        "real_time_factor": steps * dt / wall,
        "steps": steps,
        "dt": dt,
    }
    if qs is not None:
        out["q"] = qs
    return out
