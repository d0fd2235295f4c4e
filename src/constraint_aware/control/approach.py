"""Guarded Cartesian motions for the phases around the manipulation: reach, approach, retreat.

`guarded_move` drives a robot (the executor's `Robot` protocol) through per-period setpoints
and stops, with a named outcome and reason, at the first of:

- "reached": the last setpoint was commanded and the measured tool point settled within
  `position_tolerance` of it;
- "contact": |F - F_0| rose above `contact_limit` [N] where the motion allows contact (the
  last centimetres of an approach); F_0 is the mean reading of the first `offset_samples`
  periods, held in place (the hand's weight);
- "force_limit": the same force where no contact is allowed, or any reading above
  `force_limit` [N];
- "nan": a non-finite wrench reading; "bad_pose": a non-finite pose reading;
- "bad_command": a setpoint that is not finite or lies further than the step bound from the
  previous one (it is not sent);
- "not_following": the measured tool point stayed more than `max_lag` [m] from the setpoint
  for `lag_patience` periods;
- "timeout": the hand did not settle within `settle_periods` after the last setpoint;
- "error": an exception (re-raised with the record attached as `move_record`).

The robot is told to hold (its optional `hold()`) on every stop other than "reached". Every
period's reading is checked before the next setpoint is sent; nothing non-finite or oversized
is ever commanded. No simulator is imported: a real arm runs the same code.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from constraint_aware.control.robot import Robot, request_hold
from constraint_aware.errors import ConfigError, check_int, check_number
from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose

MOVE_OUTCOMES: dict[str, str] = {
    "reached": "the tool point settled at the last setpoint",
    "contact": "a force above the contact limit where contact was expected (the approach's end)",
    "force_limit": "a force above the contact limit where none was expected, or above the "
    "force limit",
    "nan": "the wrench reading was not finite",
    "bad_pose": "the pose reading was not finite",
    "bad_command": "a setpoint was not finite or jumped beyond the step bound (not sent)",
    "not_following": "the tool point stayed too far from its setpoint",
    "timeout": "the tool point did not settle at the last setpoint in time",
    "error": "an exception ended the motion",
}


@dataclass(frozen=True)
class MoveConfig:
    """A guarded motion's limits. Units in brackets."""

    speed: float = 0.1  # [m/s] of the setpoint along a straight line
    turn_rate: float = 0.6  # [rad/s] of the setpoint's rotation
    contact_limit: float = 4.0  # [N] |F - F_0| that counts as contact
    force_limit: float = 30.0  # [N] no reading may pass this, contact allowed or not
    position_tolerance: float = 0.01  # [m] "reached": within this of the last setpoint
    settle_periods: int = 20  # periods allowed for settling after the last setpoint
    max_lag: float = 0.08  # [m] measured-to-setpoint distance that counts as not following
    lag_patience: int = 10  # periods beyond max_lag before "not_following"
    offset_samples: int = 3  # held periods averaged into F_0 before moving
    step_margin: float = 0.005  # [m] a setpoint may move speed x period plus this per period
    max_lead_in: float = 0.05  # [m] a path may begin this far from the hand (a straight
    # lead-in joins them); further is refused as a bad command

    def __post_init__(self) -> None:
        n = "MoveConfig."
        for name in ("speed", "turn_rate", "contact_limit", "position_tolerance", "max_lag",
                     "max_lead_in"):  # fmt: skip
            check_number(n + name, getattr(self, name), low=0.0, low_open=True)
        check_number(n + "force_limit", self.force_limit, low=self.contact_limit, unit="N")
        check_number(n + "step_margin", self.step_margin, low=0.0, unit="m")
        for name in ("settle_periods", "lag_patience", "offset_samples"):
            check_int(n + name, getattr(self, name), low=1)


@dataclass(frozen=True)
class Waypoint:
    """One period's setpoint: the tool pose, and optionally the arm's joint posture the
    robot's null space should hold (a planned joint path; robots without one ignore it)."""

    pose: Pose
    posture: FloatArray | None = None


