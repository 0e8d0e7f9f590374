"""Tests of the Python package `dvrk_twin` (crates/dvrk-py), on real numbers.

Build and install the wheel first, from the workspace root:

    maturin build --release -m crates/dvrk-py/Cargo.toml -o dist
    pip install --force-reinstall dist/dvrk_twin-*.whl
    pytest tests/python -q

Units: m, rad. Tests that need the external dVRK data (../shared/data/external/) skip, saying
so, when it is absent.
"""

import csv
import math
import threading
from pathlib import Path

import numpy as np
import pytest

import dvrk_twin
from dvrk_twin import DvrkError, IkError, InputError, Model, ModelError, ModelNotFoundError

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "models"
EXTERNAL = ROOT.parent / "shared" / "data" / "external"
DVRK_CONFIG = EXTERNAL / "dvrk-config"
JHU_CSV = EXTERNAL / "jhu-kinematic-calib" / "Si_tool_fixed.csv"

needs_dvrk_config = pytest.mark.skipif(
    not DVRK_CONFIG.is_dir(),
    reason=f"external dVRK configuration files not found at {DVRK_CONFIG} "
    "(a fresh clone has no ../shared/data/external; CI has it)",
)
needs_jhu_data = pytest.mark.skipif(
    not (JHU_CSV.is_file() and DVRK_CONFIG.is_dir()),
    reason=f"external JHU calibration recording not found at {JHU_CSV} "
    "(a fresh clone has no ../shared/data/external; CI has it)",
)

# PSM remote centre of motion in its base frame (m): 0.516 - 0.0296 along -y (Table 4).
PSM_RCM = np.array([0.0, -0.4864, 0.0])


@pytest.fixture(scope="module")
def psm() -> Model:
    return Model.load("psm")


@pytest.fixture(scope="module")
def ecm() -> Model:
    return Model.load("ecm")


def random_q(model: Model, n: int, seed: int = 0, margin: float = 0.0) -> np.ndarray:
    """n configurations uniformly within the joint limits (shrunk by `margin` of the range)."""
    rng = np.random.default_rng(seed)
    lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
    u = margin + (1.0 - 2.0 * margin) * rng.random((n, model.nq))
    return lo + (hi - lo) * u


def pos(model: Model, number: int) -> int:
    """Frame position of the paper's frame `number`."""
    return model.frame_indices.index(number)


def transform_point(poses: np.ndarray, p) -> np.ndarray:
    """World position of point p (m, given in the frame) for poses (..., 4, 4)."""
    return poses[..., :3, :3] @ np.asarray(p, float) + poses[..., :3, 3]


def rotation_angle(r: np.ndarray) -> float:
    """Angle (rad) of the rotation matrix r, accurate near zero."""
    f = np.linalg.norm(r - np.eye(3))
    return 2.0 * math.asin(min(float(f) / (2.0 * math.sqrt(2.0)), 1.0))


def rodrigues(rv: np.ndarray) -> np.ndarray:
    a = np.linalg.norm(rv)
    if a == 0.0:
        return np.eye(3)
    k = rv / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


def call_with_timeout(fn, seconds: float = 60.0):
    """Run fn() in a daemon thread: a solver that never returns fails the test instead of
    hanging the suite (ik releases the GIL, so the wait works)."""
    out = {}

    def run():
        try:
            out["value"] = fn()
        except BaseException as e:  # noqa: BLE001 - re-raised below
            out["error"] = e

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    if t.is_alive():
        pytest.fail(f"did not return within {seconds} s")
    if "error" in out:
        raise out["error"]
    return out["value"]


# ---------------------------------------------------------------- module and loading


def test_module_exports():
    assert isinstance(dvrk_twin.__version__, str) and dvrk_twin.__version__.count(".") == 2
    names = dvrk_twin.builtin_models()
    assert {"psm", "ecm", "cart", "suj-psm1", "suj-ecm", "mtml", "mtmr", "psm-serial"} <= set(names)
    # The exception hierarchy that callers rely on.
    assert issubclass(ModelError, DvrkError) and issubclass(ModelError, ValueError)
    assert issubclass(InputError, DvrkError) and issubclass(InputError, ValueError)
    assert issubclass(IkError, DvrkError) and issubclass(IkError, ValueError)
    assert issubclass(ModelNotFoundError, DvrkError)
    assert issubclass(ModelNotFoundError, FileNotFoundError) and issubclass(ModelNotFoundError, ValueError)
    assert DvrkError.__module__ == "dvrk_twin" and Model.__module__ == "dvrk_twin"
    # Every public function carries a docstring with its units.
    for f in (Model.fk, Model.jacobian, Model.ik, Model.closure_residual, Model.pivot_residual):
        assert f.__doc__ and ("(m" in f.__doc__ or " m)" in f.__doc__ or "rad" in f.__doc__), f
    assert Path(dvrk_twin.__file__).with_name("py.typed").is_file()
    assert Path(dvrk_twin.__file__).with_name("_dvrk_twin.pyi").is_file()


