"""Reference direction controllers on the training observation, batched.

Each maps observations (N, >= 6) starting with (F/|F|, d), and the guide friction (N,), to
actions (N, 3).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from constraint_aware.geometry import FloatArray, unit
from constraint_aware.training.config import EnvConfig

BatchController = Callable[[FloatArray, FloatArray], FloatArray]


def noop(obs: FloatArray, friction: FloatArray) -> FloatArray:
    """Keep the initial direction: a = 0."""
    return np.zeros((obs.shape[0], 3))


def projection(obs: FloatArray, friction: FloatArray) -> FloatArray:
    """a = -(d.F^)F^: remove the part of d along the force. Exact without friction and noise."""
    f_hat, d = obs[:, :3], obs[:, 3:6]
    return -np.sum(d * f_hat, axis=1, keepdims=True) * f_hat


def friction_oracle(obs: FloatArray, friction: FloatArray) -> FloatArray:
    """Knows mu: undo the atan(mu) tilt that sliding friction gives the guide force.

    While sliding, F^ = -(mu u + p)/sqrt(1 + mu^2) with p the unit push across the guide, so the
    direction w perpendicular to F^ in span(d, F^) is u rotated by atan(mu), and
    u = cos(phi) w - sin(phi) F^. With a zero (below-threshold) force it keeps d.
    """
    f_hat, d = obs[:, :3], obs[:, 3:6]
    w = unit(d - np.sum(d * f_hat, axis=1, keepdims=True) * f_hat)
    phi = np.arctan(friction)[:, None]
    u_est = np.cos(phi) * w - np.sin(phi) * f_hat
    seen = (np.linalg.norm(f_hat, axis=1, keepdims=True) > 0) & (
        np.linalg.norm(w, axis=1, keepdims=True) > 0
    )
    return np.where(seen, u_est - d, 0.0)


def assumed_friction_oracle(mu: float) -> BatchController:
    """The oracle's correction for a fixed, assumed mu instead of the true one."""

    def controller(obs: FloatArray, friction: FloatArray) -> FloatArray:
        return friction_oracle(obs, np.full(obs.shape[0], mu))

    return controller


def reference_controllers(config: EnvConfig) -> dict[str, BatchController]:
    """The reference controllers evaluated beside every trained policy.

    "mu_agnostic" assumes the median friction of the training range: a policy that sees only
    (F/|F|, d) cannot tell the tilt atan(mu) from the direction error (the observation fixes
    only their sum), so this controller approximates the best any such policy can do.
    """
    return {
        "noop": noop,
        "projection": projection,
        "mu_agnostic": assumed_friction_oracle(float(np.mean(config.friction))),
        "oracle": friction_oracle,
    }
