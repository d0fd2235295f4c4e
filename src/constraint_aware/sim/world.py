"""Embodiment 1: the project's two-finger hook hand on six virtual Cartesian impedance joints.

`ManipulationSim` satisfies the executor's `Robot` protocol (wrench, pose, command, advance;
sim/robot_adapter.py) and its `TaskMonitor` protocol (admissible direction, progress, slip,
success; sim/monitor.py) without importing the executor. This module holds only what is
specific to this hand: its model (`build_spec`: the scene with the hand composed in), the
pose <-> arm-joint mapping of its virtual arm, and where it holds each handle. The grasp
choreography is sim/grasp.py.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.geometry import FloatArray
from constraint_aware.sim.embodiment import Embodiment
from constraint_aware.sim.hand import (
    ARM_JOINTS,
    FINGER_JOINTS,
    FORCE_SENSOR,
    HAND_GEOM_PREFIX,
    TCP_SITE,
    TORQUE_SENSOR,
    WRIST_SITE,
    hand_spec,
)
from constraint_aware.sim.robot_adapter import (
    CONTROL_PERIOD,
    FILTER_STEPS,
    RAMP_CHUNKS,
    SETTLE_TIME,
    TIMESTEP,
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
    "build_mjcf",
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


def build_mjcf(task: TaskConfig) -> str:
    """The complete MJCF of a task (the composed spec, written out)."""
    return str(build_spec(task).to_xml())


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
        self.model = model if model is not None else build_spec(task).compile()
        self.data = mujoco.MjData(self.model)
        self.control_period_s = control_period
        m = self.model
        # names -> ids, once
        h = HOOK_PREFIX
        self._arm_qpos = np.array([m.jnt_qposadr[m.joint(h + j).id] for j in ARM_JOINTS])
        self._finger_qpos = np.array([m.jnt_qposadr[m.joint(h + j).id] for j in FINGER_JOINTS])
        self._arm_act = np.array([m.actuator(h + j).id for j in ARM_JOINTS])
        self._finger_act = np.array([m.actuator(h + j).id for j in FINGER_JOINTS])
        self._bind_sensor(h + WRIST_SITE, h + TCP_SITE, h + FORCE_SENSOR, h + TORQUE_SENSOR)
        names = [m.geom(i).name for i in range(m.ngeom)]
        hand = {i for i, n in enumerate(names) if n.startswith(h + HAND_GEOM_PREFIX)}
        self._bind_monitor(hand, OBJECT_PREFIX)
        self._mount = Rotation.from_matrix(task.hand_mount())
        self._tcp_local = np.array([0.0, 0.0, task.hand.tcp_depth])
        self._target = np.zeros(6)

    # --- pose <-> arm joints --------------------------------------------------------------
    def _joint_targets(self, pose: Pose) -> FloatArray:
        wrist = pose.position - pose.orientation.apply(self._tcp_local)
        yaw, pitch, roll = (pose.orientation * self._mount.inv()).as_euler("ZYX")
        return np.array([*wrist, yaw, pitch, roll])

    def _set_arm_ctrl(self, q: FloatArray) -> None:
        self.data.ctrl[self._arm_act] = q

    def _unwrapped(self, q: FloatArray) -> FloatArray:
        """Joint targets with angles unwrapped next to the current ones (no 2 pi spins)."""
        q = q.copy()
        q[3:] = self._target[3:] + (q[3:] - self._target[3:] + np.pi) % (2 * np.pi) - np.pi
        return q

    def _apply_setpoint(self, pose: Pose) -> None:
        self._target = self._unwrapped(self._joint_targets(pose))
        self._set_arm_ctrl(self._target)

    def _rest_at_measured(self) -> None:
        self._target = self.data.qpos[self._arm_qpos].copy()
        self._set_arm_ctrl(self._target)

    def commanded_pose(self) -> Pose:
        q = self._target
        orientation = Rotation.from_euler("ZYX", q[3:]) * self._mount
        return Pose(q[:3] + orientation.apply(self._tcp_local), orientation)

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
        q = self._joint_targets(pose)
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
        q = self._joint_targets(pose)
        d.qpos[self._arm_qpos] = q
        self._target = q
        d.qpos[self._finger_qpos] = [self.task.finger_angle, -self.task.finger_angle]
        d.ctrl[self._finger_act] = [self.task.finger_angle, -self.task.finger_angle]
