"""The session both calibrations drive a robot with, through the Robot protocol alone.

A `CalibrationSession` commands the robot one control period at a time and reads it once per
period, every reading checked; `run_calibration` runs a calibration's phases on one and ends
it safely; `rest_phase`, `measure_noise` and `force_spread` are the rest phase and the force
noise both calibrations measure. It never imports MuJoCo.

Safety: every reading is checked (finite force and poses, not stale, |F - F_rest| within the
calibration's `force_limit`); no setpoint is ever commanded further than `travel_limit` from
where the calibration started; it stops after `max_periods`. On every stop, on any exception
and at the end, the starting setpoint is commanded back and the robot is told to hold
(`hold()`, when it has one). A named stop (`CalibrationStop`) returns the profile with what
was measured before it and the outcome; an exception carries the partial profile as
`exc.robot_profile`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

import numpy as np

from constraint_aware.control.profile import Measurement, RobotProfile
from constraint_aware.control.robot import Robot, request_hold
from constraint_aware.deadband import MIN_THRESHOLD, NOISE_SIGMAS, threshold_from_noise
from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose

__all__ = [
    "POOL_RATIO",
    "QUIET_SIGMA",
    "SAFE_SHARE",
    "SETTLE_SHARE",
    "STALE_SAMPLES",
    "TAU_COVERAGE",
    "TAU_RELATIVE_UNCERTAINTY",
    "CalibrationSession",
    "CalibrationStop",
    "Reading",
    "SessionLimits",
    "force_spread",
    "measure_noise",
    "noise_dof",
    "pool_rest_windows",
    "rest_phase",
    "run_calibration",
    "set_noise",
]

#: Identical wrench samples in a row that stop the calibration (a stale driver).
STALE_SAMPLES = 3
#: A push's level is settled when the hand moved less than this share of the push's depth over
#: the period it was held (a grasp that yields under the push still creeps by a few
#: hundredths); the hand has settled at the start when it moved less than this share of
#: free_travel (the free-space calibration: of its step) in a period.
SETTLE_SHARE = 0.05
#: The readings at rest after the pushes (or the free-space steps) are pooled into the noise
#: only when their spread is within this factor of the spread before them (either way); a
#: larger difference is taken for a grasp still moving after the pushes. Two windows of the
#: same noise (12 and 8 readings) differ by more in about 6 % of calibrations, which then keep
#: only the first window: less precision, no bias.
POOL_RATIO = 1.5
#: Below this sigma [N] a force reading is implausibly quiet at rest (frozen, or noise-free).
QUIET_SIGMA = 1e-6
#: A stair (a push's, or one clearing a free-space path) may use at most this share of the
#: headroom to the force limit, should the object block all of it at the stiffest the arm may
#: be (the noise and the arm's dynamics add).
SAFE_SHARE = 0.8
#: tau is unmeasured when the fit's standard uncertainty exceeds this share of it (the
#: tolerance tau is meant to within: a wider fit did not determine it).
TAU_RELATIVE_UNCERTAINTY = 0.2
#: The deflection error per speed is at least this many standard uncertainties of tau times
#: the stiffness, the free-space lag error at least this many of tau (the coverage of a
#: 3-sigma bound).
TAU_COVERAGE = 3.0


class SessionLimits(Protocol):
    """The limits a session holds the robot to (a calibration's config)."""

    @property
    def rest_periods(self) -> int:
        """Readings at rest, one per period, in the rest phase."""
        ...

    @property
    def force_limit(self) -> float:
        """[N] |F - F_rest| above this stops the calibration."""
        ...

    @property
    def travel_limit(self) -> float:
        """[m] the furthest a setpoint is ever commanded from the start."""
        ...

    @property
    def max_periods(self) -> int:
        """The budget of control periods."""
        ...


#: A calibration's config (its limits hold the session).
LimitsT = TypeVar("LimitsT", bound=SessionLimits)
#: A calibration's session (a calibration may carry its own state on one).
SessionT = TypeVar("SessionT", bound="CalibrationSession[Any]")


@dataclass
class Reading:
    """One control period's reading. Vectors (3,) in the world frame."""

    period: int  # control periods advanced before it
    force: FloatArray  # [N]
    position: FloatArray  # [m] the measured tool point
    commanded: FloatArray  # [m] the setpoint
    pose: Pose  # the measured pose

    @property
    def stretch(self) -> FloatArray:
        """[m] commanded minus measured position: the arm spring's deflection (and lag)."""
        return self.commanded - self.position


class CalibrationStop(Exception):
    """A named stop of the calibration (a profile outcome, not a robot error).

    Args:
        outcome: the profile's outcome it ends with (e.g. "force_limit", "contact").
        reason: what happened, with the numbers, for the profile's notes.
    """

    def __init__(self, outcome: str, reason: str) -> None:
        super().__init__(reason)
        self.outcome = outcome


class CalibrationSession(Generic[LimitsT]):
    """The robot, commanded within the travel limit and read once per period, every reading
    checked: finite, fresh, within the force limit.

    Args:
        robot: the Robot calibrated; only its required members are used.
        cfg: the calibration's config: its limits hold the session (`SessionLimits`).
        home: the commanded pose the calibration starts from (and comes back to).
    """

    def __init__(self, robot: Robot, cfg: LimitsT, home: Pose) -> None:
        self.robot = robot
        self.cfg = cfg
        self.home = home
        self.periods = 0
        self.rest_force: FloatArray | None = None  # [N] once the rest phase is done
        self._last: FloatArray | None = None
        self._repeats = 0
        self.log: list[Reading] = []  # every reading, in order

    @property
    def remaining(self) -> int:
        """Control periods left in the budget."""
        return self.cfg.max_periods - self.periods

    def at(self, direction: FloatArray, depth: float) -> Pose:
        """The starting pose moved `depth` [m] along `direction`, within the travel limit."""
        depth = min(depth, self.cfg.travel_limit)
        return Pose(self.home.position + depth * direction, self.home.orientation)

    def step(self, target: Pose | None = None) -> Reading:
        """Command `target` (None: keep the setpoint), let one period pass, read."""
        if self.periods >= self.cfg.max_periods:
            raise CalibrationStop(
                "time_limit", f"the budget of {self.cfg.max_periods} periods is used up"
            )
        if target is not None:
            offset = float(np.linalg.norm(np.asarray(target.position) - self.home.position))
            if not offset <= self.cfg.travel_limit * (1 + 1e-9):  # also catches NaN
                raise CalibrationStop(
                    "bad_reading", f"a target {offset} m from the start was refused"
                )
            self.robot.command_pose(target)
        self.robot.advance()
        self.periods += 1
        return self.read()

    def read(self) -> Reading:
        """Read the robot without advancing: a CalibrationStop on a non-finite force or pose,
        on STALE_SAMPLES identical wrench samples in a row, or (after the rest phase) on
        |F - F_rest| above the force limit; the reading is logged."""
        wrench = self.robot.read_wrench()
        force = np.asarray(wrench.force, dtype=float)
        if force.shape != (3,) or not np.all(np.isfinite(force)):
            raise CalibrationStop(
                "bad_reading", f"wrench force {wrench.force!r} is not 3 finite numbers"
            )
        sample = np.concatenate([force, np.asarray(wrench.torque, dtype=float).ravel()])
        if self._last is not None and np.array_equal(sample, self._last):
            self._repeats += 1
            if self._repeats >= STALE_SAMPLES - 1:
                raise CalibrationStop(
                    "stale_wrench", f"{STALE_SAMPLES} identical wrench samples in a row"
                )
        else:
            self._repeats = 0
        self._last = sample
        pose = self.robot.read_pose()
        commanded = self.robot.commanded_pose()
        for what, p in (("pose", pose), ("commanded pose", commanded)):
            _check_pose(p, what)
        if self.rest_force is not None:
            change = float(np.linalg.norm(force - self.rest_force))
            if change > self.cfg.force_limit:
                raise CalibrationStop(
                    "force_limit",
                    f"|F - F_rest| = {change:.1f} N > the calibration's limit "
                    f"{self.cfg.force_limit:g} N",
                )
        reading = Reading(
            self.periods,
            force,
            np.asarray(pose.position, dtype=float),
            np.asarray(commanded.position, dtype=float),
            pose,
        )
        self.log.append(reading)
        return reading

    def restore(self, notes: list[str], wait: bool) -> None:
        """Command the starting setpoint back (and let a period pass when `wait`), then tell
        the robot to hold; failures become notes (the profile must still be returned)."""
        try:
            moved = float(np.linalg.norm(self.robot.commanded_pose().position - self.home.position))
            self.robot.command_pose(self.home)
            if wait and not moved <= 1e-9:  # back already: nothing to wait for
                self.robot.advance()
                self.periods += 1
        except Exception as exc:
            notes.append(f"restoring the starting setpoint failed: {exc!r}")
        request_hold(self.robot, notes)


def _check_pose(pose: Pose, what: str) -> None:
    """A CalibrationStop ("bad_reading") naming `what` when `pose` is not finite."""
    position = np.asarray(pose.position, dtype=float)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(pose.orientation.as_quat()))):
        raise CalibrationStop("bad_reading", f"{what} {pose.position!r} is not finite")


