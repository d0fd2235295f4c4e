"""Calibration: measure what the controllers need from a robot through the Robot protocol alone.

`calibrate(robot, name=...)` holds, then pushes the grasped object in known directions, and
returns a `RobotProfile` (control/profile.py): for each quantity its value, uncertainty, unit
and method, or the reason it could not be measured. It uses only the protocol's required
members (wrench, pose, commanded pose, command, advance, control period); the optional reports
(`translational_stiffness`, `tracking_time_constant`) are only noted beside the measured
values. It never imports MuJoCo.

The phases (one reading per control period throughout):

1. Rest: `rest_periods` readings while holding: their mean is the force offset.
2. Pushes in the workplane's directions (`control.probe.push_directions`: four in the plane,
   or the six world axes without one). Each push is a staircase: the setpoint moves further
   along the direction every period, by at most twice its last stair and never by more than
   would take |dF| (the force change from the reading before the push) past 0.8 of the way
   to `force_limit` should the object block the whole stair at the stiffest the arm may
   be: `max_stiffness` until a slope of |dF| over the stretch has been measured, twice
   that slope after. Once the force rises the stairs are sized from that slope. The push
   ends when
   - |dF| reaches `contact_force`: blocked. That stair, held a period, is level A; one more
     stair, sized from the slope to add push_force - contact_force and held a period, is
     level B. Where B fell short (an arm whose joints stick reads a steep jump at contact
     and a shallower spring after it), further held stairs from B, sized from the slope
     between A and B, while the budget leaves room for them and the way back;
   - the hand has followed the setpoint `free_travel` with |dF| below `contact_force`: free
     (the object's own motion, or play in the grasp);
   - the setpoint reaches `travel_limit`: soft (neither).
   The setpoint then goes back to where it started, at once after a blocked push and in
   `return_periods` equal steps after a free one, and holds until the hand settles. The
   opposite of a free or soft direction is skipped once a free and a blocked direction are
   known (before that it may be the blocked one the stiffness needs); pushing stops once
   two blocked directions and a free one are known, or when the budget (`max_periods`)
   would not leave room for another push. What is left of the budget is spent holding at
   the start.
3. The quantities:
   - force noise sigma: the readings' spread about a straight line per axis (a drifting
     reading is not noise), pooled over the rest before the pushes and the rest after them
     (when the two spreads agree within POOL_RATIO);
     the dead band is `deadband.threshold_from_noise(sigma)`;
   - stiffness k: what the controller's step force k x step means, the force one setpoint
     step adds against a blocked direction: k = |F_B - F_A| / |setpoint_B - setpoint_A|
     (workplane components; each level read the period after its stair, when the
     controller reads what its step did), the mean over the blocked pushes whose hand had
     settled at both levels; each direction's value is noted (the arms are anisotropic).
     Not |F| / |setpoint| at one level: the force at a level also holds what the step does
     not explain (a grasp's preload, an arm's joint friction fed forward). Where the object
     gave way under every push (the hand still moved), the setpoint's step is shared with
     the object's motion: k is then the arm's spring, |dF| over the stretch (commanded -
     measured position) with tau v (the arm's damping at the hand's velocity v) taken off;
   - deflection error: the executor's deflection model (k x the hand's deflection from its
     target, tau v credited along its motion: control.lag) against the read force over every
     push reading: its largest excess with the hand at rest, and per unit speed while the
     hand moved steadily, at least three standard uncertainties of tau times k
     (control.sensor_health's dead-sensor test);
   - grasp play: `control.probe.grasp_play` on the (A, B) pairs, the hand's travel against
     the force extrapolated to zero force;
   - sensor convention: `control.probe`'s own verdict on the level-A pushes (the median
     cosine between the force change and the stretch change: -1 for the Robot convention);
   - tracking time constant tau: on the free push, the tool point x along the push obeys
     the arm's impedance, m x'' = k (s - x) - c x' - R, with s the setpoint (a straight line
     within each period, as the protocol's "reached over the next control period") and R
     the force the object resists with (from the wrist reading). The two parameters m / k
     and c / k are fitted to the measured positions by least squares on the exact
     discretization of that model; tau = c / k, the lag per unit speed (the Robot protocol:
     a tool following a setpoint at speed v trails it by tau v). Without a free push, on a
     soft one (the hand moved against a rising resistance). A fit whose standard
     uncertainty exceeds TAU_RELATIVE_UNCERTAINTY of tau leaves it unmeasured.

The tracking time constant is the arm controller's, not the task's: `calibrate_free_space`
measures it (and the noise) once per robot with the hand in free space, from setpoint steps
over a path a staircase has cleared first, and the lag model's error per unit speed
(`lag_error`) from setpoint ramps at the executor's step per period over the same path; given
to `calibrate` as `free_space_profile`, its tau replaces the pushes' estimate, and k x its lag
error is the deflection error per speed where no push moved the hand at a steady speed, the
`source` of each quantity naming that calibration.

Safety: every reading is checked (finite force and poses, not stale, |F - F_rest| within
`force_limit`); no setpoint is ever commanded further than `travel_limit` from where the
calibration started; it stops after `max_periods`. On every stop, on any exception and at
the end, the starting setpoint is commanded back and the robot is told to hold (`hold()`,
when it has one). A named stop returns the profile with what was measured before it and the
outcome; an exception carries the partial profile as `exc.robot_profile`.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.lag import LagModel
from constraint_aware.control.probe import (
    STIFFNESS_VERDICTS,
    ProbeConfig,
    ProbePush,
    ProbeResult,
    grasp_play,
    push_directions,
)
from constraint_aware.control.probe import _push as judge_push
from constraint_aware.control.probe import _verdict as judge_pushes
from constraint_aware.control.profile import QUANTITY_NAMES, Measurement, RobotProfile
from constraint_aware.control.robot import (
    Robot,
    reported_stiffness,
    reported_time_constant,
    request_hold,
)
from constraint_aware.control.sensor_health import steady_speed
from constraint_aware.deadband import MIN_THRESHOLD, NOISE_SIGMAS, threshold_from_noise
from constraint_aware.errors import (
    InvalidInputError,
    check_int,
    check_number,
    check_unit_vector,
)
from constraint_aware.geometry import FloatArray, in_plane
from constraint_aware.spatial import Pose

__all__ = ["CalibrationConfig", "FreeSpaceConfig", "calibrate", "calibrate_free_space"]

#: Identical wrench samples in a row that stop the calibration (a stale driver).
STALE_SAMPLES = 3
#: A level is settled when the hand moved less than this share of the push's depth over the
#: period it was held (a grasp that yields under the push still creeps by a few hundredths);
#: the hand has settled at the start when it moved less than this share of free_travel in a
#: period.
SETTLE_SHARE = 0.05
#: Periods at most to wait after a push for the hand to settle at the start.
SETTLE_PERIODS = 2
#: The readings at rest after the pushes are pooled into the noise only when their spread is
#: within this factor of the spread before them (either way); a larger difference is taken
#: for a grasp still moving after the pushes. Two windows of the same noise (12 and 8
#: readings) differ by more in about 6 % of calibrations, which then keep only the first
#: window: less precision, no bias.
POOL_RATIO = 1.5
#: Below this sigma [N] a force reading is implausibly quiet at rest (frozen, or noise-free).
QUIET_SIGMA = 1e-6
#: Level B is used for the stiffness only when its |dF| exceeds level A's by at least this
#: share of (push_force - contact_force) (a push the travel limit cut short may not).
LEVEL_SPREAD = 0.5
#: The damping ratio the tau fit may take: [low, high]. Past `high` the arm is a first-order
#: lag and its mass no longer shows in per-period readings; `low` excludes ringing no
#: impedance controller is tuned to.
DAMPING_RATIO_RANGE = (0.3, 5.0)
#: Periods left in the budget from which a later blocked push also gets its level B.
B_ROOM = 22
#: A push has met something once |dF| passes TOUCH_SHARE x contact_force and TOUCH_SIGMAS
#: x the noise sigma: from there on its stairs are sized from the measured slope.
TOUCH_SHARE = 1.0 / 6.0
TOUCH_SIGMAS = 5.0
#: A stair may use at most this share of the headroom to the force limit, should the object
#: block all of it at the stiffest the arm may be (the noise and the arm's dynamics add).
SAFE_SHARE = 0.8
#: Periods kept in the budget for levels A and B of a push that met the object.
RESERVE_PERIODS = 4
#: tau is unmeasured when the fit's standard uncertainty exceeds this share of it (the
#: tolerance tau is meant to within: a wider fit did not determine it).
TAU_RELATIVE_UNCERTAINTY = 0.2
#: The deflection error per speed is at least this many standard uncertainties of tau times
#: the stiffness (the coverage of a 3-sigma bound).
TAU_COVERAGE = 3.0
#: The hand is at rest for a free-space step when it moved less than this share of the step
#: in a period.
REST_SHARE = 0.005
#: The share of a free-space step the arm's dry friction may hold it short by: [low, high]
#: (a step response stalled 60 % short never reaches 63.2 % of the step).
STALL_RANGE = (-0.2, 0.6)
#: Periods a push needs at least (a few stairs, the way back and the settling): pushing stops
#: when fewer remain in the budget.
MIN_PUSH_PERIODS = 6


@dataclass(frozen=True)
class CalibrationConfig:
    """How the calibration pushes (module docstring). Units in brackets. Validated at
    construction (ConfigError names the field and its valid range)."""

    rest_periods: int = 12  # readings at rest, one per period, for the force offset and the
    # noise (>= 3; sigma's relative standard error is about 1 / sqrt(6 (n - 2)))
    force_limit: float = 20.0  # [N] |F - F_rest| above this stops the calibration; keep it
    # below the object's limit and the executor's
    contact_force: float = 3.0  # [N] level A: a push has met the object at this |dF|
    push_force: float = 6.0  # [N] level B aims push_force - contact_force above level A
    max_stiffness: float = 20_000.0  # [N/m] the stiffest arm the pushes are sized for: until
    # a push has measured the arm, no stair is longer than 0.8 force_limit / max_stiffness
    first_push: float = 4e-4  # [m] the first stair of each push
    free_travel: float = 0.003  # [m] a direction where the hand follows the setpoint this
    # far with |dF| below contact_force is free
    travel_limit: float = 0.04  # [m] the furthest the setpoint ever moves from the start
    return_periods: int = 2  # periods to bring the setpoint back from a free push
    max_periods: int = 49  # the calibration's budget of control periods: the pushes stop
    # short of it, what is left is spent at rest (more noise readings)

    def __post_init__(self) -> None:
        n = "CalibrationConfig."
        check_int(n + "rest_periods", self.rest_periods, low=3)
        limit = check_number(n + "force_limit", self.force_limit, low=0, low_open=True, unit="N")
        contact = check_number(
            n + "contact_force", self.contact_force, low=0, low_open=True, high=limit,
            high_open=True, unit="N",
        )  # fmt: skip
        check_number(
            n + "push_force", self.push_force, low=contact, low_open=True, high=limit,
            high_open=True, unit="N",
        )  # fmt: skip
        check_number(n + "max_stiffness", self.max_stiffness, low=0, low_open=True, unit="N/m")
        travel = check_number(
            n + "travel_limit", self.travel_limit, low=0, low_open=True, high=0.05, unit="m"
        )
        check_number(n + "first_push", self.first_push, low=1e-5, high=travel, unit="m")
        check_number(
            n + "free_travel", self.free_travel, low=0, low_open=True, high=travel, unit="m"
        )
        check_int(n + "return_periods", self.return_periods, low=1)
        check_int(n + "max_periods", self.max_periods, low=self.rest_periods + 1)


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


@dataclass
class Push:
    """One staircase push along `direction` (3,) unit; `kind`: blocked, free or soft."""

    direction: FloatArray
    base: Reading  # the reading at the start just before the push
    kind: str = "soft"
    stairs: list[Reading] = field(default_factory=list)  # one per period on the way out
    depths: list[float] = field(default_factory=list)  # [m] the setpoint's depth per stair
    level_a: Reading | None = None  # blocked: the stair that reached contact_force
    level_b: Reading | None = None  # blocked: the held stair toward push_force
    depth_a: float = 0.0  # [m]
    depth_b: float = 0.0  # [m]
    settled_a: bool = False
    settled_b: bool = False
    before_a: Reading | None = None  # the reading a period before level A (its velocity)
    before_b: Reading | None = None
    back: list[Reading] = field(default_factory=list)  # the way back and the settling

    def change(self, reading: Reading) -> tuple[float, float]:
        """(|dF| [N], the hand's travel along the push [m]) since the base."""
        df = float(np.linalg.norm(reading.force - self.base.force))
        return df, float((reading.position - self.base.position) @ self.direction)


class _Stop(Exception):
    """A named stop of the calibration (a profile outcome, not a robot error)."""

    def __init__(self, outcome: str, reason: str) -> None:
        super().__init__(reason)
        self.outcome = outcome


class _Session:
    """The robot, commanded within the travel limit and read once per period, every reading
    checked: finite, fresh, within the force limit."""

    def __init__(self, robot: Robot, cfg: CalibrationConfig, home: Pose) -> None:
        self.robot = robot
        self.cfg = cfg
        self.home = home
        self.periods = 0
        self.rest_force: FloatArray | None = None  # [N] once the rest phase is done
        self.stiffness: float | None = None  # [N/m] the steepest slope a push has measured
        self.notes: list[str] = []  # what the profile should say about the pushes
        self.touch = cfg.contact_force / 3.0  # [N] |dF| from which a push has met something
        self._last: FloatArray | None = None
        self._repeats = 0
        self.log: list[Reading] = []  # every reading, in order

    @property
    def remaining(self) -> int:
        return self.cfg.max_periods - self.periods

    def at(self, direction: FloatArray, depth: float) -> Pose:
        """The starting pose moved `depth` [m] along `direction`, within the travel limit."""
        depth = min(depth, self.cfg.travel_limit)
        return Pose(self.home.position + depth * direction, self.home.orientation)

    def step(self, target: Pose | None = None) -> Reading:
        """Command `target` (None: keep the setpoint), let one period pass, read."""
        if self.periods >= self.cfg.max_periods:
            raise _Stop("time_limit", f"the budget of {self.cfg.max_periods} periods is used up")
        if target is not None:
            offset = float(np.linalg.norm(np.asarray(target.position) - self.home.position))
            if not offset <= self.cfg.travel_limit * (1 + 1e-9):  # also catches NaN
                raise _Stop("bad_reading", f"a target {offset} m from the start was refused")
            self.robot.command_pose(target)
        self.robot.advance()
        self.periods += 1
        return self.read()

    def read(self) -> Reading:
        wrench = self.robot.read_wrench()
        force = np.asarray(wrench.force, dtype=float)
        if force.shape != (3,) or not np.all(np.isfinite(force)):
            raise _Stop("bad_reading", f"wrench force {wrench.force!r} is not 3 finite numbers")
        sample = np.concatenate([force, np.asarray(wrench.torque, dtype=float).ravel()])
        if self._last is not None and np.array_equal(sample, self._last):
            self._repeats += 1
            if self._repeats >= STALE_SAMPLES - 1:
                raise _Stop("stale_wrench", f"{STALE_SAMPLES} identical wrench samples in a row")
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
                raise _Stop(
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
    position = np.asarray(pose.position, dtype=float)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(pose.orientation.as_quat()))):
        raise _Stop("bad_reading", f"{what} {pose.position!r} is not finite")


