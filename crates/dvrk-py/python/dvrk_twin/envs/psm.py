"""The PSM tasks: one core over a BatchSim of n copies, the single and the vector environments.

Units: rad, m, s, N·m, N. Observations are float32: ``q`` (7), ``qd`` (7), then the task's
(PSMJoint: the goal configuration, 7; PSMReach: the tip's position and the goal point in the
scene's world frame, 3 + 3). Rewards: PSMJoint, minus the weighted distance to the goal
configuration (rad; the insertion's metres weighted by 10, so 1 cm counts as 0.1 rad);
PSMReach, minus the tip's distance to the goal (m). An episode terminates at the goal (every
weighted joint error under 0.01 rad; the tip within 2 mm) and is truncated after
``max_episode_steps`` control steps.
"""

from __future__ import annotations

from typing import Any, Optional, Sequence

import numpy as np
import gymnasium
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .._dvrk_twin import BatchSim

ACTION_TYPES = ("servo_jp", "servo_jf")
# Goals and starts are drawn from the middle of each joint's range: this share of it stays clear
# at each end (the tool's wrist at its stops is not a task).
MARGIN = 0.2
# servo_jp: the largest target move per control step (rad; m for the insertion).
MAX_DELTA_RAD, MAX_DELTA_M = 0.02, 0.002
INSERTION_WEIGHT = 10.0  # 1 / m: a centimetre of insertion counts as 0.1 rad
JOINT_TOLERANCE = 0.01  # rad (weighted)
REACH_TOLERANCE = 0.002  # m


class _Core:
    """``n`` PSMs on one BatchSim with a task: sampling, commands, observations, rewards."""

    def __init__(self, n: int, task: str, action_type: str, control_period: float, threads: int, engine: str):
        if action_type not in ACTION_TYPES:
            raise ValueError(f"action_type = {action_type!r}: expected one of {ACTION_TYPES}")
        self.batch = BatchSim.from_scene("psm", n, engine=engine, threads=threads)
        dt = self.batch.dt
        self.k = int(round(control_period / dt))
        if self.k < 1:
            raise ValueError(f"control_period = {control_period} s: at least the simulator's step, {dt} s")
        self.period = self.k * dt
        self.task, self.action_type, self.n = task, action_type, n
        limits = self.batch.joint_limits
        self.lo, self.hi = limits[:, 0].copy(), limits[:, 1].copy()
        span = self.hi - self.lo
        self.box_lo, self.box_hi = self.lo + MARGIN * span, self.hi - MARGIN * span
        names = self.batch.joint_names
        prismatic = np.array(["insertion" in name for name in names])
        self.weight = np.where(prismatic, INSERTION_WEIGHT, 1.0)
        self.max_delta = np.where(prismatic, MAX_DELTA_M, MAX_DELTA_RAD)
        self.effort_limits = np.asarray(self.batch.effort_limits)
        if action_type == "servo_jf":
            for j in range(self.batch.nq):
                self.batch.set_mode(j, "effort")
        # The tool tip's world pose is the scene's mount times the model's FK: the mount from home.
        from .. import Model

        self.model = Model.load("psm")
        home_tip = self.model.fk(self.model.home, frame="tool_tip")
        self.mount = self.batch.frame_poses("tool_tip")[0] @ np.linalg.inv(home_tip)
        goal_dim = 3 if task == "reach" else self.batch.nq
        self.goal = np.zeros((n, goal_dim))
        self.rngs = [seeding.np_random(None)[0] for _ in range(n)]

    def seed(self, seeds: Sequence[Optional[int]]) -> None:
        self.rngs = [seeding.np_random(s)[0] for s in seeds]

    def tip(self, q: np.ndarray) -> np.ndarray:
        """The tip's world position (m) at configuration ``q``."""
        return (self.mount @ self.model.fk(q, frame="tool_tip"))[:3, 3]

    def reset(self, idx: np.ndarray) -> None:
        """Copies ``idx`` to a new start and goal drawn from each copy's own generator."""
        if len(idx) == 0:
            return
        starts = np.empty((len(idx), self.batch.nq))
        for r, i in enumerate(idx):
            rng = self.rngs[i]
            starts[r] = rng.uniform(self.box_lo, self.box_hi)
            goal_q = rng.uniform(self.box_lo, self.box_hi)
            self.goal[i] = self.tip(goal_q) if self.task == "reach" else goal_q
        self.batch.reset([int(i) for i in idx], q=starts)

    def apply(self, action: np.ndarray) -> None:
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(self.n, -1), -1.0, 1.0)
        if self.action_type == "servo_jp":
            delta = a * self.max_delta
            self.batch.target = np.clip(self.batch.target + delta, self.lo, self.hi)
            self.batch.target_velocity = delta / self.period
        else:
            self.batch.effort_command = a * self.effort_limits

    def advance(self) -> None:
        self.batch.step(self.k)

    def observe(self) -> np.ndarray:
        b = self.batch
        if self.task == "reach":
            tips = b.frame_poses("tool_tip")[:, :3, 3]
            obs = np.concatenate([b.q, b.qd, tips, self.goal], axis=1)
        else:
            obs = np.concatenate([b.q, b.qd, self.goal], axis=1)
        return obs.astype(np.float32)

    def reward_and_done(self) -> tuple[np.ndarray, np.ndarray]:
        b = self.batch
        if self.task == "reach":
            distance = np.linalg.norm(b.frame_poses("tool_tip")[:, :3, 3] - self.goal, axis=1)
            return -distance, distance < REACH_TOLERANCE
        error = np.abs((b.q - self.goal) * self.weight)
        return -np.linalg.norm(error, axis=1), error.max(axis=1) < JOINT_TOLERANCE

    def single_spaces(self) -> tuple[spaces.Box, spaces.Box]:
        nq = self.batch.nq
        dim = 2 * nq + (6 if self.task == "reach" else nq)
        observation = spaces.Box(-np.inf, np.inf, (dim,), np.float32)
        action = spaces.Box(-1.0, 1.0, (nq,), np.float32)
        return observation, action


