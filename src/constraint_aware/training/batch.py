"""The single-system episode logic for N synchronized environments at once (numpy)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import (
    FloatArray,
    angle_deg,
    normalize_force,
    random_perpendicular,
    random_unit,
    rotate_about,
    unit,
    update_direction_rule,
)
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.physics import ForceModel, analytic_constraint_force

OBS_DIM = 6  # (F/|F| (3), d (3)), world frame
ACT_DIM = 3


@dataclass
class EpisodeParams:
    """Per-episode draws, each (N, ...)."""

    axis: FloatArray  # (N, 3) unit joint axis u, oriented so that d0 . u > 0
    workplane_normal: FloatArray  # (N, 3)
    offset_deg: FloatArray  # (N,) signed initial angle of d0 from u about the normal [deg]
    friction: FloatArray  # (N,) [-]
    stiffness: FloatArray  # (N,) [N/m]
    force_gain: FloatArray  # (N,) [-]


class SingleSystemBatch:
    """N copies of the paper's training environment stepping in lock-step.

    All episodes start and end together (fixed length T), so one counter serves the batch.
    Randomness comes only from the generator handed to `reset`.
    """

    def __init__(
        self, n_envs: int, config: EnvConfig | None = None, physics: ForceModel | None = None
    ) -> None:
        if n_envs < 1:
            raise InvalidInputError(f"n_envs must be >= 1, got {n_envs}")
        self.n_envs = n_envs
        self.config = config or EnvConfig()
        self.physics: ForceModel = physics or analytic_constraint_force
        self.rng = np.random.default_rng()
        self.t = 0
        self.params = self.sample_params(self.rng)
        self.direction = self.params.axis.copy()
        self.force = np.zeros((n_envs, 3))

    # --- sampling -------------------------------------------------------------------------
    def sample_params(self, rng: np.random.Generator) -> EpisodeParams:
        c, n = self.config, self.n_envs
        if c.workplane == "horizontal":
            normal = np.tile([0.0, 0.0, 1.0], (n, 1))
        else:
            normal = random_unit(rng, n)
        axis = random_perpendicular(rng, normal)
        magnitude = rng.uniform(*c.offset_deg, size=n)
        sign = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        return EpisodeParams(
            axis=axis,
            workplane_normal=normal,
            offset_deg=sign * magnitude,
            friction=rng.uniform(*c.friction, size=n),
            stiffness=rng.uniform(*c.stiffness, size=n),
            force_gain=rng.uniform(*c.force_gain, size=n),
        )

    # --- dynamics -------------------------------------------------------------------------
    def _move(self) -> FloatArray:
        """Command the hand along the current direction; returns the true guide force (N, 3)."""
        p = self.params
        self.force = self.physics(
            p.axis, self.direction, p.friction, p.stiffness, self.config.step_length
        )
        return self.force

    def _observe(self, noisy: bool) -> FloatArray:
        c = self.config
        measured = self.params.force_gain[:, None] * self.force
        f_hat = normalize_force(measured, c.threshold)
        d_obs = self.direction
        if noisy:
            seen = np.linalg.norm(f_hat, axis=1, keepdims=True) > 0
            noisy_f = unit(f_hat + c.force_noise * self.rng.normal(size=f_hat.shape))
            f_hat = np.where(seen, noisy_f, 0.0)
            d_obs = unit(d_obs + c.direction_noise * self.rng.normal(size=d_obs.shape))
        return np.concatenate([f_hat, d_obs], axis=1)

    def reset(self, rng: np.random.Generator | None = None) -> FloatArray:
        """Start N new episodes; the hand makes its first move along d0. Returns obs (N, 6)."""
        if rng is not None:
            self.rng = rng
        self.params = self.sample_params(self.rng)
        p = self.params
        self.direction = rotate_about(p.axis, p.workplane_normal, np.radians(p.offset_deg))
        self.t = 0
        self._move()
        return self._observe(noisy=True)

    def step(self, action: FloatArray) -> tuple[FloatArray, FloatArray, bool]:
        """Apply actions (N, 3) in [-1, 1]: returns (obs (N, 6), reward (N,), episode_done)."""
        c = self.config
        a = c.action_scale * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        self.direction = update_direction_rule(self.direction, a)
        force = self._move()
        self.t += 1
        scale = self.params.stiffness * c.step_length
        reward = -np.linalg.norm(force, axis=1) / scale
        obs = self._observe(noisy=c.noise_every_step)
        return obs, reward, self.t >= c.episode_length

    # --- diagnostics ----------------------------------------------------------------------
    def angle_to_axis_deg(self) -> FloatArray:
        """Angle [deg] between the current motion direction and the admissible direction u."""
        return np.asarray(angle_deg(self.direction, self.params.axis))