def calibrate(
    robot: Robot,
    name: str = "robot",
    workplane_normal: FloatArray | tuple[float, float, float] | None = None,
    config: CalibrationConfig | None = None,
    setup: str = "",
    free_space_profile: RobotProfile | None = None,
) -> RobotProfile:
    """Measure the robot's force noise and offset, stiffness, tracking time constant, grasp
    play and sensor convention (module docstring).

    Args:
        robot: a Robot holding its grasp, at rest; only its required members are used.
        name: the robot's name, recorded in the profile.
        workplane_normal: (3,) the plane to push in (the task's workplane); None pushes
            along the six world axes.
        config: how to push; None: CalibrationConfig's defaults.
        setup: what the hand holds, recorded in the profile.
        free_space_profile: the same robot's free-space calibration (`calibrate_free_space`,
            at the same control period): its tracking time constant is taken, with its
            `source` named, in place of the pushes' estimate (noted beside it), and used for
            the stiffness and the deflection error; where no push moved the hand at a steady
            speed, the deflection error per speed is the stiffness times its `lag_error`.
            None: tau from the pushes.

    Returns:
        The profile; its `outcome` says whether every phase ran. The robot is told to hold
        at the end. A robot exception propagates with the partial profile attached as
        `exc.robot_profile`.
    """
    if not isinstance(name, str) or not name.strip():
        raise InvalidInputError(f"name: must be a non-empty string, got {name!r}")
    if not isinstance(setup, str):
        raise InvalidInputError(f"setup: must be a string, got {setup!r}")
    cfg = config or CalibrationConfig()
    normal = None
    if workplane_normal is not None:
        normal = np.asarray(check_unit_vector("workplane_normal", workplane_normal))
    period = check_number("robot.control_period", robot.control_period, low=0, low_open=True)
    prior = _free_space_tau(free_space_profile, period)
    lag_prior = _free_space_quantity(free_space_profile, "lag_error")
    profile = RobotProfile(
        robot=name,
        quantities={q: Measurement.unmeasured(q, "not reached") for q in QUANTITY_NAMES},
        control_period=period,
        setup=setup,
        workplane_normal=None if normal is None else (normal[0], normal[1], normal[2]),
    )
    return _calibration(
        robot, cfg, profile, lambda session: _run(session, normal, profile, prior, lag_prior)
    )


