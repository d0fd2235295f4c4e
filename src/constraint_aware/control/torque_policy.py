"""The appendix's additional policy: hand rotation per step for fixed-orientation grasps.

Each step the hand turns by w about the workplane normal n (oriented so that the motion turns
positively about it). After the step, the torque about n that the object exerts on the hand,
tau, adjusts w: +beta when tau > alpha (the hand lags: turn more), -beta when tau < -alpha, else
unchanged. The initial w = v / r with v the step length and r the rotation radius.

Units: the paper gives alpha = 10 without units; with this project's wrist (5 N m/rad) and
hand, a torque in N m with alpha = 0.1 N m (the paper's 10 read as N cm) responds to a
mismatch of ~1 deg, while 10 N m would never fire. beta = 1 deg per step, as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray


@dataclass
class TorquePolicy:
    """Rotation w [rad per step] about the workplane normal, adapted from the torque."""

    radius: float  # [m] rotation radius r (from the demonstration or the task)
    step_length: float = 0.01  # [m] translation per step v
    alpha: float = 0.1  # [N m] torque dead-band
    beta: float = float(np.radians(1.0))  # [rad] adjustment of w per step
    w: float = 0.0  # [rad per step], set by reset()

    def __post_init__(self) -> None:
        if self.radius <= 0:
            raise InvalidInputError(f"radius must be positive, got {self.radius}")
        self.reset()

    def reset(self) -> None:
        self.w = self.step_length / self.radius

    def update(self, torque: FloatArray, normal: FloatArray) -> float:
        """Adjust w from the offset torque (3,) [N m]; returns the new w [rad per step]."""
        tau = float(torque @ normal)
        if tau > self.alpha:
            self.w += self.beta
        elif tau < -self.alpha:
            self.w -= self.beta
        return self.w
