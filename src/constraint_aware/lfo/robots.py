"""The simulated robots as the execution sequence (lfo/sequence.py) sees them: the executor's
`Robot` protocol, a hand that pre-shapes, closes by force-exertion type and opens, a home, and
paths between poses (the Jaco's: collision-aware joint paths, sim/reach.py).

`SequenceRobot` wraps an embodiment and forwards only the Robot protocol's members; the
simulator's ground truth (the object's pose, joint, the task monitor) is not reachable through
it. Where the hand holds a handle it is told (`grasp_pose_at`: a contact point and an
orientation, both perceived); how each hand holds each handle shape is the hand's own
knowledge (the finger angles of sim.tasks.HANDLE_GRASPS for the hook hand, sim.jaco.JACO_GRASPS
for the Jaco).
"""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.approach import MoveConfig, Waypoint, straight_line
from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.embodiment import Embodiment
from constraint_aware.sim.jaco import JACO_GRASPS, JacoSim
from constraint_aware.sim.reach import (
    HANDLE_SHAPES,
    HOOK_PRESHAPE,
    JACO_PRESHAPE,
    JacoPlanner,
    PlanningError,
    believed_handle,
    segment_distance,
)
from constraint_aware.sim.tasks import HANDLE_GRASPS, TaskConfig
from constraint_aware.sim.world import ManipulationSim
from constraint_aware.spatial import Pose, Wrench


def _check_shape(shape: str) -> str:
    if shape not in HANDLE_SHAPES:
        raise UnknownNameError("handle shape", shape, HANDLE_SHAPES)
    return shape


class SequenceRobot(ABC):
    """An embodiment behind the Robot protocol plus its hand and home (module docstring)."""

    name = "robot"
    #: [rad] the hand's turn about its approach from the handle's mount at the grasp: how
    #: this robot holds the handle from where it stands (lfo.sequence.Station.grasp_roll)
    grasp_roll = 0.0

    def __init__(self, sim: Embodiment) -> None:
        self._sim = sim

    # --- the Robot protocol ----------------------------------------------------------------
    @property
    def control_period(self) -> float:
        return float(self._sim.control_period_s)

    def read_wrench(self) -> Wrench:
        return self._sim.read_wrench()

    def read_pose(self) -> Pose:
        return self._sim.read_pose()

    def commanded_pose(self) -> Pose:
        return self._sim.commanded_pose()

    def command_pose(self, pose: Pose) -> None:
        self._sim.command_pose(pose)

    def advance(self) -> None:
        self._sim.advance()

    def hold(self) -> None:
        self._sim.hold()

    def grasp_contact(self) -> bool | None:
        return self._sim.grasp_contact()

    @property
    def translational_stiffness(self) -> float:
        return float(self._sim.translational_stiffness)

    @property
    def tracking_time_constant(self) -> float:
        return float(self._sim.tracking_time_constant)

    # --- the hand --------------------------------------------------------------------------
    @property
    def settle_time(self) -> float:
        """[s] how long closing or opening the hand takes (and settling after it)."""
        return float(self._sim.settle_time)

    @staticmethod
    def press_depth(shape: str) -> float:
        """[m] how far past first contact a passive closure presses the tool point into the
        handle along the approach (sim.tasks.HANDLE_GRASPS)."""
        return float(HANDLE_GRASPS[_check_shape(shape)].get("press_depth", 0.0))

    @abstractmethod
    def preshape(self, shape: str) -> None:
        """Open the hand as the grasp of a `shape` handle needs before the approach."""

    @abstractmethod
    def close_hand(self, shape: str) -> None:
        """Close the hand by the force-exertion type of a `shape` handle."""

    @abstractmethod
    def open_hand(self, shape: str) -> None:
        """Open the hand to release a `shape` handle."""

    def grasp_touches(self, shape: str) -> bool:
        """Whether the closed hand touches a `shape` handle it holds (its contact sensing
        must then report contact before the manipulation); True unless the hand says."""
        _check_shape(shape)
        return True

    def grasp_pose_at(self, point: FloatArray, orientation: Rotation, shape: str) -> Pose:
        """The tool pose that holds a `shape` handle whose grasp centre is `point` (3,) [m]
        with the hand at `orientation`."""
        return self._sim.grasp_pose_at(point, orientation, _check_shape(shape))  # type: ignore[attr-defined]

    def believe(self, task: TaskConfig, joint_position: float) -> None:
        """What the robot believes about the object, for its paths around it: `task`'s object
        at `joint_position` [m or rad]."""
        del task, joint_position

    def ready_for_manipulation(self) -> None:
        """Fix the arm's tracking time constant at the grasp configuration (the Robot
        protocol's optional member, measured there once, as at reset)."""
        self._sim._tracking_time_constant = self._sim._free_space_time_constant()

    # --- home and paths --------------------------------------------------------------------
    @abstractmethod
    def start_at_home(self, shape: str) -> None:
        """Reset the simulation with the robot at home, the hand pre-shaped for `shape`."""

    @abstractmethod
    def home_pose(self) -> Pose:
        """The tool pose at home."""

    def path_to(self, goal: Pose, config: MoveConfig, then: Pose | None = None) -> list[Waypoint]:
        """Per-period setpoints from the current setpoint to `goal` (a straight line);
        `then`: the pose the hand goes on to (an arm arrives in the posture that suits it)."""
        del then
        return straight_line(self.commanded_pose(), goal, config, self.control_period)

    def path_home(self, config: MoveConfig) -> list[Waypoint]:
        return self.path_to(self.home_pose(), config)