def _calibration(
    robot: Robot,
    cfg: CalibrationConfig,
    profile: RobotProfile,
    body: Callable[[_Session], None],
) -> RobotProfile:
    """Run `body` on a session from the robot's commanded pose; on every end (done, a named
    stop, an exception) the start is commanded back and the robot told to hold, and
    `profile` says how it ended (an exception carries it as `exc.robot_profile`)."""
    session: _Session | None = None
    try:
        start = robot.commanded_pose()
        _check_pose(start, "commanded pose")
        session = _Session(robot, cfg, start)
        body(session)
    except _Stop as stop:
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


def _finish(robot: Robot, session: _Session | None, profile: RobotProfile, wait: bool) -> None:
    """Restore the start and hold (or only hold, when the start was never read)."""
    if session is None:
        request_hold(robot, profile.notes)
        return
    session.restore(profile.notes, wait=wait)
    profile.periods = session.periods


def _mark_unreached(profile: RobotProfile, reason: str) -> None:
    for name, m in profile.quantities.items():
        if not m.measured and m.reason == "not reached":
            profile.quantities[name] = Measurement.unmeasured(name, reason)


def _free_space_tau(free_space: RobotProfile | None, period: float) -> Measurement | None:
    """The free-space profile's tracking time constant, its source named; None when there is
    no profile or it left tau unmeasured. InvalidInputError when the profile is not a
    RobotProfile or was calibrated at another control period."""
    if free_space is None:
        return None
    if not isinstance(free_space, RobotProfile):
        raise InvalidInputError(
            f"free_space_profile: must be a RobotProfile, got {type(free_space).__name__}"
        )
    if not math.isclose(free_space.control_period, period, rel_tol=1e-6, abs_tol=1e-12):
        raise InvalidInputError(
            f"free_space_profile: calibrated at a control period of "
            f"{free_space.control_period:g} s, the robot's is {period:g} s"
        )
    return _free_space_quantity(free_space, "tracking_time_constant")


def _free_space_quantity(free_space: RobotProfile | None, name: str) -> Measurement | None:
    """The free-space profile's measurement `name`, its source named; None when there is no
    profile or it left the quantity unmeasured."""
    if free_space is None:
        return None
    m = free_space.quantities[name]
    if not m.measured:
        return None
    return dataclasses.replace(m, source=m.source or free_space.describe())


def _time_constant_or_prior(
    profile: RobotProfile, pushes: list[Push], period: float, prior: Measurement | None
) -> None:
    """tau from the free-space calibration (`prior`) when there is one, the pushes' own
    estimate (`_time_constant`) in a note; else the pushes'. tau is the arm controller's, not
    the task's: measured where the arm moves freely, free of the object's resistance and of
    joints stuck under load (the accuracy of each: docs/design/calibration.md)."""
    _time_constant(profile, pushes, period)
    own = profile.quantities["tracking_time_constant"]
    if prior is None:
        return
    pushes_say = f"{own.value:.3g} s" if own.value is not None else f"unmeasured ({own.reason})"
    note = f"tracking_time_constant from the {prior.source}; the pushes' own: {pushes_say}"
    if note not in profile.notes:
        profile.notes.append(note)
    profile.quantities["tracking_time_constant"] = prior


def _run(
    session: _Session,
    normal: FloatArray | None,
    profile: RobotProfile,
    prior: Measurement | None = None,
    lag_prior: Measurement | None = None,
) -> None:
    robot, cfg = session.robot, session.cfg
    k_report, k_note = reported_stiffness(robot)
    tau_report, tau_note = reported_time_constant(robot)
    profile.notes.extend(note for note in (k_note, tau_note) if note)
    rest = _rest(session, profile)
    pushes = _pushes(session, normal, rest[-1], profile)
    profile.notes.extend(dict.fromkeys(session.notes))
    final = _final_rest(session)
    if len(final) >= 3:
        first, last = (_spread(w) for w in (rest, final))
        if first > 0 and 1 / POOL_RATIO <= last / first <= POOL_RATIO:
            _noise(profile, [rest, final])
        else:
            profile.notes.append(
                f"the readings at rest after the pushes spread {last:.3g} N against "
                f"{first:.3g} N before them (the grasp still moving): not pooled into the noise"
            )
    period = robot.control_period
    _stiffness(profile, pushes, normal, cfg, period)
    _time_constant_or_prior(profile, pushes, period, prior)
    tau = profile.value("tracking_time_constant")
    if tau is not None:  # once more, the hand's damping removed from the stretch
        _stiffness(profile, pushes, normal, cfg, period, tau)
        _time_constant_or_prior(profile, pushes, period, prior)
    profile.quantities["lag_error"] = lag_prior or Measurement.unmeasured(
        "lag_error", "measured in free space only (calibrate_free_space)"
    )
    _deflection_error(profile, pushes, session.log, period, cfg)
    _play(profile, pushes, normal, cfg)
    _convention(profile, pushes, normal, cfg)
    if k_report is not None:
        profile.notes.append(f"the robot reports translational_stiffness {k_report:g} N/m")
    if tau_report is not None:
        profile.notes.append(f"the robot reports tracking_time_constant {tau_report:g} s")


