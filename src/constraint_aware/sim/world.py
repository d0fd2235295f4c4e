"""Embodiment 1: the project's two-finger hook hand on six virtual Cartesian impedance joints.

`ManipulationSim` satisfies the executor's `Robot` protocol (wrench, pose, command, advance;
sim/robot_adapter.py) and its `TaskMonitor` protocol (admissible direction, progress, slip,
success; sim/monitor.py) without importing the executor. This module holds only what is
specific to this hand: its model (`build_spec`: the scene with the hand composed in), the
pose <-> arm-joint mapping of its virtual arm, and where it holds each handle. The grasp
choreography is sim/grasp.py.

A task's compiled model is built once per process and shared by every simulation of that
task (`build_model`): runs of the same task configuration (a sweep's controllers on one seed's
draw) each get their own `MjData` on it.
"""

from __future__ import annotations

import functools
import math

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.geometry import FloatArray
from constraint_aware.sim.base import Embodiment
from constraint_aware.sim.hand import (
    ARM_JOINTS,
    FINGER_JOINTS,
    FORCE_SENSOR,
    HAND_BODY,
    HAND_GEOM_PREFIX,
    TCP_SITE,
    TORQUE_SENSOR,
    WRIST_SITE,
    hand_spec,
)
from constraint_aware.sim.objects import OBJECT_BODY
from constraint_aware.sim.robot_adapter import (
    CONTROL_PERIOD,
    FILTER_STEPS,
    RAMP_CHUNKS,
    RAMP_FRACTIONS,
    SETTLE_TIME,
    TIMESTEP,
    add_wrench_filter,
    consecutive,
)
from constraint_aware.sim.scene import OBJECT_PREFIX, scene_spec
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose

__all__ = [
    "CONTROL_PERIOD",
    "FILTER_STEPS",
    "RAMP_CHUNKS",
    "SETTLE_TIME",
    "TIMESTEP",
    "ManipulationSim",
    "build_filtered_spec",
    "build_mjcf",
    "build_model",
    "build_spec",
]


HOOK_PREFIX = "hook:"  # the hook hand's names in the composed scene: "hook:arm_x", ...


def build_spec(task: TaskConfig, *, solid_for_arms: bool = False) -> mujoco.MjSpec:
    """A task's scene (sim/scene.py) with the hook hand on its virtual arm composed in
    (`solid_for_arms`: see `sim.objects.object_spec`; the hook hand's runs are the same)."""
    x, y, z, w = Rotation.from_matrix(task.hand_mount()).as_quat()

    def attach_hand(spec: mujoco.MjSpec) -> None:
        frame = spec.worldbody.add_frame()
        spec.attach(hand_spec(task.hand, (w, x, y, z)), prefix=HOOK_PREFIX, frame=frame)

    return scene_spec(task, attach_hand, solid_for_arms=solid_for_arms)


@functools.lru_cache(maxsize=32)
def _hand_mount(task: TaskConfig) -> Rotation:
    """The hand's mounting orientation on a task (`TaskConfig.hand_mount`), computed once per
    task configuration (a Rotation is immutable: runs share it)."""
    return Rotation.from_matrix(task.hand_mount())


def build_mjcf(task: TaskConfig) -> str:
    """The complete MJCF of a task (the composed spec, written out)."""
    return str(build_spec(task).to_xml())


@functools.lru_cache(maxsize=32)
def build_model(task: TaskConfig, *, solid_for_arms: bool = False) -> mujoco.MjModel:
    """The compiled model `ManipulationSim` runs: `build_spec` with the wrist sensor's filter
    (sim.robot_adapter.add_wrench_filter). Built once per task configuration and process and
    shared: do not modify it (copy it: `copy.copy(model)`)."""
    return build_filtered_spec(task, solid_for_arms=solid_for_arms).compile()


def build_filtered_spec(task: TaskConfig, *, solid_for_arms: bool = False) -> mujoco.MjSpec:
    """`build_model`'s spec before compiling (more can be composed in: a camera)."""
    spec = build_spec(task, solid_for_arms=solid_for_arms)
    h = HOOK_PREFIX
    add_wrench_filter(
        spec,
        tcp_site=h + TCP_SITE,
        hand_body=h + HAND_BODY,
        object_body=OBJECT_PREFIX + OBJECT_BODY,
    )
    return spec


