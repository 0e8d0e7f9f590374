"""dvrk_twin.Sim and run_scene: stepping, control modes, physics figures and bad commands."""

import numpy as np
import pytest

import dvrk_twin


def test_builtin_scenes_and_joint_names():
    assert {"psm", "ecm"} <= set(dvrk_twin.builtin_scenes())
    sim = dvrk_twin.Sim.from_scene("psm")
    assert sim.nq == 7 and sim.joint_names[0] == "PSM1/outer_yaw"
    assert sim.dt == pytest.approx(1e-3)


def test_pid_holds_and_tracks_a_step():
    sim = dvrk_twin.Sim.from_scene("psm")
    q0 = sim.q.copy()
    sim.set_target("PSM1/outer_yaw", q0[0] + 0.1)
    sim.step(2000)  # 2 s
    assert sim.time == pytest.approx(2.0, abs=1e-9)
    assert abs(sim.q[0] - (q0[0] + 0.1)) < 0.01  # rad
    assert sim.closure_error < 1e-3  # m
    assert np.all(np.isfinite(sim.qd))


def test_effort_mode_clamps_at_the_effort_limit():
    sim = dvrk_twin.Sim.from_scene("psm")
    sim.set_mode(3, "effort")
    sim.set_effort(3, 100.0)  # far above the roll's 0.33 N·m
    sim.step(5)
    assert sim.effort(3) == pytest.approx(0.33, rel=1e-9)


def test_run_scene_reports_the_papers_figures():
    s = dvrk_twin.run_scene("psm", 2.0, trajectory="sine")
    assert s["scene"] == "psm" and s["finite"]
    assert s["real_time_factor"] > 1.0
    assert len(s["joints"]) == 7
    assert s["max_closure_error"] < 1e-3  # m
    yaw = s["joints"][0]
    assert yaw["joint"] == "outer_yaw" and 0.0 < yaw["rms_error"] < 0.05  # rad


def test_bad_commands_are_rejected():
    sim = dvrk_twin.Sim.from_scene("psm")
    with pytest.raises(ValueError, match="finite"):
        sim.set_target(0, float("nan"))
    with pytest.raises(ValueError, match="gain"):
        sim.set_gains(0, -1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="unknown joint"):
        sim.set_target("PSM9/yaw", 0.0)
    with pytest.raises(ValueError, match="mode"):
        sim.set_mode(0, "fly")
    with pytest.raises(dvrk_twin.DvrkError):
        dvrk_twin.Sim.from_scene("no-such-scene")
    with pytest.raises(ValueError, match="duration"):
        dvrk_twin.run_scene("psm", -1.0)


def diverging_scene(tmp_path):
    """The PSM scene with a derivative gain its inertia cannot carry (kd dt / I >> 2)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "models" / "scenes" / "psm.toml").read_text()
    lines = []
    for line in text.splitlines():
        if line.startswith("kd = "):
            line = "kd = [5000.0, 5000.0, 5000.0, 5000.0, 5000.0, 5000.0, 5000.0]"
        elif line.startswith("armature = "):
            line = "armature = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]"
        lines.append(line)
    path = tmp_path / "blow.toml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_a_diverging_simulation_raises_and_never_reads_as_closed(tmp_path):
    scene = diverging_scene(tmp_path)
    with pytest.raises(dvrk_twin.DvrkError, match="went non-finite"):
        dvrk_twin.run_scene(scene, 1.0)
    sim = dvrk_twin.Sim.from_scene(scene)
    sim.set_target(0, 0.3)
    with pytest.raises(dvrk_twin.DvrkError, match=r"went non-finite at t = .* s: joint \d+"):
        sim.step(1000)
    # The state is left as it is, and its loop-closure gap reads as open (NaN or large), not 0.
    assert not (np.all(np.isfinite(sim.q)) and np.all(np.isfinite(sim.qd)))
    gap = sim.closure_error
    assert np.isnan(gap) or gap > 1e-3, gap