@dataclass
class MoveRecord:
    """One guarded motion: its outcome (`MOVE_OUTCOMES`), reason, length in periods, the
    largest |F - F_0| [N] seen, and where it started and ended (tool points [m])."""

    name: str
    outcome: str = "running"
    reason: str = ""
    periods: int = 0
    peak_force: float = 0.0
    start: list[float] = field(default_factory=list)
    end: list[float] = field(default_factory=list)
    goal: list[float] = field(default_factory=list)
    distance_to_goal: float = math.nan  # [m] measured tool point to the last setpoint
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.outcome in ("reached", "contact")

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("peak_force", "distance_to_goal"):
            if not math.isfinite(out[key]):
                out[key] = None
        return out


def straight_line(start: Pose, goal: Pose, config: MoveConfig, period: float) -> list[Waypoint]:
    """Per-period setpoints from `start` to `goal` (3-D line, rotation by slerp), at most
    `speed` [m/s] and `turn_rate` [rad/s]; the last one is `goal`."""
    distance = float(np.linalg.norm(goal.position - start.position))
    turn = float((goal.orientation * start.orientation.inv()).magnitude())
    periods = max(
        1, math.ceil(max(distance / (config.speed * period), turn / (config.turn_rate * period)))
    )
    fractions = np.arange(1, periods + 1) / periods
    slerp = Slerp([0.0, 1.0], Rotation.concatenate([start.orientation, goal.orientation]))
    rotations = slerp(fractions)
    return [
        Waypoint(Pose(start.position + f * (goal.position - start.position), rotations[i]))
        for i, f in enumerate(fractions)
    ]


def advance_period(robot: Robot, on_period: Callable[[], None] | None = None) -> FloatArray | None:
    """Advance `robot` one control period (then call `on_period`); the wrench's force (3,)
    [N] after it, None when it is not finite."""
    robot.advance()
    if on_period is not None:
        on_period()
    force = np.asarray(robot.read_wrench().force, dtype=float)
    return force if np.all(np.isfinite(force)) else None


def finite_pose(pose: Pose) -> bool:
    """Whether `pose`'s position and orientation (quaternion) are all finite."""
    return bool(
        np.all(np.isfinite(pose.position)) and np.all(np.isfinite(pose.orientation.as_quat()))
    )


def guarded_move(
    robot: Robot,
    name: str,
    path: Sequence[Waypoint],
    config: MoveConfig | None = None,
    contact_from: int | None = None,
    on_period: Callable[[], None] | None = None,
) -> MoveRecord:
    """Drive `robot` through `path` (one waypoint per control period) under the guards of the
    module docstring. contact_from: the index of the first waypoint from which contact ends
    the motion as "contact" rather than "force_limit" (None: contact is never expected).
    on_period: called after every `advance()` (recording, rendering: not for control)."""
    cfg = config or MoveConfig()
    if not path:
        raise ConfigError("path", "[]", "at least one waypoint")
    record = MoveRecord(name, goal=[float(v) for v in path[-1].pose.position])
    period = float(robot.control_period)
    bound = cfg.speed * period + cfg.step_margin
    try:
        return _run(robot, record, path, cfg, contact_from, on_period, period, bound)
    except BaseException as exc:
        record.outcome, record.reason = "error", f"{type(exc).__name__}: {exc}"
        request_hold(robot, record.notes)
        exc.move_record = record  # type: ignore[attr-defined]
        raise


def _stop(robot: Robot, record: MoveRecord, outcome: str, reason: str) -> MoveRecord:
    record.outcome, record.reason = outcome, reason
    if outcome != "reached":
        request_hold(robot, record.notes)
    return record