def run_calibration(
    robot: Robot,
    profile: RobotProfile,
    open_session: Callable[[Pose], SessionT],
    body: Callable[[SessionT], None],
) -> RobotProfile:
    """Run `body` on a session from the robot's commanded pose; on every end (done, a named
    stop, an exception) the start is commanded back and the robot told to hold, and
    `profile` says how it ended (an exception carries it as `exc.robot_profile`).

    Args:
        robot: the Robot calibrated.
        profile: the profile `body` fills in; its outcome, notes and periods are set here.
        open_session: the session on `robot` from the starting pose it is given (checked
            finite first).
        body: the calibration's phases; a `CalibrationStop` ends them with its outcome.

    Returns:
        `profile`. Exceptions other than a CalibrationStop propagate, the profile attached.
    """
    session: SessionT | None = None
    try:
        start = robot.commanded_pose()
        _check_pose(start, "commanded pose")
        session = open_session(start)
        body(session)
    except CalibrationStop as stop:
        profile.outcome = stop.outcome
        profile.notes.append(f"stopped ({stop.outcome}): {stop}")
        _mark_unreached(profile, f"the calibration stopped first ({stop.outcome}: {stop})")
        _finish(robot, session, profile, wait=True)
    except BaseException as exc:
        profile.outcome = "error"
        profile.notes.append(f"stopped (error): {type(exc).__name__}: {exc}")
        _mark_unreached(profile, f"the robot raised first ({type(exc).__name__})")
        try:  # first: a second Ctrl-C during the restore must not lose it
            exc.robot_profile = profile  # type: ignore[attr-defined]
        except AttributeError:
            profile.notes.append("could not attach the profile to the exception")
        _finish(robot, session, profile, wait=False)
        raise
    else:
        _finish(robot, session, profile, wait=True)
    return profile


