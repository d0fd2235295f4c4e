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
     (when the two spreads agree within POOL_RATIO; with a free-space calibration, the
     windows that agree with its noise, pooled with its readings: `_noise`);
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

The tracking time constant is the arm controller's, not the task's: the free-space
calibration (`control.free_space.calibrate_free_space`) measures it (and the noise) once per
robot with the hand in free space, from setpoint steps over a path a staircase has cleared
first, and the lag model's error per unit speed (`lag_error`) from setpoint ramps at the
executor's step per period over the same path; given to `calibrate` as `free_space_profile`,
its tau replaces the pushes' estimate, k x its lag error is the deflection error per
speed where no push moved the hand at a steady speed, the `source` of each quantity naming
that calibration, and its readings at rest are pooled into the noise (the sensor's, which
free space, where nothing held creeps, measures with more readings than a grasp's budget
leaves) with the grasp's windows at rest whose spread agrees with it within POOL_RATIO.

Safety (`control.calibration_session`, the session both calibrations drive the robot with):
every reading is checked (finite force and poses, not stale, |F - F_rest| within
`force_limit`); no setpoint is ever commanded further than `travel_limit` from where the
calibration started; it stops after `max_periods`. On every stop, on any exception and at
the end, the starting setpoint is commanded back and the robot is told to hold (`hold()`,
when it has one). A named stop returns the profile with what was measured before it and the
outcome; an exception carries the partial profile as `exc.robot_profile`. The impedance fit
is `control.tracking_fit`'s.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.calibration_session import (
    POOL_RATIO,
    SAFE_SHARE,
    SETTLE_SHARE,
    TAU_COVERAGE,
    TAU_RELATIVE_UNCERTAINTY,
    CalibrationSession,
    Reading,
    force_spread,
    measure_noise,
    noise_dof,
    pool_rest_windows,
    rest_phase,
    run_calibration,
    set_noise,
)
from constraint_aware.control.free_space import HELD_ONLY
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
from constraint_aware.control.robot import Robot, reported_stiffness, reported_time_constant
from constraint_aware.control.sensor_health import steady_speed
from constraint_aware.control.tracking_fit import fit_impedance
from constraint_aware.errors import (
    InvalidInputError,
    check_int,
    check_number,
    check_unit_vector,
)
from constraint_aware.geometry import FloatArray, in_plane
from constraint_aware.spatial import Pose

__all__ = ["CalibrationConfig", "calibrate"]

#: Periods at most to wait after a push for the hand to settle at the start.
SETTLE_PERIODS = 2
#: Level B is used for the stiffness only when its |dF| exceeds level A's by at least this
#: share of (push_force - contact_force) (a push the travel limit cut short may not).
LEVEL_SPREAD = 0.5
#: Periods left in the budget from which a later blocked push also gets its level B.
B_ROOM = 22
#: A push has met something once |dF| passes TOUCH_SHARE x contact_force and TOUCH_SIGMAS
#: x the noise sigma: from there on its stairs are sized from the measured slope.
TOUCH_SHARE = 1.0 / 6.0
TOUCH_SIGMAS = 5.0
#: Periods kept in the budget for levels A and B of a push that met the object.
RESERVE_PERIODS = 4
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


class _PushSession(CalibrationSession[CalibrationConfig]):
    """A session that also carries what the pushes learn as they go."""

    def __init__(self, robot: Robot, cfg: CalibrationConfig, home: Pose) -> None:
        super().__init__(robot, cfg, home)
        self.stiffness: float | None = None  # [N/m] the steepest slope a push has measured
        self.notes: list[str] = []  # what the profile should say about the pushes
        self.touch = cfg.contact_force / 3.0  # [N] |dF| from which a push has met something


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
        free_space_profile: the same robot's free-space calibration
            (`control.free_space.calibrate_free_space`, at the same control period): its
            tracking time constant is taken, with its `source` named, in place of the
            pushes' estimate (noted beside it), and used for the stiffness and the deflection
            error; where no push moved the hand at a steady speed, the deflection error per
            speed is the stiffness times its `lag_error`; its readings at rest are pooled
            into the noise with the grasp's windows that agree with it (`_noise`). None:
            tau from the pushes, the noise from the grasp's readings alone.

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
    noise_prior = _free_space_quantity(free_space_profile, "force_noise")
    profile = RobotProfile(
        robot=name,
        quantities={q: Measurement.unmeasured(q, "not reached") for q in QUANTITY_NAMES},
        control_period=period,
        setup=setup,
        workplane_normal=None if normal is None else (normal[0], normal[1], normal[2]),
    )
    return run_calibration(
        robot,
        profile,
        lambda start: _PushSession(robot, cfg, start),
        lambda session: _run(session, normal, profile, prior, lag_prior, noise_prior),
    )