def _run(
    robot: Robot,
    record: MoveRecord,
    path: Sequence[Waypoint],
    cfg: MoveConfig,
    contact_from: int | None,
    on_period: Callable[[], None] | None,
    period: float,
    bound: float,
) -> MoveRecord:
    set_posture = getattr(robot, "set_posture", None)
    # start from where the hand is (a path is planned from the measured state)
    request_hold(robot, record.notes)
    hold_pose = robot.commanded_pose()
    samples: list[FloatArray] = []
    for _ in range(cfg.offset_samples):
        robot.command_pose(hold_pose)
        force = advance_period(robot, on_period)
        record.periods += 1
        if force is None:
            return _stop(robot, record, "nan", "the wrench reading is not finite (holding)")
        samples.append(force)
    offset = np.mean(samples, axis=0)
    start = robot.read_pose()
    if not finite_pose(start):
        return _stop(robot, record, "bad_pose", "the pose reading is not finite")
    record.start = [float(v) for v in start.position]
    if finite_pose(path[0].pose):
        # the hand settled elsewhere than the path begins: lead in along a straight line
        gap = float(np.linalg.norm(path[0].pose.position - hold_pose.position))
        if gap > cfg.max_lead_in:
            return _stop(
                robot, record, "bad_command",
                f"the path starts {gap * 1000:.0f} mm from the hand (at most "
                f"{cfg.max_lead_in * 1000:.0f} mm; not sent)",
            )  # fmt: skip
        if gap > bound:
            lead = straight_line(hold_pose, path[0].pose, cfg, period)[:-1]
            path = [*lead, *path]
            if contact_from is not None:
                contact_from += len(lead)
    last = hold_pose.position
    lagging = 0
    settle = 0
    i = 0
    while True:
        final = i >= len(path)
        waypoint = path[min(i, len(path) - 1)]
        target = waypoint.pose
        if not final:
            if not finite_pose(target):
                return _stop(robot, record, "bad_command", f"setpoint {i} is not finite (not sent)")
            jump = float(np.linalg.norm(target.position - last))
            if jump > bound:
                return _stop(
                    robot, record, "bad_command",
                    f"setpoint {i} jumps {jump * 1000:.1f} mm (bound {bound * 1000:.1f} mm; "
                    "not sent)",
                )  # fmt: skip
            if set_posture is not None and waypoint.posture is not None:
                set_posture(waypoint.posture)
            robot.command_pose(target)
            last = target.position
        reading = advance_period(robot, on_period)
        record.periods += 1
        if reading is None:
            return _stop(robot, record, "nan", f"the wrench reading is not finite at period {i}")
        force = reading - offset
        magnitude = float(np.linalg.norm(force))
        record.peak_force = max(record.peak_force, magnitude)
        pose = robot.read_pose()
        if not finite_pose(pose):
            return _stop(robot, record, "bad_pose", f"the pose reading is not finite at period {i}")
        record.end = [float(v) for v in pose.position]
        record.distance_to_goal = float(np.linalg.norm(pose.position - path[-1].pose.position))
        if magnitude > cfg.force_limit:
            return _stop(
                robot, record, "force_limit",
                f"|F| {magnitude:.1f} N above the force limit {cfg.force_limit:.0f} N",
            )  # fmt: skip
        if magnitude > cfg.contact_limit:
            if contact_from is not None and i >= contact_from:
                return _stop(
                    robot, record, "contact",
                    f"contact: |F| {magnitude:.1f} N, {record.distance_to_goal * 1000:.0f} mm "
                    "from the goal",
                )  # fmt: skip
            return _stop(
                robot, record, "force_limit",
                f"unexpected contact: |F| {magnitude:.1f} N above {cfg.contact_limit:.0f} N "
                f"at period {i} of {len(path)}",
            )  # fmt: skip
        lag = float(np.linalg.norm(pose.position - target.position))
        lagging = lagging + 1 if lag > cfg.max_lag else 0
        if lagging >= cfg.lag_patience:
            return _stop(
                robot, record, "not_following",
                f"the tool point stayed {lag * 1000:.0f} mm from its setpoint for "
                f"{lagging} periods",
            )  # fmt: skip
        if final:
            if record.distance_to_goal <= cfg.position_tolerance:
                return _stop(robot, record, "reached", "")
            settle += 1
            if settle >= cfg.settle_periods:
                return _stop(
                    robot, record, "timeout",
                    f"{record.distance_to_goal * 1000:.0f} mm from the goal after "
                    f"{settle} periods of settling",
                )  # fmt: skip
        i += 1