def _finish(
    robot: Robot, session: CalibrationSession[Any] | None, profile: RobotProfile, wait: bool
) -> None:
    """Restore the start and hold (or only hold, when the start was never read)."""
    if session is None:
        request_hold(robot, profile.notes)
        return
    session.restore(profile.notes, wait=wait)
    profile.periods = session.periods


def _mark_unreached(profile: RobotProfile, reason: str) -> None:
    """Give every quantity still "not reached" the reason the calibration ended first."""
    for name, m in profile.quantities.items():
        if not m.measured and m.reason == "not reached":
            profile.quantities[name] = Measurement.unmeasured(name, reason)


def rest_phase(session: CalibrationSession[Any], profile: RobotProfile) -> list[Reading]:
    """Hold for `rest_periods` readings: the force offset (`force_offset_x/y/z`) and a first
    estimate of the noise (`measure_noise`) go into `profile`, the offset into
    `session.rest_force`.

    Args:
        session: the session, before any other phase.
        profile: the profile the quantities go into.

    Returns:
        The readings, in order.
    """
    n = session.cfg.rest_periods
    readings = [session.step() for _ in range(n)]
    forces = np.array([r.force for r in readings])
    residual = _about_a_line(forces)
    offset = forces.mean(axis=0)
    error = np.sqrt(np.sum(residual**2, axis=0) / (n - 2) / n)
    for i, axis in enumerate("xyz"):
        profile.quantities[f"force_offset_{axis}"] = Measurement(
            float(offset[i]), float(error[i]), "N", f"mean of {n} readings at rest", n
        )
    session.rest_force = offset
    measure_noise(profile, [readings])  # kept if the calibration stops early; refined after it
    return readings


