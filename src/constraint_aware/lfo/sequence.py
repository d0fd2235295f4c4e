"""The execution phase end to end: see the object, reach it, grasp it, manipulate it, release
it and return home, from the demonstration, the camera and the robot alone.

The phases (`PHASES`), each a named part of the `SequenceRecord` with its own outcome and
reason; the first that fails ends the sequence with the robot told to hold, the record kept:

1. perceive: one depth image from the head camera, the crop around the demonstrated point,
   the recognizer's contact point and approach (lfo/perception.py); the skill is corrected
   by them (start, and for a hinge radius and initial direction).
2. reach: from home to the pre-grasp, `pre_grasp` back from the grasp along the approach,
   the hand pre-shaped for the force-exertion type; no contact allowed (control/approach.py;
   the Jaco follows a collision-aware joint path, sim/reach.py).
3. look: a sidestep to the look pose, from which the wrist camera sees the perceived
   contact point along the approach (lfo.perception.WristCamera); its depth image and the
   head camera's in one crop around that point, recognized again (`perception.
   perceive_again`: the head camera alone sees some handles only partly, past a distractor or
   the object's own edge); the skill is corrected by the second recognition and the hand
   moves to its pre-grasp. Straight lines, no contact allowed. Without a wrist camera the
   phase keeps the first recognition and says so in the record's notes.
4. approach: in along the approach to `contact_zone` before the grasp; there the hand is
   turned to the grasp's orientation (a compliant wrist with dry friction in its joints
   arrives some degrees off, and keeps what it is not turned out of); then on to the
   grasp. A force above the contact limit stops it: near the grasp as contact, earlier as a
   failure. Passive closures (plate, knob) aim `overshoot` past the perceived surface and
   stop at contact.
5. grasp: the hand closes by the force-exertion type; a passive closure presses
   `press_depth` on; the wrist then rests where it settled (no preload) and the hand must
   report contact, unless it holds the handle with play (`grasp_touches`: the hook hand's
   bar, touched only when the hand pulls; a bar outside the hook shows in the manipulation
   as the executor's lost-contact stop). A grasp with play has it taken up
   (`SequenceConfig.take_up`): closing leaves the handle on the far side of the play, and the
   manipulation's first step would strike it. So has a hook (lazy closure) that closing left
   untouched (the Jaco's fingers curl to a fixed angle: whether they touch the bar depends on
   where it sits in the hook); it must then touch it, or have felt it bear on the hand in
   the take-up.
6. manipulate: the executor (control/executor.py) with the corrected skill's estimates in
   charge, exactly as `lfo.execute` runs it, without the simulator's task monitor.
7. release: the wrist rests where it is, the hand opens to the shape it came in with (a way
   out known to be free); a hand that pressed (plate, knob) rests again where opening pushed
   it.
8. retreat: back along the hand's approach axis by `retreat`.
9. home: back to the home pose (the Jaco around the object, which it believes moved as far as
   its own hand did).

`run_in_simulation` builds the simulated world (the true object, the robot at the station
the demonstration implies, the head camera; a robot on a base moves it when the grasp it
perceives from there is out of reach) and runs `execute_sequence` on it; only the
`SequenceRobot` adapter (no ground truth through it) and the camera reach the pipeline.
`on_phase(name)` is called after each phase and `on_period()` after every control period,
for scoring and rendering outside the pipeline.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.approach import (
    MoveConfig,
    MoveRecord,
    Waypoint,
    advance_period,
    finite_pose,
    guarded_move,
    straight_line,
)
from constraint_aware.control.controllers import driving_policy
from constraint_aware.control.executor import Executor
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.record import RunRecord
from constraint_aware.control.robot import request_hold
from constraint_aware.errors import CapError, UnknownNameError, check_int, check_number
from constraint_aware.geometry import FloatArray, unit
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.lfo.manipulation import SENSOR_NOISE, goal_label, manipulation_setup
from constraint_aware.lfo.perception import (
    Perception,
    WristCamera,
    corrected_skill,
    head_camera,
    nominal_frame,
    perceive,
    perceive_again,
    wrist_camera,
)
from constraint_aware.lfo.scene import scene_from_skill
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.recognizer import (
    CROP_SIZE,
    GraspFrame,
    RecognitionError,
    Recognizer,
    make_recognizer,
)
from constraint_aware.sim.camera import (
    CameraMount,
    DepthCamera,
    DepthImage,
    add_camera,
    add_tool_camera,
    body_tree_geoms,
)
from constraint_aware.sim.embodiment import DEFAULT_ROBOT, Embodiment, parse_robot
from constraint_aware.sim.robot_adapter import CONTROL_PERIOD
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose

if TYPE_CHECKING:
    from constraint_aware.sim.reach import View

PHASES = (
    "perceive", "reach", "look", "approach", "grasp", "manipulate", "release", "retreat", "home",
)  # fmt: skip
#: points per side of the grid the Jaco's head camera must see from home (`station_for`)
VIEW_GRID = 5
START_HOME = "home"
START_AT_GRASP = "at-grasp"
STARTS = (START_HOME, START_AT_GRASP)


@dataclass(frozen=True)
class SequenceConfig:
    """The sequence's geometry and motion limits, and what its manipulation is given (the
    robot's profile, strict inputs). Units in brackets."""

    pre_grasp: float = 0.10  # [m] back from the grasp along the approach
    overshoot: float = 0.012  # [m] passive closures aim this far past the surface
    contact_zone: float = 0.02  # [m] contact within this of the grasp counts as arrival
    # where the approach enters the contact zone the hand is turned to the grasp's
    # orientation: the setpoint is turned by the remaining error, at most `align_tries` times
    # (each resting `settle_time`), until the hand is within `align_tolerance`
    align_tolerance: float = 0.5  # [deg]
    align_tries: int = 4
    retreat: float = 0.10  # [m] back along the approach after release
    reach: MoveConfig = field(default_factory=lambda: MoveConfig(speed=0.06))
    # a grasp with play (the hook around a bar) takes it up before the manipulation: slowly
    # along the demonstrated initial direction until the handle bears on the hand, at most
    # `take_up_travel`, then the wrist rests there
    take_up: MoveConfig = field(
        default_factory=lambda: MoveConfig(speed=0.01, contact_limit=1.0, position_tolerance=0.002)
    )
    take_up_travel: float = 0.005  # [m]
    approach: MoveConfig = field(default_factory=lambda: MoveConfig(speed=0.03))
    leave: MoveConfig = field(
        default_factory=lambda: MoveConfig(speed=0.05, contact_limit=6.0, position_tolerance=0.02)
    )
    hook_home_back: float = 0.30  # [m] the hook hand's home: back along the approach from
    # the farthest the demonstrated motion brings the handle toward the hand ...
    hook_home_up: float = 0.10  # [m] ... and up
    jaco_home_forward: float = -0.10  # [m] the Jaco's home tool point: from its base toward
    jaco_home_up: float = 0.50  # [m] the object, and up
    recognizer: str = "cnn"
    profile: RobotProfile | None = None  # the robot's calibration, for the manipulation
    strict_inputs: bool = False  # refuse to manipulate when a stage's input is missing

    def __post_init__(self) -> None:
        for name in ("pre_grasp", "overshoot", "contact_zone", "retreat", "take_up_travel",
                     "hook_home_back", "hook_home_up", "jaco_home_up"):  # fmt: skip
            check_number(f"SequenceConfig.{name}", getattr(self, name), low=0.0, unit="m")
        check_number("SequenceConfig.jaco_home_forward", self.jaco_home_forward, unit="m")
        check_number("SequenceConfig.align_tolerance", self.align_tolerance, low=0.0, unit="deg")
        check_int("SequenceConfig.align_tries", self.align_tries, low=0)