@pytest.mark.parametrize("name", dvrk_twin.builtin_models())
def test_every_builtin_model_loads_and_evaluates(name):
    m = Model.load(name)
    assert m.name and m.nq == len(m.joint_names) == len(m.joint_types) == m.joint_limits.shape[0]
    assert m.nframes == len(m.frame_names) == len(m.frame_indices) == len(m.frame_parents)
    assert sorted(f for _, fs in m.bodies for f in fs) == list(range(m.nframes))
    lo, hi = m.joint_limits.T
    assert np.all(lo <= m.home) and np.all(m.home <= hi)
    frames = m.fk(m.home)
    assert frames.shape == (m.nframes, 4, 4) and frames.dtype == np.float64
    assert m.closure_residual(m.home) < 1e-12
    assert repr(m).startswith(f"<dvrk_twin.Model '{m.name}'")


def test_load_model_file_by_path_equals_builtin(psm):
    q = random_q(psm, 5, seed=3)
    for arg in (str(MODELS / "psm.toml"), MODELS / "psm.toml"):
        m = Model.load(arg)
        assert m.name == "psm"
        np.testing.assert_array_equal(m.fk(q), psm.fk(q))


def test_psm_properties(psm):
    assert psm.name == "psm" and psm.nq == 7 and psm.nframes == 17
    assert psm.joint_names == [
        "outer_yaw", "outer_pitch", "outer_insertion", "outer_roll",
        "outer_wrist_pitch", "outer_wrist_yaw", "jaw",
    ]
    assert psm.joint_types[2] == "prismatic" and psm.joint_types.count("revolute") == 6
    lim = psm.joint_limits
    assert lim.shape == (7, 2)
    np.testing.assert_array_equal(lim[0], [-1.588, 1.588])  # rad
    np.testing.assert_array_equal(lim[2], [0.0, 0.24])  # m
    np.testing.assert_array_equal(psm.home, [0, 0, 0.12, 0, 0, 0, 0.3])
    assert sorted(psm.frame_indices) == list(range(1, 18))
    # Parents come before children; frame 1 hangs from the base; frames 3, 4, 5 from frame 2.
    parents = psm.frame_parents
    assert parents[pos(psm, 1)] is None
    assert all(p is None or p < i for i, p in enumerate(parents))
    for child in (3, 4, 5):
        assert parents[pos(psm, child)] == pos(psm, 2)
    assert psm.tip == pos(psm, 17) and psm.frame_names[psm.tip] == "tool_tip"
    assert psm.frame_position(17) == psm.frame_position("tool_tip") == psm.tip
    np.testing.assert_allclose(psm.rcm, PSM_RCM, atol=1e-12)
    np.testing.assert_array_equal(psm.base, np.eye(4))
    bodies = dict(psm.bodies)
    assert set(bodies["pitch_back_link"]) == {pos(psm, 3), pos(psm, 5), pos(psm, 10)}
    (c1, c2) = psm.closures
    assert c1[0] == "c1" and c1[1] == pos(psm, 4) and c1[3] == pos(psm, 6)
    np.testing.assert_array_equal(c1[2], [0.150, 0, 0])
    np.testing.assert_array_equal(c1[4], [0.096, 0, 0])
    assert c2[0] == "c2" and c2[1] == pos(psm, 7) and c2[3] == pos(psm, 8)


def test_ecm_and_models_without_rcm(ecm):
    assert ecm.nq == 4 and ecm.rcm is not None and ecm.rcm.shape == (3,)
    assert ecm.pivot_residual(ecm.home) < 1e-12
    mtm = Model.load("mtml")
    assert mtm.rcm is None and mtm.pivot_residual(mtm.home) is None
    # The MTM's elbow parallelogram closes exactly (the rod on the forearm).
    assert mtm.closure_residual(mtm.home) < 1e-12 and len(mtm.closures) == 1


