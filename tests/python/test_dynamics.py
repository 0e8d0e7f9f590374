"""Model.inverse_dynamics, mass_matrix, gravity, regressor: batched over numpy, checked against
closed forms that share no code with the dynamics (a payload's weight through the FK Jacobian)
and against their own identities (ID = M qdd + h, Y pi = ID, g = ID at rest)."""

import pathlib

import numpy as np
import pytest

import dvrk_twin

MODELS = pathlib.Path(__file__).resolve().parents[2] / "models"


def random_states(model, n, seed=0):
    rng = np.random.default_rng(seed)
    lo, hi = model.joint_limits[:, 0], model.joint_limits[:, 1]
    q = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo), size=(n, model.nq))
    return q, rng.normal(size=(n, model.nq)), rng.normal(size=(n, model.nq))


@pytest.mark.parametrize("name", ["psm", "ecm"])
def test_the_dynamics_identities_hold_on_a_batch(name):
    m = dvrk_twin.Model.load(name)
    q, qd, qdd = random_states(m, 50)
    tau = m.inverse_dynamics(q, qd, qdd, effects=False)
    assert tau.shape == (50, m.nq)
    bias = m.inverse_dynamics(q, qd, None, effects=False)
    mass = m.mass_matrix(q, effects=False)
    assert mass.shape == (50, m.nq, m.nq)
    np.testing.assert_allclose(tau, bias + np.einsum("nij,nj->ni", mass, qdd), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mass, np.transpose(mass, (0, 2, 1)), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(mass) > 0)
    np.testing.assert_allclose(m.gravity(q), m.inverse_dynamics(q, effects=False), rtol=1e-12, atol=1e-12)
    y = m.regressor(q, qd, qdd)
    np.testing.assert_allclose(y @ m.inertial_parameters(), tau, rtol=1e-9, atol=1e-9)
    # One configuration: the shapes without the batch axis, the same numbers.
    np.testing.assert_allclose(m.inverse_dynamics(q[3], qd[3], qdd[3], effects=False), tau[3], rtol=1e-14)


def test_a_payloads_weight_is_its_jacobian_transpose(tmp_path):
    """0.3 kg at the origin of `pitch_end` adds J_p(q)^T (0, 0, m g) to the gravity torque, J_p
    the frame's linear Jacobian from FK: a closed form the dynamics code does not share."""
    base = (MODELS / "psm.toml").read_text()
    path = tmp_path / "psm-payload.toml"
    path.write_text(base + '\n[[effects]]\nname = "payload_mass"\nlink = "pitch_end"\nparameters = { mass = 0.3 }\n')
    plain, loaded = dvrk_twin.Model.load(str(MODELS / "psm.toml")), dvrk_twin.Model.load(str(path))
    q, _, _ = random_states(plain, 20, seed=4)
    extra = loaded.gravity(q) - plain.gravity(q)
    jac = plain.jacobian(q, frame="pitch_end")[:, :3, :]
    want = np.einsum("nij,i->nj", jac, np.array([0.0, 0.0, 0.3 * 9.81]))
    np.testing.assert_allclose(extra, want, rtol=1e-9, atol=1e-12)
    assert np.abs(want).max() > 0.1


def test_effects_add_friction_and_motor_inertia(tmp_path):
    base = (MODELS / "psm.toml").read_text()
    path = tmp_path / "psm-friction.toml"
    path.write_text(base + '\n[[effects]]\nname = "viscous_friction"\njoint = "outer_yaw"\nparameters = { fv = 0.5 }\n'
                    '\n[[effects]]\nname = "motor_inertia"\nactuator = 1\nparameters = { inertia = 0.01 }\n')
    m = dvrk_twin.Model.load(str(path))
    q, qd, qdd = random_states(m, 5, seed=2)
    diff = m.inverse_dynamics(q, qd, qdd) - m.inverse_dynamics(q, qd, qdd, effects=False)
    np.testing.assert_allclose(diff[:, 0], 0.5 * qd[:, 0] + 0.01 * qdd[:, 0], rtol=1e-9)
    np.testing.assert_allclose(diff[:, 1:], 0.0, atol=1e-12)
    dm = m.mass_matrix(q) - m.mass_matrix(q, effects=False)
    np.testing.assert_allclose(dm[:, 0, 0], 0.01, rtol=1e-12)


def test_bad_input_is_named():
    m = dvrk_twin.Model.load("psm")
    with pytest.raises(ValueError, match="qd must have the shape of q"):
        m.inverse_dynamics(m.home, np.zeros(3))
    with pytest.raises(ValueError, match="qdd"):
        m.inverse_dynamics(m.home, None, np.full(7, np.nan))
    with pytest.raises(ValueError, match="inertials"):
        dvrk_twin.Model.load("cart").gravity(dvrk_twin.Model.load("cart").home)