@dataclass
class PhaseRecord:
    """One phase: outcome "ok", a failure's name, or "not_run"; its reason; control periods;
    the largest |F| [N] (less the hand's weight) seen; what it found."""

    name: str
    outcome: str = "not_run"
    reason: str = ""
    periods: int = 0
    peak_force: float = 0.0
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.outcome == "ok"


@dataclass
class SequenceRecord:
    """The whole sequence: its phases in order, the manipulation's run record, and whether
    every phase succeeded."""

    label: dict[str, Any]
    phases: list[PhaseRecord] = field(default_factory=lambda: [PhaseRecord(p) for p in PHASES])
    manipulation: RunRecord | None = None
    success: bool = False
    failed_phase: str | None = None
    reason: str = ""
    notes: list[str] = field(default_factory=list)

    def phase(self, name: str) -> PhaseRecord:
        for p in self.phases:
            if p.name == name:
                return p
        raise UnknownNameError("phase", name, PHASES)

    @property
    def periods(self) -> int:
        return sum(p.periods for p in self.phases)

    @property
    def peak_force(self) -> float:
        """[N] the largest |F| of any phase."""
        return max((p.peak_force for p in self.phases), default=0.0)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "label": self.label,
            "success": self.success,
            "failed_phase": self.failed_phase,
            "reason": self.reason,
            "periods": self.periods,
            "peak_force_N": self.peak_force,
            "notes": list(self.notes),
            "phases": [dataclasses.asdict(p) for p in self.phases],
            "manipulation": None if self.manipulation is None else self.manipulation.to_dict(),
        }
        return _strict(out)


