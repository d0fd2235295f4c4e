"""Stable-Baselines3 VecEnv over the batched numpy environment (no per-env Python objects)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from constraint_aware.training.batch import ACT_DIM, SingleSystemBatch, observation_space
from constraint_aware.training.config import EnvConfig


class BatchedSingleSystemVecEnv(VecEnv):
    """All N episodes run in lock-step and auto-reset together after T steps."""

    render_mode = None  # SB3 reads it through get_attr

    def __init__(self, n_envs: int, config: EnvConfig | None = None, seed: int = 0) -> None:
        obs_space = observation_space(config or EnvConfig())
        action_space = gym.spaces.Box(-1.0, 1.0, shape=(ACT_DIM,), dtype=np.float32)
        super().__init__(n_envs, obs_space, action_space)
        self.batch = SingleSystemBatch(n_envs, config)
        self._rng = np.random.default_rng(seed)
        self._actions = np.zeros((n_envs, ACT_DIM))
        self._returns = np.zeros(n_envs)
        self.completed_final_angles: list[np.ndarray] = []  # drained by the training callback

    def reset(self) -> VecEnvObs:
        self._returns[:] = 0.0
        return self.batch.reset(self._rng).astype(np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float64)

    def step_wait(self) -> VecEnvStepReturn:
        obs, reward, done = self.batch.step(self._actions)
        self._returns += reward
        dones = np.full(self.num_envs, done)
        if not done:
            infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
            return obs.astype(np.float32), reward.astype(np.float32), dones, infos
        final_angle = self.batch.angle_to_axis_deg()
        self.completed_final_angles.append(final_angle)
        terminal = obs.astype(np.float32)
        ep_len = self.batch.t
        infos = [
            {
                "terminal_observation": terminal[i],
                "episode": {"r": float(self._returns[i]), "l": ep_len},
                "final_angle_deg": float(final_angle[i]),
            }
            for i in range(self.num_envs)
        ]
        new_obs = self.reset()
        return new_obs, reward.astype(np.float32), dones, infos

    def close(self) -> None:
        pass

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        self._rng = np.random.default_rng(seed)
        return [seed] * self.num_envs

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
    ) -> list[Any]:
        raise NotImplementedError("the batched env has no per-environment objects")

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: Any = None) -> list[bool]:
        return [False] * len(self._indices(indices))

    def _indices(self, indices: Any) -> Sequence[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)