def _free_space_tau(free_space: RobotProfile | None, period: float) -> Measurement | None:
    """The free-space profile's tracking time constant, its source named; None when there is
    no profile or it left tau unmeasured. InvalidInputError when the profile is not a
    RobotProfile, was calibrated at another control period, or held an object (it measured
    a quantity only a grasp measures: free_space.HELD_ONLY)."""
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
    held = [q for q in HELD_ONLY if free_space.quantities[q].measured]
    if held:  # a grasp's profile: its noise already holds free-space readings, its tau too
        raise InvalidInputError(
            f"free_space_profile: a calibration holding an object (it measured "
            f"{', '.join(held)}), not a free-space one (calibrate_free_space; cap calibrate "
            "--free-space)"
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
    joints stuck under load (the accuracy of each: docs/design/free-space-calibration.md)."""
    _time_constant(profile, pushes, period)
    own = profile.quantities["tracking_time_constant"]
    if prior is None:
        return
    pushes_say = f"{own.value:.3g} s" if own.value is not None else f"unmeasured ({own.reason})"
    head = f"tracking_time_constant from the {prior.source}; the pushes' own: "
    # the second pass (the stretch less tau v) refits the pushes' own: one note, the last fit
    profile.notes[:] = [n for n in profile.notes if not n.startswith(head)]
    profile.notes.append(head + pushes_say)
    profile.quantities["tracking_time_constant"] = prior


def _noise(
    profile: RobotProfile, rest: list[Reading], final: list[Reading], prior: Measurement | None
) -> None:
    """The force noise from the windows at rest before and after the pushes (`final` counts
    with three readings or more; `measure_noise`).

    With the free-space calibration's noise (`prior`): the windows whose spread agrees with it
    within POOL_RATIO, pooled with it (`_pool_noise`); a window that spreads more or less is
    left out, noted (a grasp still settling: its creep is not the sensor's noise). Without
    it, or when no window agrees (something in the grasp adds spread, which its dead band
    must cover): both windows when they agree with each other within POOL_RATIO, else the
    one before the pushes."""
    windows = {"before": rest, "after": final} if len(final) >= 3 else {"before": rest}
    if prior is not None and prior.value:
        agree = []
        for when, window in windows.items():
            ratio = force_spread(window) / prior.value
            if 1 / POOL_RATIO <= ratio <= POOL_RATIO:
                agree.append(window)
            else:
                profile.notes.append(
                    f"the readings at rest {when} the pushes spread {ratio:.2f} x the "
                    f"free-space calibration's noise ({prior.value:.3g} N): not pooled into "
                    "the noise"
                )
        if agree:
            measure_noise(profile, agree)
            _pool_noise(profile, prior)
            return
    pool_rest_windows(profile, rest, final, "the pushes", " (the grasp still moving)")


def _pool_noise(profile: RobotProfile, prior: Measurement) -> None:
    """The force noise pooled with the free-space calibration's (`prior`), weighted by their
    degrees of freedom: the noise is the sensor's, and free space, where nothing the hand
    holds creeps, gives it more readings than a grasp's budget leaves."""
    own = profile.quantities["force_noise"]
    assert own.value is not None and prior.value is not None
    dof_own, dof_prior = noise_dof(own), noise_dof(prior)
    dof = dof_own + dof_prior
    sigma = math.sqrt((dof_own * own.value**2 + dof_prior * prior.value**2) / dof)
    set_noise(
        profile,
        Measurement(
            sigma,
            sigma / math.sqrt(2 * dof),
            "N",
            f"{own.method}; pooled with the {prior.count} readings at rest of the {prior.source}",
            own.count + prior.count,
        ),
    )


def _run(
    session: _PushSession,
    normal: FloatArray | None,
    profile: RobotProfile,
    prior: Measurement | None = None,
    lag_prior: Measurement | None = None,
    noise_prior: Measurement | None = None,
) -> None:
    robot, cfg = session.robot, session.cfg
    k_report, k_note = reported_stiffness(robot)
    tau_report, tau_note = reported_time_constant(robot)
    profile.notes.extend(note for note in (k_note, tau_note) if note)
    rest = rest_phase(session, profile)
    # the force a push has met something at: well above the noise, well below contact
    session.touch = max(TOUCH_SHARE * cfg.contact_force, TOUCH_SIGMAS * force_spread(rest))
    pushes = _pushes(session, normal, rest[-1], profile)
    profile.notes.extend(dict.fromkeys(session.notes))
    _noise(profile, rest, _final_rest(session), noise_prior)
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


# --- phase 1: rest (before the pushes: calibration_session.rest_phase) ------------------
def _final_rest(session: _PushSession) -> list[Reading]:
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


# --- phase 2: pushes ----------------------------------------------------------------------
def _pushes(
    session: _PushSession, normal: FloatArray | None, rest: Reading, profile: RobotProfile
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
    session: _PushSession, u: FloatArray, base: Reading, level_b: bool, extend: bool = False
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


def _safe_step(session: _PushSession, push: Push, df: float, slope: float | None = None) -> float:
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
    session: _PushSession, push: Push, depth: float, level_b: bool, extend: bool = False
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


def _return(session: _PushSession, push: Push, ramp: bool) -> None:
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
