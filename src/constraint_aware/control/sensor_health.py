"""A dead or frozen force sensor, judged from what calibration knows about the robot.

Two ways a wrist sensor fails without returning a non-finite number or repeating one sample,
dying (the first three tests) and freezing (the last):

- it dies but its electronics keep producing fresh noise around the tare: every reading is
  new and plausible, and reads "no force" while the hand pushes an object. A compliant arm
  pressing against a resisting object is deflected from its target, and that deflection times
  the arm's stiffness is a force the wrench must show (control.guards.arm_force). When the
  reading stays within the dead band while the hand is measured moving and the deflection
  implies more force than the arm-force check allows, the stop is `sensor_dead` (a hand that
  does not move is an arm not following its target: `not_following`). This needs
  the stiffness: the robot's report, the configuration's, or a robot profile's
  (control.calibrate), so a robot reporting none is covered once it has been calibrated;
- the same dead sensor where the deflection implies less than the arm-force check's
  allowance (a hand dragging a light object along its constraint: a few newtons): with a
  robot profile that measured the deflection model's own error (control.calibrate:
  `deflection_error` with the hand at rest, `deflection_error_per_speed` while it moved at a
  steady speed), the profile's stiffness times the lagged deflection (its tau credited) must
  show in the reading to within that error, a + b |v|. A reading within the dead band while
  the hand moves at a steady speed and the implied force exceeds the reading by more than
  that, DEAD_PERIODS periods in a row, stops `sensor_dead`. The test uses the profile's own
  stiffness and tau (the ones its error was measured with), whatever the run's step force
  comes from; it is off without them, and while the hand accelerates (where tau v is not
  the lag);
- the same dead sensor where the object resists too little for any deflection model to show
  (a light drawer dragged at a fraction of a newton, below the dead band): a live sensor on a
  hand that moves an object reads the object's resistance, however small, in the same
  direction period after period, so the mean reading over `QUIET_WINDOW` moving periods
  stands clear of zero; a dead one's readings are the calibrated noise around zero. A mean
  below `QUIET_SIGMAS` sigma / sqrt(QUIET_WINDOW) (what the noise alone stays below in half of
  all windows: a dead sensor is caught within a few windows, a live one only when the
  object resists with less than that, 0.07 N at sigma = 0.1 N) stops `sensor_dead`. Needs the
  calibrated sigma (robot profile), like the frozen test;
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
docs/design/dead-sensor.md.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.guards import Stop
from constraint_aware.control.lag import LagModel
from constraint_aware.deadband import noise_std
from constraint_aware.geometry import FloatArray, norm

#: A window's pooled spread below this fraction of the sensor's noise sigma is a frozen
#: reading.
STALE_FRACTION = 0.1
#: [control periods] readings the frozen test looks at.
STALE_WINDOW = 5
#: A hand whose measured travel over the last period reaches this fraction of the step length
#: is moving (a frozen arm's hand travels only its pose noise).
MOVING_FRACTION = 0.25
#: The hand moves at a steady speed when its velocity changed by at most this share of its
#: speed over the last period (the lag model tau v describes a steady follower, not one
#: accelerating after a jump of its setpoint).
STEADY_SHARE = 0.25
#: [control periods] moving periods the quiet-sensor test averages (the frozen test's window).
QUIET_WINDOW = STALE_WINDOW
#: The quiet-sensor test's floor in units of sigma / sqrt(QUIET_WINDOW): the median of the chi
#: distribution with 3 degrees of freedom, sqrt(2.366), which the norm of the mean of
#: QUIET_WINDOW zero-mean Gaussian 3-vectors of sigma per axis falls below half the time.
QUIET_SIGMAS = 1.538
#: Periods in a row the implied force must exceed the reading by more than the measured error
#: before the sensor is judged dead (a single reading is one noise draw).
DEAD_PERIODS = 2


def steady_speed(velocity: FloatArray, previous: FloatArray) -> bool:
    """Whether the hand's `velocity` (3,) [m/s] differs from the last period's `previous` (3,)
    [m/s] by at most STEADY_SHARE of its speed."""
    speed = norm(velocity)
    return speed > 0 and norm(np.asarray(velocity) - np.asarray(previous)) <= STEADY_SHARE * speed


@dataclass(frozen=True)
class DeflectionModel:
    """A robot profile's deflection model and its measured error (control.calibrate).

    Attributes:
        stiffness: [N/m] the calibrated k.
        tracking_time_constant: [s] the calibrated tau, or None (no lag credited).
        error: [N] the model's largest error with the hand at rest (a).
        error_per_speed: [N s/m] its largest excess per unit hand speed at a steady speed (b).
    """

    stiffness: float
    tracking_time_constant: float | None
    error: float
    error_per_speed: float

    def error_at(self, velocity: FloatArray) -> float:
        """[N] the model's measured error a + b |v| at the hand's velocity `velocity` (3,)
        [m/s]."""
        return self.error + self.error_per_speed * norm(velocity)

    def implied(self, lag: LagModel, position: FloatArray, target: FloatArray) -> float:
        """[N] k x |lagged deflection| of the hand at `position` (3,) [m] from `target` (3,)
        [m], with the run's preload and velocity (`lag`) and this model's tau."""
        own = LagModel(self.tracking_time_constant, lag.deflection0, velocity=lag.velocity)
        return self.stiffness * norm(own.lagged_deflection(position, target))


@dataclass
class SensorHealth:
    """The dead- and frozen-sensor tests of one run (module docstring).

    Attributes:
        noise: [N] the sensor's calibrated noise sigma per axis (robot profile), or None: no
            frozen-reading test.
    """

    noise: float | None
    model: DeflectionModel | None = None
    window: deque[FloatArray] = field(default_factory=lambda: deque(maxlen=STALE_WINDOW))
    previous_velocity: FloatArray = field(default_factory=lambda: np.zeros(3))
    short: int = 0  # periods in a row the reading fell short of the implied force
    # F - F_d (3,) [N] of the last moving periods in a row, for the quiet-sensor test
    moving_forces: deque[FloatArray] = field(default_factory=lambda: deque(maxlen=QUIET_WINDOW))

    @classmethod
    def for_run(
        cls, calibrated_noise: float | None, model: DeflectionModel | None = None
    ) -> SensorHealth:
        """The tests for a run; `calibrated_noise` [N] the profile's sigma, or None; `model`
        the profile's deflection model, or None (no deflection test)."""
        usable = calibrated_noise is not None and calibrated_noise > 0
        return cls(calibrated_noise if usable else None, model)

    def check_deflection(
        self,
        lag: LagModel,
        position: FloatArray,
        target: FloatArray,
        magnitude: float,
        dead_band: float,
        hand_travel: float | None,
        step_length: float,
    ) -> Stop | None:
        """The deflection test (module docstring), once per period with a trusted pose.

        Args:
            lag: the run's lag model (its preload and the hand's velocity [m/s]).
            position: (3,) [m] the measured tool point.
            target: (3,) [m] the commanded target.
            magnitude: [N] the read |F - F_d|.
            dead_band: [N] the run's dead band.
            hand_travel: [m] the hand's travel over the last period (None before moving).
            step_length: [m] the run's step.
        """
        velocity, previous = lag.velocity, self.previous_velocity
        self.previous_velocity = np.array(velocity, dtype=float)
        m = self.model
        if m is None or lag.deflection0 is None or hand_travel is None:
            return None
        moving = hand_travel >= MOVING_FRACTION * step_length and steady_speed(velocity, previous)
        if not moving or magnitude >= dead_band:
            self.short = 0
            return None
        implied = m.implied(lag, position, target)
        bound = m.error_at(velocity)
        if implied - magnitude <= bound:
            self.short = 0
            return None
        self.short += 1
        if self.short < DEAD_PERIODS:
            return None
        return Stop(
            "sensor_dead",
            f"the sensor reads no force (|F| = {magnitude:.2f} N, within the dead band "
            f"{dead_band:.2g} N) while the hand moves steadily ({norm(velocity) * 1000:.0f} "
            f"mm/s) and its deflection implies {implied:.1f} N, more than the calibrated "
            f"model's error {bound:.2f} N above the reading, {self.short} periods in a row",
        )

    def check_quiet(
        self, force: FloatArray, hand_travel: float | None, step_length: float
    ) -> Stop | None:
        """The quiet-sensor test (module docstring), once per period.

        Args:
            force: (3,) [N] the reading less F_d, F = F_s - F_d.
            hand_travel: [m] the hand's travel over the last period (None before moving).
            step_length: [m] the run's step.
        """
        if self.noise is None or hand_travel is None:
            return None
        if hand_travel < MOVING_FRACTION * step_length:
            self.moving_forces.clear()  # the window holds moving periods in a row only
            return None
        self.moving_forces.append(np.array(force, dtype=float))
        if len(self.moving_forces) < QUIET_WINDOW:
            return None
        mean = norm(np.mean(self.moving_forces, axis=0))
        floor = QUIET_SIGMAS * self.noise / math.sqrt(QUIET_WINDOW)
        if mean >= floor:
            return None
        return Stop(
            "sensor_dead",
            f"the sensor reads only noise while the hand moves: the mean of F over the last "
            f"{QUIET_WINDOW} moving periods is {mean:.3f} N, below {floor:.3f} N "
            f"({QUIET_SIGMAS:g} x the calibrated noise sigma {self.noise:.3g} N / "
            f"sqrt({QUIET_WINDOW})); a live sensor reads the moved object's resistance",
        )

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