def measure_noise(
    profile: RobotProfile, windows: list[list[Reading]], between: str = "the pushes"
) -> None:
    """sigma (`force_noise`) from the readings at rest: the spread about a straight line per
    axis and window (a drifting reading is not noise), pooled over the axes and the windows
    of at least three readings; the dead band (`dead_band`) from it.

    Args:
        profile: the profile the two quantities (and notes on drift) go into.
        windows: the windows of readings at rest; at least one of three readings or more.
        between: what the windows are before and after (the method's text).
    """
    used = [w for w in windows if len(w) >= 3]
    squares = sum(float(np.sum(_about_a_line(np.array([r.force for r in w])) ** 2)) for w in used)
    dof = sum(3 * (len(w) - 2) for w in used)
    count = sum(len(w) for w in used)
    sigma = math.sqrt(squares / dof)
    sigma_u = sigma / math.sqrt(2 * dof)
    set_noise(
        profile,
        Measurement(
            sigma,
            sigma_u,
            "N",
            f"{count} readings at rest, one per period ("
            + (
                f"windows of {' + '.join(str(len(w)) for w in used)}, before and after {between}"
                if len(used) > 1
                else "one window"
            )
            + "): the spread about a straight line per axis and window (drift removed), "
            "pooled over x, y, z",
            count,
        ),
    )
    if sigma < QUIET_SIGMA:
        profile.notes.append(
            f"the force reading is implausibly quiet at rest (sigma {sigma:.2g} N): a frozen "
            "or noise-free reading"
        )
    for w in used:
        forces = np.array([r.force for r in w])
        drift = float(np.max(np.abs(forces[-1] - forces[0])))
        if drift > max(NOISE_SIGMAS * sigma, MIN_THRESHOLD) * 2:
            profile.notes.append(
                f"the force reading drifted about {drift:.2f} N over {len(w)} periods at rest "
                "(a creeping grasp or a drifting sensor): removed from the noise"
            )
    if len(used) == 2:
        first, last = (np.mean([r.force for r in w], axis=0) for w in used)
        change = float(np.linalg.norm(last - first))
        if change > max(NOISE_SIGMAS * sigma, MIN_THRESHOLD):
            profile.notes.append(
                f"the reading at rest changed by {change:.2f} N over the calibration (the "
                "grasp or the object moved under the pushes)"
            )


def pool_rest_windows(
    profile: RobotProfile,
    first: list[Reading],
    last: list[Reading],
    between: str,
    cause: str = "",
) -> None:
    """The noise from the windows at rest before and after `between` (the method's text),
    pooled (`measure_noise`) when their spreads agree within POOL_RATIO; else the estimate
    from `first` stays and a note says why `last` is left out (`cause`, e.g. " (the grasp
    still moving)", after the spreads). `last` counts with three readings or more."""
    if len(last) < 3:
        return
    before, after = force_spread(first), force_spread(last)
    if before > 0 and 1 / POOL_RATIO <= after / before <= POOL_RATIO:
        measure_noise(profile, [first, last], between)
    else:
        profile.notes.append(
            f"the readings at rest after {between} spread {after:.3g} N against {before:.3g} "
            f"N before them{cause}: not pooled into the noise"
        )


def set_noise(profile: RobotProfile, noise: Measurement) -> None:
    """Put the force noise sigma `noise` [N] into `profile` (`force_noise`) with the dead band
    derived from it (`dead_band`: `deadband.threshold_from_noise`)."""
    assert noise.value is not None and noise.uncertainty is not None
    band = threshold_from_noise(noise.value)
    profile.quantities["force_noise"] = noise
    profile.quantities["dead_band"] = Measurement(
        band,
        0.0 if band == MIN_THRESHOLD else NOISE_SIGMAS * noise.uncertainty,
        "N",
        f"deadband.threshold_from_noise: max({MIN_THRESHOLD:g} N, {NOISE_SIGMAS:g} sigma)",
        noise.count,
        source=noise.source,
    )


def noise_dof(noise: Measurement) -> float:
    """The degrees of freedom of a noise sigma measured by `measure_noise` (its standard
    uncertainty is sigma / sqrt(2 dof)); 0 when unmeasured or given no uncertainty."""
    if noise.value is None or not noise.uncertainty:
        return 0.0
    return 0.5 * (noise.value / noise.uncertainty) ** 2


def force_spread(window: list[Reading]) -> float:
    """[N] the per-axis spread of a window's force readings about a straight line, pooled.

    Args:
        window: three readings or more, one per period.
    """
    residual = _about_a_line(np.array([r.force for r in window]))
    return math.sqrt(float(np.sum(residual**2)) / (3 * (len(window) - 2)))


def _about_a_line(forces: FloatArray) -> FloatArray:
    """(n, 3) the residuals of (n, 3) readings about a least-squares straight line in time."""
    n = len(forces)
    t = np.arange(n, dtype=float)
    design = np.stack([np.ones(n), t - t.mean()], axis=1)
    coef, *_ = np.linalg.lstsq(design, forces, rcond=None)
    return np.asarray(forces - design @ coef, dtype=float)
