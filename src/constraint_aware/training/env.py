"""Gymnasium environment: the paper's single composite body on a prismatic joint."""

from __future__ import annotations

from typing import Any, Literal

import gymnasium as gym
import numpy as np

from constraint_aware.errors import UnknownNameError
from constraint_aware.training.batch import ACT_DIM, SingleSystemBatch, observation_space
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.physics import (
    ForceModel,
    MujocoConstraintForce,
    analytic_constraint_force,
)

Backend = Literal["analytic", "mujoco"]
BACKENDS: tuple[str, ...] = ("analytic", "mujoco")


def make_force_model(backend: str, config: EnvConfig) -> ForceModel:
    """The physics backend by name: "analytic" (closed form) or "mujoco"."""
    if backend == "analytic":
        return analytic_constraint_force
    if backend == "mujoco":
        return MujocoConstraintForce(
            substeps=config.substeps, mass=config.hand_mass, damping_ratio=config.damping_ratio
        )
    raise UnknownNameError("backend", backend, BACKENDS)


class SingleSystemEnv(gym.Env[np.ndarray, np.ndarray]):
    """One composite body (hand + object) on a prismatic joint, commanded 1 cm per step.

    Episode: a random joint axis u (in a random or horizontal workplane), an initial motion
    direction d0 rotated from u by a random signed offset (0..45 deg by default) about the
    workplane normal, and random guide friction mu, hand stiffness k and sensor gain.

    Each step the hand is commanded `step_length` along d from the body's pose; the body slides
    along u only, against Coulomb friction; the guide's force F on the body results.

    Resistance (`EnvConfig` documents the ranges): the object's own dry friction,
    damping, inertia and a released grasp preload along the joint; none by default.

    Observation: `config.observation` (policy.OBSERVATIONS), (F/|F|, d) in R^6 for the paper,
        world frame. |F| (times the sensor gain) below `threshold` is observed as the zero
        vector. Gaussian noise (std `force_noise`, `direction_noise`)
        perturbs the observed F/|F| and d at the first observation (then renormalized).
    Action (3,) in [-1, 1]: a = action_scale * action; d <- (d + a)/|d + a| (kept when
        |d + a| ~ 0).
    Reward: -|F + R u| / (k * step_length), the dimensionless constraint force beyond the
        object's own resistance R along u after the move (-|F| / (k * step_length) without it).
    Episode end: terminated after `episode_length` (T = 5) actions. `info["final_angle_deg"]`
        is then the angle between d and u.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium convention)

    def __init__(self, config: EnvConfig | None = None, backend: str = "analytic") -> None:
        self.config = config or EnvConfig()
        self.backend = backend
        self._batch = SingleSystemBatch(1, self.config, make_force_model(backend, self.config))
        self.observation_space = observation_space(self.config)
        self.action_space = gym.spaces.Box(-1.0, 1.0, shape=(ACT_DIM,), dtype=np.float32)

    def _info(self) -> dict[str, Any]:
        b = self._batch
        return {
            "angle_deg": float(b.angle_to_axis_deg()[0]),
            "force": b.force[0].copy(),
            "axis": b.params.axis[0].copy(),
            "direction": b.direction[0].copy(),
            "friction": float(b.params.friction[0]),
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        obs = self._batch.reset(self.np_random)
        return obs[0].astype(np.float32), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, reward, done = self._batch.step(np.asarray(action, dtype=np.float64)[None, :])
        info = self._info()
        if done:
            info["final_angle_deg"] = info["angle_deg"]
        return obs[0].astype(np.float32), float(reward[0]), bool(done), False, info
