"""A deliberate sensor probe at setup: push the grasped object in known directions and check
the wrench convention and the stiffness the robot reports.

The executor's start-of-run self-check (`sensor_convention`) can only judge moves that happen
to carry a force, and on most healthy runs it ends "inconclusive" (README: hook hand 83 of
100 suite runs, Jaco 54). The probe makes the moves itself. Holding the grasp, it commands
the hand `amplitude` away from its setpoint in evenly spaced workplane directions, one at a
time, waits until the hand has settled, reads the wrench and the pose, and commands the hand
back, where it reads them again: each push is compared with the reading at the setpoint just
before it. Where the object blocks a push, the arm's spring stretches and, with the `Robot`
convention (the object's force on the hand), the change of the force opposes the change of
the stretch (the robot's setpoint minus the measured position):

    dF = -k d(stretch)      so cos(dF, d stretch) = -1 and |dF| / |d stretch| = k.

A flipped sign gives cos = +1; a frame rotated about the normal gives the rotation's cosine.
The ratio is the arm's stiffness along the push as the wrist sensor sees it, which the
policy's step force k*delta and the executor's force prediction take from
`translational_stiffness`. Pushes the object follows (along a drawer's rail) carry little
force and are not judged.

The grasp's play: each judged push is repeated `play_amplitude` deep. How far the hand moved
against the force it met (`give`) is the play in the grasp plus the grasp's and the object's
compliance, g = p + |dF| / k_object; two depths give the line and its intercept p, the play.
A grasp with play hides up to k p of the constraint force when the hand first moves off the
path (the hook hand on a bar: about 1.5 mm, 3 N at 2000 N/m); the `policy` controller adds it
back (`SteadyConfig.play_compensation`).

What is not a sensor convention is named as such, not judged: a reading at the setpoint that
changes between pushes (`unsteady`: a drifting sensor, a creeping grasp), identical samples
(`bad_reading`, a stale driver) and an arm that neither moves nor meets a force on any push
(`not_following`).

Safety, as in the executor: every reading is checked (finite, not stale, |dF| below
`force_limit`); a stop commands the setpoint back (when it was read and finite), waits, and
calls `hold()`; an exception does the same as far as the robot lets it and carries the result
as `exc.probe_result`. A completed probe leaves the setpoint where it found it and does not
call `hold()`, which would move the setpoint onto the measured pose and release the grasp's
preload before the run. It never imports MuJoCo.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from constraint_aware.control.executor_config import ExecutorConfig, max_grasp_play
from constraint_aware.control.robot import (
    Robot,
    reported_stiffness,
    reported_time_constant,
    request_hold,
)
from constraint_aware.control.self_check import MIN_FORCE as SELF_CHECK_MIN_FORCE
from constraint_aware.errors import ConfigError, check_int, check_number, check_unit_vector
from constraint_aware.geometry import FloatArray, in_plane
from constraint_aware.spatial import Pose

#: Every verdict, with what it means.
PROBE_VERDICTS: dict[str, str] = {
    "consistent": "the force opposes the arm's stretch on the judged pushes (the convention holds)",
    "flipped_sign": "the force points along the stretch: the wrench sign is flipped",
    "inconsistent": "the force and the stretch are neither opposed nor aligned (a rotated frame)",
    "stiffness_mismatch": "the convention holds, but the measured arm stiffness is not the "
    "reported one",
    "inconclusive": "too few pushes met a blocked direction and settled",
    "unsteady": "the reading at the setpoint changed between pushes, or the hand did not "
    "settle back there (a drifting sensor, a creeping grasp, the arm's friction hysteresis): "
    "stopped, setpoint restored",
    "not_following": "the hand neither moved nor met a force on any push: the arm does not "
    "follow its setpoint",
    "force_limit": "a push raised |dF| above the force limit: stopped, setpoint restored",
    "bad_reading": "a non-finite or stale wrench, or a non-finite pose: stopped, setpoint restored",
    "error": "the robot raised: setpoint restored where possible, held, the result attached to "
    "the exception",
}
#: The verdicts whose measured arm stiffness can be used (the wrench convention holds).
STIFFNESS_VERDICTS = ("consistent", "stiffness_mismatch")
#: The verdicts that say the wrench convention is wrong: a run must not start.
CONVENTION_VERDICTS = ("flipped_sign", "inconsistent")
#: Judged pushes a verdict needs (two directions the object blocks, e.g. both sides of a rail).
PROBE_MIN_JUDGED = 2
#: |median cos(dF, stretch)| at least this judges the convention: within 60 deg of opposed
#: (consistent) or of aligned (flipped); in between the frame is rotated.
PROBE_CONVENTION_COS = 0.5
#: A reported stiffness off the measured one by more than this factor is a mismatch.
STIFFNESS_TOLERANCE = 1.5
#: Each push waits at least this many of the robot's reported tracking time constants (the
#: force builds with the arm's lag even where the hand hardly moves), and at least
#: MIN_SETTLE_PERIODS control periods.
SETTLE_TIME_CONSTANTS = 3.0
MIN_SETTLE_PERIODS = 2
#: Periods a stop waits after commanding the setpoint back, before `hold()`.
RESTORE_PERIODS = 3
#: Identical wrench samples in a row that stop the probe (a stale driver).
STALE_SAMPLES = 3
#: The reading at the setpoint may change by at most this x min_force from one push to the
#: next; more is drift, not the push.
DRIFT_SHARE = 0.5
#: A push moved the hand when it moved at least this x amplitude (else blocked or frozen).
MOVED_SHARE = 0.1
#: A deep push measures the play only when its |dF| exceeds the shallow push's by at least
#: this x min_force (else the line through the two is not determined).
PLAY_FORCE_SPREAD = 1.0
#: [m] the deepest push the probe makes (ProbeConfig.amplitude and play_amplitude)
MAX_PUSH = 0.02


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
    # at least this (the self-check's own gate); < force_limit
    play_amplitude: float | None = 0.0045  # [m] each judged push repeated this deep, for the
    # grasp's play (module docstring); > amplitude (6 mm moves the hook hand's door from
    # rest); None: play not measured

    def __post_init__(self) -> None:
        n = "ProbeConfig."
        check_number(n + "amplitude", self.amplitude, low=1e-4, high=MAX_PUSH, unit="m")
        check_int(n + "directions", self.directions, low=2)
        check_number(n + "settle_tolerance", self.settle_tolerance, low=0, high=1, low_open=True)
        check_int(n + "max_settle_periods", self.max_settle_periods, low=MIN_SETTLE_PERIODS)
        check_int(n + "samples", self.samples, low=1)
        limit = check_number(n + "force_limit", self.force_limit, low=0, low_open=True, unit="N")
        check_number(
            n + "min_force", self.min_force, low=0, high=limit, low_open=True, high_open=True,
            unit="N",
        )  # fmt: skip
        if self.play_amplitude is not None:
            check_number(
                n + "play_amplitude", self.play_amplitude, low=self.amplitude, high=MAX_PUSH,
                low_open=True, unit="m",
            )  # fmt: skip


@dataclass
class ProbePush:
    """One push. Vectors (3,) in the world frame, in-plane parts when the normal is known."""

    direction: list[float]  # unit push direction
    amplitude: float  # [m] how far the setpoint was pushed
    force_change: list[float]  # dF [N]: the reading minus the one at the setpoint before it
    stretch_change: list[float]  # [m] (setpoint - measured) minus its value at the setpoint
    moved: float  # [m] how far the hand moved from where it held at the setpoint
    settled: bool  # the hand settled within max_settle_periods
    judged: bool  # settled, |dF| >= min_force and a measurable stretch
    cos: float | None  # cos(dF, d stretch) when judged; -1 for the Robot convention
    arm_stiffness: float | None  # [N/m] |dF| / |d stretch| when judged
    push_stiffness: float  # [N/m] -dF . direction / amplitude: arm, grasp and object in series
    give: float | None  # [m] when judged: how far the hand moved against the force it met,
    # i.e. the play in the grasp plus the grasp's and the object's own compliance
    shallow: int | None = None  # a deep push: the index of its push in `ProbeResult.pushes`


@dataclass
class ProbeResult:
    """What the probe found. `verdict` is one of PROBE_VERDICTS."""

    verdict: str = "running"
    reason: str = ""
    pushes: list[ProbePush] = field(default_factory=list)
    force_offset: list[float] = field(default_factory=list)  # [N] the first setpoint reading
    median_cos: float | None = None
    arm_stiffness: float | None = None  # [N/m] median over judged pushes
    give: float | None = None  # [m] median over judged pushes (ProbePush.give)
    play_pushes: list[ProbePush] = field(default_factory=list)  # the deep pushes (not judged
    # for the verdict: only `pushes` are)
    play: float | None = None  # [m] the grasp's play: median over the judged directions of
    # the give-against-force line's intercept, >= 0 (None: not measured)
    reported_stiffness: float | None = None  # [N/m] the robot's translational_stiffness
    workplane_normal: list[float] | None = None  # (3,) the plane pushed in; None: 3-D
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
    result = ProbeResult(workplane_normal=None if normal is None else normal.tolist())
    home: Pose | None = None
    try:
        result.reported_stiffness, note = reported_stiffness(robot)
        tau, tau_note = reported_time_constant(robot)
        result.notes.extend(n for n in (note, tau_note) if n)
        reader = _Reader(robot, cfg, tau, result)
        start = robot.commanded_pose()
        _check_pose(start, "commanded pose")
        home = start
        base_force, base_stretch, base_pose, rested = reader.settle_push(None)
        if not rested:
            raise _Stop(
                "unsteady",
                f"the hand did not settle at the setpoint within {cfg.max_settle_periods} "
                "periods before the first push",
            )
        result.force_offset = base_force.tolist()
        base = (base_force, base_stretch, base_pose)
        for i, u in enumerate(push_directions(cfg.directions, normal)):
            base = _push_and_return(
                robot, reader, home, u, cfg.amplitude, base, normal, cfg, result.pushes,
                f"push {i + 1}",
            )  # fmt: skip
        _verdict(result, cfg)
        if cfg.play_amplitude is not None and result.verdict in STIFFNESS_VERDICTS:
            _measure_play(robot, reader, home, base, normal, cfg, result)
    except _Stop as stop:
        result.verdict, result.reason = stop.verdict, str(stop)
        _restore(robot, home, result)
        return result
    except BaseException as exc:
        result.verdict = "error"
        result.reason = f"{type(exc).__name__}: {exc}"
        try:  # first: a second Ctrl-C during the restore must not lose it
            exc.probe_result = result  # type: ignore[attr-defined]
        except AttributeError:
            result.notes.append("could not attach the result to the exception")
        _restore(robot, home, result, wait=False)
        raise
    # completed: the setpoint is back where it was, so the hand holds the grasp as before the
    # probe (hold() would move the setpoint onto the measured pose and release the preload)
    return result


def _measure_play(
    robot: Robot,
    reader: _Reader,
    home: Pose,
    base: tuple[FloatArray, FloatArray, Pose],
    normal: FloatArray | None,
    cfg: ProbeConfig,
    result: ProbeResult,
) -> None:
    """The deep pushes and `result.play` (module docstring). They come after the ring and its
    verdict, so that they cannot disturb the pushes the verdict judges (an arm with joint
    friction keeps some of a push's deflection). A deep push whose force, extrapolated from
    its shallow push past the give, would pass the force limit is not made; one that leaves
    the setpoint reading unsteady (the grasp or the object moved) ends the deep pushes with a
    note, and the play comes from the pairs before it (None without one). A safety stop
    during a deep push (`force_limit`, `bad_reading`) still stops the probe and replaces the
    verdict: the extrapolation is a guard, not a promise."""
    deep = cfg.play_amplitude
    assert deep is not None
    for i, push in enumerate(result.pushes):
        if not push.judged or push.give is None:
            continue
        # past the give the force grows at least as fast as the push: a linear extrapolation
        # from the push's stretch would understate a grasp with play
        free = min(max(push.give, 0.0), 0.9 * push.amplitude)
        predicted = math.hypot(*push.force_change) * (deep - free) / (push.amplitude - free)
        if predicted > cfg.force_limit:
            result.notes.append(
                f"deep push {i + 1} not made: about {predicted:.1f} N expected, above the "
                f"{cfg.force_limit:g} N limit"
            )
            continue
        try:
            base = _push_and_return(
                robot, reader, home, np.asarray(push.direction), deep, base, normal, cfg,
                result.play_pushes, f"deep push {i + 1}", shallow=i,
            )  # fmt: skip
        except _Stop as stop:
            if stop.verdict != "unsteady":
                raise
            # the grasp or the object moved on this push: it is not used, nor any after it
            if result.play_pushes and result.play_pushes[-1].shallow == i:
                result.play_pushes.pop()
            result.notes.append(f"deep pushes stopped, {stop}; the play from the ones before")
            break
    result.play = grasp_play(result.pushes, result.play_pushes, cfg.min_force)


def _push_and_return(
    robot: Robot,
    reader: _Reader,
    home: Pose,
    u: FloatArray,
    amplitude: float,
    base: tuple[FloatArray, FloatArray, Pose],
    normal: FloatArray | None,
    cfg: ProbeConfig,
    into: list[ProbePush],
    label: str,
    shallow: int | None = None,
) -> tuple[FloatArray, FloatArray, Pose]:
    """One push `amplitude` along u from the setpoint `home` and back; the push, compared with
    the setpoint reading `base` (force, stretch, pose) before it, is appended to `into` before
    the hand goes back (kept if that fails). Returns the setpoint reading after it (the next
    push's base). Stops `unsteady` when the hand does not settle back, or the setpoint
    reading drifted."""
    base_force, base_stretch, base_pose = base
    robot.command_pose(Pose(home.position + amplitude * u, home.orientation))
    force, stretch, pose, settled = reader.settle_push(base_force)
    push = _push(u, amplitude, force - base_force, stretch - base_stretch, pose, base_pose,
                 settled, normal, cfg)  # fmt: skip
    push.shallow = shallow
    into.append(push)
    robot.command_pose(home)
    after, after_stretch, after_pose, back = reader.settle_push(base_force)
    if not back:
        raise _Stop(
            "unsteady",
            f"the hand did not settle back at the setpoint after {label} within "
            f"{cfg.max_settle_periods} periods",
        )
    drift = float(np.linalg.norm(in_plane(after - base_force, normal)))
    if drift > DRIFT_SHARE * cfg.min_force:
        raise _Stop(
            "unsteady",
            f"the reading at the setpoint changed by {drift:.2f} N over {label} "
            f"(at most {DRIFT_SHARE * cfg.min_force:.2f} N)",
        )
    return after, after_stretch, after_pose


class _Reader:
    """Settles and reads, checking every sample: finite, not stale, |F - base| within the
    force limit once a base exists."""

    def __init__(
        self, robot: Robot, cfg: ProbeConfig, tau: float | None, result: ProbeResult
    ) -> None:
        self.robot = robot
        self.cfg = cfg
        waits = 0 if tau is None else math.ceil(SETTLE_TIME_CONSTANTS * tau / robot.control_period)
        self.min_periods = max(MIN_SETTLE_PERIODS, waits)
        if self.min_periods > cfg.max_settle_periods:
            result.notes.append(
                f"waiting {cfg.max_settle_periods} periods per push (max_settle_periods), less "
                f"than {SETTLE_TIME_CONSTANTS:g} tracking time constants ({self.min_periods})"
            )
            self.min_periods = cfg.max_settle_periods
        self._period = 0  # control periods advanced
        self._last: tuple[int, FloatArray] | None = None  # (period, force and torque)
        self._repeats = 0

    def settle_push(self, base: FloatArray | None) -> tuple[FloatArray, FloatArray, Pose, bool]:
        """Advance until the hand moves less than settle_tolerance x amplitude in a period
        (after at least min_periods; at most max_settle_periods), then average `samples`
        readings. Returns (F, stretch = setpoint - measured, pose, settled)."""
        cfg = self.cfg
        last = self._pose()
        settled = False
        for period in range(1, cfg.max_settle_periods + 1):
            self._advance()
            pose = self._pose()
            self._force(base)
            moved = float(np.linalg.norm(pose.position - last.position))
            last = pose
            if period >= self.min_periods and moved < cfg.settle_tolerance * cfg.amplitude:
                settled = True
                break
        forces = []
        for i in range(cfg.samples):
            if i:
                self._advance()
            forces.append(self._force(base))
        pose = self._pose()
        setpoint = self.robot.commanded_pose()
        _check_pose(setpoint, "commanded pose")
        return np.mean(forces, axis=0), setpoint.position - pose.position, pose, settled

    def _advance(self) -> None:
        self.robot.advance()
        self._period += 1

    def _pose(self) -> Pose:
        pose = self.robot.read_pose()
        _check_pose(pose, "pose")
        return pose

    def _force(self, base: FloatArray | None) -> FloatArray:
        wrench = self.robot.read_wrench()
        raw = wrench.force
        f = np.asarray(raw, dtype=float)
        if f.shape != (3,) or not np.all(np.isfinite(f)):
            raise _Stop("bad_reading", f"wrench force {raw!r} is not 3 finite numbers")
        # stale: the same force and torque in consecutive periods (a second read within one
        # period may repeat; a noise-free simulator at rest repeats too, and is stopped)
        sample = np.concatenate([f, np.asarray(wrench.torque, dtype=float).ravel()])
        if self._last is not None and self._last[0] != self._period:
            if np.array_equal(sample, self._last[1]):
                self._repeats += 1
                if self._repeats >= STALE_SAMPLES - 1:
                    raise _Stop("bad_reading", f"{STALE_SAMPLES} identical wrench samples (stale)")
            else:
                self._repeats = 0
        self._last = (self._period, sample)
        if base is not None:
            change = float(np.linalg.norm(f - base))
            if change > self.cfg.force_limit:
                raise _Stop("force_limit", f"|dF| = {change:.1f} N > {self.cfg.force_limit:g} N")
        return f


def _check_pose(pose: Pose, what: str) -> None:
    if not (np.all(np.isfinite(pose.position)) and np.all(np.isfinite(pose.orientation.as_quat()))):
        raise _Stop("bad_reading", f"{what} {pose.position!r} is not finite")


def _push(
    u: FloatArray,
    amplitude: float,
    d_force: FloatArray,
    d_stretch: FloatArray,
    pose: Pose,
    base_pose: Pose,
    settled: bool,
    normal: FloatArray | None,
    cfg: ProbeConfig,
) -> ProbePush:
    d_force, d_stretch = in_plane(d_force, normal), in_plane(d_stretch, normal)
    f, s = float(np.linalg.norm(d_force)), float(np.linalg.norm(d_stretch))
    # a stretch below the settle tolerance has no direction to compare
    judged = settled and f >= cfg.min_force and s >= cfg.settle_tolerance * amplitude
    travel = in_plane(pose.position - base_pose.position, normal)
    return ProbePush(
        direction=u.tolist(),
        amplitude=amplitude,
        force_change=d_force.tolist(),
        stretch_change=d_stretch.tolist(),
        moved=float(np.linalg.norm(travel)),
        settled=settled,
        judged=judged,
        cos=float(d_force @ d_stretch) / (f * s) if judged else None,
        arm_stiffness=f / s if judged else None,
        push_stiffness=-float(d_force @ u) / amplitude,
        give=-float(travel @ d_force) / f if judged else None,
    )


def _verdict(result: ProbeResult, cfg: ProbeConfig) -> None:
    pushes = result.pushes
    judged = [p for p in pushes if p.judged]
    unsettled = sum(not p.settled for p in pushes)
    if unsettled:
        result.notes.append(f"{unsettled} of {len(pushes)} pushes did not settle")
    idle = [
        p
        for p in pushes
        if p.moved < MOVED_SHARE * cfg.amplitude and math.hypot(*p.force_change) < cfg.min_force
    ]
    if pushes and len(idle) == len(pushes):
        result.verdict = "not_following"
        result.reason = (
            f"on all {len(pushes)} pushes the hand moved less than "
            f"{MOVED_SHARE * cfg.amplitude * 1000:.1f} mm and |dF| stayed below "
            f"{cfg.min_force:g} N"
        )
        return
    if len(judged) < PROBE_MIN_JUDGED:
        blocked = sum(math.hypot(*p.force_change) >= cfg.min_force for p in pushes)
        result.verdict = "inconclusive"
        result.reason = (
            f"{len(judged)} of {len(pushes)} pushes judged ({PROBE_MIN_JUDGED} needed): "
            f"{blocked} met a force of {cfg.min_force:g} N, {unsettled} did not settle"
        )
        return
    cos = float(np.median([p.cos for p in judged if p.cos is not None]))
    stiffness = float(np.median([p.arm_stiffness for p in judged if p.arm_stiffness]))
    result.median_cos, result.arm_stiffness = cos, stiffness
    result.give = float(np.median([p.give for p in judged if p.give is not None]))
    counted = f"median cos(dF, stretch) {cos:+.2f} over {len(judged)} pushes"
    if cos >= PROBE_CONVENTION_COS:
        result.verdict, result.reason = "flipped_sign", counted
    elif cos > -PROBE_CONVENTION_COS:
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


def grasp_play(
    pushes: list[ProbePush], deep_pushes: list[ProbePush], min_force: float
) -> float | None:
    """[m] The grasp's play from pairs of judged pushes along one direction at two depths (a
    deep push's `shallow` index names its pair): the intercept p of give = p + |dF| /
    k_object, at most the shallow push's give; the median over the pairs. Pairs whose forces
    differ by less than PLAY_FORCE_SPREAD x min_force, or whose give falls as the force grows
    (no positive compliance: not the model), are skipped; None without a pair."""
    plays = []
    for deep in deep_pushes:
        if deep.shallow is None or not 0 <= deep.shallow < len(pushes):
            continue
        shallow = pushes[deep.shallow]
        if not (shallow.judged and deep.judged) or shallow.give is None or deep.give is None:
            continue
        f1, f2 = math.hypot(*shallow.force_change), math.hypot(*deep.force_change)
        if f2 - f1 < PLAY_FORCE_SPREAD * min_force or deep.give < shallow.give:
            continue
        compliance = (deep.give - shallow.give) / (f2 - f1)  # [m/N] 1 / k_object
        plays.append(min(max(shallow.give - f1 * compliance, 0.0), shallow.give))
    return float(np.median(plays)) if plays else None


def probed_settings(probed: ProbeResult, config: ExecutorConfig) -> dict[str, float]:
    """The ExecutorConfig fields a setup probe measured, for `config.with_overrides(**...)`:
    the arm stiffness the wrist sees (`robot__stiffness`) and the grasp's play
    (`robot__grasp_play`, capped at the executor's bound for `config`'s step,
    `max_grasp_play`), when the wrench convention holds; none otherwise."""
    if probed.verdict not in STIFFNESS_VERDICTS or not probed.arm_stiffness:
        return {}
    out = {"robot__stiffness": probed.arm_stiffness}
    if probed.play is not None:
        out["robot__grasp_play"] = min(probed.play, max_grasp_play(config.step_length))
    return out


def check_force_limit(config: ProbeConfig, limit: float) -> ProbeConfig:
    """`config`, its force limit checked against an object's `limit` [N]: an error names the
    field when the probe's is higher."""
    if config.force_limit > limit:
        raise ConfigError(
            "ProbeConfig.force_limit", config.force_limit, f"<= the object's limit {limit:g} [N]"
        )
    return config


def _restore(robot: Robot, home: Pose | None, result: ProbeResult, wait: bool = True) -> None:
    """After a stop: command the setpoint back (when it was read and finite), let
    RESTORE_PERIODS pass (not after an exception: the robot may not advance), and hold."""
    try:
        if home is not None:
            robot.command_pose(home)
            for _ in range(RESTORE_PERIODS if wait else 0):
                robot.advance()
    except Exception as exc:  # the result must still be returned
        result.notes.append(f"restoring the setpoint failed: {exc!r}")
    request_hold(robot, result.notes)