class ManipulationSim(Embodiment):
    """One task in MuJoCo with the hook hand, from reset and grasp to per-period stepping.

    Typical use: `sim = ManipulationSim(task); sim.reset()` leaves the hand grasping the handle
    at rest; then the executor drives it through the `Robot` methods.
    """

    def __init__(
        self,
        task: TaskConfig,
        model: mujoco.MjModel | None = None,
        control_period: float = CONTROL_PERIOD,
    ) -> None:
        self.task = task
        self.model = model if model is not None else build_model(task)
        self.data = mujoco.MjData(self.model)
        self.control_period_s = control_period
        m = self.model
        # names -> ids, once
        h = HOOK_PREFIX
        self._arm_qpos = np.array([m.jnt_qposadr[m.joint(h + j).id] for j in ARM_JOINTS])
        self._finger_qpos = np.array([m.jnt_qposadr[m.joint(h + j).id] for j in FINGER_JOINTS])
        self._arm_act = np.array([m.actuator(h + j).id for j in ARM_JOINTS])
        self._arm_ctrl = consecutive(self._arm_act, "the hook hand's arm actuators")
        self._finger_act = np.array([m.actuator(h + j).id for j in FINGER_JOINTS])
        self._bind_sensor(h + WRIST_SITE, h + TCP_SITE, h + FORCE_SENSOR, h + TORQUE_SENSOR)
        names = [m.geom(i).name for i in range(m.ngeom)]
        hand = {i for i, n in enumerate(names) if n.startswith(h + HAND_GEOM_PREFIX)}
        self._bind_monitor(hand, OBJECT_PREFIX)
        self._mount = _hand_mount(task)
        self._mount_matrix = self._mount.as_matrix()
        self._tcp_local = np.array([0.0, 0.0, task.hand.tcp_depth])
        self._target = np.zeros(6)
        # `_ramp`'s work arrays: the I, K, K^2 terms and the [1, sin, 1 - cos] coefficients
        self._ramp_terms = np.zeros((3, 8))
        self._ramp_coefficients = np.ones((RAMP_CHUNKS, 3))

    # --- pose <-> arm joints --------------------------------------------------------------
    def _joint_targets(self, positions: FloatArray, rotations: FloatArray) -> FloatArray:
        """(k, 6) arm joint targets (wrist x, y, z [m]; yaw, pitch, roll [rad] of the hand
        relative to its mount, intrinsic ZYX, each in (-pi, pi]) for k TCP poses: positions
        (k, 3) [m], rotation matrices (k, 3, 3). (`_ramp` computes the same for a period's
        pieces.)"""
        wrist = positions - rotations @ self._tcp_local
        rel = rotations @ self._mount_matrix.T
        yaw = np.arctan2(rel[:, 1, 0], rel[:, 0, 0])
        pitch = np.arctan2(-rel[:, 2, 0], np.hypot(rel[:, 0, 0], rel[:, 1, 0]))
        roll = np.arctan2(rel[:, 2, 1], rel[:, 2, 2])
        return np.column_stack([wrist, yaw, pitch, roll])

    def _unwrapped(self, q: FloatArray) -> FloatArray:
        """Joint targets (k, 6) in sequence after the current ones, angles unwrapped (no 2 pi
        spins between consecutive targets); `q` is changed in place and returned."""
        angles = q[:, 3:]
        turns = np.empty_like(angles)
        turns[0] = angles[0] - self._target[3:]
        np.subtract(angles[1:], angles[:-1], out=turns[1:])
        turns = (turns + np.pi) % (2 * np.pi) - np.pi
        angles[:] = self._target[3:] + turns.cumsum(axis=0)
        return q

    def _set_arm_ctrl(self, q: FloatArray) -> None:
        self.data.ctrl[self._arm_ctrl] = q

    def _apply_setpoint_matrix(self, position: FloatArray, rotation: FloatArray) -> None:
        self._target = self._unwrapped(self._joint_targets(position[None], rotation[None]))[0]
        self._set_arm_ctrl(self._target)

    def _ramp(
        self, start: FloatArray, shift: FloatArray, start_rotation: FloatArray, turn: FloatArray
    ) -> None:
        """The period's pieces as joint targets, all at once; one `mj_step` call per piece.

        Piece i's rotation is exp(f_i turn) R0 = (I + sin(f_i a) K + (1 - cos(f_i a)) K^2) R0
        (Rodrigues; a = |turn|, K the cross-product matrix of its axis): the entries the joint
        targets read (five of R M^T for the angles, M the mount, and R t for the wrist, t the
        tool point on the hand) are one product [1, sin, 1 - cos] (pieces, 3) by their I, K,
        K^2 terms (3, 8)."""
        angle = math.sqrt(float(turn @ turn))
        relative = start_rotation @ self._mount_matrix.T
        tool = start_rotation @ self._tcp_local
        terms = self._ramp_terms
        terms[0, :5], terms[0, 5:] = relative[_EULER_ENTRIES], tool
        coefficients = self._ramp_coefficients
        if angle > 1e-12:
            k = _cross_matrix(turn / angle)
            k_relative, k_tool = k @ relative, k @ tool
            terms[1, :5], terms[1, 5:] = k_relative[_EULER_ENTRIES], k_tool
            terms[2, :5], terms[2, 5:] = (k @ k_relative)[_EULER_ENTRIES], k @ k_tool
            coefficients[:, 1] = np.sin(RAMP_FRACTIONS * angle)
            coefficients[:, 2] = 1.0 - np.cos(RAMP_FRACTIONS * angle)
        else:
            coefficients[:, 1:] = 0.0
        e = coefficients @ terms  # per piece: r10, r00, r20, r21, r22 of R M^T, then R t
        q = np.empty((RAMP_CHUNKS, 6))
        q[:, :3] = start + RAMP_FRACTIONS[:, None] * shift - e[:, 5:]
        q[:, 3] = np.arctan2(e[:, 0], e[:, 1])
        q[:, 4] = np.arctan2(-e[:, 2], np.hypot(e[:, 1], e[:, 0]))
        q[:, 5] = np.arctan2(e[:, 3], e[:, 4])
        targets = self._unwrapped(q)
        ctrl, arm = self.data.ctrl, self._arm_ctrl
        for target, n in zip(targets, self._piece_steps.tolist(), strict=True):
            ctrl[arm] = target
            self._step(n)
        self._target = targets[-1]

    def _rest_at_measured(self) -> None:
        self._target = self.data.qpos[self._arm_qpos].copy()
        self._set_arm_ctrl(self._target)

    def _setpoint(self) -> tuple[FloatArray, FloatArray]:
        q = self._target
        rotation = _zyx_matrix(q[3], q[4], q[5]) @ self._mount_matrix
        return q[:3] + rotation @ self._tcp_local, rotation

    @property
    def translational_stiffness(self) -> float:
        """[N/m] the wrist's Cartesian impedance stiffness (each axis)."""
        return self.task.hand.translational_stiffness

    # --- reset and grasp ------------------------------------------------------------------
    def grasp_pose(self) -> Pose:
        """The TCP pose at which the hand holds the handle (object at joint position 0)."""
        return self.grasp_pose_at(
            self.task.object.handle_position, self._mount, self.task.object.handle
        )

    def grasp_pose_at(self, point: FloatArray, orientation: Rotation, handle: str) -> Pose:
        """The TCP pose that holds a `handle` shape ("bar", "pole", "plate", "knob") whose
        grasp centre is `point` (3,) [m] with the hand at `orientation`: the TCP at a bar's or
        a pole's centre, the palm face on a knob's top face, the straight fingers' tip pads on
        a plate's top face."""
        pos = np.array(point, dtype=float)
        if handle == "knob":
            # palm face on the knob's top face: the TCP lies tcp_depth below it
            pos = pos + orientation.apply(self._tcp_local)
        elif handle == "plate":
            # fingertip pads (the distal plates' outer faces) on the plate's top face
            hand = self.task.hand
            tip_depth = hand.proximal_length + hand.finger_thickness
            pos = pos - orientation.apply([0.0, 0.0, tip_depth - hand.tcp_depth])
        return Pose(pos, orientation)

    def set_fingers(self, angle: float) -> None:
        """Finger servo targets [rad]: 0 straight, + closes toward the palm's centre line,
        - opens (the two fingers mirror each other)."""
        self.data.ctrl[self._finger_act] = [angle, -angle]

    def start_at(self, pose: Pose, finger_angle: float) -> None:
        """Reset the physics (object at rest at joint position 0) with the TCP at `pose` and
        the fingers at `finger_angle` [rad] (`set_fingers`), then settle for `settle_time`."""
        d = self.data
        mujoco.mj_resetData(self.model, d)
        q = self._joint_targets(pose.position[None], pose.orientation.as_matrix()[None])[0]
        d.qpos[self._arm_qpos] = q
        self._target = q
        self._set_arm_ctrl(q)
        d.qpos[self._finger_qpos] = [finger_angle, -finger_angle]
        self.set_fingers(finger_angle)
        mujoco.mj_forward(self.model, d)
        self._step(round(self.settle_time / TIMESTEP))
        self._settle_filter()

    def _place(self, pose: Pose) -> None:
        d = self.data
        q = self._joint_targets(pose.position[None], pose.orientation.as_matrix()[None])[0]
        d.qpos[self._arm_qpos] = q
        self._target = q
        d.qpos[self._finger_qpos] = [self.task.finger_angle, -self.task.finger_angle]
        d.ctrl[self._finger_act] = [self.task.finger_angle, -self.task.finger_angle]


#: The entries of R M^T the joint angles read: r10, r00 (yaw), r20 (pitch), r21, r22 (roll)
_EULER_ENTRIES = (np.array([1, 0, 2, 2, 2]), np.array([0, 0, 0, 1, 2]))


def _cross_matrix(v: FloatArray) -> FloatArray:
    """(3, 3) K with K u = v x u."""
    x, y, z = v.tolist()
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _zyx_matrix(yaw: float, pitch: float, roll: float) -> FloatArray:
    """(3, 3) the rotation of intrinsic ZYX angles [rad]: Rz(yaw) Ry(pitch) Rx(roll)."""
    cy, sy = math.cos(yaw), math.sin(yaw)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cr, sr = math.cos(roll), math.sin(roll)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )
