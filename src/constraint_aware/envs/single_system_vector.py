"""Gymnasium `VectorEnv` twin of the batched training environment (no per-env objects).

`gym.make_vec("constraint_aware/SingleSystem-v0", num_envs=N)` builds it: N episodes of
`training.batch.SingleSystemBatch` stepping as one numpy batch, the same episodes as N copies of
`SingleSystem-v0` would run (same config, same physics backend). All episodes have length T, so
they end together; the step after that resets them all (Gymnasium's NEXT_STEP autoreset: that
step's actions are ignored, its rewards are 0).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from constraint_aware.envs.single_system import RENDER_MODES, check_render_mode, draw_single_system
from constraint_aware.errors import InvalidInputError
from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.env import make_force_model


class SingleSystemVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """N single-system episodes in lock-step. Observations (N, obs_dim), actions (N, 3).

    Observation, action, reward and info are those of `SingleSystemEnv`, batched; when the
    episodes end, `infos["final_angle_deg"]` (N,) holds the angle between d and u [deg].
    """

    metadata: dict[str, Any] = {  # noqa: RUF012 (gymnasium convention)
        "render_modes": list(RENDER_MODES),
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }

    def __init__(
        self,
        num_envs: int = 1,
        config: EnvConfig | None = None,
        backend: str = "analytic",
        render_mode: str | None = None,
    ) -> None:
        check_render_mode(render_mode)
        if num_envs < 1:
            raise InvalidInputError(f"num_envs must be >= 1, got {num_envs}")
        self.num_envs = num_envs
        self.config = config or EnvConfig()
        self.backend = backend
        self.render_mode = render_mode
        self.batch = SingleSystemBatch(
            num_envs, self.config, make_force_model(backend, self.config)
        )
        # the observation size is the batch's (a policy may observe more than (F/|F|, d)):
        # read it from one throw-away reset instead of assuming a constant
        obs_dim = int(SingleSystemBatch(1, self.config).reset(np.random.default_rng(0)).shape[1])
        act_dim = 3  # a direction change in the world frame
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (obs_dim,), np.float32)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (act_dim,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._needs_reset = True

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        if isinstance(seed, list):  # one generator drives the whole batch
            seed = seed[0]
        super().reset(seed=seed)
        obs = self.batch.reset(self.np_random)
        self._needs_reset = False
        return obs.astype(np.float32), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        n = self.num_envs
        if self._needs_reset:  # NEXT_STEP autoreset: start new episodes, ignore the actions
            obs, _ = self.reset()
            return obs, np.zeros(n), np.zeros(n, bool), np.zeros(n, bool), {}
        obs, reward, done = self.batch.step(np.asarray(actions, dtype=np.float64))
        infos: dict[str, Any] = {}
        if done:
            infos["final_angle_deg"] = self.batch.angle_to_axis_deg()
            infos["_final_angle_deg"] = np.ones(n, bool)
            self._needs_reset = True
        return (
            obs.astype(np.float32),
            reward.astype(np.float64),
            np.full(n, done),
            np.zeros(n, bool),
            infos,
        )

    def render(self) -> tuple[np.ndarray, ...] | None:
        if self.render_mode is None:
            return None
        return tuple(draw_single_system(self.batch, i) for i in range(self.num_envs))
