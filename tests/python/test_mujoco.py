"""A second engine agrees: the exported MJCF (``dvrk_twin.export_mjcf``) run in MuJoCo under the
same PID (``dvrk_twin.mujoco_run``) on the section 4.3 tracking test, against our rapier run of
the same scene (``dvrk_twin.run_scene``). Units: m, rad, s.

The issue asks each joint's tracking RMS within 2% of ours. Measured (10 s, dt = 1 ms): every
joint of the ECM and every PSM joint but two within 0.1%. The two PSM joints driven through a
cable (insertion with its counterweight, the jaw with its second blade) differ by 5% and 26%: the
200 rad/s cable (omega dt = 0.2) is integrated differently by the two engines (rapier: implicit on
the follower, explicit across; MuJoCo's Euler: explicit tendon), the RMS of both joints is mostly
their start-up transient (the cables start unstretched), and the difference halves with each
halving of dt (checked below), i.e. it is first-order discretisation error, not a model
difference. Those two joints are held to that convergence instead of the 2%.
"""

import numpy as np
import pytest

mujoco = pytest.importorskip(
    "mujoco",
    reason="the MuJoCo cross-check needs the PyPI package `mujoco` (pip install mujoco), "
    "which could not be imported here",
)

import dvrk_twin  # noqa: E402
from dvrk_twin import mujoco_run  # noqa: E402

#: PSM joints coupled to a passive joint by a cable (see the module docstring).
CABLE_JOINTS = {"PSM1/outer_insertion", "PSM1/jaw"}


def ratios(scene, duration):
    """Per joint: MuJoCo RMS / our RMS, and both runs' summaries."""
    ours = dvrk_twin.run_scene(scene, duration)
    mj = mujoco_run.run_tracking(dvrk_twin.export_mjcf(scene), duration)
    names = [f'{j["arm"]}/{j["joint"]}' for j in ours["joints"]]
    assert names == [j["name"] for j in mj["joints"]]
    r = {n: m["rms_error"] / o["rms_error"] for n, m, o in zip(names, mj["joints"], ours["joints"]) if o["rms_error"] > 0}
    for n in r:
        print(f"{scene} {n}: MuJoCo/ours tracking RMS = {r[n]:.4f}")
    print(f"{scene}: loop-closure gap MuJoCo {mj['max_closure_error']:.3e} m, ours {ours['max_closure_error']:.3e} m")
    return r, ours, mj


def test_every_builtin_scene_compiles_in_mujoco_with_our_masses_and_counts():
    for scene in dvrk_twin.builtin_scenes():
        m = mujoco.MjModel.from_xml_string(dvrk_twin.export_mjcf(scene))
        sim = dvrk_twin.Sim.from_scene(scene)
        assert m.nu == sim.nq, scene
        assert m.opt.timestep == sim.dt, scene
        drives = mujoco_run.Drives(m)
        assert drives.names == sim.joint_names, scene
        # MuJoCo's qpos at its reference configuration is our home q.
        d = mujoco.MjData(m)
        np.testing.assert_allclose(drives.q(d), sim.q, atol=1e-12)
        # Bodies (world excluded) each with a joint, and a positive mass.
        assert m.nbody - 1 == m.njnt and (m.body_mass[1:] > 0).all(), scene


def test_psm_tracking_rms_agrees_with_mujoco():
    r, ours, mj = ratios("psm", 10.0)
    for n, x in r.items():
        if n not in CABLE_JOINTS:
            assert abs(x - 1) < 0.02, (n, x)
    # Cable joints at dt = 1 ms: measured 0.951 (insertion) and 0.736 (jaw).
    assert abs(r["PSM1/outer_insertion"] - 1) < 0.06, r
    assert abs(r["PSM1/jaw"] - 1) < 0.30, r
    # MuJoCo's stiff connects hold the parallelograms within 2 um (ours: 1e-8 m).
    assert mj["max_closure_error"] < 2e-6 and ours["max_closure_error"] < 1e-7


def test_ecm_tracking_rms_agrees_with_mujoco():
    r, ours, mj = ratios("ecm", 10.0)
    assert len(r) == 4
    for n, x in r.items():
        assert abs(x - 1) < 0.02, (n, x)
    assert mj["max_closure_error"] < 2e-6


def test_cable_joint_difference_is_discretisation_error(tmp_path):
    """Halving dt halves the cable joints' difference (first-order convergence to agreement)."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "models" / "scenes" / "psm.toml").read_text()
    assert "\ndt = 0.001\n" in text
    gaps = []
    for dt in [0.001, 0.0005, 0.00025]:
        scene = tmp_path / f"psm-{dt}.toml"
        scene.write_text(text.replace("\ndt = 0.001\n", f"\ndt = {dt}\n"))
        r, _, _ = ratios(str(scene), 2.0)
        gaps.append({n: abs(r[n] - 1) for n in CABLE_JOINTS})
        # The other joints stay within 2% at every step size.
        assert all(abs(x - 1) < 0.02 for n, x in r.items() if n not in CABLE_JOINTS), r
    print("cable joints |MuJoCo/ours - 1| at dt = 1, 0.5, 0.25 ms:", gaps)
    for n in CABLE_JOINTS:
        assert gaps[1][n] < 0.7 * gaps[0][n] and gaps[2][n] < 0.7 * gaps[1][n], (n, gaps)
    assert gaps[2]["PSM1/outer_insertion"] < 0.02, gaps


def test_full_cart_agrees_and_mujoco_holds_the_setup_joints():
    """The cart: setup joints held by the MJCF's joint equalities (regression: MuJoCo counts a
    joint equality's polynomial from the joint's ``ref``, so a hold written at the absolute home
    coordinate flung the SUJ 2 rad away and the scene blew up within 5 ms)."""
    r, ours, mj = ratios("full", 2.0)
    for n, x in r.items():
        if n.split("/")[1] not in {"outer_insertion", "jaw"} and not n.startswith("SUJ"):
            assert abs(x - 1) < 0.02, (n, x)
    suj = [j for j in mj["joints"] if j["name"].startswith("SUJ")]
    assert len(suj) == 22 and max(j["max_error"] for j in suj) < 1e-6, suj
    assert mj["max_closure_error"] < 2e-6