# --- phase 1: rest ------------------------------------------------------------------------
def _rest(session: _Session, profile: RobotProfile) -> list[Reading]:
    """Hold for rest_periods readings: the force offset, and a first noise estimate (the
    force from which a push has met something)."""
    n = session.cfg.rest_periods
    readings = [session.step() for _ in range(n)]
    forces = np.array([r.force for r in readings])
    residual = _about_a_line(forces)
    sigma = float(np.sqrt(np.sum(residual**2) / (3 * (n - 2))))
    offset = forces.mean(axis=0)
    error = np.sqrt(np.sum(residual**2, axis=0) / (n - 2) / n)
    for i, axis in enumerate("xyz"):
        profile.quantities[f"force_offset_{axis}"] = Measurement(
            float(offset[i]), float(error[i]), "N", f"mean of {n} readings at rest", n
        )
    session.rest_force = offset
    # the force a push has met something at: well above the noise, well below contact
    session.touch = max(TOUCH_SHARE * session.cfg.contact_force, TOUCH_SIGMAS * sigma)
    _noise(profile, [readings])  # kept if the pushes stop early; refined after them
    return readings


def _final_rest(session: _Session) -> list[Reading]:
    """Hold at the start for what is left of the budget (noise readings); the leading ones
    while the hand still moved are dropped."""
    readings = [session.step(session.home) for _ in range(max(session.remaining, 0))]
    tolerance = SETTLE_SHARE * session.cfg.free_travel
    while (
        len(readings) >= 2
        and np.linalg.norm(readings[1].position - readings[0].position) >= tolerance
    ):
        readings.pop(0)
    return readings[1:] if readings else []