class _PSMEnv(gymnasium.Env):
    """One PSM (a BatchSim of one copy on one thread)."""

    metadata = {"render_modes": []}
    task = "joint"

    def __init__(self, action_type: str = "servo_jp", control_period: float = 0.02, engine: str = "reduced"):
        self.core = _Core(1, self.task, action_type, control_period, 1, engine)
        self.observation_space, self.action_space = self.core.single_spaces()

    def reset(self, *, seed: Optional[int] = None, options: Optional[dict[str, Any]] = None):
        super().reset(seed=seed)
        self.core.rngs = [self.np_random]
        self.core.reset(np.array([0]))
        return self.core.observe()[0], {}

    def step(self, action):
        self.core.apply(np.asarray(action)[None, :])
        self.core.advance()
        reward, done = self.core.reward_and_done()
        return self.core.observe()[0], float(reward[0]), bool(done[0]), False, {}


class _PSMVectorEnv(VectorEnv):
    """``num_envs`` PSMs stepped together in one BatchSim (gymnasium's next-step autoreset)."""

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}
    task = "joint"

    def __init__(
        self,
        num_envs: int = 1,
        action_type: str = "servo_jp",
        control_period: float = 0.02,
        engine: str = "reduced",
        threads: int = 0,
        max_episode_steps: Optional[int] = None,
    ):
        self.num_envs = num_envs
        self.core = _Core(num_envs, self.task, action_type, control_period, threads, engine)
        self.single_observation_space, self.single_action_space = self.core.single_spaces()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.max_episode_steps = max_episode_steps
        self._steps = np.zeros(num_envs, dtype=np.int64)
        self._autoreset = np.zeros(num_envs, dtype=bool)

    def reset(self, *, seed: Optional[int | Sequence[Optional[int]]] = None, options: Optional[dict[str, Any]] = None):
        # As SyncVectorEnv seeds its environments: copy i with seed + i; None keeps each copy's
        # generator going.
        if seed is not None:
            seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: {len(seeds)} seeds for {self.num_envs} environments")
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
            self.core.seed(seeds)
        self.core.reset(np.arange(self.num_envs))
        self._steps[:] = 0
        self._autoreset[:] = False
        return self.core.observe(), {}

    def step(self, actions):
        restart = np.flatnonzero(self._autoreset)
        actions = np.array(actions, dtype=np.float64).reshape(self.num_envs, -1)
        actions[restart] = 0.0
        self.core.apply(actions)
        self.core.advance()
        reward, terminated = self.core.reward_and_done()
        self._steps += 1
        truncated = np.zeros(self.num_envs, dtype=bool) if self.max_episode_steps is None else self._steps >= self.max_episode_steps
        # Next-step autoreset: copies that ended last step start again now (their physics of this
        # step is discarded), returning the new start with reward 0 and neither flag.
        self.core.reset(restart)
        reward[restart] = 0.0
        terminated[restart] = False
        truncated[restart] = False
        self._steps[restart] = 0
        self._autoreset = terminated | truncated
        return self.core.observe(), reward, terminated, truncated, {}


class PSMJointEnv(_PSMEnv):
    """Drive the PSM's joints to a goal configuration (``dvrk_twin/PSMJoint-v0``)."""

    task = "joint"


class PSMReachEnv(_PSMEnv):
    """Bring the PSM's tool tip to a goal point (``dvrk_twin/PSMReach-v0``)."""

    task = "reach"


class PSMJointVectorEnv(_PSMVectorEnv):
    """``dvrk_twin/PSMJoint-v0``'s native vector environment."""

    task = "joint"


class PSMReachVectorEnv(_PSMVectorEnv):
    """``dvrk_twin/PSMReach-v0``'s native vector environment."""

    task = "reach"
