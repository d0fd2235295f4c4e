"""What the simulated robots know for the execution sequence (lfo/sequence.py, lfo/robots.py):
how each hand pre-shapes and opens for each handle shape, where the handle is believed to be
after a motion, and the Jaco's base placement and paths.

The Jaco's paths (`JacoPlanner`): mink's differential inverse kinematics from the current joint
angles toward a tool pose or a joint configuration, one control period per iteration, under
the joint limits, a joint speed limit and collision avoidance between every arm and hand geom
and every part of the object and its furniture as the robot believes them to be (the object
built from the demonstration, lfo/scene.py, at the joint position the robot estimates): the
robot's own model, never the simulated object. The joint path is re-timed so that the tool
point moves at most `MoveConfig.speed`, and each period's tool pose is commanded with its joint
posture (the controller's null space follows the planned arm configuration).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.jaco import (
    ARM_JOINTS,
    BASE_PLACEMENT,
    FINGER_JOINTS,
    JACO_GRASPS,
    TCP_SITE,
    JacoSim,
    OscConfig,
    arm_base,
    build_spec,
)
from constraint_aware.sim.objects import VISUAL_GROUP, object_frame
from constraint_aware.sim.robot_adapter import rotvec
from constraint_aware.sim.scene import OBJECT_PREFIX
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose

HANDLE_SHAPES = ("bar", "pole", "plate", "knob")
#: [rad] the hook hand's fingers before the approach and after the release (+ closes,
#: - opens): open around a bar, a pole and a knob; straight (the tip pads press) over a plate.
HOOK_PRESHAPE = {"bar": -0.9, "pole": -0.9, "plate": 0.0, "knob": -0.6}
#: [rad] the Jaco's fingers before the approach and after the release (0 open, 1.5
#: closed): open around a bar or a pole, the grasp's own start shape over a plate (a fist)
#: and a knob.
JACO_PRESHAPE = {"bar": 0.2, "pole": 0.3, "plate": JACO_GRASPS["plate"].finger_start,
                 "knob": JACO_GRASPS["knob"].finger_start}  # fmt: skip


def believed_handle(task: TaskConfig, joint_position: float) -> FloatArray:
    """(2, 3) [m] the handle as a segment (its two ends) at `joint_position` [m or rad] of
    `task`'s object: a bar or pole along its length, a plate or knob as its centre."""
    obj = task.object
    frame = object_frame(obj)
    centre = np.asarray(obj.handle_position, dtype=float)
    if obj.handle == "bar":
        along = frame[:, 2] if obj.joint_type == "revolute" else frame[:, 1]
        half = 0.5 * obj.handle_length
    elif obj.handle == "pole":
        along, half = frame[:, 2], 0.5 * obj.handle_length
    else:
        along, half = frame[:, 2], 0.0
    ends = np.stack([centre - half * along, centre + half * along])
    if obj.joint_type == "prismatic":
        return ends + joint_position * np.asarray(obj.axis, dtype=float)
    turn = Rotation.from_rotvec(joint_position * np.asarray(obj.axis, dtype=float))
    pivot = np.asarray(obj.position, dtype=float)
    return np.asarray(pivot + turn.apply(ends - pivot))


def segment_distance(points: FloatArray, ends: FloatArray) -> float:
    """[m] the least distance of points (N, 3) from the segment `ends` (2, 3)."""
    a, b = ends
    ab = b - a
    denom = float(ab @ ab)
    t = np.zeros(len(points)) if denom < 1e-12 else np.clip((points - a) @ ab / denom, 0, 1)
    return float(np.min(np.linalg.norm(points - (a + t[:, None] * ab), axis=1)))


#: Pieces `JacoPlanner.motion_ik` follows the object's motion in.
MOTION_PIECES = 10
#: [rad] the most a joint may move over one piece of the motion: more is a change of the
#: arm's inverse-kinematics branch (a tenth of a door's swing turns the joints by at most
#: about half a radian), which the arm cannot make while it holds the handle.
BRANCH_JUMP = 1.0
#: [rad] two joint solutions no joint of which differs by this much are the same posture.
SAME_SOLUTION = 0.2