class HookHandRobot(SequenceRobot):
    """The hook hand on its virtual Cartesian arm (sim/world.py); home: a pose given by the
    station (the hand floats: no base). Its way home keeps `clearance` from the handle as
    the robot believes it moved (the hand touches nothing else of the object)."""

    name = "hook-hand"
    clearance = 0.08  # [m] from the believed handle's segment
    #: via points tried on the way home, in the hand's (back along its axis, up) [m]
    VIAS = ((0.0, 0.0), (0.1, 0.0), (0.1, 0.15), (0.0, 0.2), (0.15, 0.25), (0.25, 0.35))

    def __init__(self, sim: ManipulationSim, home: Pose) -> None:
        super().__init__(sim)
        self._hook = sim
        self._home = home
        self._handle: FloatArray | None = None

    def believe(self, task: TaskConfig, joint_position: float) -> None:
        self._handle = believed_handle(task, joint_position)

    def path_home(self, config: MoveConfig) -> list[Waypoint]:
        start = self.commanded_pose()
        if self._handle is None:
            return straight_line(start, self._home, config, self.control_period)
        axis = start.orientation.apply([0.0, 0.0, 1.0])
        up = np.array([0.0, 0.0, 1.0])
        for back, lift in self.VIAS:
            via = start.moved(-back * axis + lift * up)
            legs = [start, via, self._home] if back or lift else [start, self._home]
            path = [
                w
                for a, b in itertools.pairwise(legs)
                for w in straight_line(a, b, config, self.control_period)
            ]
            points = np.array([w.pose.position for w in path])
            if segment_distance(points, self._handle) >= self.clearance:
                return path
        return straight_line(start, self._home, config, self.control_period)

    def preshape(self, shape: str) -> None:
        self._hook.set_fingers(HOOK_PRESHAPE[_check_shape(shape)])

    def close_hand(self, shape: str) -> None:
        self._hook.set_fingers(float(HANDLE_GRASPS[_check_shape(shape)]["finger_angle"]))

    def grasp_touches(self, shape: str) -> bool:
        # a bar is hooked: straight fingers behind it, with play, touch it only when the hand
        # pulls (a bar outside the hook shows as the executor's lost-contact stop)
        return _check_shape(shape) != "bar"

    def open_hand(self, shape: str) -> None:
        # back to the shape the hand came in with: that way out is known to be free, and
        # fingers opened wider around a knob swing into the crank's arm
        self._hook.set_fingers(HOOK_PRESHAPE[_check_shape(shape)])

    def home_pose(self) -> Pose:
        return self._home

    def start_at_home(self, shape: str) -> None:
        self._hook.start_at(self._home, HOOK_PRESHAPE[_check_shape(shape)])


