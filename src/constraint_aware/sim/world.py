"""A task's MuJoCo world: model assembly, the grasp, and the robot + ground-truth interface.

`ManipulationSim` satisfies the executor's `Robot` protocol (wrench, pose, command, advance) and
its `TaskMonitor` protocol (admissible direction, progress, slip, success) without importing the
executor.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from constraint_aware.geometry import FloatArray, unit
from constraint_aware.sim.hand import (
    ARM_JOINTS,
    FINGER_JOINTS,
    FORCE_SENSOR,
    HAND_BODY,
    HAND_GEOM_PREFIX,
    TCP_SITE,
    TORQUE_SENSOR,
    WRIST_SITE,
    hand_actuators,
    hand_defaults,
    hand_mjcf,
    hand_sensors,
)
from constraint_aware.sim.objects import (
    HANDLE_SITE,
    OBJECT_BODY,
    OBJECT_GEOM_PREFIX,
    OBJECT_JOINT,
    object_mjcf,
)
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose, Wrench

TIMESTEP = 0.002  # [s]
CONTROL_PERIOD = 0.1  # [s] paper 5.1: the direction is updated every 100 ms
RAMP_CHUNKS = 10  # the commanded pose is interpolated over the period in this many pieces
SETTLE_TIME = 0.4  # [s] after placing the hand, and again after re-targeting the wrist
FILTER_STEPS = 10  # the wrench is averaged over the last 10 substeps (20 ms) of a period


def build_mjcf(task: TaskConfig) -> str:
    """The complete MJCF of a task: floor, light, camera, hand on its arm, object."""
    mount = Rotation.from_matrix(task.hand_mount())
    x, y, z, w = mount.as_quat()
    focus = task.object.handle_position
    return f"""
<mujoco model="{task.name}">
  <compiler angle="radian"/>
  <option timestep="{TIMESTEP}" integrator="implicitfast" cone="elliptic" impratio="5"/>
  <visual><global offwidth="640" offheight="480"/><quality shadowsize="2048"/></visual>
  <default>
    <default class="hand">{hand_defaults(task.hand)}</default>
  </default>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1=".85 .85 .85" rgb2=".75 .75 .75"
             width="256" height="256"/>
    <material name="grid" texture="grid" texrepeat="8 8"/>
  </asset>
  <worldbody>
    <light pos="{focus[0] + 1:.3f} {focus[1] - 1:.3f} 3" dir="-0.3 0.3 -1" directional="true"/>
    <geom name="scene_floor" type="plane" size="3 3 0.1" material="grid"
          contype="0" conaffinity="0"/>
    <camera name="overview" mode="targetbody" target="{OBJECT_BODY}"
            pos="{focus[0] + 0.9:.3f} {focus[1] - 0.9:.3f} {focus[2] + 0.7:.3f}"/>
    {
        hand_mjcf(task.hand, (w, x, y, z)).replace(
            f'name="{HAND_BODY}"', f'name="{HAND_BODY}" childclass="hand"'
        )
    }
    {object_mjcf(task.object)}
  </worldbody>
  <actuator>
    {hand_actuators(task.hand)}
  </actuator>
  <sensor>
    {hand_sensors()}
  </sensor>