class PlanningError(CapError):
    """No collision-free joint path to the goal was found."""


def import_mink() -> Any:
    """The mink module (the Jaco's paths need it); CapError saying how to install it if absent."""
    try:
        import mink
    except ImportError:
        raise CapError("the Jaco's paths need mink: pip install 'constraint-aware[arm]'") from None
    return mink


@dataclass(frozen=True)
class PlannerConfig:
    """mink's differential IK as a path planner. Units in brackets."""

    joint_speed: float = 0.6  # [rad/s] each arm joint
    clearance: float = 0.02  # [m] kept between the arm and the object (as the robot sees it)
    detection: float = 0.15  # [m] collision pairs closer than this are constrained
    position_tolerance: float = 0.003  # [m] the goal pose is reached within this ...
    rotation_tolerance: float = 0.02  # [rad] ... and this
    joint_tolerance: float = 0.01  # [rad] a joint goal is reached within this, each joint
    max_periods: int = 300  # iterations (control periods of joint motion) before giving up
    orientation_cost: float = 0.5  # [-] relative to the position's 1
    posture_cost: float = 1e-3  # [-] toward the start configuration (regularization)
    damping: float = 1e-3


class JacoPlanner:
    """Joint paths for the Jaco standing at `base` (3,) [m] around the object the robot
    believes in (`set_object`), by mink (module docstring)."""

    def __init__(self, base: FloatArray, config: PlannerConfig | None = None) -> None:
        self.base = np.asarray(base, dtype=float)
        self.config = config or PlannerConfig()
        self.fingers = 0.2  # [rad] the fingers' angle in the planning model (the hand's shape)
        self._model: mujoco.MjModel | None = None
        self._task: TaskConfig | None = None
        self._joint = 0.0

    def set_object(self, task: TaskConfig, joint_position: float = 0.0) -> None:
        """The object as the robot believes it: `task`'s object (built from the demonstration)
        with its joint at `joint_position` [m or rad]."""
        self._joint = float(joint_position)
        if task == self._task:  # the same object moved: its model stands
            return
        self._model = build_spec(task, self.base, solid_for_arms=True).compile()
        self._task = task
        m = self._model
        self._arm_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in ARM_JOINTS])
        self._arm_dof = np.array([m.jnt_dofadr[m.joint(j).id] for j in ARM_JOINTS])
        frozen = [m.jnt_dofadr[m.joint(j).id] for j in FINGER_JOINTS]
        self._finger_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in FINGER_JOINTS])
        frozen.append(int(m.jnt_dofadr[m.joint(OBJECT_PREFIX + "object_joint").id]))
        self._frozen = frozen
        self._object_qpos = int(m.jnt_qposadr[m.joint(OBJECT_PREFIX + "object_joint").id])
        robot = [g for g in range(m.ngeom) if m.body(m.geom_bodyid[g]).name.startswith("jaco/")]
        scene = [g for g in range(m.ngeom) if m.geom(g).name.startswith(OBJECT_PREFIX)]
        # and the hand against the arm's base links: a way home can fold the arm onto itself
        hand = [g for g in robot if "/hand/" in m.body(m.geom_bodyid[g]).name]
        base_links = ("jaco/b_base", "jaco/b_1", "jaco/b_2")
        links = [g for g in robot if m.body(m.geom_bodyid[g]).name in base_links]
        self._pairs = [
            ([m.geom(g).name for g in robot], [m.geom(g).name for g in scene]),
            ([m.geom(g).name for g in hand], [m.geom(g).name for g in links]),
        ]
        # the arm's links: the base stands on the floor, away from the object
        self._robot_geoms = [g for g in robot if m.body(m.geom_bodyid[g]).name != "jaco/b_base"]
        self._scene_geoms = scene
        handle_body = m.body(OBJECT_PREFIX + "object").id
        self._furniture_geoms = [
            g
            for g in scene
            if not (m.geom_bodyid[g] == handle_body and m.geom_group[g] != VISUAL_GROUP)
        ]
        self._scratch = mujoco.MjData(m)
        self._tcp = m.site(TCP_SITE).id
        joints = [m.joint(j).id for j in ARM_JOINTS]
        self._limited = np.array([bool(m.jnt_limited[j]) for j in joints])
        self._range = np.array([m.jnt_range[j] for j in joints])

    @property
    def model(self) -> mujoco.MjModel:
        if self._model is None:
            raise CapError("JacoPlanner: set_object() first")
        return self._model

    def _full(self, q: FloatArray) -> FloatArray:
        """The planning model's qpos for arm angles `q`: the fingers and the object at rest
        inside their ranges (they are frozen), the object at its believed position."""
        m = self.model
        full = np.zeros(m.nq)
        for j in range(m.njnt):
            if m.jnt_limited[j]:
                full[m.jnt_qposadr[j]] = np.clip(0.0, *m.jnt_range[j])
        full[self._finger_qpos] = self.fingers
        full[self._arm_qpos] = q
        full[self._object_qpos] = self._joint
        return full

    def _configuration(self, q: FloatArray) -> Any:
        """mink's configuration of the planning model at arm angles `q`."""
        mink = import_mink()
        return mink.Configuration(self.model, self._full(q))

    def tool_pose(self, q: FloatArray) -> Pose:
        """The tool pose at joint angles `q` (6,) [rad] (forward kinematics)."""
        m = self.model
        d = self._scratch
        d.qpos[:] = self._full(q)
        mujoco.mj_kinematics(m, d)
        site = self._tcp
        return Pose(d.site_xpos[site].copy(), Rotation.from_matrix(d.site_xmat[site].reshape(3, 3)))

    def clearance(self, q: FloatArray, handle: bool = True) -> float:
        """[m] the smallest distance between an arm geom and the object at `q` (negative:
        inside), up to 0.5 m; without the handle's geoms unless `handle`."""
        m = self.model
        d = self._scratch
        d.qpos[:] = self._full(q)
        mujoco.mj_kinematics(m, d)
        scene = self._scene_geoms if handle else self._furniture_geoms
        best = 0.5
        for a in self._robot_geoms:
            for b in scene:
                best = min(best, mujoco.mj_geomDistance(m, d, a, b, 0.5, None))
        return float(best)

    def solve_ik(
        self,
        pose: Pose,
        near: FloatArray,
        handle: bool = True,
        clearance: float | None = None,
        margin: float = 0.0,
    ) -> FloatArray:
        """(6,) [rad] joint angles putting the tool at `pose`, clear of the object by at
        least `clearance` [m] (default the planner's; of everything but the handle unless
        `handle`: a grasp holds it, its fingers reach behind it) and at least `margin` [rad]
        from every joint limit, nearest (in joint space) to `near`; damped least squares from
        `near` and from the arm's usual elbow-up seeds. PlanningError when none."""
        seeds = self._seeds(pose, near)
        need = self.config.clearance if clearance is None else clearance
        found: list[FloatArray] = []
        for seed in seeds:
            q = self._ik_from(seed, pose)
            if q is None or self.limit_margin(q) < margin:
                continue
            if self.clearance(q, handle) >= need:
                found.append(q)
                if len(found) >= 3:  # enough to choose the nearest from
                    break
        if not found:
            raise PlanningError(
                "no collision-free joint angles reach the goal pose"
                + (f" {margin:g} rad inside the joint limits" if margin > 0 else "")
            )
        return min(found, key=lambda q: float(np.sum(_wrapped(q - near) ** 2)))

    def limit_margin(self, q: FloatArray) -> float:
        """[rad] the least distance of `q` (6,) [rad] from a joint limit (pi: none limited)."""
        return float(
            np.min(
                np.where(
                    self._limited,
                    np.minimum(q - self._range[:, 0], self._range[:, 1] - q),
                    math.pi,
                )
            )
        )

    def hidden(self, q: FloatArray, eye: FloatArray, points: FloatArray) -> int:
        """How many of `points` (N, 3) [m] the arm at joint angles `q` (6,) [rad] hides from a
        camera at `eye` (3,) [m]: the first surface on the line of sight is an arm's or hand's
        geom, nearer than the point."""
        m, d = self.model, self._scratch
        d.qpos[:] = self._full(q)
        mujoco.mj_kinematics(m, d)
        arm = set(self._robot_geoms)
        eye = np.asarray(eye, dtype=float)
        hit = np.array([-1], dtype=np.int32)
        count = 0
        for point in np.asarray(points, dtype=float):
            ray = point - eye
            distance = float(np.linalg.norm(ray))
            at = mujoco.mj_ray(m, d, eye, ray / distance, None, 1, -1, hit)
            count += int(hit[0] in arm and 0.0 <= at < distance)
        return count

    def _usual_solutions(self, pose: Pose) -> Iterator[FloatArray]:
        """The joint solutions (6,) [rad] for `pose` reached from the arm's usual elbow-up and
        elbow-down seeds turned toward it (`_seeds`), in the seeds' order."""
        for seed in self._seeds(pose, self._seeds(pose, np.zeros(6))[1])[1:]:
            q = self._ik_from(seed, pose)
            if q is not None:
                yield q

    def roomiest_ik(self, pose: Pose) -> FloatArray:
        """(6,) [rad] of the collision-free solutions for `pose` (everything but the handle),
        the one farthest from the joint limits (as the arm is placed at a grasp,
        sim.jaco.JacoSim._search_ik); PlanningError when none."""
        best, best_margin = None, -math.inf
        for q in self._usual_solutions(pose):
            if self.clearance(q, handle=False) < 0.0:
                continue
            margin = self.limit_margin(q)
            if margin > best_margin:
                best, best_margin = q, margin
        if best is None:
            raise PlanningError("no collision-free joint angles reach the grasp")
        return best

    def motion_ik(
        self, grasp: Pose, margin: float = 0.0, clear: bool = True
    ) -> tuple[FloatArray, float]:
        """The grasp's joint solution (6,) [rad] from which the arm follows the believed
        object's motion (`set_object`'s task, from its joint at 0 to its success progress,
        `motion_poses`) without leaving its inverse-kinematics branch, and the least
        joint-limit margin [rad] over that motion; of several, the one with the largest
        margin. The motion is followed in `MOTION_PIECES` pieces, each solved from the last
        (the arm moves continuously: it cannot change branch mid-motion); a piece whose
        solution jumps by more than `BRANCH_JUMP` in any joint, fails, comes within `margin`
        [rad] of a joint limit or, when `clear`, puts the arm into the furniture ends that
        candidate. PlanningError when no candidate follows the whole motion."""
        task = self._task
        if task is None:
            raise CapError("JacoPlanner: set_object() first")
        joint = self._joint
        fractions = tuple(i / MOTION_PIECES for i in range(MOTION_PIECES + 1))
        poses = motion_poses(task, grasp, fractions)
        best, best_margin = None, -math.inf
        tried: list[FloatArray] = []
        try:
            for q0 in self._usual_solutions(grasp):
                if any(largest_turn(q0, t) < SAME_SOLUTION for t in tried):
                    continue
                tried.append(q0)
                least = self._follow(q0, poses, fractions, task, margin, clear)
                if least is not None and least > best_margin:
                    best, best_margin = q0, least
        finally:
            self.set_object(task, joint)
        if best is None:
            raise PlanningError(
                f"no grasp posture follows the {task.name}'s motion {margin:g} rad inside the "
                "joint limits without changing its arm configuration"
            )
        return best, best_margin

    def pre_grasp_ik(self, pre: Pose, at_grasp: FloatArray, margin: float = 0.0) -> FloatArray:
        """(6,) [rad] the pre-grasp posture on the branch of `at_grasp` (6,) [rad]: solved from
        it (the approach is a short straight line the arm follows continuously), within
        `BRANCH_JUMP` of it in every joint, the planner's clearance from the believed object
        and `margin` [rad] from the joint limits; PlanningError otherwise."""
        q = self._ik_from(at_grasp, pre)
        if q is None or largest_turn(q, at_grasp) > BRANCH_JUMP:
            raise PlanningError("the pre-grasp is not on the grasp posture's arm configuration")
        if self.limit_margin(q) < margin or self.clearance(q) < self.config.clearance:
            raise PlanningError(
                "the pre-grasp on the grasp posture's arm configuration is too near a joint "
                "limit or the object"
            )
        return q

    def _follow(
        self,
        q: FloatArray,
        poses: list[Pose],
        fractions: tuple[float, ...],
        task: TaskConfig,
        margin: float,
        clear: bool,
    ) -> float | None:
        """The least joint-limit margin [rad] of the arm following `poses` from `q` (the
        first pose's solution), or None where `motion_ik`'s conditions fail."""
        least = math.inf
        for f, pose in zip(fractions, poses, strict=True):
            nxt = self._ik_from(q, pose)
            if nxt is None or largest_turn(nxt, q) > BRANCH_JUMP:
                return None
            q = nxt
            least = min(least, self.limit_margin(q))
            if least < margin:
                return None
            if clear:
                self.set_object(task, f * task.success_progress)
                if self.clearance(q, handle=False) < 0.0:
                    return None
        return least

    def ik_solutions(self, pose: Pose, near: FloatArray) -> list[FloatArray]:
        """Up to three collision-free joint solutions for `pose`, nearest to `near` first."""
        first = self.solve_ik(pose, near)
        found = [first]
        for seed in self._seeds(pose, near)[1:]:
            q = self._ik_from(seed, pose)
            if q is None or self.clearance(q) < self.config.clearance:
                continue
            if all(largest_turn(q, f) > SAME_SOLUTION for f in found):
                found.append(q)
            if len(found) >= 3:
                break
        return sorted(found, key=lambda q: float(np.sum(_wrapped(q - near) ** 2)))

    def _seeds(self, pose: Pose, near: FloatArray) -> list[FloatArray]:
        """`near` and the arm's usual elbow-up and elbow-down seeds turned toward `pose`."""
        seeds = [np.asarray(near, dtype=float)]
        rel = pose.position - self.base
        yaw = -math.atan2(rel[1], rel[0])
        for dyaw in (0.0, 0.8, -0.8, 1.6, -1.6, math.pi):
            for q2, q3 in ((2.6, 1.2), (3.6, 5.0), (2.9, 1.7)):
                seeds.append(np.array([yaw + dyaw, q2, q3, 4.0, 0.0, 0.0]))
        return seeds

    def _ik_from(self, q: FloatArray, pose: Pose) -> FloatArray | None:
        m, d = self.model, self._scratch
        jacp, jacr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
        lo, hi = self._range[:, 0], self._range[:, 1]
        target_rot = pose.orientation.as_matrix()
        best = math.inf
        full = self._full(q)  # the frozen joints' part, the same every iteration
        for i in range(200):
            full[self._arm_qpos] = q
            d.qpos[:] = full
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            rot = d.site_xmat[self._tcp].reshape(3, 3)
            err = np.concatenate(
                [pose.position - d.site_xpos[self._tcp], rotvec(target_rot @ rot.T)]
            )
            if float(np.linalg.norm(err[:3])) < 1e-4 and float(np.linalg.norm(err[3:])) < 1e-3:
                return np.asarray(q, dtype=float)
            size = float(np.linalg.norm(err))
            if i % 25 == 24:  # no progress over 25 iterations: out of reach from this seed
                if size > 0.9 * best:
                    return None
                best = size
            mujoco.mj_jacSite(m, d, jacp, jacr, self._tcp)
            jac = np.vstack([jacp, jacr])[:, self._arm_dof]
            step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err)
            q = q + np.clip(step, -0.3, 0.3)
            q = np.where(self._limited, np.clip(q, lo, hi), q)
        return None

    def plan(
        self,
        start: FloatArray,
        goal: Pose | FloatArray,
        speed: float,
        turn_rate: float,
        period: float,
    ) -> list[tuple[Pose, FloatArray]]:
        """Waypoints (one per control period) from joint angles `start` (6,) [rad] to a tool
        pose (through the nearest collision-free inverse-kinematics solution) or to joint
        angles `goal`: mink's differential IK toward the goal angles under the joint limits,
        the joint speed limit and collision avoidance; PlanningError when it does not arrive
        within `max_periods`."""

        start = np.asarray(start, dtype=float)
        targets = (
            self.ik_solutions(goal, start) if isinstance(goal, Pose) else [np.asarray(goal, float)]
        )
        failures = []
        for target in targets:
            try:
                path = self._joint_path(start, target, period)
                return self._retime(path, speed, turn_rate, period)
            except PlanningError as exc:
                failures.append(str(exc))
        raise PlanningError("; ".join(failures))

    def _joint_path(self, start: FloatArray, target: FloatArray, period: float) -> list[FloatArray]:
        """Joint angles per control period from `start` to `target` (mink, module docstring)."""
        mink = import_mink()

        c = self.config
        # the goal's angles unwrapped next to the start's (continuous joints: no full turns)
        target = start + _wrapped(target - start)
        m = self.model
        cfg = self._configuration(start)
        posture = mink.PostureTask(m, cost=1.0)
        posture.set_target(self._full(target))
        speeds = {m.joint(j).name: c.joint_speed for j in ARM_JOINTS}
        limits = [
            mink.ConfigurationLimit(m),
            mink.VelocityLimit(m, speeds),
            mink.CollisionAvoidanceLimit(
                m, self._pairs, minimum_distance_from_collisions=c.clearance,
                collision_detection_distance=c.detection,
            ),
        ]  # fmt: skip
        freeze = [mink.DofFreezingTask(m, dof_indices=self._frozen)]
        path = [start.copy()]
        for _ in range(c.max_periods):
            q = cfg.q[self._arm_qpos]
            if bool(np.all(np.abs(q - target) < c.joint_tolerance)):
                break
            velocity = mink.solve_ik(
                cfg, [posture], period, "daqp", damping=c.damping, limits=limits, constraints=freeze
            )
            cfg.integrate_inplace(velocity, period)
            path.append(cfg.q[self._arm_qpos].copy())
        else:
            left = float(np.max(np.abs(cfg.q[self._arm_qpos] - target)))
            raise PlanningError(
                f"no collision-free joint path to the goal within {c.max_periods} periods "
                f"(stopped {left:.2f} rad from it)"
            )
        path.append(target)
        return path

    def _retime(
        self, path: list[FloatArray], speed: float, turn_rate: float, period: float
    ) -> list[tuple[Pose, FloatArray]]:
        """The joint path resampled so that the tool point moves at most `speed` [m/s] and
        turns at most `turn_rate` [rad/s]; each period's tool pose with its joint angles."""
        qs = np.asarray(path)
        poses = [self.tool_pose(q) for q in qs]
        out: list[tuple[Pose, FloatArray]] = []
        for i in range(1, len(qs)):
            a, b = poses[i - 1], poses[i]
            dist = float(np.linalg.norm(b.position - a.position))
            turn = float((b.orientation * a.orientation.inv()).magnitude())
            n = max(1, math.ceil(max(dist / (speed * period), turn / (turn_rate * period))))
            for k in range(1, n + 1):
                q = qs[i - 1] + (k / n) * (qs[i] - qs[i - 1])
                out.append((self.tool_pose(q), q))
        if not out:
            out.append((poses[0], qs[0]))
        return out


