"""dvrk_twin.envs: the gymnasium 1.x PSM tasks, single (env_checker) and native vector (BatchSim),
the vector one step for step equal to SyncVectorEnv of the single ones."""

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium", reason="gymnasium is not installed (the README's test command installs it from PyPI)")
from gymnasium.utils.env_checker import check_env  # noqa: E402

import dvrk_twin.envs  # noqa: E402,F401  (registers the ids)

IDS = ["dvrk_twin/PSMJoint-v0", "dvrk_twin/PSMReach-v0"]


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("action_type", ["servo_jp", "servo_jf"])
def test_single_env_passes_gymnasiums_checker(env_id, action_type):
    env = gymnasium.make(env_id, action_type=action_type)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    obs2, _ = env.reset(seed=3)
    np.testing.assert_array_equal(obs, obs2)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert np.isfinite(reward) and env.observation_space.contains(obs)
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_the_native_vector_env_equals_sync_vector_env_of_single_envs(env_id):
    n, steps = 4, 12
    native = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", max_episode_steps=5, threads=2)
    assert type(native).__name__.endswith("VectorEnv") and "Sync" not in type(native).__name__
    sync = gymnasium.make_vec(env_id, num_envs=n, vectorization_mode="sync", max_episode_steps=5)
    o1, _ = native.reset(seed=11)
    o2, _ = sync.reset(seed=11)
    np.testing.assert_array_equal(o1, o2)
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(steps):
        a = rng.uniform(-1, 1, size=native.action_space.shape).astype(np.float32)
        r1 = native.step(a)
        r2 = sync.step(a)
        for x, y in zip(r1[:4], r2[:4]):
            np.testing.assert_array_equal(x, y)
        ended += int(np.sum(r1[3]))
    assert ended == 2 * n  # truncated at 5 steps twice each (next-step autoreset in between)
    native.close()
    sync.close()


def test_a_servo_jp_policy_toward_the_goal_reaches_it():
    """A proportional policy on the observation reaches the joint goal: the task is solvable."""
    env = gymnasium.make("dvrk_twin/PSMJoint-v0")
    obs, _ = env.reset(seed=5)
    nq = 7
    for _ in range(200):
        q, goal = obs[:nq], obs[2 * nq:]
        obs, reward, terminated, truncated, _ = env.step(np.clip((goal - q) / 0.02, -1, 1))
        if terminated or truncated:
            break
    assert terminated, (reward, obs[:nq] - obs[2 * nq:])
