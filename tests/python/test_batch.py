"""dvrk_twin.BatchSim: many copies stepped in parallel, each as a lone Sim, without the GIL."""

import pathlib
import threading

import numpy as np
import pytest

import dvrk_twin


def commands(home, n, step, dt):
    """Per copy and joint a different small sine about home: (targets, velocities), (n, nq)."""
    t = step * dt
    c = np.arange(n)[:, None]
    j = np.arange(home.size)[None, :]
    w = 2.0 + c + 0.3 * j
    return home + 0.05 * np.sin(w * t), 0.05 * w * np.cos(w * t)


def test_each_copy_steps_as_a_lone_sim_with_the_same_commands():
    n, calls, k = 4, 20, 10
    batch = dvrk_twin.BatchSim.from_scene("psm", n, threads=2)
    assert (batch.n, batch.nq, batch.threads) == (n, 7, 2)
    assert batch.q.shape == (n, 7) and batch.joint_names[0] == "PSM1/outer_yaw"
    home = batch.q[0].copy()
    np.testing.assert_array_equal(batch.target, np.tile(home, (n, 1)))  # holding the start
    q_view = batch.q
    history = []
    for s in range(calls):
        batch.target[:], batch.target_velocity[:] = commands(home, n, s * k, batch.dt)
        batch.step(k)
        history.append(batch.q.copy())
    assert q_view is batch.q or np.shares_memory(q_view, batch.q)  # updated in place
    assert batch.time == pytest.approx([calls * k * batch.dt] * n)
    for c in (0, n - 1):
        sim = dvrk_twin.Sim.from_scene("psm", engine="reduced")
        for s in range(calls):
            p, v = commands(home, n, s * k, batch.dt)
            for j in range(7):
                sim.set_target(j, p[c, j], v[c, j])
            sim.step(k)
            np.testing.assert_array_equal(sim.q, history[s][c])
    assert np.abs(history[-1][0] - history[-1][1]).max() > 1e-3  # the copies differ


def test_stepping_releases_the_gil():
    batch = dvrk_twin.BatchSim.from_scene("psm", 8, threads=1)
    count = [0]
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            count[0] += 1

    thread = threading.Thread(target=spin)
    thread.start()
    try:
        before = count[0]
        batch.step(4000)  # 8 x 4 s of PSM: a good fraction of a second with the GIL released
        during = count[0] - before
    finally:
        stop.set()
        thread.join()
    # Holding the GIL, the spinning thread would not run at all during the call.
    assert during > 10000, during


def test_reset_modes_models_and_bad_input(tmp_path):
    batch = dvrk_twin.BatchSim.from_scene("psm", 3, threads=2)
    home = batch.q[0].copy()
    batch.target = home + 0.05  # broadcast to every copy
    batch.step(500)
    start = home.copy()
    start[:2] += 0.2
    batch.reset([1], q=start)
    np.testing.assert_array_equal(batch.q[1], start)
    np.testing.assert_array_equal(batch.target[1], start)
    assert batch.time[1] == 0.0 and batch.time[0] == pytest.approx(0.5)
    batch.reset()  # all at the scene's start
    np.testing.assert_array_equal(batch.q, np.tile(home, (3, 1)))
    # Effort mode on one copy's roll: the command is clamped at the roll's effort limit.
    batch.set_mode("PSM1/outer_roll", "effort", copy=2)
    batch.effort_command[2, 3] = 100.0
    batch.step(5)
    assert batch.effort[2, 3] == pytest.approx(0.33, rel=1e-9)
    assert batch.effort[0, 3] != pytest.approx(0.33, rel=1e-3)
    # A payload on copy 0 from a model file: its pitch needs more effort to hold home.
    models = pathlib.Path(__file__).resolve().parents[2] / "models"
    text = (models / "psm.toml").read_text()
    path = tmp_path / "payload.toml"
    path.write_text(text + '\n[[effects]]\nname = "payload_mass"\nlink = "pitch_end"\nparameters = { mass = 0.3, y = -0.2 }\n')
    batch.reset()
    batch.set_model(0, str(path))
    batch.step(3000)
    assert abs(batch.effort[0, 1] - batch.effort[1, 1]) > 0.1
    # Bad input: named, nothing moves.
    q = batch.q.copy()
    batch.target[2, 4] = np.nan
    with pytest.raises(dvrk_twin.DvrkError, match=r"target\[2, 4\]"):
        batch.step(1)
    np.testing.assert_array_equal(batch.q, q)
    with pytest.raises(ValueError, match="3 copies"):
        batch.reset(5)
    with pytest.raises(ValueError, match="shape"):
        batch.reset(0, q=np.zeros(3))
    with pytest.raises(ValueError, match="engine"):
        dvrk_twin.BatchSim.from_scene("psm", 2, engine="bullet")