def _wrapped(a: FloatArray) -> FloatArray:
    return np.asarray((a + np.pi) % (2 * np.pi) - np.pi)


def largest_turn(a: FloatArray, b: FloatArray) -> float:
    """[rad] the most any joint turns between joint angles `a` and `b` (6,), each difference
    wrapped into [-pi, pi)."""
    return float(np.max(np.abs(_wrapped(a - b))))


#: Placements (distance [m], azimuth [deg], height [m], sim.jaco.arm_base) tried for the base
#: when the kind's own (`BASE_PLACEMENT`) cannot reach the demonstrated motion, nearest first.
BASE_CANDIDATES: tuple[tuple[float, float, float], ...] = tuple(
    (reach, azimuth, height)
    for reach in (0.45, 0.35)
    for azimuth in (45.0, -45.0, 90.0, -90.0, 0.0)
    for height in (-0.2,)
)


#: Turns [rad] of the Jaco's hand about its approach tried in order at a knob (its grasp: the
#: palm on top, the fingers closing on two opposite sides of the knob's box): the kind's own
#: hand mount first, then across it (the fingers off the line from the knob to the hub, on
#: the box's other two sides), then reversed (the same sides). Near its hub a knob leaves no
#: room for the finger the mount curls toward the hub (it meets the crank's arm or hub).
#: Every other handle is held one way: its own mount.
KNOB_ROLLS = (0.0, 0.5 * math.pi, -0.5 * math.pi, math.pi)


