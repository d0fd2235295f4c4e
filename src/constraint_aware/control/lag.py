"""The hand's lag behind its moving target, and the arm's deflection it leaves to a force.

A compliant arm reads force from its deflection, the measured pose less the commanded one:
F = k (x - x_c) + c dx/dt for an impedance with stiffness k and damping c. A hand following a
target that moves at velocity v trails it by tau v (tau = c / k, the robot's optional
`tracking_time_constant`) and feels no force from that trail. Guards that compare the wrench
with the deflection (the arm-force check in control.guards, the sensor self-check in
control.self_check) would read that trail as a force the sensor does not show, and stop healthy
runs on a slow arm; `LagModel` credits it to the lag instead. Without a reported tau the model
is quasi-static (the arm settles within one control period) and credits nothing.

Guarded against here: an over-reported tau. Credited along the hand's motion, an excess would
add deflection that no force explains, so the arm-force check credits no more lag than the
hand shows (`lagged_deflection`). A frozen arm has no velocity and gets no credit at all, so a
lag model can never hide it. The constants' measured origins: docs/design/executor-guards.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.geometry import FloatArray


@dataclass
class LagModel:
    """The hand's measured velocity (from trusted poses) and the deflection it explains.

    tracking_time_constant: [s] tau, the robot's report, or None (quasi-static).
    """

    tracking_time_constant: float | None
    deflection0: FloatArray | None = None  # [m] (3,) measured - commanded when moving began
    last_position: FloatArray | None = None  # [m] (3,) the last trusted position while moving
    periods_since_position: int = 0  # control periods since `last_position` was read
    velocity: FloatArray = field(default_factory=lambda: np.zeros(3))  # [m/s] (3,)

    def begin(self, position: FloatArray, commanded: FloatArray) -> None:
        """Moving begins at the trusted `position` (3,) [m] with the robot's `commanded`
        position (3,) [m]: their difference is the grasp's own preload, not a deflection."""
        self.deflection0 = np.asarray(position, dtype=float) - np.asarray(commanded, dtype=float)
        self.last_position = np.array(position, dtype=float)
        self.periods_since_position = 0  # this reading is also the first control step's

    def note_motion(self, position: FloatArray | None, period: float) -> None:
        """Once per control period: the trusted `position` (3,) [m], or None when the pose
        was not trusted; `period` [s] the control period. The velocity spans the periods
        since the last trusted position."""
        if position is None or self.last_position is None:
            self.periods_since_position += 1
            return
        position = np.asarray(position, dtype=float)
        if self.periods_since_position > 0:
            elapsed = self.periods_since_position * period
            self.velocity = (position - self.last_position) / elapsed
        self.last_position = position.copy()
        self.periods_since_position = 1

    def deflection(
        self, position: FloatArray, target: FloatArray, lag_share: float = 1.0
    ) -> FloatArray:
        """[m] (3,) the deflection the wrench should explain: `position` - `target` (3,) [m]
        less the preload at the start, plus `lag_share` x tau x the measured velocity (the
        self-check also asks for agreement at a share of tau; 0: the deflection alone)."""
        if self.deflection0 is None:
            raise RuntimeError("LagModel.deflection: call begin() first")
        out = np.asarray(position, dtype=float) - np.asarray(target, dtype=float)
        out = out - self.deflection0
        if self.tracking_time_constant is not None and lag_share > 0:
            out = out + lag_share * self.tracking_time_constant * self.velocity
        return out

    def lagged_deflection(self, position: FloatArray, target: FloatArray) -> FloatArray:
        """[m] (3,) `deflection` with the lag credit limited to the lag actually there: the
        part of the deflection against the hand's motion. An over-reported tau then adds
        nothing along the motion; a hand without velocity gets no credit."""
        if self.deflection0 is None:
            raise RuntimeError("LagModel.lagged_deflection: call begin() first")
        # in Python floats (every control period), in the order of `deflection`'s numpy ops;
        # dot products summed x, y, z in turn
        p0, p1, p2 = np.asarray(position, dtype=float).tolist()
        t0, t1, t2 = np.asarray(target, dtype=float).tolist()
        b0, b1, b2 = self.deflection0.tolist()
        o0, o1, o2 = p0 - t0 - b0, p1 - t1 - b1, p2 - t2 - b2
        tau = self.tracking_time_constant
        v0, v1, v2 = self.velocity.tolist()
        speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
        if tau is None or speed < 1e-9:
            return np.array([o0, o1, o2])
        m0, m1, m2 = v0 / speed, v1 / speed, v2 / speed  # the direction of motion
        behind = max(0.0, -(o0 * m0 + o1 * m1 + o2 * m2))  # [m] how far the hand trails
        credit = min(tau * speed, behind)
        return np.array([o0 + credit * m0, o1 + credit * m1, o2 + credit * m2])