def test_cart_loads_and_evaluates():
    cart = Model.load("cart")
    assert cart.nq > 40 and cart.nframes > 80
    assert any(n.startswith("PSM1/") for n in cart.frame_names)
    frames = cart.fk(cart.home)
    assert frames.shape == (cart.nframes, 4, 4)
    np.testing.assert_array_equal(frames[:, 3], np.tile([0, 0, 0, 1.0], (cart.nframes, 1)))
    q = random_q(cart, 20, seed=5)
    batch = cart.fk(q)
    assert batch.shape == (20, cart.nframes, 4, 4)
    np.testing.assert_array_equal(batch[7], cart.fk(q[7]))
    assert max(cart.closure_residual(x) for x in q) < 1e-12
    assert cart.fk(q, frame="PSM1/tool_tip").shape == (20, 4, 4)


# ---------------------------------------------------------------- forward kinematics


def test_psm_closures_and_pivot_hold_over_1000_configurations(psm):
    q = random_q(psm, 1000, seed=1)
    frames = psm.fk(q)
    assert frames.shape == (1000, 17, 4, 4)
    # Closure c1: point (0.150, 0, 0) of frame 4 is point (0.096, 0, 0) of frame 6.
    a = transform_point(frames[:, pos(psm, 4)], [0.150, 0.0, 0.0])
    b = transform_point(frames[:, pos(psm, 6)], [0.096, 0.0, 0.0])
    assert np.linalg.norm(a - b, axis=1).max() < 1e-12
    # Every closure the model declares (c2's partner point is computed at home).
    for _, f, p, g, pp in psm.closures:
        gap = transform_point(frames[:, f], p) - transform_point(frames[:, g], pp)
        assert np.linalg.norm(gap, axis=1).max() < 1e-12
    # Pivot: the insertion axis (z of frame 9) passes through the RCM (0, -0.4864, 0) m.
    f9 = frames[:, pos(psm, 9)]
    rcm = transform_point(psm.base, psm.rcm)
    v = rcm - f9[:, :3, 3]
    z = f9[:, :3, 2]
    dist = np.linalg.norm(v - z * np.sum(z * v, axis=1, keepdims=True), axis=1)
    assert dist.max() < 1e-12
    # The scalar residuals agree with the ones computed here.
    for k in range(0, 1000, 50):
        assert psm.closure_residual(q[k]) < 1e-12
        assert abs(psm.pivot_residual(q[k]) - dist[k]) < 1e-13


def test_batch_fk_equals_loop_of_single_calls(psm, ecm):
    for m in (psm, ecm):
        q = random_q(m, 64, seed=2)
        batch = m.fk(q)
        single = np.stack([m.fk(x) for x in q])
        np.testing.assert_array_equal(batch, single)
        tip = m.frame_indices[m.tip]
        np.testing.assert_array_equal(m.fk(q, frame=tip), batch[:, m.tip])
        np.testing.assert_array_equal(m.fk(q[3], frame=m.frame_names[m.tip]), batch[3, m.tip])
        # Any array-like and any memory layout: lists, Fortran order, strided views, ints.
        np.testing.assert_array_equal(m.fk(q.tolist()), batch)
        np.testing.assert_array_equal(m.fk(np.asfortranarray(q)), batch)
        np.testing.assert_array_equal(m.fk(np.repeat(q, 2, axis=0)[::2]), batch)
        np.testing.assert_array_equal(m.fk(np.zeros(m.nq, dtype=int)), m.fk(np.zeros(m.nq)))
    assert psm.fk(np.zeros((0, 7))).shape == (0, 17, 4, 4)


def test_fk_poses_are_rigid_transforms(psm):
    frames = psm.fk(random_q(psm, 200, seed=4))
    r = frames[..., :3, :3]
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    np.testing.assert_array_equal(frames[..., 3, :], np.broadcast_to([0, 0, 0, 1.0], frames[..., 3, :].shape))