def grasp_rolls(handle: str) -> tuple[float, ...]:
    """The turns [rad] about the approach a grasp of `handle` may take (`KNOB_ROLLS`)."""
    return KNOB_ROLLS if handle == "knob" else (0.0,)


def rolled(pose: Pose, roll: float) -> Pose:
    """`pose` turned by `roll` [rad] about its own approach (the tool's z axis)."""
    return Pose(pose.position, pose.orientation * Rotation.from_rotvec([0.0, 0.0, roll]))


def motion_poses(task: TaskConfig, grasp: Pose, fractions: tuple[float, ...]) -> list[Pose]:
    """The tool poses that move with the handle from `grasp` at joint position 0 to the
    given fractions of `task`'s success progress (a hinge turns the hand with it)."""
    obj = task.object
    axis = np.asarray(obj.axis, dtype=float)
    out = []
    for f in fractions:
        q = f * task.success_progress
        if obj.joint_type == "prismatic":
            out.append(grasp.moved(q * axis))
        else:
            turn = Rotation.from_rotvec(q * axis)
            pivot = np.asarray(obj.position, dtype=float)
            position = pivot + turn.apply(grasp.position - pivot)
            out.append(Pose(position, turn * grasp.orientation))
    return out


@dataclass(frozen=True)
class View:
    """What the robot's head camera must see from the robot's home: `points` (N, 3) [m] from
    the camera's position `eye` (3,) [m]."""

    eye: FloatArray
    points: FloatArray


