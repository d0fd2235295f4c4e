"""The single-system episode logic for N synchronized environments at once (numpy)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import gymnasium as gym
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
from constraint_aware.policy import MAGNITUDE_CLIP, MAGNITUDE_OBSERVATIONS, OBSERVATIONS
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.physics import ForceModel, analytic_constraint_force

OBS_DIM = 6  # the paper's observation (F/|F| (3), d (3)), world frame
ACT_DIM = 3


def obs_dim(config: EnvConfig) -> int:
    """Length of the observation vector of `config.observation` (policy.OBSERVATIONS)."""
    return len(OBSERVATIONS[config.observation])


def observation_space(config: EnvConfig) -> gym.spaces.Box:
    """The Box of `config.observation`: unit vectors in [-1, 1], |F|/(k*delta) up to its clip."""
    high = np.ones(obs_dim(config), dtype=np.float32)
    if config.observation == "magnitude":
        high[-1] = MAGNITUDE_CLIP
    elif config.observation == "magnitude_flag":
        high[-2] = MAGNITUDE_CLIP  # the flag's bound stays 1
    return gym.spaces.Box(-high, high, dtype=np.float32)


@dataclass
class EpisodeParams:
    """Per-episode draws, each (N, ...)."""

    axis: FloatArray  # (N, 3) unit joint axis u, oriented so that d0 . u > 0
    workplane_normal: FloatArray  # (N, 3)
    offset_deg: FloatArray  # (N,) signed initial angle of d0 from u about the normal [deg]
    friction: FloatArray  # (N,) [-]
    stiffness: FloatArray  # (N,) [N/m]
    force_gain: FloatArray  # (N,) [-]
    dry_friction: FloatArray  # (N,) R0 [N]
    damping: FloatArray  # (N,) c [N s/m]
    mass: FloatArray  # (N,) m [kg] of the object along the joint
    preload: FloatArray  # (N, 3) [N] force recorded in F_d that vanishes once the body slides
    step_force_known: FloatArray  # (N,) 1 where the robot reports k*delta, else 0


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
        self.resistance = np.zeros(n_envs)  # [N] along-axis resistance of the last step
        self.speed = np.zeros(n_envs)  # [m/s] body speed along u during the last step
        self.released = np.zeros(n_envs, dtype=bool)  # preload gone (the body has slid)
        self._prev_obs = np.zeros((n_envs, 6))

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
        friction = rng.uniform(*c.friction, size=n)  # drawn before the resistance: stable streams
        if c.stiffness_log_uniform:  # one draw per episode either way: the same streams
            low, high = math.log(c.stiffness[0]), math.log(c.stiffness[1])
            stiffness = np.exp(rng.uniform(low, high, size=n))
        else:
            stiffness = rng.uniform(*c.stiffness, size=n)
        params = EpisodeParams(
            axis=axis,
            workplane_normal=normal,
            offset_deg=sign * magnitude,
            friction=friction,
            stiffness=stiffness,
            force_gain=rng.uniform(*c.force_gain, size=n),
            dry_friction=np.zeros(n),
            damping=np.zeros(n),
            mass=np.zeros(n),
            preload=np.zeros((n, 3)),
            step_force_known=np.ones(n),
        )
        if c.observation in MAGNITUDE_OBSERVATIONS and c.step_force_unknown_share > 0:
            params.step_force_known = (rng.random(n) >= c.step_force_unknown_share).astype(float)
        if c.has_resistance:  # draws only here, so the paper's env keeps its random stream
            step_force = stiffness * c.step_length
            v_nom = c.step_length / c.control_period
            on = rng.random(n) >= c.resistance_free_share
            params.dry_friction = on * (
                rng.uniform(*c.dry_friction, size=n) * step_force
                + rng.uniform(*c.dry_friction_abs, size=n)
            )
            params.damping = on * rng.uniform(*c.damping, size=n) * step_force / v_nom
            params.mass = (
                on * rng.uniform(*c.inertia, size=n) * step_force / (v_nom / c.control_period)
            )
            tilt = np.radians(c.preload_cone_deg) * np.sqrt(rng.random(n))
            across = random_perpendicular(rng, axis)
            direction = np.cos(tilt)[:, None] * axis + np.sin(tilt)[:, None] * across
            magnitude_p = on * rng.uniform(*c.preload, size=n) * step_force
            params.preload = magnitude_p[:, None] * direction
        return params

    # --- dynamics -------------------------------------------------------------------------
    def _move(self) -> FloatArray:
        """Command the hand along the current direction; returns the true guide force (N, 3).

        The resistance of this step is R0 + c*v + m*(v - v_prev)/period with v the body's speed
        along u if it slides (the commanded advance along u per control period), clipped at
        zero (a decelerating body pushing the hand is left out). Bodies that stick get v = 0.
        """
        p, c = self.params, self.config
        along = np.maximum(np.sum(self.direction * p.axis, axis=1), 0.0)
        v = along * c.step_length / c.control_period
        resistance = np.maximum(
            p.dry_friction + p.damping * v + p.mass * (v - self.speed) / c.control_period, 0.0
        )
        self.force = self.physics(
            p.axis, self.direction, p.friction, p.stiffness, c.step_length, resistance
        )
        # it slid when the guide's force along u is at the limit, not holding the full drive
        drive = p.stiffness * c.step_length * along
        held = np.abs(np.sum(self.force * p.axis, axis=1))
        slid = (drive > 0) & (held < drive * (1.0 - 1e-3))  # MuJoCo: a held body creeps
        self.speed = np.where(slid, v, 0.0)
        self.released |= slid
        self.resistance = resistance
        return self.force

    def measured_force(self) -> FloatArray:
        """The force a sensor reports after F_d: gain * F, minus the preload once released."""
        p = self.params
        return p.force_gain[:, None] * self.force - self.released[:, None] * p.preload

    def _observe(self, noisy: bool) -> FloatArray:
        c = self.config
        measured = self.measured_force()
        f_hat = normalize_force(measured, c.threshold)
        d_obs = self.direction
        if noisy:
            seen = np.linalg.norm(f_hat, axis=1, keepdims=True) > 0
            noisy_f = unit(f_hat + c.force_noise * self.rng.normal(size=f_hat.shape))
            f_hat = np.where(seen, noisy_f, 0.0)
            d_obs = unit(d_obs + c.direction_noise * self.rng.normal(size=d_obs.shape))
        current = np.concatenate([f_hat, d_obs], axis=1)
        if c.observation == "paper":
            return current
        if c.observation == "history":
            obs = np.concatenate([current, self._prev_obs], axis=1)
            self._prev_obs = current
            return obs
        # "magnitude": |F| over the robot's step force k*delta (zero below the threshold)
        step_force = self.params.stiffness * c.step_length
        norm = np.linalg.norm(measured, axis=1)
        ratio = np.where(norm >= c.threshold, np.minimum(norm / step_force, MAGNITUDE_CLIP), 0.0)
        known = self.params.step_force_known
        ratio = ratio * known
        if c.observation == "magnitude_flag":
            return np.concatenate([current, ratio[:, None], known[:, None]], axis=1)
        return np.concatenate([current, ratio[:, None]], axis=1)

    def reset(self, rng: np.random.Generator | None = None) -> FloatArray:
        """Start N new episodes; the hand makes its first move along d0. Returns obs (N, obs)."""
        if rng is not None:
            self.rng = rng
        self.params = self.sample_params(self.rng)
        p = self.params
        self.direction = rotate_about(p.axis, p.workplane_normal, np.radians(p.offset_deg))
        self.t = 0
        self.speed = np.zeros(self.n_envs)  # the body starts at rest
        self.released = np.zeros(self.n_envs, dtype=bool)
        self._prev_obs = np.zeros((self.n_envs, 6))  # no previous step: zeros
        self._move()
        return self._observe(noisy=True)

    def step(self, action: FloatArray) -> tuple[FloatArray, FloatArray, bool]:
        """Apply actions (N, 3) in [-1, 1]: returns (obs (N, obs), reward (N,), episode_done).

        Reward: -|F + R u|/(k*delta), the constraint force beyond the object's own along-axis
        resistance R (which the simulator knows); with R = 0 the paper's -|F|/(k*delta). As a
        vector, not |F| - R: near alignment |F| - R ~ |N|^2 / (2R) hardly penalizes a small
        error, while |F + R u| keeps the paper's |N| sqrt(1 + mu^2) while sliding.
        """
        c = self.config
        a = c.action_scale * np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        self.direction = update_direction_rule(self.direction, a)
        force = self._move()
        self.t += 1
        scale = self.params.stiffness * c.step_length
        excess = force + self.resistance[:, None] * self.params.axis
        reward = -np.linalg.norm(excess, axis=1) / scale
        obs = self._observe(noisy=c.noise_every_step)
        return obs, reward, self.t >= c.episode_length

    # --- diagnostics ----------------------------------------------------------------------
    def angle_to_axis_deg(self) -> FloatArray:
        """Angle [deg] between the current motion direction and the admissible direction u."""
        return np.asarray(angle_deg(self.direction, self.params.axis))
