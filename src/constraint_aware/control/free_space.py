"""The free-space calibration: the arm's tracking time constant, its lag model's error per
speed and the force noise, measured with the hand holding nothing.

`calibrate_free_space(robot, name=...)` rests, steps the setpoint and ramps it along each
world axis over a path a staircase has cleared first, and returns a `RobotProfile`
(control/profile.py) whose stiffness, grasp play, deflection error and sensor convention are
unmeasured (`HELD_ONLY`: there is nothing to push against). The tracking time constant is the
arm controller's, not the task's: measured once per robot and controller setting, it is given
to a grasp's calibration (`control.calibrate.calibrate(..., free_space_profile=...)`). It
drives the robot through a `control.calibration_session.CalibrationSession` (the same checks
and the same safe end as a grasp's calibration) and never imports MuJoCo.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np

from constraint_aware.control.calibration_session import (
    SAFE_SHARE,
    SETTLE_SHARE,
    TAU_COVERAGE,
    TAU_RELATIVE_UNCERTAINTY,
    CalibrationSession,
    CalibrationStop,
    Reading,
    pool_rest_windows,
    rest_phase,
    run_calibration,
)
from constraint_aware.control.lag import LagModel
from constraint_aware.control.profile import QUANTITY_NAMES, Measurement, RobotProfile
from constraint_aware.control.robot import Robot, reported_time_constant
from constraint_aware.control.sensor_health import steady_speed
from constraint_aware.control.tracking_fit import fit_step_response, step_rise_time
from constraint_aware.errors import InvalidInputError, check_int, check_number
from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose

__all__ = ["HELD_ONLY", "REST_SHARE", "FreeSpaceConfig", "calibrate_free_space"]

#: The session a free-space calibration runs (held to its FreeSpaceConfig's limits).
_Session: TypeAlias = CalibrationSession["FreeSpaceConfig"]

#: The hand is at rest for a free-space step when it moved less than this share of the step
#: in a period.
REST_SHARE = 0.005


@dataclass(frozen=True)
class FreeSpaceConfig:
    """How the free-space calibration moves (`calibrate_free_space`). Units in brackets.
    Validated at construction (ConfigError names the field and its valid range)."""

    rest_periods: int = 24  # readings at rest before the steps and again after them (>= 3):
    # the noise a grasp's calibration pools with its own
    force_limit: float = 20.0  # [N] |F - F_rest| above this stops the calibration
    contact_force: float = 3.0  # [N] |F - F_rest| at which a move has met something: stop
    max_stiffness: float = 20_000.0  # [N/m] the stiffest arm the clearance stairs are sized
    # for: a stair blocked whole at this stiffness stays within 0.8 of the force limit
    step: float = 0.01  # [m] the setpoint step whose response gives tau (the arm's response
    # depends on the step's size where its joints have dry friction: step as large as the
    # task's moves)
    step_periods: int = 8  # [periods] the response read after each step
    ramp_travel: float = 0.04  # [m] how far the setpoint ramps (out and back) along each
    # axis, over the path the clearance staircase cleared: long enough for the hand to reach
    # a steady speed at ramp_step per period
    ramp_step: float = 0.01  # [m] the ramp's setpoint step per control period: the
    # executor's step length, so the lag error is measured at the speed the runs move at
    max_periods: int = 720  # the budget of control periods (a slow arm settling after every
    # move needs up to about 700)

    def __post_init__(self) -> None:
        n = "FreeSpaceConfig."
        check_int(n + "rest_periods", self.rest_periods, low=3)
        limit = check_number(n + "force_limit", self.force_limit, low=0, low_open=True, unit="N")
        check_number(
            n + "contact_force", self.contact_force, low=0, low_open=True, high=limit,
            high_open=True, unit="N",
        )  # fmt: skip
        check_number(n + "max_stiffness", self.max_stiffness, low=0, low_open=True, unit="N/m")
        check_number(n + "step", self.step, low=1e-4, high=0.05, unit="m")
        check_int(n + "step_periods", self.step_periods, low=4)
        check_number(n + "ramp_travel", self.ramp_travel, low=1e-3, high=0.1, unit="m")
        check_number(
            n + "ramp_step", self.ramp_step, low=1e-4, high=self.ramp_travel / 3, unit="m"
        )  # at least three ramp periods: a steady speed needs two in a row
        check_int(n + "max_periods", self.max_periods, low=2 * self.rest_periods + 1)

    @property
    def travel(self) -> float:
        """[m] the furthest the setpoint goes from the start along an axis."""
        return max(self.step, self.ramp_travel)

    @property
    def travel_limit(self) -> float:
        """[m] the furthest a setpoint is ever commanded from the start (the session's
        limit: `travel`)."""
        return self.travel


#: Quantities only a calibration holding an object measures.
HELD_ONLY = (
    "stiffness",
    "grasp_play",
    "deflection_error",
    "deflection_error_per_speed",
    "sensor_convention",
)


def calibrate_free_space(
    robot: Robot,
    name: str = "robot",
    config: FreeSpaceConfig | None = None,
    setup: str = "free space",
) -> RobotProfile:
    """Measure the force noise and offset, the tracking time constant and the lag model's
    error per speed with the hand in free space (holding nothing, clear of everything by more
    than `config.travel` along +x, +y and +z): once per robot and controller setting;
    `calibrate(..., free_space_profile=...)` takes its tau, its lag error where a grasp's
    pushes do not measure the deflection error per speed, and pools its readings at rest
    into the grasp's noise.

    The phases (one reading per control period, every reading checked as `calibrate`'s):
    1. rest: `rest_periods` readings (the force offset, the noise);
    2. per world axis +x, +y, +z: a clearance staircase out to `travel` (stairs no longer
       than 0.8 (force_limit - contact_force) / max_stiffness, so an obstacle met along it
       stays within the force limit), a ramp back to the start; then, each from rest (the
       hand moving less than REST_SHARE x step in a period), a setpoint step out to `step`
       and one back, at once over the path just cleared, the hand's response read for
       `step_periods` periods after each; a ramp out to `ramp_travel` and back, `ramp_step`
       per period;
    3. rest again: `rest_periods` readings (pooled into the noise when their spread agrees).

    tau per step: the arm's impedance m x'' = k (s - x) - c x' fitted to the response
    (`control.tracking_fit.fit_step_response`, the setpoint a straight line within each
    period), then the fitted model's 63.2 % rise time for a step (`step_rise_time`; c / k for
    a well-damped arm); tau is the mean over
    the steps whose fit's standard uncertainty is within TAU_RELATIVE_UNCERTAINTY (the
    per-step values are noted): one number for the three axes, as the Robot protocol's.
    lag_error [s]: the largest |lagged deflection| over the hand's speed on the ramps while it
    moved at a steady speed (`_lag_error`). Stiffness, grasp play, deflection error and
    sensor convention are left unmeasured: there is nothing to push against.

    Safety: |F - F_rest| reaching `contact_force` during any move stops the calibration with
    outcome "contact" (the free space was not free); the force limit, the travel (never
    more than `travel` from the start), non-finite or stale readings and the budget stop it as
    `calibrate`'s do. On every stop, on any exception and at the end the starting setpoint is
    commanded back and the robot is told to hold.

    Args:
        robot: a Robot at rest in free space; only its required members are used.
        name: the robot's name, recorded in the profile.
        config: how to move; None: FreeSpaceConfig's defaults.
        setup: what the hand held, recorded in the profile.

    Returns:
        The profile (`outcome` "complete" or the named stop). A robot exception propagates
        with the partial profile attached as `exc.robot_profile`.
    """
    if not isinstance(name, str) or not name.strip():
        raise InvalidInputError(f"name: must be a non-empty string, got {name!r}")
    if not isinstance(setup, str):
        raise InvalidInputError(f"setup: must be a string, got {setup!r}")
    cfg = config or FreeSpaceConfig()
    period = check_number("robot.control_period", robot.control_period, low=0, low_open=True)
    profile = RobotProfile(
        robot=name,
        quantities={q: Measurement.unmeasured(q, "not reached") for q in QUANTITY_NAMES},
        control_period=period,
        setup=setup,
    )
    for q in HELD_ONLY:
        profile.quantities[q] = Measurement.unmeasured(
            q, "a free-space calibration: nothing to push against"
        )
    return run_calibration(
        robot,
        profile,
        lambda start: CalibrationSession(robot, cfg, start),
        lambda session: _run_free_space(session, cfg, profile),
    )


def _run_free_space(session: _Session, cfg: FreeSpaceConfig, profile: RobotProfile) -> None:
    tau_report, tau_note = reported_time_constant(session.robot)
    if tau_note:
        profile.notes.append(tau_note)
    rest = rest_phase(session, profile)
    responses = []
    ramps: list[list[Reading]] = []
    for u in np.eye(3):
        steps, axis_ramps = _step_response(session, cfg, u)
        for i, response in enumerate(steps):
            responses.append((-u if i % 2 else u, response))
        ramps.extend(axis_ramps)
    final = [session.step(session.home) for _ in range(cfg.rest_periods)]
    tolerance = SETTLE_SHARE * cfg.step
    while len(final) >= 2 and np.linalg.norm(final[1].position - final[0].position) >= tolerance:
        final.pop(0)
    final = final[1:]
    pool_rest_windows(profile, rest, final, "the steps")
    _step_time_constant(profile, responses, session.robot.control_period)
    _lag_error(profile, ramps, session.robot.control_period, cfg)
    if tau_report is not None:
        profile.notes.append(f"the robot reports tracking_time_constant {tau_report:g} s")


def _guarded_step(session: _Session, cfg: FreeSpaceConfig, target: Pose | None) -> Reading:
    """One period toward `target`; |F - F_rest| at contact_force stops the calibration."""
    reading = session.step(target)
    assert session.rest_force is not None
    change = float(np.linalg.norm(reading.force - session.rest_force))
    if change >= cfg.contact_force:
        raise CalibrationStop(
            "contact",
            f"|F - F_rest| = {change:.2f} N >= contact_force {cfg.contact_force:g} N during a "
            "free-space move: the hand met something",
        )
    return reading


def _step_response(
    session: _Session, cfg: FreeSpaceConfig, u: FloatArray
) -> tuple[list[list[Reading]], list[list[Reading]]]:
    """Clear the path along `u` with a staircase to `cfg.travel` and ramp back to the start;
    then, from rest, step out to `step` and back at once, and ramp out to `ramp_travel` and
    back, all over the cleared path. Returns the two step responses (the readings from the
    settled one through `step_periods` after) and the three ramps (the readings from the
    settled one through the ramp and the settling after it). The first ramp back is not a step
    response: the slow staircase before it leaves an arm with dry friction in its joints
    loaded unlike a step from rest."""
    stair = SAFE_SHARE * (cfg.force_limit - cfg.contact_force) / cfg.max_stiffness
    depth = 0.0
    while depth < cfg.travel:
        depth = min(depth + stair, cfg.travel)
        last = _guarded_step(session, cfg, session.at(u, depth))
    ramps = [_ramp(session, cfg, u, depth, 0.0, _settle(session, cfg, last))]
    last = ramps[-1][-1]
    responses = []
    for target in (session.at(u, cfg.step), session.home):
        last = _settle(session, cfg, last)
        response = [last]
        for _ in range(cfg.step_periods):
            response.append(_guarded_step(session, cfg, target))
        responses.append(response)
        last = response[-1]
    for start, end in ((0.0, cfg.ramp_travel), (cfg.ramp_travel, 0.0)):
        ramps.append(_ramp(session, cfg, u, start, end, _settle(session, cfg, last)))
        last = ramps[-1][-1]
    return responses, ramps


def _ramp(
    session: _Session, cfg: FreeSpaceConfig, u: FloatArray, start: float, end: float, last: Reading
) -> list[Reading]:
    """From the settled reading `last` (setpoint `start` [m] along `u`), move the setpoint to
    `end` [m] by `ramp_step` per period, then hold until the hand settles: the readings, the
    settled one first."""
    readings = [last]
    periods = math.ceil(abs(end - start) / cfg.ramp_step - 1e-9)
    for i in range(1, periods + 1):
        depth = start + (end - start) * min(1.0, i * cfg.ramp_step / abs(end - start))
        readings.append(_guarded_step(session, cfg, session.at(u, depth)))
    readings.append(_settle(session, cfg, readings[-1]))
    return readings


def _settle(session: _Session, cfg: FreeSpaceConfig, last: Reading) -> Reading:
    """Hold until the hand moved less than REST_SHARE x step in a period (at most
    2 step_periods): the next step starts from rest, as the fitted model does."""
    for _ in range(2 * cfg.step_periods):
        held = _guarded_step(session, cfg, None)
        moved = float(np.linalg.norm(held.position - last.position))
        last = held
        if moved < REST_SHARE * cfg.step:
            break
    return last


def _step_time_constant(
    profile: RobotProfile, responses: list[tuple[FloatArray, list[Reading]]], period: float
) -> None:
    """tau: the mean over the axes of the fitted impedance's 63.2 % step rise time
    (`calibrate_free_space`)."""
    method = (
        "free-space setpoint steps back along x, y and z: the arm's impedance m x'' = "
        "k (s - x) - c x' fitted to each response, tau its 63.2 % rise time for a step; the "
        "mean over the axes"
    )
    values: list[tuple[float, float]] = []
    notes: list[str] = []
    for u, readings in responses:
        base = readings[0]
        drive = np.array([(r.commanded - base.commanded) @ u for r in readings])
        position = np.array([(r.position - base.position) @ u for r in readings])
        fit = fit_step_response(drive, position, period)
        axis = ("+" if u.sum() > 0 else "-") + "xyz"[int(np.argmax(np.abs(u)))]
        if fit is None:
            notes.append(f"{axis}: the fit did not converge")
            continue
        b, b_u, zeta, stall, _rms = fit
        rise = step_rise_time(b, zeta, (1.0 - math.exp(-1.0)) / (1.0 - stall))
        if not (b_u <= TAU_RELATIVE_UNCERTAINTY * b and math.isfinite(rise)):
            notes.append(
                f"{axis}: c / k {b:.3g} s +- {b_u / b:.0%}, stalled {stall:.0%} short: undetermined"
            )
            continue
        values.append((rise, b_u * rise / b))
        notes.append(
            f"{axis}: {rise:.3g} s (c / k {b:.3g} s, damping ratio {zeta:.2g}, stalled "
            f"{stall:.0%} short)"
        )
    profile.notes.append("tracking time constant by axis: " + "; ".join(notes))
    if not values:
        profile.quantities["tracking_time_constant"] = Measurement.unmeasured(
            "tracking_time_constant",
            "no axis's step response determined tau within "
            f"{TAU_RELATIVE_UNCERTAINTY:.0%} ({'; '.join(notes)})",
            method,
            len(responses),
        )
        return
    tau = float(np.mean([v for v, _ in values]))
    tau_u = math.sqrt(sum(e**2 for _, e in values)) / len(values)
    profile.quantities["tracking_time_constant"] = Measurement(tau, tau_u, "s", method, len(values))


def _lag_error(
    profile: RobotProfile, ramps: list[list[Reading]], period: float, cfg: FreeSpaceConfig
) -> None:
    """lag_error [s]: over the free-space ramps' readings with the hand moving at a steady
    speed (`steady_speed`), the largest |lagged deflection| (control.lag.LagModel with the
    measured tau, the deflection counted from the ramp's settled start) over the hand's speed,
    and at least TAU_COVERAGE x tau's standard uncertainty. In free space the wrench reads
    about nothing, so the stiffness times this is the deflection model's error per unit speed
    (`calibrate` takes it where the pushes did not measure one)."""
    q = profile.quantities
    tau = q["tracking_time_constant"]
    method = (
        f"free-space setpoint ramps of {cfg.ramp_step * 1e3:g} mm per period out to "
        f"{cfg.ramp_travel * 1e3:g} mm and back along x, y and z: the largest |lagged "
        "deflection| (tau credited along the hand's motion) over the hand's speed while it "
        "moved at a steady speed"
    )
    if tau.value is None:
        q["lag_error"] = Measurement.unmeasured(
            "lag_error", "the tracking time constant is unmeasured: no lag model", method
        )
        return
    rest_speed = REST_SHARE * cfg.step / period  # [m/s]
    errors: list[float] = []
    speeds: list[float] = []
    for readings in ramps:
        base = readings[0]
        lag = LagModel(tau.value, deflection0=base.position - base.commanded)
        previous = np.zeros(3)
        for before, reading in itertools.pairwise(readings):
            lag.velocity = (reading.position - before.position) / period
            speed = float(np.linalg.norm(lag.velocity))
            if speed >= rest_speed and steady_speed(lag.velocity, previous):
                deflection = lag.lagged_deflection(reading.position, reading.commanded)
                errors.append(float(np.linalg.norm(deflection)) / speed)
                speeds.append(speed)
            previous = lag.velocity
    if not errors:
        q["lag_error"] = Measurement.unmeasured(
            "lag_error", "the hand never moved at a steady speed during the ramps", method
        )
        return
    value = max(max(errors), TAU_COVERAGE * (tau.uncertainty or 0.0))
    profile.notes.append(
        f"lag error at a steady speed: largest {max(errors):.3g} s, median {np.median(errors):.3g}"
        f" s over {len(errors)} readings at {min(speeds) * 1e3:.0f}-{max(speeds) * 1e3:.0f} mm/s"
    )
    method += f"; at least {TAU_COVERAGE:g} x tau's standard uncertainty"
    q["lag_error"] = Measurement(value, 0.0, "s", method, len(errors))