def choose_base(
    task: TaskConfig,
    pre_grasp: float = 0.10,
    home: tuple[float, float] | None = None,
    view: View | None = None,
) -> tuple[FloatArray, tuple[float, float, float], float]:
    """Where the Jaco stands for `task` (the object as the robot believes it), and how its
    hand turns about the approach: the kind's placement (sim.jaco.BASE_PLACEMENT) if from it
    the arm reaches what `reaches_from` asks, else the first of `BASE_CANDIDATES` that does,
    with the hand at the kind's mount; else the same with the next of the handle's
    `grasp_rolls`. CapError when none does. Returns the base (3,) [m], the placement and the
    roll [rad]."""
    kind = (task.object.joint_type, task.object.handle)
    first = [BASE_PLACEMENT[kind]] if kind in BASE_PLACEMENT else []
    grasp = _grasp(task)
    rolls = grasp_rolls(task.object.handle)
    for roll in rolls:
        for placement in [*first, *BASE_CANDIDATES]:
            base = arm_base(task, placement)
            if reaches_from(task, base, pre_grasp, home, grasp, view, roll):
                return base, placement, roll
    turns = f" with the hand turned {len(rolls)} ways" if len(rolls) > 1 else ""
    raise CapError(
        f"the Jaco reaches the demonstrated motion of the {task.name} from none of "
        f"{len(BASE_CANDIDATES) + len(first)} base placements{turns}"
    )


