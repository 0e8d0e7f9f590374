"""Our closed-loop dynamics against Pinocchio (PyPI ``pin``) on the URDF we export with inertials.

The URDF is the model's frame tree with every passive frame a mimic joint (``phi = c q + b``,
the relation the loops impose). Pinocchio computes the tree's dynamics in all its joints, each
free; virtual work brings them to ``q``: ``tau = C^T tau_tree(C q + b, C qd, C qdd)``, ``M = C^T
M_tree C`` (the map is affine, so no velocity-product term appears). None of our dynamics code is
in that path: the inertials and the mimic table are read from the URDF text.
"""

import xml.etree.ElementTree as ET

import numpy as np
import pytest

import dvrk_twin

pin = pytest.importorskip("pinocchio", reason="pin (Pinocchio) is not installed (the README's test command installs it from PyPI)")


def tree_map(urdf, model, joint_names):
    """C (nq_tree x nq) and b from the URDF's joints: a joint named after a model joint is that
    joint; a mimic joint follows its joint's column by multiplier, offset."""
    root = ET.fromstring(urdf)
    mimic = {}
    for j in root.iter("joint"):
        m = j.find("mimic")
        if m is not None:
            mimic[j.get("name")] = (m.get("joint"), float(m.get("multiplier", 1)), float(m.get("offset", 0)))
    c = np.zeros((model.nq, len(joint_names)))
    b = np.zeros(model.nq)
    for jid in range(1, model.njoints):
        name, iq = model.names[jid], model.joints[jid].idx_q
        if name in mimic:
            primary, k, off = mimic[name]
            c[iq, joint_names.index(primary)] = k
            b[iq] = off
        else:
            c[iq, joint_names.index(name)] = 1.0
    return c, b


@pytest.mark.parametrize("name", ["psm", "ecm", "mtmr", "mtmr-wpi"])
def test_inverse_dynamics_mass_matrix_and_gravity_match_pinocchio(name):
    ours = dvrk_twin.Model.load(name)
    urdf = ours.export_urdf(inertials=True)
    model = pin.buildModelFromXML(urdf)
    data = model.createData()
    c, b = tree_map(urdf, model, ours.joint_names)
    rng = np.random.default_rng(7)
    lo, hi = ours.joint_limits[:, 0], ours.joint_limits[:, 1]
    worst = {"tau": 0.0, "M": 0.0, "g": 0.0}
    for _ in range(20):
        q = rng.uniform(lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo))
        qd, qdd = rng.normal(size=ours.nq), rng.normal(size=ours.nq)
        phi, phid, phidd = c @ q + b, c @ qd, c @ qdd
        tau_pin = c.T @ pin.rnea(model, data, phi, phid, phidd)
        m_tree = pin.crba(model, data, phi)
        m_tree = np.triu(m_tree) + np.triu(m_tree, 1).T
        m_pin = c.T @ m_tree @ c
        g_pin = c.T @ pin.computeGeneralizedGravity(model, data, phi)
        tau, mass, g = ours.inverse_dynamics(q, qd, qdd, effects=False), ours.mass_matrix(q, effects=False), ours.gravity(q)
        worst["tau"] = max(worst["tau"], np.abs(tau - tau_pin).max() / np.abs(tau_pin).max())
        worst["M"] = max(worst["M"], np.abs(mass - m_pin).max() / np.abs(m_pin).max())
        worst["g"] = max(worst["g"], np.abs(g - g_pin).max() / np.abs(g_pin).max())
    print(f"{name}: largest relative difference to Pinocchio {pin.__version__}: " + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()))
    assert max(worst.values()) < 1e-9, worst
