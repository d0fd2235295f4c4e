"""A deliberate sensor probe at setup: push the grasped object in known directions and check
the wrench convention and the stiffness the robot reports.

The executor's start-of-run self-check (`sensor_convention`) can only judge moves that happen
to carry a force, and on most healthy runs it ends "inconclusive" (README: hook hand 83 of
100 suite runs, Jaco 54). The probe makes the moves itself. Holding the grasp, it commands
the hand `amplitude` away from its setpoint in evenly spaced workplane directions, one at a
time, waits until the hand has settled, reads the wrench and the pose, and commands the hand
back. Where the object blocks a push, the arm's spring stretches and, with the `Robot`
convention (the object's force on the hand), the change of the force opposes the change of
the stretch (commanded minus measured position):

    dF = -k d(stretch)      so cos(dF, d stretch) = -1 and |dF| / |d stretch| = k.

A flipped sign gives cos = +1; a frame rotated about the normal gives the rotation's cosine.
The ratio is the arm's stiffness along the push, which the policy's step force k*delta and the
executor's force prediction take from `translational_stiffness`. Pushes the object follows
(along a drawer's rail) carry little force and are not judged.

Safety, as in the executor: every reading is checked (finite, |dF| below `force_limit`); a stop
commands the setpoint back, waits, and calls `hold()`; an exception gets the result attached as
`exc.probe_result` after `hold()`. A completed probe leaves the setpoint where it found it and
does not call `hold()`, which would move the setpoint onto the measured pose and release the
grasp's preload before the run: on the Jaco's door at +15 deg (seed 0) a run after a probe that
ended with hold() peaked at 18.8 N, and 9.6 N after one that did not. It never imports MuJoCo.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from constraint_aware.control.executor import SELF_CHECK_CONFIRM_COS, SELF_CHECK_MIN_FORCE
from constraint_aware.control.robot import Robot, reported_stiffness
from constraint_aware.errors import check_int, check_number, check_unit_vector
from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose

#: Every verdict, with what it means.
PROBE_VERDICTS: dict[str, str] = {
    "consistent": "the force opposes the arm's stretch on the judged pushes (the convention holds)",
    "flipped_sign": "the force points along the stretch: the wrench sign is flipped",
    "inconsistent": "the force and the stretch are neither opposed nor aligned (a rotated frame)",
    "stiffness_mismatch": "the convention holds, but the measured arm stiffness is not the "
    "reported one",
    "inconclusive": "too few pushes met a blocked direction (the object followed them)",
    "force_limit": "a push raised |dF| above the force limit: stopped, setpoint restored",
    "bad_reading": "a non-finite wrench or pose: stopped, setpoint restored",
    "error": "the robot raised: held, the result attached to the exception",
}
#: The verdicts whose measured arm stiffness can be used (the wrench convention holds).
STIFFNESS_VERDICTS = ("consistent", "stiffness_mismatch")
#: The verdicts that say the wrench convention is wrong: a run must not start.
CONVENTION_VERDICTS = ("flipped_sign", "inconsistent")
#: Judged pushes a verdict needs (two directions the object blocks, e.g. both sides of a rail).
PROBE_MIN_JUDGED = 2
#: A reported stiffness off the measured one by more than this factor is a mismatch.
STIFFNESS_TOLERANCE = 1.5


@dataclass(frozen=True)
class ProbeConfig:
    """How the probe pushes. Validated at construction (errors name the field and range)."""

    amplitude: float = 0.003  # [m] each push; 6 N against a blocked 2000 N/m arm
    directions: int = 8  # pushes, evenly spaced in the workplane (6: +-x, +-y, +-z without it)
    settle_tolerance: float = 0.02  # settled when the hand moves less than this x amplitude
    # in one control period
    max_settle_periods: int = 40  # periods to wait for the hand to settle, at most
    samples: int = 3  # readings averaged after settling, one per period (sensor noise)
    force_limit: float = 20.0  # [N] |dF| above this stops the probe
    min_force: float = SELF_CHECK_MIN_FORCE  # [N] a push is judged when its in-plane |dF| is
    # at least this (the self-check's own gate)

    def __post_init__(self) -> None:
        check_number("amplitude", self.amplitude, low=1e-4, high=0.02, unit="m")
        check_int("directions", self.directions, low=2)
        check_number("settle_tolerance", self.settle_tolerance, low=0, high=1, low_open=True)
        check_int("max_settle_periods", self.max_settle_periods, low=1)
        check_int("samples", self.samples, low=1)
        check_number("force_limit", self.force_limit, low=0, low_open=True, unit="N")
        check_number("min_force", self.min_force, low=0, low_open=True, unit="N")


@dataclass
class ProbePush:
    """One push. Vectors (3,) in the world frame, in-plane parts when the normal is known."""

    direction: list[float]  # unit push direction
    force_change: list[float]  # dF [N]: the reading minus the one at the setpoint
    stretch_change: list[float]  # [m] (commanded - measured) minus its value at the setpoint
    settled: bool  # the hand settled within max_settle_periods
    judged: bool  # |dF| >= min_force and a measurable stretch
    cos: float | None  # cos(dF, d stretch) when judged; -1 for the Robot convention
    arm_stiffness: float | None  # [N/m] |dF| / |d stretch| when judged
    push_stiffness: float  # [N/m] -dF . direction / amplitude: arm, grasp and object in series


@dataclass
class ProbeResult:
    """What the probe found. `verdict` is one of PROBE_VERDICTS."""

    verdict: str = "running"
    reason: str = ""
    pushes: list[ProbePush] = field(default_factory=list)
    force_offset: list[float] = field(default_factory=list)  # [N] the reading at the setpoint
    median_cos: float | None = None
    arm_stiffness: float | None = None  # [N/m] median over judged pushes
    reported_stiffness: float | None = None  # [N/m] the robot's translational_stiffness
    notes: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return self.verdict == "consistent"

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "meaning": PROBE_VERDICTS.get(self.verdict, "")}


class _Stop(Exception):
    """A named stop inside the probe (not a robot error)."""

    def __init__(self, verdict: str, reason: str) -> None:
        super().__init__(reason)
        self.verdict = verdict


def push_directions(count: int, normal: FloatArray | None) -> list[FloatArray]:
    """`count` unit directions evenly spaced in the plane normal to `normal` (3,), or the six
    world axes +-x, +-y, +-z when no normal is given."""
    if normal is None:
        return [s * e for e in np.eye(3) for s in (1.0, -1.0)]
    n = np.asarray(normal, dtype=float)
    e1 = np.cross(n, [1.0, 0.0, 0.0])
    if np.linalg.norm(e1) < 0.1:
        e1 = np.cross(n, [0.0, 1.0, 0.0])
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    angles = 2 * math.pi * np.arange(count) / count
    return [math.cos(a) * e1 + math.sin(a) * e2 for a in angles]


def probe_sensor(
    robot: Robot,
    workplane_normal: FloatArray | tuple[float, float, float] | None = None,
    config: ProbeConfig | None = None,
) -> ProbeResult:
    """Push the grasped object in known directions; check the wrench sign and frame and the
    reported stiffness (module docstring). The hand must hold the grasp, at rest.

    workplane_normal: (3,) the plane to push in (and to judge F in: forces along the normal,
    e.g. a press, are not the arm spring's); None pushes along the six world axes.
    Returns the result; a robot exception propagates with `exc.probe_result` attached.
    """
    cfg = config or ProbeConfig()
    normal = None
    if workplane_normal is not None:
        normal = np.asarray(check_unit_vector("workplane_normal", workplane_normal))
    result = ProbeResult()
    result.reported_stiffness, note = reported_stiffness(robot)
    if note:
        result.notes.append(note)
    home: Pose | None = None
    try:
        home = robot.commanded_pose()
        _check_pose(home, "commanded pose")
        base_force, base_pose, _ = _settle_and_read(robot, cfg, None, None)
        result.force_offset = base_force.tolist()
        base_stretch = home.position - base_pose.position
        for u in push_directions(cfg.directions, normal):
            target = Pose(home.position + cfg.amplitude * u, home.orientation)
            robot.command_pose(target)
            force, pose, settled = _settle_and_read(robot, cfg, base_force, target)
            d_force = _in_plane(force - base_force, normal)
            d_stretch = _in_plane(target.position - pose.position - base_stretch, normal)
            result.pushes.append(_push(u, d_force, d_stretch, settled, cfg))
            robot.command_pose(home)
            _settle_and_read(robot, cfg, base_force, home)
    except _Stop as stop:
        result.verdict, result.reason = stop.verdict, str(stop)
        _restore(robot, home, result)
        return result
    except BaseException as exc:
        result.verdict = "error"
        result.reason = f"{type(exc).__name__}: {exc}"
        _hold(robot, result)
        try:
            exc.probe_result = result  # type: ignore[attr-defined]
        except AttributeError:
            result.notes.append("could not attach the result to the exception")
        raise
    # completed: the setpoint is back where it was, so the hand holds the grasp as before the
    # probe (hold() would move the setpoint onto the measured pose and release the preload)
    _verdict(result)
    return result


def _settle_and_read(
    robot: Robot, cfg: ProbeConfig, base: FloatArray | None, target: Pose | None
) -> tuple[FloatArray, Pose, bool]:
    """Advance until the hand moves less than settle_tolerance x amplitude in a period (or
    max_settle_periods), then average `samples` readings. Every reading is checked: finite,
    and |F - base| within the force limit once a base exists."""
    last = robot.read_pose()
    _check_pose(last, "pose")
    settled = False
    for _ in range(cfg.max_settle_periods):
        robot.advance()
        pose = robot.read_pose()
        _check_pose(pose, "pose")
        _check_force(robot.read_wrench().force, base, cfg)
        moved = float(np.linalg.norm(pose.position - last.position))
        last = pose
        if moved < cfg.settle_tolerance * cfg.amplitude:
            settled = True
            break
    forces = []
    for i in range(cfg.samples):
        if i:
            robot.advance()
        forces.append(_check_force(robot.read_wrench().force, base, cfg))
    pose = robot.read_pose()
    _check_pose(pose, "pose")
    return np.mean(forces, axis=0), pose, settled


def _check_force(force: object, base: FloatArray | None, cfg: ProbeConfig) -> FloatArray:
    f = np.asarray(force, dtype=float)
    if f.shape != (3,) or not np.all(np.isfinite(f)):
        raise _Stop("bad_reading", f"wrench force {force!r} is not 3 finite numbers")
    if base is not None:
        change = float(np.linalg.norm(f - base))
        if change > cfg.force_limit:
            raise _Stop("force_limit", f"|dF| = {change:.1f} N > {cfg.force_limit:g} N")
    return f


def _check_pose(pose: Pose, what: str) -> None:
    if not (np.all(np.isfinite(pose.position)) and np.all(np.isfinite(pose.orientation.as_quat()))):
        raise _Stop("bad_reading", f"{what} {pose.position!r} is not finite")


def _in_plane(v: FloatArray, normal: FloatArray | None) -> FloatArray:
    return v if normal is None else v - float(v @ normal) * normal


def _push(
    u: FloatArray, d_force: FloatArray, d_stretch: FloatArray, settled: bool, cfg: ProbeConfig
) -> ProbePush:
    f, s = float(np.linalg.norm(d_force)), float(np.linalg.norm(d_stretch))
    # a stretch below 2 % of the push is within the settle tolerance: no direction to compare
    judged = settled and f >= cfg.min_force and s >= cfg.settle_tolerance * cfg.amplitude
    return ProbePush(
        direction=u.tolist(),
        force_change=d_force.tolist(),
        stretch_change=d_stretch.tolist(),
        settled=settled,
        judged=judged,
        cos=float(d_force @ d_stretch) / (f * s) if judged else None,
        arm_stiffness=f / s if judged else None,
        push_stiffness=-float(d_force @ u) / cfg.amplitude,
    )


def _verdict(result: ProbeResult) -> None:
    judged = [p for p in result.pushes if p.judged]
    unsettled = sum(not p.settled for p in result.pushes)
    if unsettled:
        result.notes.append(f"{unsettled} of {len(result.pushes)} pushes did not settle")
    if len(judged) < PROBE_MIN_JUDGED:
        result.verdict = "inconclusive"
        result.reason = (
            f"{len(judged)} of {len(result.pushes)} pushes met a blocked direction "
            f"({PROBE_MIN_JUDGED} needed)"
        )
        return
    cos = float(np.median([p.cos for p in judged if p.cos is not None]))
    stiffness = float(np.median([p.arm_stiffness for p in judged if p.arm_stiffness]))
    result.median_cos, result.arm_stiffness = cos, stiffness
    counted = f"median cos(dF, stretch) {cos:+.2f} over {len(judged)} pushes"
    if cos >= SELF_CHECK_CONFIRM_COS:
        result.verdict, result.reason = "flipped_sign", counted
    elif cos > -SELF_CHECK_CONFIRM_COS:
        result.verdict = "inconsistent"
        angle = math.degrees(math.acos(max(-1.0, min(1.0, -cos))))
        result.reason = f"{counted}: the frame looks rotated by about {angle:.0f} deg"
    else:
        reported = result.reported_stiffness
        ratio = None if reported is None else stiffness / reported
        if ratio is not None and not 1 / STIFFNESS_TOLERANCE <= ratio <= STIFFNESS_TOLERANCE:
            result.verdict = "stiffness_mismatch"
            result.reason = (
                f"{counted}; measured {stiffness:.0f} N/m against the reported {reported:.0f} N/m"
            )
        else:
            result.verdict, result.reason = "consistent", f"{counted}; arm {stiffness:.0f} N/m"


def _restore(robot: Robot, home: Pose | None, result: ProbeResult) -> None:
    """After a named stop: command the setpoint back (when known and finite), let a few
    periods pass, and hold."""
    try:
        if home is not None:
            robot.command_pose(home)
            for _ in range(3):
                robot.advance()
    except Exception as exc:  # the result must still be returned
        result.notes.append(f"restoring the setpoint failed: {exc!r}")
    _hold(robot, result)


def _hold(robot: Robot, result: ProbeResult) -> None:
    hold = getattr(robot, "hold", None)
    if hold is None:
        return
    try:
        hold()
    except Exception as exc:
        result.notes.append(f"robot.hold() failed: {exc!r}")