class JacoRobot(SequenceRobot):
    """The Jaco arm and hand (sim/jaco.py); home: a joint configuration; paths: `JacoPlanner`."""

    name = "jaco"

    def __init__(
        self, sim: JacoSim, home: FloatArray, planner: JacoPlanner, grasp_roll: float = 0.0
    ) -> None:
        super().__init__(sim)
        self._jaco = sim
        self._home = np.asarray(home, dtype=float)
        self.planner = planner
        self.grasp_roll = float(grasp_roll)

    def preshape(self, shape: str) -> None:
        self._jaco.set_fingers(JACO_PRESHAPE[_check_shape(shape)])
        self.planner.fingers = JACO_PRESHAPE[shape]  # paths for the hand as it is shaped

    def close_hand(self, shape: str) -> None:
        self._jaco.set_fingers(JACO_GRASPS[_check_shape(shape)].finger_target)

    def open_hand(self, shape: str) -> None:
        # back to the shape the hand came in with: a fist opened on a plate would push its
        # fingers into it (9.5 N at the retreat's first period)
        self._jaco.set_fingers(JACO_PRESHAPE[_check_shape(shape)])
        self.planner.fingers = JACO_PRESHAPE[shape]

    def set_posture(self, q: FloatArray) -> None:
        self._jaco.set_posture(q)

    def believe(self, task: TaskConfig, joint_position: float) -> None:
        self.planner.set_object(task, joint_position)

    def ready_for_manipulation(self) -> None:
        self._jaco.set_posture(self._jaco.joint_positions())
        super().ready_for_manipulation()

    def home_pose(self) -> Pose:
        return self.planner.tool_pose(self._home)

    def start_at_home(self, shape: str) -> None:
        self._jaco.start_at_joints(self._home, JACO_PRESHAPE[_check_shape(shape)])

    def path_to(self, goal: Pose, config: MoveConfig, then: Pose | None = None) -> list[Waypoint]:
        """A joint path to `goal`; with `then` (the grasp after a pre-grasp), to the solution
        for `goal` on the arm configuration of the posture at `then` from which the arm
        follows the believed object's whole motion farthest from the joint limits
        (`JacoPlanner.motion_ik`, `pre_grasp_ik`): the manipulation starts from there, and the
        arm cannot change configuration while it holds the handle. The station checked the
        motion's clearance; here a grasp perceived to some millimetres may graze the believed
        furniture at the start, so only the joint limits count. Where no posture follows the
        motion, the solution nearest the roomiest posture at `then`."""
        start = self._jaco.joint_positions()
        speed, turn, period = config.speed, config.turn_rate, self.control_period
        if then is not None:
            try:
                try:
                    at_grasp, _ = self.planner.motion_ik(then, clear=False)
                    target = self.planner.pre_grasp_ik(goal, at_grasp)
                except PlanningError:
                    target = self.planner.solve_ik(goal, self.planner.roomiest_ik(then))
                return _waypoints(self.planner.plan(start, target, speed, turn, period))
            except PlanningError:
                pass  # the nearest solution instead
        return _waypoints(self.planner.plan(start, goal, speed, turn, period))

    #: via tool points tried on the way home when the direct joint path is blocked, in the
    #: hand's (back along its approach axis, up) [m]
    VIAS = ((0.1, 0.15), (0.2, 0.0), (0.0, 0.25), (0.25, 0.3))

    def path_home(self, config: MoveConfig) -> list[Waypoint]:
        """A joint path home; when the object (as believed) blocks it, through a via tool
        pose further back and up first (`VIAS`)."""
        start = self._jaco.joint_positions()
        period = self.control_period
        speed, turn = config.speed, config.turn_rate
        # home is the tool's home pose, in the arm posture nearest the present one: the
        # controller follows a tool path, its null space only loosely a joint path
        home = self.home_pose()
        try:
            return _waypoints(self.planner.plan(start, home, speed, turn, period))
        except PlanningError as exc:
            failures = [str(exc)]
        here = self.planner.tool_pose(start)
        axis = here.orientation.apply([0.0, 0.0, 1.0])
        for back, up in self.VIAS:
            via = here.moved(-back * axis + np.array([0.0, 0.0, up]))
            try:
                first = self.planner.plan(start, via, speed, turn, period)
                second = self.planner.plan(first[-1][1], home, speed, turn, period)
            except PlanningError as exc:
                failures.append(str(exc))
                continue
            return _waypoints([*first, *second])
        raise PlanningError("; ".join(failures[:2]))


def _waypoints(path: list[tuple[Pose, FloatArray]]) -> list[Waypoint]:
    return [Waypoint(pose, q) for pose, q in path]
