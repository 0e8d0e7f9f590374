"""gymnasium 1.x environments on the twin (optional extra: ``pip install "dvrk-twin[gymnasium]"``).

Registered when this module is imported::

    import gymnasium, dvrk_twin.envs
    env = gymnasium.make("dvrk_twin/PSMReach-v0")
    envs = gymnasium.make_vec("dvrk_twin/PSMReach-v0", num_envs=1024)  # native, on BatchSim

- ``dvrk_twin/PSMJoint-v0``: drive the PSM's seven joints to a goal configuration.
- ``dvrk_twin/PSMReach-v0``: bring the instrument tip to a goal point of the workspace (a point
  the tip reaches at some configuration, so the remote centre of motion holds by construction).

Both take ``action_type="servo_jp"`` (the default: each action moves the joint targets by up to
``max_delta`` per control step, the dVRK's ``servo_jp``) or ``"servo_jf"`` (efforts, a share of
each joint's effort limit: ``servo_jf``), and ``control_period`` (s, 0.02 by default: 20 steps of
the simulator's 1 ms). ``gymnasium.make_vec(..., vectorization_mode="vector_entry_point")``
(the default for these ids) steps all copies in one ``BatchSim`` in parallel, with gymnasium's
next-step autoreset and per-copy seeds ``seed + i``, exactly as ``SyncVectorEnv`` of the single
environments would (tests/python/test_envs.py). See docs/batch.md.
"""

try:
    import gymnasium as _gymnasium
except ImportError as e:  # pragma: no cover - depends on the extra
    raise ImportError('dvrk_twin.envs needs gymnasium >= 1.0: pip install "dvrk-twin[gymnasium]" (or pip install gymnasium)') from e

from .psm import PSMJointEnv, PSMJointVectorEnv, PSMReachEnv, PSMReachVectorEnv

MAX_EPISODE_STEPS = 200

for _name, _single, _vector in (
    ("PSMJoint-v0", "PSMJointEnv", "PSMJointVectorEnv"),
    ("PSMReach-v0", "PSMReachEnv", "PSMReachVectorEnv"),
):
    _id = f"dvrk_twin/{_name}"
    if _id not in _gymnasium.registry:
        _gymnasium.register(
            id=_id,
            entry_point=f"dvrk_twin.envs.psm:{_single}",
            vector_entry_point=f"dvrk_twin.envs.psm:{_vector}",
            max_episode_steps=MAX_EPISODE_STEPS,
        )

__all__ = ["PSMJointEnv", "PSMJointVectorEnv", "PSMReachEnv", "PSMReachVectorEnv", "MAX_EPISODE_STEPS"]
