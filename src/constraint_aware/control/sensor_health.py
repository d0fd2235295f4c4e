"""A dead or frozen force sensor, judged from what calibration knows about the robot.

Two ways a wrist sensor fails without returning a non-finite number or repeating one sample:

- it dies but its electronics keep producing fresh noise around the tare: every reading is
  new and plausible, and reads "no force" while the hand pushes an object. A compliant arm
  pressing against a resisting object is deflected from its target, and that deflection times
  the arm's stiffness is a force the wrench must show (control.guards.arm_force). When the
  reading stays within the dead band while the hand is measured moving and the deflection
  implies more force than the arm-force check allows, the stop is `sensor_dead` (a hand that
  does not move is an arm not following its target: `not_following`, as before). This needs
  the stiffness: the robot's report, the configuration's, or a robot profile's
  (control.calibrate), so a robot reporting none is covered once it has been calibrated;
- it freezes with a jitter far below its noise (a driver that re-sends a held value with
  rounding, or a filter stuck at its state): the readings are not identical, so the stale
  guard's exact-repeat test passes, but their spread over `STALE_WINDOW` periods is below
  `STALE_FRACTION` of the sensor's calibrated noise sigma (robot profile); the F_d samples
  themselves are judged before the first move. Without a calibration there is no reference:
  the spread of the F_d samples is no noise floor (a noise-free reading at rest spreads only
  by the hand's micro-motion, which a steady pull can undercut), so only exact repeats are
  caught.

A Gaussian reading of sigma per axis has a pooled spread below 0.1 sigma over 5 readings of 3
axes (12 degrees of freedom) with probability below 1e-12, and a real force only adds spread,
so a healthy sensor never trips the frozen test. The limits of each detection, with numbers:
docs/design/calibration.md.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.guards import Stop
from constraint_aware.deadband import noise_std
from constraint_aware.geometry import FloatArray

#: A window's pooled spread below this fraction of the sensor's noise sigma is a frozen
#: reading.
STALE_FRACTION = 0.1
#: [control periods] readings the frozen test looks at.
STALE_WINDOW = 5
#: A hand whose measured travel over the last period reaches this fraction of the step length
#: is moving (a frozen arm's hand travels only its pose noise).
MOVING_FRACTION = 0.25


@dataclass
class SensorHealth:
    """The dead- and frozen-sensor tests of one run (module docstring).

    Attributes:
        noise: [N] the sensor's calibrated noise sigma per axis (robot profile), or None: no
            frozen-reading test.
    """

    noise: float | None
    window: deque[FloatArray] = field(default_factory=lambda: deque(maxlen=STALE_WINDOW))

    @classmethod
    def for_run(cls, calibrated_noise: float | None) -> SensorHealth:
        """The tests for a run; `calibrated_noise` [N] the profile's sigma, or None."""
        usable = calibrated_noise is not None and calibrated_noise > 0
        return cls(calibrated_noise if usable else None)

    def offset_sampled(self, forces: FloatArray) -> Stop | None:
        """The F_d samples (n, 3) [N] are in: a stop when they are frozen against the
        calibrated sigma."""
        return self._frozen(noise_std(forces), len(forces), "before moving")

    def check_reading(self, force: FloatArray) -> Stop | None:
        """One raw force reading (3,) [N] per control period while moving: a stop when the
        last STALE_WINDOW readings are frozen."""
        if self.noise is None:
            return None
        self.window.append(np.asarray(force, dtype=float))
        if len(self.window) < STALE_WINDOW:
            return None
        return self._frozen(noise_std(np.array(self.window)), STALE_WINDOW, "while moving")

    def _frozen(self, spread: float, count: int, when: str) -> Stop | None:
        if self.noise is None or spread >= STALE_FRACTION * self.noise:
            return None
        return Stop(
            "sensor_dead",
            f"frozen force reading {when}: spread {spread:.2g} N over {count} periods, below "
            f"{STALE_FRACTION:g} x the calibrated noise sigma {self.noise:.3g} N",
        )

    @staticmethod
    def classify(
        stop: Stop | None,
        magnitude: float,
        dead_band: float,
        hand_travel: float | None,
        step_length: float,
    ) -> Stop | None:
        """The arm-force check's `stop` relabelled `sensor_dead` when it says the arm implies
        more force than the sensor reads (`not_following`) while the reading |F| =
        `magnitude` [N] is within `dead_band` [N] and the hand travelled at least
        MOVING_FRACTION x `step_length` [m] over the last period (`hand_travel` [m], None
        before the first move). Any other stop is returned unchanged."""
        if stop is None or stop.outcome != "not_following" or hand_travel is None:
            return stop
        if magnitude >= dead_band or hand_travel < MOVING_FRACTION * step_length:
            return stop
        return Stop(
            "sensor_dead",
            f"the sensor reads no force (|F| = {magnitude:.2f} N, within the dead band "
            f"{dead_band:.2g} N) while the hand moves ({hand_travel * 1000:.1f} mm in the last "
            f"period) against a resistance its deflection puts above the arm-force check's "
            f"allowance ({stop.reason})",
        )