def _noise(profile: RobotProfile, windows: list[list[Reading]]) -> None:
    """sigma from the readings at rest: the spread about a straight line per axis and
    window (a drifting reading is not noise), pooled over the axes and the windows of at
    least three readings; the dead band from it."""
    used = [w for w in windows if len(w) >= 3]
    squares = sum(float(np.sum(_about_a_line(np.array([r.force for r in w])) ** 2)) for w in used)
    dof = sum(3 * (len(w) - 2) for w in used)
    count = sum(len(w) for w in used)
    sigma = math.sqrt(squares / dof)
    sigma_u = sigma / math.sqrt(2 * dof)
    q = profile.quantities
    q["force_noise"] = Measurement(
        sigma,
        sigma_u,
        "N",
        f"{count} readings at rest, one per period (windows of "
        f"{' + '.join(str(len(w)) for w in used)}, before and after the pushes): the spread "
        "about a straight line per axis and window (drift removed), pooled over x, y, z",
        count,
    )
    band = threshold_from_noise(sigma)
    q["dead_band"] = Measurement(
        band,
        0.0 if band == MIN_THRESHOLD else NOISE_SIGMAS * sigma_u,
        "N",
        f"deadband.threshold_from_noise: max({MIN_THRESHOLD:g} N, {NOISE_SIGMAS:g} sigma)",
        count,
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


def _spread(window: list[Reading]) -> float:
    """[N] the per-axis spread of a window's readings about a straight line, pooled."""
    residual = _about_a_line(np.array([r.force for r in window]))
    return math.sqrt(float(np.sum(residual**2)) / (3 * (len(window) - 2)))


def _about_a_line(forces: FloatArray) -> FloatArray:
    """(n, 3) the residuals of (n, 3) readings about a least-squares straight line in time."""
    n = len(forces)
    t = np.arange(n, dtype=float)
    design = np.stack([np.ones(n), t - t.mean()], axis=1)
    coef, *_ = np.linalg.lstsq(design, forces, rcond=None)
    return np.asarray(forces - design @ coef, dtype=float)


# --- phase 2: pushes ----------------------------------------------------------------------
def _pushes(
    session: _Session, normal: FloatArray | None, rest: Reading, profile: RobotProfile
) -> list[Push]:
    """Staircase pushes until two blocked directions and a free one are known (module
    docstring), in the order e1, e2, -e1, -e2 (e3, -e3 without a workplane): the stiffness
    and a free direction first; the opposite of a free direction is skipped once a free and a
    blocked one are known (before that it may be the blocked one the stiffness needs)."""
    axes = push_directions(4, normal)
    if normal is None:  # the six world axes as +x, -x, +y, -y, +z, -z
        axes = axes[0::2] + axes[1::2]
    pushes: list[Push] = []
    base = rest
    for u in axes:
        blocked = sum(p.kind == "blocked" for p in pushes)
        free = any(p.kind == "free" for p in pushes)
        if blocked >= 2 and free:
            break
        opposite = next((p for p in pushes if float(p.direction @ u) < -0.99), None)
        if opposite is not None and opposite.kind != "blocked" and free and blocked:
            continue
        if session.remaining < MIN_PUSH_PERIODS:
            profile.notes.append(
                f"pushing stopped with {session.remaining} periods left of the budget "
                f"({session.cfg.max_periods})"
            )
            break
        # level B (for the stiffness) on the first blocked push, and on later ones while
        # the budget leaves room for a free push after them
        first = not any(p.level_b is not None for p in pushes)
        # further stairs toward level B only until one push has its two levels apart
        extend = not any(_levels_apart(p, session.cfg) for p in pushes)
        push = _staircase(session, u, base, first or session.remaining >= B_ROOM, extend)
        pushes.append(push)
        base = push.back[-1]
    return pushes


def _staircase(
    session: _Session, u: FloatArray, base: Reading, level_b: bool, extend: bool = False
) -> Push:
    cfg = session.cfg
    push = Push(direction=u, base=base)
    depth, step = 0.0, cfg.first_push
    aim = 0.5 * (cfg.contact_force + cfg.push_force)  # passing contact_force in one stair
    while True:
        depth = min(depth + step, cfg.travel_limit)
        reading = session.step(session.at(u, depth))
        push.stairs.append(reading)
        push.depths.append(depth)
        df, travel = push.change(reading)
        if df >= cfg.contact_force:
            push.kind = "blocked"
            break
        if travel >= cfg.free_travel:
            push.kind = "free"
            break
        if depth >= cfg.travel_limit:
            break
        if session.remaining <= cfg.return_periods + RESERVE_PERIODS:
            session.notes.append("a push ended early: the budget needs the rest to come back")
            break
        # the next stair: at most twice the last and half of free_travel (a free push takes
        # a few stairs); once the force rises with a slope it can be trusted, what the slope
        # says passes contact_force (at least half the last stair: a smaller one would change
        # |dF| by little more than the noise); never more than _safe_step
        grow = 2.0 * step
        slope = _contact_slope(push, session.touch)
        if slope is None:
            grow = min(grow, 0.5 * cfg.free_travel)
        else:  # a soft arm needs long stairs to reach contact_force within the budget
            grow = min(grow, max((aim - df) / slope, 0.5 * step))
        step = min(grow, _safe_step(session, push, df))
    if push.kind == "blocked":
        _levels(session, push, depth, level_b, extend)
        slopes = [
            x for x in (_contact_slope(push, session.touch), _level_slope(push)) if x is not None
        ]
        if slopes:
            session.stiffness = max([*slopes, session.stiffness or 0.0])
    _return(session, push, ramp=push.kind == "free")
    return push


def _safe_step(session: _Session, push: Push, df: float, slope: float | None = None) -> float:
    """[m] the largest stair that keeps |dF| within the force limit should the object block
    all of it: SAFE_SHARE of the headroom (force_limit - |dF|) over the stiffest the arm
    may be, twice the steepest slope measured (this push's, `slope` [N/m] between its
    levels, or an earlier push's), or max_stiffness before any."""
    known = [x for x in (_contact_slope(push, session.touch), slope, session.stiffness) if x]
    bound = 2.0 * max(known) if known else session.cfg.max_stiffness
    return SAFE_SHARE * max(session.cfg.force_limit - df, 0.0) / bound


def _contact_slope(push: Push, touch: float) -> float | None:
    """[N/m] the change of |dF| over the change of |d stretch| from the first stair whose
    |dF| passed `touch` [N] to the last (a wide base: over one small stair the sensor's
    noise would dominate); None with fewer than two such stairs, or when |dF| rose by less
    than `touch` between them (a slope the noise could make)."""
    touching = [r for r in push.stairs if push.change(r)[0] >= touch]
    if len(touching) < 2:
        return None
    a, b = touching[0], touching[-1]
    fa, fb = push.change(a)[0], push.change(b)[0]
    sa = float(np.linalg.norm(a.stretch - push.base.stretch))
    sb = float(np.linalg.norm(b.stretch - push.base.stretch))
    if sb - sa <= 1e-6 or fb - fa < touch:
        return None
    return (fb - fa) / (sb - sa)


def _levels(
    session: _Session, push: Push, depth: float, level_b: bool, extend: bool = False
) -> None:
    """Hold the stair that reached contact_force a period: level A. Then (when `level_b`)
    one more stair toward push_force - contact_force above A, sized from the trusted slope
    and never beyond _safe_step or travel_limit, held a period: level B. While B is short of
    A by less than LEVEL_SPREAD x (push_force - contact_force) and the budget leaves room
    for it and the way back, one more stair from B, held a period, sized from the slope
    between A and B when B gained at least the touch force over A: once, or, when `extend`
    (no earlier push has its levels apart: the stiffness needs one), as long as the budget
    allows, and then also when B gained less but the hand settled there, twice the last
    stair (a first stair sized from a slope the arm's breakaway from static friction
    steepened adds little: an arm whose joints stick reads a jump at contact and a
    shallower spring after it). Otherwise the push ends (the object gives way, or a later
    push is not to spend the budget the free direction needs)."""
    cfg = session.cfg
    reached = push.stairs[-1]
    held = session.step()
    push.level_a, push.depth_a, push.before_a = held, depth, reached
    push.settled_a = _settled(reached, held, depth)
    if not level_b:
        return
    slope = _contact_slope(push, session.touch)
    wanted = push.change(held)[0] + (cfg.push_force - cfg.contact_force)
    last_stair: float | None = None
    for tries in itertools.count():
        if tries >= 2 and not extend:
            return
        now = push.level_b or held
        df = push.change(now)[0]
        start = push.depth_b or depth
        step = _safe_step(session, push, df, slope)
        if slope is not None:
            step = min(step, max(wanted - df, 0.0) / slope)
        elif last_stair is not None:
            step = min(step, 2.0 * last_stair)
        depth_b = min(start + step, cfg.travel_limit)
        # a further stair keeps the periods the way back and the settling need
        room = 2 if push.level_b is None else 3 + SETTLE_PERIODS
        if depth_b - start < 1e-5 or session.remaining < room:
            return
        first = session.step(session.at(push.direction, depth_b))
        last = session.step()
        push.level_b, push.depth_b, push.before_b = last, depth_b, first
        push.settled_b = _settled(first, last, depth_b)
        last_stair = depth_b - start
        gained = push.change(last)[0] - push.change(held)[0]
        if gained >= LEVEL_SPREAD * (cfg.push_force - cfg.contact_force):
            return
        ds = float(np.linalg.norm(last.stretch - held.stretch))
        if gained >= session.touch and ds > 1e-6:
            slope = gained / ds
        elif push.settled_b and extend:  # held still and barely loaded: the joints stick
            slope = None
        else:  # the object gives way under the push: more stairs would move it further
            return


def _levels_apart(push: Push, cfg: CalibrationConfig) -> bool:
    """Whether the push has both levels, |F_B - F_A| at least LEVEL_SPREAD x (push_force -
    contact_force) apart (what the stiffness needs)."""
    if push.level_a is None or push.level_b is None:
        return False
    df = float(np.linalg.norm(push.level_b.force - push.level_a.force))
    return df >= LEVEL_SPREAD * (cfg.push_force - cfg.contact_force)


def _level_slope(push: Push) -> float | None:
    """[N/m] |F_B - F_A| / |stretch_B - stretch_A| (None without both levels)."""
    if push.level_a is None or push.level_b is None:
        return None
    ds = float(np.linalg.norm(push.level_b.stretch - push.level_a.stretch))
    df = float(np.linalg.norm(push.level_b.force - push.level_a.force))
    return df / ds if ds > 1e-6 else None


def _settled(before: Reading, after: Reading, depth: float) -> bool:
    return float(np.linalg.norm(after.position - before.position)) < SETTLE_SHARE * depth


def _return(session: _Session, push: Push, ramp: bool) -> None:
    """Bring the setpoint back, in return_periods equal steps (ramp) or at once, then hold
    until the hand settles (at most SETTLE_PERIODS periods): the next push starts at rest."""
    far = push.level_b.commanded if push.level_b is not None else push.stairs[-1].commanded
    home = session.home.position
    steps = session.cfg.return_periods if ramp else 1
    for i in range(1, steps + 1):
        position = far + (home - far) * (i / steps)
        push.back.append(session.step(Pose(position, session.home.orientation)))
    tolerance = SETTLE_SHARE * session.cfg.free_travel
    for _ in range(SETTLE_PERIODS):
        reading = session.step()
        moved = float(np.linalg.norm(reading.position - push.back[-1].position))
        push.back.append(reading)
        if moved < tolerance:
            break


# --- phase 3: the quantities --------------------------------------------------------------
def _stiffness(
    profile: RobotProfile,
    pushes: list[Push],
    normal: FloatArray | None,
    cfg: CalibrationConfig,
    period: float,
    tau: float | None = None,
) -> None:
    """k from the levels of the blocked pushes; with the tracking time constant `tau` [s]
    known, the part tau v of each stretch the hand's velocity v explains (the arm's damping,
    where the object gives way under the push) is not counted as spring."""
    q = profile.quantities
    sigma = q["force_noise"].value or 0.0
    method = (
        "blocked pushes: the force per setpoint step, |F_B - F_A| / |setpoint_B - setpoint_A|, "
        f"between a held reading at {cfg.contact_force:g} N and one about "
        f"{cfg.push_force - cfg.contact_force:g} N above it, in the workplane"
    )

    def spring(reading: Reading, before: Reading | None) -> FloatArray:
        if tau is None or before is None:
            return reading.stretch
        return reading.stretch - tau * (reading.position - before.position) / period

    estimates: list[tuple[float, float]] = []
    moving: list[tuple[float, float]] = []
    directions: list[str] = []
    for p in pushes:
        if p.level_a is None or p.level_b is None:
            continue
        df = in_plane(p.level_b.force - p.level_a.force, normal)
        f = float(np.linalg.norm(df))
        if f < LEVEL_SPREAD * (cfg.push_force - cfg.contact_force):
            continue
        if p.settled_a and p.settled_b:
            # the force per setpoint step against the blocked direction: what k x step means
            s = float(np.linalg.norm(in_plane(p.level_b.commanded - p.level_a.commanded, normal)))
            if s > 1e-6:
                estimates.append((f / s, f))
                directions.append(f"({', '.join(f'{x:.2g}' for x in p.direction)}) {f / s:.0f}")
            continue
        # the object gave way (the hand still moved): the setpoint's step is shared with the
        # object's motion, so only the arm's spring, from its stretch, is left to measure
        ds = in_plane(spring(p.level_b, p.before_b) - spring(p.level_a, p.before_a), normal)
        s = float(np.linalg.norm(ds))
        if s > 1e-6:
            moving.append((f / s, f))
    if not estimates and moving:
        estimates = moving
        method = (
            "the object gave way under every push (the hand still moved): |F_B - F_A| / "
            "|stretch_B - stretch_A| (stretch = setpoint - measured tool point), the arm's "
            "spring alone"
        ) + (f"; stretch less tau v (tau {tau:.3g} s, v the hand's velocity)" if tau else "")
    elif directions:
        note = "stiffness by blocked direction [N/m]: " + "; ".join(directions)
        if note not in profile.notes:  # the second pass (with tau) finds the same
            profile.notes.append(note)
    if estimates:
        values = [k for k, _ in estimates]
        value = float(np.mean(values))
        spread = float(np.std(values, ddof=1)) / math.sqrt(len(values)) if len(values) > 1 else 0
        # the readings' noise on |F_B - F_A|, relative
        resolution = value * math.sqrt(2.0) * sigma / min(f for _, f in estimates)
        q["stiffness"] = Measurement(
            value,
            math.hypot(spread, resolution / math.sqrt(len(values))),
            "N/m",
            f"{method}; the mean over {len(values)} directions",
            len(values),
        )
    else:
        kinds = ", ".join(p.kind for p in pushes) or "none"
        q["stiffness"] = Measurement.unmeasured(
            "stiffness",
            f"no push met {cfg.contact_force:g} N and then "
            f"{cfg.push_force - cfg.contact_force:g} N more within the "
            f"{cfg.travel_limit * 1000:g} mm travel limit (pushes: {kinds}): nothing to push "
            "against",
            method,
        )


def _play(
    profile: RobotProfile, pushes: list[Push], normal: FloatArray | None, cfg: CalibrationConfig
) -> None:
    """The grasp's play from the blocked pushes' two levels (control.probe.grasp_play)."""
    q = profile.quantities
    pairs = [p for p in pushes if p.level_a is not None and p.level_b is not None]
    probe_cfg = _probe_config(cfg)
    shallow, deep = [], []
    for p in pairs:
        assert p.level_a is not None and p.level_b is not None
        a = _as_probe_push(p, p.level_a, p.depth_a, p.settled_a, normal, probe_cfg)
        b = _as_probe_push(p, p.level_b, p.depth_b, p.settled_b, normal, probe_cfg)
        shallow.append(a)
        deep.append(dataclasses.replace(b, shallow=len(shallow) - 1))
    play_method = (
        "control.probe.grasp_play on the two levels of each blocked push: the hand's travel "
        "against the force, extrapolated to zero force"
    )
    plays = [
        one
        for a, b in zip(shallow, deep, strict=True)
        if (one := grasp_play([a], [dataclasses.replace(b, shallow=0)], probe_cfg.min_force))
        is not None
    ]
    if not plays:
        q["grasp_play"] = Measurement.unmeasured(
            "grasp_play",
            "no blocked push with two settled levels whose travel grew with the force",
            play_method,
        )
        return
    play = grasp_play(shallow, deep, probe_cfg.min_force)
    assert play is not None
    spread = float(np.std(plays, ddof=1)) / math.sqrt(len(plays)) if len(plays) > 1 else 0.0
    if play > 0 and spread >= play * (1.0 - 1e-9):  # equal when one direction reads zero
        # the directions disagree as much as the play itself: one direction's travel is the
        # object giving way under the push (a crank turning), not play in the grasp
        q["grasp_play"] = Measurement.unmeasured(
            "grasp_play",
            f"the blocked directions disagree ({', '.join(f'{x * 1000:.2f}' for x in plays)} "
            "mm): the standard uncertainty reaches the play itself",
            play_method,
            len(plays),
        )
        return
    q["grasp_play"] = Measurement(
        play, spread, "m", play_method + f"; the median over {len(plays)}", len(plays)
    )


def _probe_config(cfg: CalibrationConfig) -> ProbeConfig:
    """control.probe's settings for judging the calibration's pushes (its force gate at most
    the calibration's contact force)."""
    return ProbeConfig(
        amplitude=min(cfg.free_travel, 0.02),
        force_limit=cfg.force_limit,
        min_force=min(ProbeConfig.min_force, cfg.contact_force),
        play_amplitude=None,
    )


def _as_probe_push(
    push: Push,
    reading: Reading,
    depth: float,
    settled: bool,
    normal: FloatArray | None,
    probe_cfg: ProbeConfig,
) -> ProbePush:
    """A reading of a push as control.probe judges one (force and stretch changes from the
    reading before the push)."""
    cfg = dataclasses.replace(probe_cfg, amplitude=min(max(depth, 1e-4), 0.02))
    return judge_push(
        np.asarray(push.direction, dtype=float),
        depth,
        reading.force - push.base.force,
        reading.stretch - push.base.stretch,
        reading.pose,
        push.base.pose,
        settled,
        normal,
        cfg,
    )


def _convention(
    profile: RobotProfile, pushes: list[Push], normal: FloatArray | None, cfg: CalibrationConfig
) -> None:
    """control.probe's verdict on level A of the blocked pushes (the others' last stairs
    are not judged)."""
    probe_cfg = _probe_config(cfg)
    result = ProbeResult(workplane_normal=None if normal is None else normal.tolist())
    for p in pushes:
        if p.level_a is not None:
            result.pushes.append(
                _as_probe_push(p, p.level_a, p.depth_a, p.settled_a, normal, probe_cfg)
            )
        elif p.stairs:
            result.pushes.append(
                _as_probe_push(p, p.stairs[-1], p.depths[-1], False, normal, probe_cfg)
            )
    judge_pushes(result, probe_cfg)
    profile.convention = result.verdict
    method = (
        "control.probe's verdict on the blocked pushes: the median cosine between the force "
        "change and the stretch change"
    )
    judged = sum(p.judged for p in result.pushes)
    if result.median_cos is None:
        profile.quantities["sensor_convention"] = Measurement.unmeasured(
            "sensor_convention", f"{result.verdict}: {result.reason}", method, judged
        )
        return
    cosines = [p.cos for p in result.pushes if p.cos is not None]
    spread = float(np.std(cosines, ddof=1)) / math.sqrt(len(cosines)) if len(cosines) > 1 else 0
    profile.quantities["sensor_convention"] = Measurement(
        result.median_cos, spread, "1", f"{method} ({result.verdict}: {result.reason})", judged
    )
    if result.verdict not in STIFFNESS_VERDICTS:
        profile.notes.append(
            f"sensor convention {result.verdict}: {result.reason}; the stiffness holds (|dF| "
            "over |d stretch|), the force's sign or frame does not"
        )


def _time_constant(profile: RobotProfile, pushes: list[Push], period: float) -> None:
    """tau = c / k from the free push (module docstring)."""
    method = (
        "the tool point's motion on a free push, out and back, fitted with the arm's "
        "impedance m x'' = k (s - x) - c x' - R (R from the wrist reading): tau = c / k"
    )
    q = profile.quantities
    # a free push; else a soft one (the hand moved, against a resistance R the model takes
    # from the wrist reading)
    free = [p for p in pushes if p.kind == "free"] or [p for p in pushes if p.kind == "soft"]
    k = q["stiffness"].value
    if not free:
        q["tracking_time_constant"] = Measurement.unmeasured(
            "tracking_time_constant",
            "no free or soft direction: every push met the object; tau needs a direction the "
            "hand can move in",
            method,
        )
        return
    if free[0].kind == "soft":
        method += " (a soft push: no direction was free)"
    if k is None:
        q["tracking_time_constant"] = Measurement.unmeasured(
            "tracking_time_constant",
            "the stiffness is unmeasured: the object's force cannot be told from the arm's lag",
            method,
        )
        return
    push = free[0]
    u = push.direction
    readings = [push.base, *push.stairs, *push.back]
    setpoint = np.array([(r.commanded - push.base.commanded) @ u for r in readings])
    position = np.array([(r.position - push.base.position) @ u for r in readings])
    resist = np.array([-(r.force - push.base.force) @ u for r in readings])
    fit = fit_impedance(setpoint - resist / k, position, period)
    if fit is None:
        q["tracking_time_constant"] = Measurement.unmeasured(
            "tracking_time_constant",
            "the fit of the arm's impedance to the free push did not converge",
            method,
            len(readings),
        )
        return
    tau, tau_u, zeta, rms = fit
    if not tau_u <= TAU_RELATIVE_UNCERTAINTY * tau:  # also catches NaN
        q["tracking_time_constant"] = Measurement.unmeasured(
            "tracking_time_constant",
            f"the fit left tau {tau:.3g} s with a standard uncertainty of {tau_u / tau:.0%}, "
            f"above {TAU_RELATIVE_UNCERTAINTY:.0%}: the push did not determine it",
            method,
            len(readings),
        )
        return
    span = float(np.ptp(position))
    q["tracking_time_constant"] = Measurement(
        tau,
        tau_u,
        "s",
        f"{method}; damping ratio {zeta:.2g}, residual {rms / span:.1%} of the motion",
        len(readings),
    )


def _deflection_error(
    profile: RobotProfile,
    pushes: list[Push],
    log: list[Reading],
    period: float,
    cfg: CalibrationConfig,
) -> None:
    """The deflection model's error (control.sensor_health's dead-sensor test): over every
    reading of every push (out, held and back), the calibrated stiffness times the lagged
    deflection from the push's start (control.lag.LagModel with the calibrated tau) less the
    read |F - F_start|. deflection_error: its largest value with the hand at rest (moving less
    than SETTLE_SHARE x free_travel per period); deflection_error_per_speed: the largest excess
    over that per unit hand speed while it moved at a steady speed (`steady_speed`: where the
    lag model, tau v, holds, as it does for the executor's even steps), and at least
    TAU_COVERAGE x stiffness x tau's standard uncertainty (what tau's error adds per speed)."""
    q = profile.quantities
    k, tau = q["stiffness"].value, q["tracking_time_constant"].value
    method = (
        "every push reading: stiffness x |lagged deflection| (tau credited along the hand's "
        "motion) less |F - F_start|; the largest with the hand at rest, and the largest "
        "excess per unit hand speed while it moved at a steady speed"
    )
    if k is None:
        for name in ("deflection_error", "deflection_error_per_speed"):
            q[name] = Measurement.unmeasured(name, "the stiffness is unmeasured", method)
        return
    rest_speed = SETTLE_SHARE * cfg.free_travel / period  # [m/s]
    still: list[float] = []
    moving: list[tuple[float, float]] = []  # (error [N], speed [m/s])
    index = {r.period: i for i, r in enumerate(log)}
    for p in pushes:
        end = p.back[-1].period if p.back else log[-1].period
        start = index[p.base.period]
        lag = LagModel(tau, deflection0=p.base.position - p.base.commanded)
        previous = np.zeros(3)
        for before, reading in zip(log[start:], log[start + 1 :], strict=False):
            if reading.period > end:
                break
            lag.velocity = (reading.position - before.position) / period
            implied = k * float(
                np.linalg.norm(lag.lagged_deflection(reading.position, reading.commanded))
            )
            error = implied - float(np.linalg.norm(reading.force - p.base.force))
            speed = float(np.linalg.norm(lag.velocity))
            if speed < rest_speed:
                still.append(error)
            elif steady_speed(lag.velocity, previous):
                moving.append((error, speed))
            previous = lag.velocity
    if not still:
        for name in ("deflection_error", "deflection_error_per_speed"):
            q[name] = Measurement.unmeasured(name, "no push reading with the hand at rest", method)
        return
    static = max(0.0, max(still))
    q["deflection_error"] = Measurement(static, 0.0, "N", method, len(still))
    if not moving or tau is None:
        why = "the hand never moved at a steady speed during the pushes"
        if tau is None:  # the whole lag k tau v then reads as deflection, unbounded in speed
            why = "the tracking time constant is unmeasured: no lag model to bound at speed"
        ramps = q["lag_error"]
        if tau is not None and ramps.value is not None:
            # the free-space ramps measured the lag model's error per speed: at this grasp's
            # stiffness it is a force per speed
            q["deflection_error_per_speed"] = Measurement(
                k * ramps.value,
                0.0,
                "N s/m",
                f"stiffness x the lag_error of the {ramps.source} ({why})",
                ramps.count,
                source=ramps.source,
            )
            profile.notes.append(
                f"deflection_error_per_speed from the {ramps.source}: stiffness x its lag_error "
                f"{ramps.value:.3g} s ({why})"
            )
            return
        q["deflection_error_per_speed"] = Measurement.unmeasured(
            "deflection_error_per_speed", why, method
        )
        return
    per_speed = max(0.0, max((e - static) / v for e, v in moving))
    tau_u = q["tracking_time_constant"].uncertainty
    if tau is not None and tau_u is not None:
        # the lag credit k tau v is off by k x tau's error at speed v: a few steady readings
        # at the calibration's low speeds cannot show what the tau's own uncertainty allows
        per_speed = max(per_speed, TAU_COVERAGE * k * tau_u)
        method += f"; at least {TAU_COVERAGE:g} x stiffness x tau's standard uncertainty"
    q["deflection_error_per_speed"] = Measurement(per_speed, 0.0, "N s/m", method, len(moving))


# --- free space ---------------------------------------------------------------------------
@dataclass(frozen=True)
class FreeSpaceConfig:
    """How the free-space calibration moves (`calibrate_free_space`). Units in brackets.
    Validated at construction (ConfigError names the field and its valid range)."""

    rest_periods: int = 12  # readings at rest before the steps and again after them (>= 3)
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
    `calibrate(..., free_space_profile=...)` takes its tau, and its lag error where a grasp's
    pushes do not measure the deflection error per speed.

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
    (`fit_impedance`, the setpoint a straight line within each period), then the fitted
    model's 63.2 % rise time for a step (c / k for a well-damped arm); tau is the mean over
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
    # the session's checks and restore with the free-space limits (the push settings unused)
    session_cfg = CalibrationConfig(
        rest_periods=cfg.rest_periods,
        force_limit=cfg.force_limit,
        contact_force=cfg.contact_force,
        push_force=0.5 * (cfg.contact_force + cfg.force_limit),
        travel_limit=cfg.travel,
        first_push=min(4e-4, cfg.step),
        free_travel=cfg.step,
        max_periods=cfg.max_periods,
    )
    return _calibration(
        robot, session_cfg, profile, lambda session: _run_free_space(session, cfg, profile)
    )


def _run_free_space(session: _Session, cfg: FreeSpaceConfig, profile: RobotProfile) -> None:
    tau_report, tau_note = reported_time_constant(session.robot)
    if tau_note:
        profile.notes.append(tau_note)
    rest = _rest(session, profile)
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
    if len(final) >= 3:
        first, last = _spread(rest), _spread(final)
        if first > 0 and 1 / POOL_RATIO <= last / first <= POOL_RATIO:
            _noise(profile, [rest, final])
        else:
            profile.notes.append(
                f"the readings at rest after the steps spread {last:.3g} N against {first:.3g} "
                "N before them: not pooled into the noise"
            )
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
        raise _Stop(
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


def step_rise_time(b: float, zeta: float, level: float = 1.0 - math.exp(-1.0)) -> float:
    """[s] the time x'' = (1 - x) / a - (b / a) x' (a = (b / (2 zeta))^2) takes from rest at
    0 to `level` after a unit step at t = 0: the first crossing; inf when it never does.

    Args:
        b: [s] c / k, the damping over the stiffness.
        zeta: the damping ratio b / (2 sqrt(a)), > 0.
        level: the share of the step, > 0 (the 63.2 % rise time by default).
    """
    if not level < 1.0 + math.exp(-math.pi * zeta / math.sqrt(max(1.0 - zeta**2, 1e-12))):
        return math.inf  # beyond the first overshoot (none when zeta >= 1)
    from scipy.optimize import brentq  # here: importing the package stays light

    a = (b / (2.0 * zeta)) ** 2
    m = np.array([[0.0, 1.0], [-1.0 / a, -b / a]])

    def x(t: float) -> float:
        return 1.0 - float(_expm(m * t)[0, 0])  # from rest: x = 1 - [e^{mt} (1, 0)]_0

    horizon = max(b, 2.0 * math.sqrt(a))
    t0 = 0.0
    for t1 in np.linspace(horizon / 50.0, 20.0 * horizon, 1000):
        if x(float(t1)) >= level:
            return float(brentq(lambda t: x(t) - level, t0, float(t1), xtol=1e-9 * horizon))
        t0 = float(t1)
    return math.inf


def fit_step_response(
    drive: FloatArray, position: FloatArray, period: float
) -> tuple[float, float, float, float, float] | None:
    """Fit x'' = ((1 - f) w - x) / a - (b / a) x' to a step response sampled once per period:
    the impedance of `fit_impedance` with the drive w (the setpoint, a straight line between
    samples, from rest at x = w = 0) short by a share f, the arm's dry friction holding it
    short of the setpoint (a linear arm fits f = 0).

    Args:
        drive: (n,) [m] the setpoint along the step at each sample.
        position: (n,) [m] the tool point along the step at each sample.
        period: [s] between samples.

    Returns:
        (b = c / k [s], its standard error [s], the damping ratio, f, the residual RMS [m]),
        or None when the fit fails. The damping ratio is held in DAMPING_RATIO_RANGE, f in
        STALL_RANGE.
    """
    w = np.asarray(drive, dtype=float)
    x = np.asarray(position, dtype=float)

    def residual(p: FloatArray) -> FloatArray:
        return _impedance_response(math.exp(p[0]), math.exp(p[1]), (1.0 - p[2]) * w, period) - x

    fit = _fit_lag(residual, [0.0], [STALL_RANGE[0]], [STALL_RANGE[1]], period, len(x))
    if fit is None:
        return None
    b, b_u, zeta, (stall,), rms = fit
    return b, b_u, zeta, stall, rms


def _fit_lag(
    residual: Callable[[FloatArray], FloatArray],
    start: list[float],
    low: list[float],
    high: list[float],
    period: float,
    n: int,
) -> tuple[float, float, float, list[float], float] | None:
    """Least squares of `residual` over (log b, log damping ratio, *rest) from three starts of
    b (the lag per speed from fast to slow; the rest from `start`, within `low`..`high`), the
    best of them: (b [s], its standard error [s], the damping ratio (held in
    DAMPING_RATIO_RANGE), the rest, the residual RMS over the `n` samples), or None when every
    start fails."""
    from scipy.optimize import least_squares  # here: importing the package stays light

    lo, hi = (math.log(z) for z in DAMPING_RATIO_RANGE)
    best = None
    for b0 in (0.3 * period, period, 3.0 * period):
        try:
            r = least_squares(
                residual,
                [math.log(b0), 0.0, *start],
                bounds=(
                    [math.log(1e-3 * period), lo, *low],
                    [math.log(30.0 * period), hi, *high],
                ),
            )
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.isfinite(r.cost) and (best is None or r.cost < best.cost):
            best = r
    if best is None or not best.success:
        return None
    b, zeta = math.exp(best.x[0]), math.exp(best.x[1])
    dof = max(n - len(best.x), 1)
    rms = math.sqrt(2.0 * best.cost / n)
    try:
        cov = (2.0 * best.cost / dof) * np.linalg.inv(best.jac.T @ best.jac)
        b_u = b * math.sqrt(max(float(cov[0, 0]), 0.0))  # d b = b d(log b)
    except np.linalg.LinAlgError:
        b_u = math.inf
    return b, b_u, zeta, [float(v) for v in best.x[2:]], rms


def fit_impedance(
    drive: FloatArray, position: FloatArray, period: float
) -> tuple[float, float, float, float] | None:
    """Fit x'' = (w - x) / a - (b / a) x' (a = m / k [s^2], b = c / k [s]) to positions
    sampled once per period, with the drive w (the setpoint less the resisting force over k)
    a straight line between samples; from rest at x = w = 0.

    Args:
        drive: (n,) [m] w at each sample.
        position: (n,) [m] x at each sample.
        period: [s] between samples.

    Returns:
        (b [s], its standard error [s], the damping ratio b / (2 sqrt(a)), the residual RMS
        [m]), or None when the fit fails. The damping ratio is held in DAMPING_RATIO_RANGE.
    """
    w = np.asarray(drive, dtype=float)
    x = np.asarray(position, dtype=float)

    def residual(p: FloatArray) -> FloatArray:
        return _impedance_response(math.exp(p[0]), math.exp(p[1]), w, period) - x

    fit = _fit_lag(residual, [], [], [], period, len(x))
    if fit is None:
        return None
    b, b_u, zeta, _, rms = fit
    return b, b_u, zeta, rms


def _impedance_response(b: float, zeta: float, w: FloatArray, period: float) -> FloatArray:
    """Positions at the samples of x'' = (w - x) / a - (b / a) x', a = (b / (2 zeta))^2,
    from rest at w[0]; w a straight line between samples (exact discretization)."""
    a = (b / (2.0 * zeta)) ** 2
    m = np.zeros((4, 4))
    m[0, 1] = 1.0
    m[1, 0], m[1, 1], m[1, 2] = -1.0 / a, -b / a, 1.0 / a
    m[2, 3] = 1.0  # the drive's slope, constant over a period
    e = _expm(m * period)
    phi, g0, g1 = e[:2, :2], e[:2, 2], e[:2, 3]
    z = np.array([w[0], 0.0])
    out = np.empty(len(w))
    out[0] = z[0]
    for i in range(1, len(w)):
        z = phi @ z + g0 * w[i - 1] + g1 * (w[i] - w[i - 1]) / period
        out[i] = z[0]
    return out


def _expm(m: FloatArray) -> FloatArray:
    """The matrix exponential of a small (n, n) matrix: a Taylor series after scaling by a
    power of two, then squared back (scipy's expm costs a millisecond or more per call on
    a 4 x 4, and the fit calls this hundreds of times)."""
    norm = float(np.max(np.sum(np.abs(m), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = m / (2.0**squarings)
    term = np.eye(len(m))
    out = term.copy()
    for i in range(1, 13):
        term = term @ a / i
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out