def test_psm_home_tip_pose(psm):
    # At home the insertion axis is vertical through the RCM, and the tip sits
    # 0.12 (insertion) + 0.4162 (tool) + 0.0091 (jaw offset) - 0.4318 (RCM offset) = 0.1135 m below it.
    t = psm.fk(psm.home, frame=17)
    np.testing.assert_allclose(t[:3, 3], [0.0, -0.4864, -0.1135], atol=1e-12)
    np.testing.assert_allclose(t[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)


# ---------------------------------------------------------------- Jacobian


def fd_jacobian(model: Model, q: np.ndarray, frame, h: float = 1e-6) -> np.ndarray:
    """Central finite differences of fk: rows linear (m per unit q), angular (rad per unit q)."""
    j = np.zeros((6, model.nq))
    for k in range(model.nq):
        dq = np.zeros(model.nq)
        dq[k] = h
        tp, tm = model.fk(q + dq, frame=frame), model.fk(q - dq, frame=frame)
        j[:3, k] = (tp[:3, 3] - tm[:3, 3]) / (2 * h)
        w = (tp[:3, :3] @ tm[:3, :3].T - tm[:3, :3] @ tp[:3, :3].T) / 2  # ~ skew(omega) * 2h
        j[3:, k] = np.array([w[2, 1], w[0, 2], w[1, 0]]) / (2 * h)
    return j


@pytest.mark.parametrize("name,frame", [("psm", 17), ("psm", 9), ("psm", "pitch_top"), ("ecm", None)])
def test_jacobian_matches_finite_differences(name, frame):
    m = Model.load(name)
    frame_arg = m.frame_indices[m.tip] if frame is None else frame
    qs = random_q(m, 8, seed=6, margin=0.01)
    for q in qs:
        j = m.jacobian(q) if frame is None else m.jacobian(q, frame=frame)
        assert j.shape == (6, m.nq)
        np.testing.assert_allclose(j, fd_jacobian(m, q, frame_arg), atol=1e-6)
    batch = m.jacobian(qs) if frame is None else m.jacobian(qs, frame=frame)
    assert batch.shape == (8, 6, m.nq)
    np.testing.assert_array_equal(batch[5], m.jacobian(qs[5], frame=frame_arg))


def test_jacobian_columns_have_their_units(psm):
    j = psm.jacobian(psm.home)
    # Insertion (m): pure translation along the tool axis, unit speed, no rotation.
    np.testing.assert_allclose(j[:3, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(j[3:, 2], 0, atol=1e-12)
    # Jaw (rad) does not move the tool-tip frame.
    np.testing.assert_array_equal(j[:, 6], 0)


# ---------------------------------------------------------------- inverse kinematics


def test_ik_round_trip_psm_tool_tip(psm):
    lo, hi = psm.joint_limits.T
    for q in random_q(psm, 12, seed=7, margin=0.05):
        target = psm.fk(q, frame=17)
        sol = call_with_timeout(lambda: psm.ik(target))
        assert sol.shape == (7,)
        assert np.all(sol >= lo - 1e-9) and np.all(sol <= hi + 1e-9)
        got = psm.fk(sol, frame=17)
        assert np.linalg.norm(got[:3, 3] - target[:3, 3]) < 1e-9
        assert rotation_angle(got[:3, :3].T @ target[:3, :3]) < 1e-8
    # From a nearby seed, the solver returns the configuration it started next to.
    q = random_q(psm, 1, seed=8, margin=0.1)[0]
    sol = call_with_timeout(lambda: psm.ik(psm.fk(q, frame="tool_tip"), seed=q + 0.01))
    np.testing.assert_allclose(sol[:6], q[:6], atol=1e-7)


def test_ik_round_trip_ecm_position(ecm):
    tip = ecm.frame_indices[ecm.tip]
    for q in random_q(ecm, 12, seed=9, margin=0.05):
        target = ecm.fk(q, frame=tip)
        sol = call_with_timeout(lambda: ecm.ik(target))
        got = ecm.fk(sol, frame=tip)
        assert np.linalg.norm(got[:3, 3] - target[:3, 3]) < 1e-9


def test_ik_other_frame(psm):
    q = random_q(psm, 1, seed=10, margin=0.1)[0]
    target = psm.fk(q, frame=9)
    sol = call_with_timeout(lambda: psm.ik(target, frame=9))
    assert np.linalg.norm(psm.fk(sol, frame=9)[:3, 3] - target[:3, 3]) < 1e-9


def test_ik_errors(psm):
    far = np.eye(4)
    far[:3, 3] = [2.0, 2.0, 2.0]  # m: far outside the workspace
    with pytest.raises(IkError, match="out of reach") as e:
        call_with_timeout(lambda: psm.ik(far))
    assert isinstance(e.value, ValueError) and isinstance(e.value, DvrkError)
    with pytest.raises(InputError, match=r"expected \(4, 4\), got \(3, 3\)"):
        psm.ik(np.eye(3))
    with pytest.raises(ValueError, match="not a rotation"):
        psm.ik(np.diag([2.0, 2.0, 2.0, 1.0]))
    nan = np.eye(4)
    nan[0, 3] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        psm.ik(nan)
    with pytest.raises(ValueError, match="expected 7, got 3"):
        psm.ik(psm.fk(psm.home, frame=17), seed=[0.0, 0.0, 0.1])


# ---------------------------------------------------------------- check


@pytest.mark.parametrize("name", ["psm", "ecm"])
def test_check_reports_ok(name):
    report = Model.load(name).check()
    assert report["ok"] is True and report["problems"] == []
    assert report["model"] == name and report["samples"] == 2000
    assert report["max_closure_residual_m"] < 1e-12
    assert report["max_pivot_residual_m"] < 1e-12
    assert report["serial_equivalence"]["max_position_error_m"] < 1e-9
    if name == "psm":
        np.testing.assert_allclose(report["rcm"], PSM_RCM, atol=1e-12)


def test_check_samples_argument():
    report = Model.load("mtml").check(samples=10)
    assert report["samples"] == 10 and report["ok"] is True
    assert report["rcm"] is None and report["max_closure_residual_m"] < 1e-12
    # The CLI's bounds (one function behind both): nothing checked is not "ok", and 10**12
    # configurations are refused, not allocated.
    for n in (0, 10**12):
        with pytest.raises(dvrk_twin.DvrkError, match=r"samples = .*: must be in 1\.\.=10000000"):
            Model.load("psm").check(samples=n)


# ---------------------------------------------------------------- bad input


def test_deeply_nested_files_raise_instead_of_crashing(tmp_path):
    # 30,000 levels took the interpreter down with SIGSEGV (issue 45).
    deep = tmp_path / "deep.urdf"
    deep.write_text('<robot name="r">' + "<a>" * 30000 + "</a>" * 30000 + "</robot>")
    with pytest.raises(DvrkError, match="nested 30001 levels deep"):
        Model.load(str(deep))
    deep_json = tmp_path / "deep.json"
    deep_json.write_text("[" * 30000 + "]" * 30000)
    with pytest.raises(DvrkError, match="nested 30000 levels deep"):
        Model.load(str(deep_json))


def test_wrong_q_length(psm):
    for call in (psm.fk, psm.jacobian, psm.closure_residual, psm.pivot_residual):
        with pytest.raises(ValueError, match="expected 7, got 6") as e:
            call(np.zeros(6))
        assert isinstance(e.value, InputError)
        assert str(e.value) == "wrong argument size for q of model psm: expected 7, got 6"
    with pytest.raises(ValueError, match="expected 7, got 8"):
        psm.fk(np.zeros((10, 8)))
    with pytest.raises(ValueError, match="shape"):
        psm.fk(np.zeros((2, 3, 7)))
    with pytest.raises(ValueError, match="shape"):
        psm.closure_residual(np.zeros((2, 7)))
    with pytest.raises(ValueError, match="shape"):
        psm.fk(1.0)


def test_non_finite_q(psm):
    q = psm.home.copy()
    q[1] = np.nan
    for call in (psm.fk, psm.jacobian, psm.closure_residual, psm.pivot_residual):
        with pytest.raises(ValueError, match="joint outer_pitch = NaN: not finite"):
            call(q)
    batch = np.tile(psm.home, (4, 1))
    batch[2, 4] = np.inf
    with pytest.raises(InputError, match=r"q\[2\]: joint outer_wrist_pitch = inf: not finite"):
        psm.fk(batch)


def test_non_numeric_q(psm):
    with pytest.raises((TypeError, ValueError)):
        psm.fk(["a"] * 7)


def test_unknown_frame(psm):
    with pytest.raises(InputError, match="unknown frame `99`; valid: yaw, pitch_base"):
        psm.fk(psm.home, frame=99)
    with pytest.raises(ValueError, match="unknown frame `nope`"):
        psm.jacobian(psm.home, frame="nope")
    with pytest.raises(TypeError):
        psm.fk(psm.home, frame=1.5)


def test_unknown_model_lists_valid_names(tmp_path):
    with pytest.raises(ModelNotFoundError) as e:
        Model.load("psm4")
    msg = str(e.value)
    assert msg.startswith("unknown model `psm4`; valid: psm, ecm,")
    assert "cart" in msg and ".toml" in msg
    assert isinstance(e.value, FileNotFoundError) and isinstance(e.value, ValueError)
    with pytest.raises(FileNotFoundError, match="no-such.toml"):
        Model.load(tmp_path / "no-such.toml")
    with pytest.raises(ModelNotFoundError, match="missing-tool.json"):
        Model.load("psm", tool=tmp_path / "missing-tool.json")


def test_malformed_model_file_names_the_file(tmp_path):
    text = (MODELS / "psm.toml").read_text()
    # A joint without its upper limit.
    broken = text.replace("lower = -0.925025\nupper = 0.925025\n", "lower = -0.925025\n", 1)
    assert broken != text
    path = tmp_path / "broken-psm.toml"
    path.write_text(broken)
    with pytest.raises(ModelError) as e:
        Model.load(str(path))
    assert str(path) in str(e.value) and "upper" in str(e.value)
    assert isinstance(e.value, ValueError) and isinstance(e.value, DvrkError)
    # Not TOML at all.
    bad = tmp_path / "garbage.toml"
    bad.write_text("name = [unclosed\n")
    with pytest.raises(ModelError, match="garbage.toml"):
        Model.load(bad)
    # A model whose expression is not affine.
    nonaffine = tmp_path / "nonaffine.toml"
    nonaffine.write_text(text.replace('theta = "q1 + pi/2"', 'theta = "q1*q2"', 1))
    with pytest.raises(ModelError, match="nonaffine.toml"):
        Model.load(nonaffine)


def test_urdf_import(tmp_path):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(
        """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <link name="link1"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="link1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
</robot>
"""
    )
    try:
        m = Model.load(urdf)
    except ModelError as e:
        if "not built yet" in str(e):
            pytest.skip(f"URDF import is not implemented in dvrk-kin yet: {e}")
        raise
    assert m.nq == 1 and m.joint_names == ["j1"]
    np.testing.assert_array_equal(m.joint_limits, [[-1.0, 1.0]])
    # Some frame is link1: at q = 0.5 rad, Rz(0.5) at (0, 0, 0.1) m.
    want = np.eye(4)
    want[:3, :3] = rodrigues(np.array([0, 0, 0.5]))
    want[2, 3] = 0.1
    frames = m.fk([0.5])
    assert min(np.abs(f - want).max() for f in frames) < 1e-12


# ---------------------------------------------------------------- external dVRK data


@needs_dvrk_config
def test_dvrk_json_with_tool_matches_closed_loop_psm(psm):
    arm = Model.load(DVRK_CONFIG / "PSM.json", tool=str(DVRK_CONFIG / "LARGE_NEEDLE_DRIVER_400006.json"))
    assert arm.nq == 7 and arm.frame_names[arm.tip] == "tool_tip"
    base = np.array(psm.check(samples=10)["serial_equivalence"]["base_transform"])
    q = random_q(psm, 200, seed=11)
    closed = psm.fk(q, frame=17)
    serial = base @ arm.fk(q, frame=arm.frame_indices[arm.tip])
    # The dVRK file gives its angles to 4 decimals (1.5708 for pi/2): agreement to ~10 um.
    assert np.abs(closed[:, :3, 3] - serial[:, :3, 3]).max() < 1e-4
    assert np.abs(closed[:, :3, :3] - serial[:, :3, :3]).max() < 1e-4


@needs_jhu_data
def test_psm_with_si_tool_reproduces_dvrk_controller_poses():
    """Real PSM recording (JHU): the controller's tool-tip pose from the same joints, in the
    PSM base (RCM) frame, with a Si large needle driver (tool file 420006)."""
    psm_si = Model.load("psm", tool=DVRK_CONFIG / "LARGE_NEEDLE_DRIVER_420006.json")
    to_rcm = np.linalg.inv(np.array(psm_si.check(samples=10)["serial_equivalence"]["base_transform"]))
    with JHU_CSV.open() as f:
        rows = list(csv.DictReader(f))
    q = np.array([[float(r[f"measured_q{i}"]) for i in range(1, 7)] + [0.0] for r in rows])
    p = np.array([[float(r[k]) for k in ("measured_x", "measured_y", "measured_z")] for r in rows])
    rv = np.array([[float(r[k]) for k in ("measured_rx", "measured_ry", "measured_rz")] for r in rows])
    tip = to_rcm @ psm_si.fk(q, frame="tool_tip")
    err = np.linalg.norm(tip[:, :3, 3] - p, axis=1)
    assert len(rows) > 4000
    assert np.median(err) < 1e-5 and err.max() < 1e-4  # m
    ang = [rotation_angle(rodrigues(rv[k]).T @ tip[k, :3, :3]) for k in range(0, len(rows), 10)]
    assert np.median(ang) < 1e-4  # rad