</mujoco>"""


class ManipulationSim:
    """One task in MuJoCo, from reset and grasp to per-period stepping.

    Typical use: `sim = ManipulationSim(task); sim.reset()` leaves the hand grasping the handle
    at rest; then the executor drives it through the `Robot` methods.
    """

    def __init__(self, task: TaskConfig, model: mujoco.MjModel | None = None) -> None:
        self.task = task
        self.model = (
            model if model is not None else mujoco.MjModel.from_xml_string(build_mjcf(task))
        )
        self.data = mujoco.MjData(self.model)
        m = self.model
        # names -> ids, once
        self._arm_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in ARM_JOINTS])
        self._finger_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in FINGER_JOINTS])
        self._arm_act = np.array([m.actuator(j).id for j in ARM_JOINTS])
        self._finger_act = np.array([m.actuator(j).id for j in FINGER_JOINTS])
        self._obj_joint = m.joint(OBJECT_JOINT).id
        self._obj_qpos = int(m.jnt_qposadr[self._obj_joint])
        self._wrist_site = m.site(WRIST_SITE).id
        self._tcp_site = m.site(TCP_SITE).id
        self._handle_site = m.site(HANDLE_SITE).id
        fs, ts = m.sensor(FORCE_SENSOR), m.sensor(TORQUE_SENSOR)
        self._force_adr = slice(int(fs.adr[0]), int(fs.adr[0]) + 3)
        self._torque_adr = slice(int(ts.adr[0]), int(ts.adr[0]) + 3)
        names = [m.geom(i).name for i in range(m.ngeom)]
        self._hand_geoms = {i for i, n in enumerate(names) if n.startswith(HAND_GEOM_PREFIX)}
        self._object_geoms = {i for i, n in enumerate(names) if n.startswith(OBJECT_GEOM_PREFIX)}
        self._mount = Rotation.from_matrix(task.hand_mount())
        self._tcp_local = np.array([0.0, 0.0, task.hand.tcp_depth])
        self._target = np.zeros(6)
        self._grasp_rel: tuple[FloatArray, Rotation] | None = None
        self._filtered = np.zeros(6)
        self._touched = False
        self._next_pose: Pose | None = None

    # --- pose <-> arm joints --------------------------------------------------------------
    def _joint_targets(self, pose: Pose) -> FloatArray:
        wrist = pose.position - pose.orientation.apply(self._tcp_local)
        yaw, pitch, roll = (pose.orientation * self._mount.inv()).as_euler("ZYX")
        return np.array([*wrist, yaw, pitch, roll])

    def _set_arm_ctrl(self, q: FloatArray) -> None:
        self.data.ctrl[self._arm_act] = q

    # --- reset and grasp ------------------------------------------------------------------
    def grasp_pose(self) -> Pose:
        """The TCP pose at which the hand holds the handle (object at joint position 0)."""
        mount = self._mount
        pos = self.task.object.handle_position.copy()
        if self.task.object.handle == "knob":
            # palm face on the knob's top face: the TCP lies tcp_depth below it
            pos = pos + mount.apply(self._tcp_local)
        elif self.task.object.handle == "plate":
            # fingertip pads (the distal plates' outer faces) on the plate's top face
            hand = self.task.hand
            tip_depth = hand.proximal_length + hand.finger_thickness
            pos = pos - mount.apply([0.0, 0.0, tip_depth - hand.tcp_depth])
        return Pose(pos, mount)

    def reset(self) -> None:
        """Place the hand at the grasp, close the fingers, press if the grasp presses, settle,
        then re-target the wrist at its measured pose and settle again (F_d is read after)."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        pose = self.grasp_pose()
        q = self._joint_targets(pose)
        d.qpos[self._arm_qpos] = q
        d.qpos[self._finger_qpos] = [self.task.finger_angle, -self.task.finger_angle]
        d.ctrl[self._finger_act] = [self.task.finger_angle, -self.task.finger_angle]
        pressed = pose.moved(pose.orientation.apply([0.0, 0.0, self.task.press_depth]))
        self._target = self._joint_targets(pressed)
        self._set_arm_ctrl(self._target)
        mujoco.mj_forward(m, d)
        mujoco.mj_step(m, d, nstep=int(SETTLE_TIME / TIMESTEP))
        if self.task.press_depth == 0.0:
            # no press: let the wrist rest where it settled (notes: closing pre-loads it)
            self._target = d.qpos[self._arm_qpos].copy()
            self._set_arm_ctrl(self._target)
            mujoco.mj_step(m, d, nstep=int(SETTLE_TIME / TIMESTEP))
        self._settle_filter()
        self._grasp_rel = self._hand_in_handle()

    # --- Robot protocol -------------------------------------------------------------------
    @property
    def control_period(self) -> float:
        return CONTROL_PERIOD

    @property
    def translational_stiffness(self) -> float:
        """[N/m] the wrist's Cartesian impedance stiffness (each axis)."""
        return self.task.hand.translational_stiffness

    def _sample_wrench(self) -> FloatArray:
        """(6,) instantaneous (F_s, tau_s about the TCP), world frame."""
        d = self.data
        rot = d.site_xmat[self._wrist_site].reshape(3, 3)
        # MuJoCo reports the parent's (arm's) action on the hand; F_s is its opposite
        force = -rot @ d.sensordata[self._force_adr]
        torque_wrist = -rot @ d.sensordata[self._torque_adr]
        lever = d.site_xpos[self._wrist_site] - d.site_xpos[self._tcp_site]
        return np.concatenate([force, torque_wrist + np.cross(lever, force)])

    def _settle_filter(self) -> None:
        """Step `FILTER_STEPS` substeps, averaging the wrench as the sensor's filter does."""
        acc = np.zeros(6)
        touched = False
        for _ in range(FILTER_STEPS):
            mujoco.mj_step(self.model, self.data)
            acc += self._sample_wrench()
            touched = touched or self.in_contact()
        self._filtered = acc / FILTER_STEPS
        self._touched = touched

    def read_wrench(self) -> Wrench:
        """The wrist wrench averaged over the last 20 ms (a sensor's low-pass filter)."""
        w = self._filtered
        return Wrench(force=w[:3].copy(), torque=w[3:].copy())

    def read_pose(self) -> Pose:
        d = self.data
        rot = Rotation.from_matrix(d.site_xmat[self._tcp_site].reshape(3, 3))
        return Pose(d.site_xpos[self._tcp_site].copy(), rot)

    def commanded_pose(self) -> Pose:
        q = self._target
        orientation = Rotation.from_euler("ZYX", q[3:]) * self._mount
        return Pose(q[:3] + orientation.apply(self._tcp_local), orientation)

    def command_pose(self, pose: Pose) -> None:
        self._next_pose = pose

    def _unwrapped(self, q: FloatArray) -> FloatArray:
        """Joint targets with angles unwrapped next to the current ones (no 2 pi spins)."""
        q = q.copy()
        q[3:] = self._target[3:] + (q[3:] - self._target[3:] + np.pi) % (2 * np.pi) - np.pi
        return q

    def advance(self) -> None:
        """One control period: the TCP pose target moves along a straight line (orientation
        by slerp) from the last setpoint to the commanded one, as an arm's Cartesian
        interpolator does; the wrench is filtered over the period's last 20 ms."""
        start = self.commanded_pose()
        goal = self._next_pose if self._next_pose is not None else start
        slerp = Slerp([0.0, 1.0], Rotation.concatenate([start.orientation, goal.orientation]))
        n = round(CONTROL_PERIOD / TIMESTEP / RAMP_CHUNKS)
        for i in range(1, RAMP_CHUNKS + 1):
            f = i / RAMP_CHUNKS
            pose = Pose(start.position + f * (goal.position - start.position), slerp(f))
            self._target = self._unwrapped(self._joint_targets(pose))
            self._set_arm_ctrl(self._target)
            if i < RAMP_CHUNKS:
                mujoco.mj_step(self.model, self.data, nstep=n)
        mujoco.mj_step(self.model, self.data, nstep=n - FILTER_STEPS)
        self._settle_filter()
        self._next_pose = None

    # --- TaskMonitor protocol -------------------------------------------------------------
    def joint_position(self) -> float:
        return float(self.data.qpos[self._obj_qpos])

    def progress(self) -> float:
        return self.joint_position()

    def succeeded(self) -> bool:
        return self.progress() >= self.task.success_progress

    def admissible_direction(self) -> FloatArray:
        d = self.data
        axis = d.xaxis[self._obj_joint].copy()
        if self.task.object.joint_type == "prismatic":
            return unit(axis)
        radial = d.site_xpos[self._tcp_site] - d.xanchor[self._obj_joint]
        return unit(np.cross(axis, radial - (radial @ axis) * axis))

    def handle_position(self) -> FloatArray:
        return self.data.site_xpos[self._handle_site].copy()

    def _hand_in_handle(self) -> tuple[FloatArray, Rotation]:
        d = self.data
        h_rot = Rotation.from_matrix(d.site_xmat[self._handle_site].reshape(3, 3))
        t_rot = Rotation.from_matrix(d.site_xmat[self._tcp_site].reshape(3, 3))
        rel = h_rot.inv().apply(d.site_xpos[self._tcp_site] - d.site_xpos[self._handle_site])
        return rel, h_rot.inv() * t_rot

    def slip(self) -> tuple[float, float]:
        if self._grasp_rel is None:
            return 0.0, 0.0
        rel, rot = self._hand_in_handle()
        rel0, rot0 = self._grasp_rel
        return float(np.linalg.norm(rel - rel0)), float(np.degrees((rot0.inv() * rot).magnitude()))

    def grasp_contact(self) -> bool | None:
        """The hand's contact sensing: any hand-object contact during the last 20 ms (a bar
        held loosely chatters, so one instant is not enough)."""
        return self._touched

    def in_contact(self) -> bool:
        """Whether any hand geom touches any object geom."""
        d = self.data
        for i in range(d.ncon):
            g1, g2 = int(d.contact.geom1[i]), int(d.contact.geom2[i])
            if (g1 in self._hand_geoms and g2 in self._object_geoms) or (
                g2 in self._hand_geoms and g1 in self._object_geoms
            ):
                return True
        return False

    def grasp_failure(self) -> str | None:
        dist, ang = self.slip()
        if dist > self.task.slip_limit:
            return f"grasp lost: hand drifted {dist * 100:.1f} cm from the handle"
        limit = self.task.slip_angle_limit
        if limit is not None and ang > limit:
            return f"grasp lost: hand turned {ang:.0f} deg relative to the handle"
        return None