def _grasp(task: TaskConfig) -> Pose:
    """The Jaco's tool pose at `task`'s grasp (its hand mount, from the kind's placement)."""
    kind = (task.object.joint_type, task.object.handle)
    return JacoSim(
        task, base=arm_base(task, BASE_PLACEMENT.get(kind, BASE_CANDIDATES[0]))
    ).grasp_pose()


def reaches_from(
    task: TaskConfig,
    base: FloatArray,
    pre_grasp: float = 0.10,
    home: tuple[float, float] | None = None,
    grasp: Pose | None = None,
    view: View | None = None,
    roll: float = 0.0,
) -> bool:
    """Whether the Jaco standing at `base` (3,) [m] reaches `task`'s object as the robot
    believes it: clear of the object (as `JacoPlanner` checks), the pre-grasp `pre_grasp` [m]
    back from the grasp, and the grasp at the start, half-way and the end of the motion with
    the object moved that far (clear of everything but the handle it holds), and, given
    `home` (forward, up) [m] from the base toward the handle, a home tool pose clear of the
    object closed and at the motion's end, from which, given `view`, the arm hides none of
    the view's points from the camera (the robot looks from home). `grasp`: the tool pose at
    the grasp at the kind's hand mount, if known; `roll` [rad]: the hand's turn about its
    approach from that mount (`grasp_rolls`).

    The hand is modelled as it reaches: pre-shaped for the object's handle
    (`JACO_PRESHAPE`). The pre-grasp and the motion must be reached `OscConfig.limit_margin`
    inside the joint limits: there the controller's joint-limit repulsion starts, and a
    posture inside it is one the arm does not hold (it stops short of the grasp)."""
    grasp = rolled(grasp or _grasp(task), roll)
    approach = grasp.orientation.apply([0.0, 0.0, 1.0])
    pre = grasp.moved(-pre_grasp * approach)
    fractions = (0.0, 0.5, 1.0)
    margin = OscConfig().limit_margin
    planner = JacoPlanner(base)
    planner.fingers = JACO_PRESHAPE[task.object.handle]
    try:
        planner.set_object(task)
        q = planner.solve_ik(pre, facing(base, pre.position), margin=margin)
        for f, pose in zip(fractions, motion_poses(task, grasp, fractions), strict=True):
            planner.set_object(task, f * task.success_progress)
            q = planner.solve_ik(pose, q, handle=False, clearance=0.0, margin=margin)
        if home is not None:
            tool = home_pose(base, grasp, home)
            for f in (1.0, 0.0):  # the last: closed, as the robot sees it
                planner.set_object(task, f * task.success_progress)
                q = planner.solve_ik(tool, facing(base, tool.position))
            if view is not None and planner.hidden(q, view.eye, view.points) > 0:
                return False
    except PlanningError:
        return False
    return True


def home_pose(base: FloatArray, grasp: Pose, home: tuple[float, float]) -> Pose:
    """The Jaco's home tool pose: `home` = (forward, up) [m] from `base` (3,) horizontally
    toward the grasp and up, the hand oriented as at the grasp."""
    up = np.array([0.0, 0.0, 1.0])
    toward = grasp.position - base
    toward = toward - float(toward @ up) * up
    toward = toward / max(float(np.linalg.norm(toward)), 1e-9)
    return Pose(base + home[0] * toward + home[1] * up, grasp.orientation)


def facing(base: FloatArray, point: FloatArray) -> FloatArray:
    """(6,) [rad] an elbow-up seed turned toward `point` from `base`."""
    rel = np.asarray(point) - base
    return np.array([-math.atan2(rel[1], rel[0]), 2.9, 1.7, 4.0, 0.0, 0.0])