def _strict(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_strict(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray):
        return _strict(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


# --- the station: where the robot and its camera are, from the demonstration ----------------
@dataclass(frozen=True)
class Station:
    """Where the robot works from, derived from the demonstration only: its head camera, for
    the Jaco its base (3,) [m], home joint angles (6,) [rad] and the hand's turn about its
    approach from the handle's mount at which the arm reaches the grasp (`grasp_roll` [rad],
    sim.reach.grasp_rolls), for the hook hand its home tool pose."""

    robot: str
    camera: CameraMount
    home_pose: Pose | None = None
    base: FloatArray | None = None
    home_joints: FloatArray | None = None
    grasp_roll: float = 0.0


def _toward_hand(skill: SkillParameters, approach: FloatArray, samples: int = 16) -> float:
    """[m] how far the demonstrated motion brings the handle toward the hand (against
    `approach`, (3,) unit), at most: a drawer's travel; 0 for motions away from the hand."""
    from constraint_aware.sim.reach import believed_handle

    believed = scene_from_skill(skill).task
    goal = float(skill.goal or 0.0)
    start = believed_handle(believed, 0.0).mean(axis=0)
    along = [
        float((start - believed_handle(believed, q).mean(axis=0)) @ approach)
        for q in np.linspace(0.0, goal, samples)
    ]
    return max(0.0, *along)


def home_view(camera: CameraMount, frame: GraspFrame) -> View:
    """What the Jaco's head `camera` must see from the robot's home: the central half of the
    recognizer's crop around the demonstrated point (`frame`'s origin), on a `VIEW_GRID`
    square grid in the crop's plane. The robot looks from home, and a crop its own arm hides
    is one the recognizer refuses; the handle lies near the demonstrated point."""
    from constraint_aware.sim.reach import View

    side = np.linspace(-0.25 * CROP_SIZE, 0.25 * CROP_SIZE, VIEW_GRID)
    points = frame.to_world(np.array([[x, y, 0.0] for x in side for y in side]))
    return View(np.asarray(camera.pose.position, dtype=float), points)


def station_for(
    robot: str, skill: SkillParameters, config: SequenceConfig | None = None
) -> Station:
    """The station of `robot` (a robot spec) for the demonstrated object."""
    cfg = config or SequenceConfig()
    spec = parse_robot(robot)
    camera = head_camera(spec.name, skill)
    _, frame = nominal_frame(skill)
    up = np.array([0.0, 0.0, 1.0])
    orientation = Rotation.from_matrix(frame.rotation)
    if spec.name == "hook-hand":
        back = cfg.hook_home_back + _toward_hand(skill, frame.rotation[:, 2])
        home = frame.origin - back * frame.rotation[:, 2] + cfg.hook_home_up * up
        return Station(spec.name, camera, home_pose=Pose(home, orientation))
    from constraint_aware.sim.reach import (
        JACO_PRESHAPE,
        JacoPlanner,
        choose_base,
        facing,
        home_pose,
        rolled,
    )

    believed = scene_from_skill(skill).task
    offsets = (cfg.jaco_home_forward, cfg.jaco_home_up)
    base, _, roll = choose_base(believed, cfg.pre_grasp, offsets, home_view(camera, frame))
    tool = home_pose(base, rolled(Pose(frame.origin, orientation), roll), offsets)
    planner = JacoPlanner(base)
    planner.fingers = JACO_PRESHAPE[believed.object.handle]  # as at home: pre-shaped
    planner.set_object(believed)
    q = planner.solve_ik(tool, facing(base, tool.position))
    return Station(spec.name, camera, base=base, home_joints=q, grasp_roll=roll)


# --- the pipeline: demonstration, camera and robot only -------------------------------------
def grasp_orientation(believed: TaskConfig, approach: FloatArray, roll: float = 0.0) -> Rotation:
    """The hand's orientation at the grasp: the hand mount of the `believed` object (built
    from the corrected skill) turned by `roll` [rad] about its approach, then by the least
    rotation that takes its approach onto the recognized `approach` (3,)."""
    mount = Rotation.from_matrix(np.asarray(believed.hand_mount())) * Rotation.from_rotvec(
        [0.0, 0.0, roll]
    )
    z = mount.apply([0.0, 0.0, 1.0])
    a = unit(np.asarray(approach, dtype=float))
    axis = np.cross(z, a)
    s, c = float(np.linalg.norm(axis)), float(z @ a)
    if s < 1e-9:
        return mount
    return Rotation.from_rotvec(axis / s * math.atan2(s, c)) * mount


def _hand_axis(pose: Pose) -> FloatArray:
    return np.asarray(pose.orientation.apply([0.0, 0.0, 1.0]))


def _turn_hand(
    robot: Any,
    phase: PhaseRecord,
    orientation: Rotation,
    cfg: SequenceConfig,
    settle: int,
    tick: Callable[[PhaseRecord, Pose], FloatArray | None],
) -> tuple[Rotation, str, str]:
    """Turn the hand to `orientation` where it is: the setpoint turned (at the approach's
    turn rate) by the hand's remaining error and held `settle` periods, at most
    `cfg.align_tries` times or until within `cfg.align_tolerance`, the setpoint's earlier
    turns kept (a hold would drop them and the joints' friction keep the hand). `tick`
    commands a pose for one period and returns the force after it (None: not finite). The
    errors before each turn [deg] go to `phase.details["hand_turn_error_deg"]`. Returns the
    setpoint's turn from `orientation`, and an outcome and reason: "ok", "force_limit" (the
    force changed by more than the approach's contact limit), "nan" (a wrench reading that is
    not finite) or "bad_pose" (a measured orientation that is not finite)."""
    turn = Rotation.identity()
    errors: list[float] = []
    phase.details["hand_turn_error_deg"] = errors
    base = np.asarray(robot.read_wrench().force, dtype=float)
    if not np.all(np.isfinite(base)):
        return turn, "nan", "the wrench reading is not finite"
    for attempt in range(cfg.align_tries + 1):
        hand = robot.read_pose()
        if not finite_pose(hand):
            return turn, "bad_pose", "the measured hand pose is not finite"
        error = orientation * hand.orientation.inv()
        errors.append(math.degrees(error.magnitude()))
        if errors[-1] <= cfg.align_tolerance or attempt == cfg.align_tries:
            break
        turn = error * turn
        here = robot.commanded_pose()
        target = Pose(here.position, turn * orientation)
        path = straight_line(here, target, cfg.approach, robot.control_period)
        for waypoint in path + [Waypoint(target)] * settle:
            force = tick(phase, waypoint.pose)
            if force is None:
                return turn, "nan", "the wrench reading is not finite"
            change = float(np.linalg.norm(force - base))
            phase.peak_force = max(phase.peak_force, change)
            if change > cfg.approach.contact_limit:
                limit = cfg.approach.contact_limit
                why = f"unexpected contact while turning the hand: |F - F_0| {change:.1f} N"
                return turn, "force_limit", f"{why} above {limit:g} N"
    return turn, "ok", ""


def _from_move(phase: PhaseRecord, move: MoveRecord) -> None:
    phase.periods += move.periods
    phase.peak_force = max(phase.peak_force, move.peak_force)
    phase.details.setdefault("moves", []).append(move.to_dict())


def execute_sequence(
    robot: Any,
    capture: Callable[[], DepthImage],
    skill: SkillParameters,
    controller: str = "policy",
    policy: ConstraintAwarePolicy | None = None,
    recognizer: Recognizer | None = None,
    config: SequenceConfig | None = None,
    label: dict[str, Any] | None = None,
    on_phase: Callable[[str], None] | None = None,
    on_period: Callable[[], None] | None = None,
    wrist: tuple[WristCamera, Callable[[], DepthImage]] | None = None,
) -> SequenceRecord:
    """Run the phases (module docstring) on `robot` (a `sim.reach.SequenceRobot` or a real
    robot with the same members) at its home, with `capture()` giving the head camera's
    depth image and `wrist` the wrist camera (where it sits on the hand, and its capture of
    a depth image where the hand is; None: the robot has none). Returns the record; an
    exception is re-raised as it came with the record attached as `sequence_record` (the
    robot told to hold first)."""
    cfg = config or SequenceConfig()
    record = SequenceRecord(dict(label or {}))
    return _execute_into(
        record, robot, capture, skill, controller, policy, recognizer, cfg, on_phase, on_period,
        wrist,
    )  # fmt: skip


def _fail(
    robot: Any, record: SequenceRecord, phase: PhaseRecord, outcome: str, reason: str
) -> SequenceRecord:
    phase.outcome, phase.reason = outcome, reason
    record.failed_phase, record.reason = phase.name, f"{phase.name}: {reason}"
    request_hold(robot, record.notes)
    return record


def _run_phases(
    robot: Any,
    capture: Callable[[], DepthImage],
    skill: SkillParameters,
    controller: str,
    policy: ConstraintAwarePolicy | None,
    recognizer: Recognizer | None,
    cfg: SequenceConfig,
    record: SequenceRecord,
    on_phase: Callable[[str], None] | None,
    on_period: Callable[[], None] | None,
    wrist: tuple[WristCamera, Callable[[], DepthImage]] | None,
) -> SequenceRecord:
    def done(phase: PhaseRecord) -> None:
        if phase.outcome == "running":
            phase.outcome = "ok"
        if on_phase is not None:
            on_phase(phase.name)

    def move(phase: PhaseRecord, path: list[Waypoint], mcfg: MoveConfig,
             contact_from: int | None = None) -> MoveRecord:  # fmt: skip
        m = guarded_move(robot, phase.name, path, mcfg, contact_from, on_period)
        _from_move(phase, m)
        return m

    # 1. perceive
    phase = record.phase("perceive")
    phase.outcome = "running"
    recognizer = recognizer or make_recognizer(cfg.recognizer)
    image = capture()
    try:
        seen = perceive(skill, image, recognizer)
    except RecognitionError as exc:
        return _fail(robot, record, phase, "not_recognized", str(exc))
    shape = seen.shape

    def plan(
        found: Perception,
    ) -> tuple[SkillParameters, TaskConfig, FloatArray, Rotation, Pose, Pose]:
        """The corrected skill, the object it describes, approach, hand orientation, grasp and
        pre-grasp of a recognition, the robot told what it now believes."""
        fixed = corrected_skill(skill, found.recognition)
        believed = scene_from_skill(fixed).task
        approach = np.asarray(found.recognition.approach, dtype=float)
        orientation = grasp_orientation(believed, approach, robot.grasp_roll)
        grasp = robot.grasp_pose_at(found.recognition.contact_point, orientation, shape)
        robot.believe(believed, 0.0)
        pre = grasp.moved(-cfg.pre_grasp * approach)
        return fixed, believed, approach, orientation, grasp, pre

    settle = max(1, round(robot.settle_time / robot.control_period))

    def tick(phase: PhaseRecord, target: Pose) -> FloatArray | None:
        """Command `target` for one control period; the wrench's force (3,) [N] after it,
        None when it is not finite."""
        robot.command_pose(target)
        phase.periods += 1
        return advance_period(robot, on_period)

    def found(perception: Perception, grasp: Pose) -> dict[str, Any]:
        return {
            "method": perception.recognition.method,
            "contact_point": [float(v) for v in perception.recognition.contact_point],
            "approach": [float(v) for v in perception.recognition.approach],
            "grasp_tool_point": [float(v) for v in grasp.position],
        }

    fixed, believed, approach, orientation, grasp, pre = plan(seen)
    phase.details.update(
        shape=shape, demonstrated_point=[float(v) for v in seen.frame.origin], **found(seen, grasp)
    )
    done(phase)

    # 2. reach
    phase = record.phase("reach")
    phase.outcome = "running"
    robot.preshape(shape)
    try:
        path = robot.path_to(pre, cfg.reach, then=grasp)
    except CapError as exc:
        return _fail(robot, record, phase, "no_path", str(exc))
    m = move(phase, path, cfg.reach)
    if not m.ok:
        return _fail(robot, record, phase, m.outcome, m.reason)
    done(phase)

    # 3. look: the second recognition, from the wrist camera, then on to the pre-grasp
    phase = record.phase("look")
    phase.outcome = "running"
    if wrist is None:
        record.notes.append(
            "no wrist camera: the grasp is the head camera's recognition alone (a handle it "
            "sees only partly is not looked at again)"
        )
        phase.details["wrist_camera"] = False
    else:
        # a sidestep across the approach, in the corridor the hand comes in by, and back: short
        # straight lines keep the arm's configuration for the grasp
        look = wrist[0].look_pose(seen.recognition.contact_point, orientation)
        m = move(phase, straight_line(pre, look, cfg.reach, robot.control_period), cfg.reach)
        if not m.ok:
            return _fail(robot, record, phase, m.outcome, m.reason)
        robot.hold()
        try:
            again = perceive_again(seen, [image, wrist[1]()], recognizer)
        except RecognitionError as exc:
            return _fail(robot, record, phase, "not_recognized", str(exc))
        fixed, believed, approach, orientation, grasp, pre = plan(again)
        shift = np.asarray(again.recognition.contact_point) - seen.recognition.contact_point
        phase.details.update(
            wrist_camera=True, shift_mm=1000.0 * float(np.linalg.norm(shift)),
            **found(again, grasp),
        )  # fmt: skip
        here = robot.commanded_pose()
        m = move(phase, straight_line(here, pre, cfg.reach, robot.control_period), cfg.reach)
        if not m.ok:
            return _fail(robot, record, phase, m.outcome, m.reason)
    done(phase)

    # 4. approach
    phase = record.phase("approach")
    phase.outcome = "running"
    passive = robot.press_depth(shape) > 0.0
    near = grasp.moved(-cfg.contact_zone * approach)
    m = move(phase, straight_line(robot.commanded_pose(), near, cfg.approach,
                                  robot.control_period), cfg.approach)  # fmt: skip
    if not m.ok:
        return _fail(robot, record, phase, m.outcome, m.reason)
    turn, outcome, reason = _turn_hand(robot, phase, orientation, cfg, settle, tick)
    if outcome != "ok":
        return _fail(robot, record, phase, outcome, reason)
    goal = grasp.moved(cfg.overshoot * approach) if passive else grasp
    goal = Pose(goal.position, turn * goal.orientation)
    path = straight_line(robot.commanded_pose(), goal, cfg.approach, robot.control_period)
    zone = cfg.contact_zone + (cfg.overshoot if passive else 0.0)
    along = [float((w.pose.position - grasp.position) @ approach) for w in path]
    contact_from = next((i for i, s in enumerate(along) if s > -zone), len(path) - 1)
    m = move(phase, path, cfg.approach, contact_from)
    if not m.ok:
        return _fail(robot, record, phase, m.outcome, m.reason)
    if passive and m.outcome != "contact":
        return _fail(
            robot, record, phase, "no_contact",
            f"no surface met {cfg.overshoot * 1000:.0f} mm past the perceived one",
        )  # fmt: skip
    phase.details["stopped_by"] = m.outcome
    done(phase)

    # 5. grasp: close by the force-exertion type, press (passive closures), settle
    phase = record.phase("grasp")
    phase.outcome = "running"
    robot.close_hand(shape)
    press = robot.press_depth(shape)
    if press > 0:  # from where the surface was met, on into it
        robot.hold()
        here = robot.commanded_pose()
        target = here.moved(press * _hand_axis(here))
    else:  # the hand stays at the grasp while the fingers close around the handle
        target = grasp

    def rest(target: Pose) -> bool | None:
        """Command `target` for `settle` periods: whether the hand touched the handle (None:
        a reading was not finite)."""
        touched = False
        for _ in range(settle):
            if tick(phase, target) is None:
                return None
            touched = touched or bool(robot.grasp_contact())
        return touched

    touched = rest(target)
    if touched is not None and press == 0:
        # the wrist rests where closing left it (no preload) ...
        robot.hold()
        touched = rest(robot.commanded_pose())
        # a hook (lazy closure) the closed hand does not touch holds the handle with play too:
        # the fingers curl to a fixed angle, not onto it, and where it sits in the hook decides
        hooked = fixed.grasp == "lazy_closure" and touched is False
        if touched is not None and (hooked or not robot.grasp_touches(shape)):
            # ... and a grasp with play has it taken up: closing sweeps the handle to one side
            # of the play, the manipulation's first step would strike it across the rest
            d0 = unit(np.asarray(fixed.initial_direction, dtype=float))
            here = robot.commanded_pose()
            path = straight_line(
                here, here.moved(cfg.take_up_travel * d0), cfg.take_up, robot.control_period
            )
            m = move(phase, path, cfg.take_up, contact_from=0)
            phase.details["take_up"] = m.outcome
            if not m.ok:
                return _fail(robot, record, phase, m.outcome, m.reason)
            robot.hold()
            touched = rest(robot.commanded_pose())
            if touched is not None:  # the wrist felt the handle bear on the hand: it is held
                touched = touched or m.outcome == "contact"
    if touched is None:
        return _fail(robot, record, phase, "nan", "the wrench reading is not finite")
    # a press stays commanded: the executor starts from the pressing setpoint (as at reset)
    if robot.grasp_touches(shape) and not (touched or robot.grasp_contact()):
        return _fail(robot, record, phase, "no_contact", "the closed hand touches nothing")
    robot.ready_for_manipulation()
    done(phase)

    # 6. manipulate: the executor, the skill's estimates in charge, no task monitor
    phase = record.phase("manipulate")
    phase.outcome = "running"
    exec_cfg, ctrl = manipulation_setup(fixed, believed, robot.control_period, controller, policy)
    d0 = np.asarray(fixed.initial_direction, dtype=float)
    run_label = {**record.label, "controller": ctrl.name, "phase": "manipulate",
                 **goal_label(fixed.constraint_type, float(fixed.goal or 0.0))}  # fmt: skip
    driver = driving_policy(ctrl)
    if driver is not None:
        run_label["policy"] = driver.name
    exec_cfg = dataclasses.replace(exec_cfg, strict_inputs=cfg.strict_inputs)
    executor = Executor(robot, ctrl, exec_cfg, profile=cfg.profile)
    if on_period is None:
        manipulation = executor.run(d0, run_label)
    else:
        manipulation = _run_observed(executor, robot, d0, run_label, on_period)
    record.manipulation = manipulation
    phase.periods = len(manipulation.steps) + exec_cfg.timing.offset_samples
    phase.peak_force = manipulation.peak_force
    phase.details.update(outcome=manipulation.outcome, steps=manipulation.n_steps)
    if not manipulation.success:
        return _fail(robot, record, phase, manipulation.outcome, manipulation.reason)
    done(phase)

    # 7. release
    phase = record.phase("release")
    phase.outcome = "running"
    robot.hold()
    robot.open_hand(shape)
    if rest(robot.commanded_pose()) is None:
        return _fail(robot, record, phase, "nan", "the wrench reading is not finite")
    if press > 0:
        # a hand that pressed stays on the handle's face: the fingers opening around it push
        # the hand, and a retreat from the loaded wrist read the unloading as a contact; the
        # wrist rests where it was pushed
        robot.hold()
        if rest(robot.commanded_pose()) is None:
            return _fail(robot, record, phase, "nan", "the wrench reading is not finite")
    done(phase)

    # 8. retreat along the hand's approach axis
    phase = record.phase("retreat")
    phase.outcome = "running"
    here = robot.commanded_pose()
    back = here.moved(-cfg.retreat * _hand_axis(here))
    m = move(phase, straight_line(here, back, cfg.leave, robot.control_period), cfg.leave)
    if not m.ok:
        return _fail(robot, record, phase, m.outcome, m.reason)
    done(phase)

    # 9. home
    phase = record.phase("home")
    phase.outcome = "running"
    moved_to = _believed_progress(fixed, grasp, here)
    robot.believe(believed, moved_to)
    phase.details["believed_progress"] = moved_to
    try:
        path = robot.path_home(cfg.leave)
    except CapError as exc:
        return _fail(robot, record, phase, "no_path", str(exc))
    m = move(phase, path, cfg.leave)
    if not m.ok:
        return _fail(robot, record, phase, m.outcome, m.reason)
    done(phase)
    record.success = True
    return record


def _believed_progress(skill: SkillParameters, grasp: Pose, released: Pose) -> float:
    """[m] or [rad] how far the robot believes the object moved: its hand's travel from the
    grasp to the release along the slide, or its angle about the fitted hinge."""
    if skill.constraint_type == "revolute" and skill.centre is not None and skill.axis is not None:
        axis = unit(np.asarray(skill.axis, dtype=float))
        centre = np.asarray(skill.centre, dtype=float)
        a = grasp.position - centre
        b = released.position - centre
        a, b = a - float(a @ axis) * axis, b - float(b @ axis) * axis
        return float(math.atan2(float(np.cross(a, b) @ axis), float(a @ b)))
    direction = unit(np.asarray(skill.initial_direction, dtype=float))
    return float((released.position - grasp.position) @ direction)


def _run_observed(
    executor: Executor,
    robot: Any,
    d0: FloatArray,
    label: dict[str, Any],
    on_period: Callable[[], None],
) -> RunRecord:
    """Executor.run's loop with `on_period` after every advance (rendering)."""
    try:
        executor.start(d0, label)
        while True:
            out = executor.step(robot.read_wrench(), robot.read_pose())
            if isinstance(out, RunRecord):
                return out
            robot.command_pose(out)
            robot.advance()
            on_period()
    except BaseException as exc:
        executor._fail(exc)
        raise


# --- the simulated world ----------------------------------------------------------------------
@dataclass
class SimulatedSequence:
    """What `run_in_simulation` built and ran: the record, the station, the embodiment (for
    scoring afterwards) and the depth image the robot saw."""

    record: SequenceRecord
    station: Station
    sim: Embodiment
    image: DepthImage | None


def build_world(
    robot: str,
    task: TaskConfig,
    station: Station,
    sensor_rng: np.random.Generator,
    sensor_noise: float = SENSOR_NOISE,
) -> tuple[Embodiment, Any]:
    """The simulated world: `task`'s object (the truth), the robot at `station` with the head
    camera and the wrist camera (`WRIST_CAMERA_NAME`, on the tool point's body) composed in;
    returns the embodiment and its `SequenceRobot` adapter."""
    spec = parse_robot(robot)
    if spec.name == "hook-hand":
        from constraint_aware.lfo.robots import HookHandRobot
        from constraint_aware.sim.hand import TCP_SITE
        from constraint_aware.sim.world import HOOK_PREFIX, ManipulationSim, build_filtered_spec

        if spec.stiffness is not None:
            task = task.with_overrides(hand__translational_stiffness=spec.stiffness)
        world = build_filtered_spec(task)
        add_camera(world, station.camera)
        add_tool_camera(world, wrist_camera(spec.name).mount(), HOOK_PREFIX + TCP_SITE)
        hook = ManipulationSim(
            task, model=world.compile(), control_period=spec.period or CONTROL_PERIOD
        )
        hook.set_sensor_noise(sensor_rng, sensor_noise)
        assert station.home_pose is not None
        return hook, HookHandRobot(hook, station.home_pose)
    from constraint_aware.lfo.robots import JacoRobot
    from constraint_aware.sim.jaco import TCP_SITE as JACO_TCP_SITE
    from constraint_aware.sim.jaco import JacoSim, OscConfig
    from constraint_aware.sim.jaco import build_spec as jaco_spec
    from constraint_aware.sim.reach import JacoPlanner

    assert station.base is not None and station.home_joints is not None
    world = jaco_spec(task, station.base)
    add_camera(world, station.camera)
    add_tool_camera(world, wrist_camera(spec.name).mount(), JACO_TCP_SITE)
    osc = OscConfig()
    if spec.stiffness is not None:
        osc = dataclasses.replace(osc, translational_stiffness=spec.stiffness)
    jaco = JacoSim(
        task, osc, spec.period or CONTROL_PERIOD, base=station.base, model=world.compile()
    )
    jaco.set_sensor_noise(sensor_rng, sensor_noise)
    return jaco, JacoRobot(
        jaco, station.home_joints, JacoPlanner(station.base), grasp_roll=station.grasp_roll
    )


def run_in_simulation(
    skill: SkillParameters,
    task: TaskConfig,
    robot: str = DEFAULT_ROBOT,
    controller: str = "policy",
    policy: ConstraintAwarePolicy | None = None,
    seed: int = 0,
    sensor_noise: float = SENSOR_NOISE,
    recognizer: Recognizer | None = None,
    config: SequenceConfig | None = None,
    on_phase: Callable[[str, Embodiment], None] | None = None,
    on_period: Callable[[Embodiment], None] | None = None,
    world_hook: Callable[[Embodiment], None] | None = None,
    wrist: bool = True,
) -> SimulatedSequence:
    """The sequence on the simulated `task` (the truth: only the world is built from it).
    The station comes from the skill (a base moved when the grasp perceived from there is out
    of reach: the world is then built again, before anything moved); the camera's noise and
    the force sensor's from `seed`. world_hook(sim) runs on each world built (tests inject
    faults through it);
    on_phase(name, sim) and on_period(sim) observe (scoring, video). `wrist`: whether the
    robot's wrist camera takes part (False: the grasp from the head camera's look alone)."""
    cfg = config or SequenceConfig()
    station = station_for(robot, skill, cfg)
    recognizer = recognizer or make_recognizer(cfg.recognizer)
    notes: list[str] = []

    def world(at: Station) -> tuple[Embodiment, Any]:
        sim, adapter = build_world(
            robot, task, at, np.random.default_rng(seed + 7919), sensor_noise
        )
        if world_hook is not None:
            world_hook(sim)
        shape, _ = nominal_frame(skill)
        adapter.start_at_home(shape)
        adapter.believe(scene_from_skill(skill).task, 0.0)
        return sim, adapter

    def look(sim: Embodiment, at: Station) -> DepthImage:
        camera = DepthCamera(sim.model, at.camera)
        try:
            return camera.capture(sim.data, np.random.default_rng(seed + 104729))
        finally:
            camera.close()

    sim, adapter = world(station)
    image: DepthImage | None = None
    if station.base is not None:
        # a robot on a mobile base looks first (the head camera depends on the demonstration
        # alone) and stands where the perceived grasp, not the demonstrated one, is reachable:
        # a demonstration locates the handle only to some centimetres
        image = look(sim, station)
        from constraint_aware.sim.reach import reaches_from

        offsets = (cfg.jaco_home_forward, cfg.jaco_home_up)
        try:
            fixed = corrected_skill(skill, perceive(skill, image, recognizer).recognition)
            perceived = scene_from_skill(fixed).task
            if not reaches_from(
                perceived, station.base, cfg.pre_grasp, offsets, roll=station.grasp_roll
            ):
                moved = dataclasses.replace(station_for(robot, fixed, cfg), camera=station.camera)
                assert moved.base is not None
                notes.append(
                    "the perceived grasp is out of reach from the demonstration's station: the "
                    f"base moved {np.round(station.base, 3).tolist()} -> "
                    f"{np.round(moved.base, 3).tolist()} m"
                )
                station = moved
                sim, adapter = world(station)
        except (RecognitionError, CapError) as exc:  # the sequence's phases report it
            notes.append(f"the base stays where the demonstration puts it: {exc}")
    if station.grasp_roll:
        notes.append(
            f"the hand holds the handle turned {math.degrees(station.grasp_roll):.0f} deg about "
            "its approach from the handle's mount: from no base placement does the arm reach "
            "the mount's grasp clear of the object"
        )
    seen: list[DepthImage] = []

    def capture() -> DepthImage:
        taken = image if image is not None else look(sim, station)
        seen.append(taken)
        return taken

    on_wrist = wrist_camera(robot)

    def capture_wrist() -> DepthImage:
        """The wrist camera's image where the hand is now, the robot's own geoms filtered."""
        mount = on_wrist.mount()
        hand = sim.model.cam_bodyid[sim.model.camera(mount.name).id]
        own = body_tree_geoms(sim.model, sim.model.body(hand).name)
        with DepthCamera(sim.model, mount, own_geoms=own) as camera:
            return camera.capture(sim.data, np.random.default_rng(seed + 130363))

    label = {
        "robot": robot,
        "controller": controller,
        "seed": seed,
        "sensor_noise_N": sensor_noise,
        "constraint_type": skill.constraint_type,
        "force_exertion_type": skill.grasp,
        "start": START_HOME,
        "recognizer": recognizer.name,
    }
    record = SequenceRecord(label, notes=notes)
    out = _execute_into(
        record, adapter, capture, skill, controller, policy, recognizer, cfg,
        None if on_phase is None else (lambda name: on_phase(name, sim)),
        None if on_period is None else (lambda: on_period(sim)),
        (on_wrist, capture_wrist) if wrist else None,
    )  # fmt: skip
    return SimulatedSequence(out, station, sim, seen[0] if seen else None)


def _execute_into(
    record: SequenceRecord,
    robot: Any,
    capture: Callable[[], DepthImage],
    skill: SkillParameters,
    controller: str,
    policy: ConstraintAwarePolicy | None,
    recognizer: Recognizer | None,
    cfg: SequenceConfig,
    on_phase: Callable[[str], None] | None,
    on_period: Callable[[], None] | None,
    wrist: tuple[WristCamera, Callable[[], DepthImage]] | None = None,
) -> SequenceRecord:
    """`execute_sequence` filling a given record (so that observers see it as it grows)."""
    try:
        _run_phases(robot, capture, skill, controller, policy, recognizer, cfg, record,
                    on_phase, on_period, wrist)  # fmt: skip
    except BaseException as exc:
        request_hold(robot, record.notes)
        current = next((p for p in record.phases if p.outcome == "running"), None)
        if current is not None:
            current.outcome, current.reason = "error", f"{type(exc).__name__}: {exc}"
            record.failed_phase, record.reason = current.name, current.reason
        exc.sequence_record = record  # type: ignore[attr-defined]
        raise
    return record


__all__ = [
    "PHASES",
    "STARTS",
    "PhaseRecord",
    "SequenceConfig",
    "SequenceRecord",
    "SimulatedSequence",
    "Station",
    "execute_sequence",
    "run_in_simulation",
    "station_for",
]
