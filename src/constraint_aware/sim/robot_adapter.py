"""The executor's `Robot` protocol on a simulated embodiment, shared by every embodiment.

`SimulatedRobot` owns what does not depend on the arm: the control period, the wrist sensor's
filter and sign convention, the Cartesian interpolation of each period's setpoint, and the
`read_*`/`command_*`/`advance` methods. An embodiment says only how a TCP pose setpoint reaches
its controller (`_apply_setpoint`), how the physics advances (`_step`: plain `mj_step` for
servo-driven joints, a control law per substep for a torque-controlled arm), and how the grasp
is placed (`_place`, see sim/grasp.py).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose, Wrench

TIMESTEP = 0.002  # [s]
CONTROL_PERIOD = 0.1  # [s] paper 5.1: the direction is updated every 100 ms
RAMP_CHUNKS = 10  # the commanded pose is interpolated over the period in this many pieces
SETTLE_TIME = 0.4  # [s] after placing the hand, and again after re-targeting the wrist
FILTER_STEPS = 10  # the wrench is averaged over the last 10 substeps (20 ms) of a period


def rotation_matrix(rotvec: FloatArray) -> FloatArray:
    """(3, 3) the rotation of a rotation vector (3,) [rad] (Rodrigues; scipy's costs ~10x
    more per call, and the interpolator calls it every chunk)."""
    angle = math.sqrt(float(rotvec @ rotvec))
    if angle < 1e-12:
        return np.eye(3)
    x, y, z = rotvec / angle
    k = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def rotation_from_matrix(matrix: FloatArray) -> Rotation:
    """A Rotation from a MuJoCo rotation matrix (9,) or (3, 3), through MuJoCo's quaternion
    (scipy's from_matrix re-orthogonalizes and costs ~3x more; MuJoCo's are orthonormal)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(matrix, dtype=float).reshape(9))
    return Rotation.from_quat(quat[[1, 2, 3, 0]])  # (x, y, z, w): scipy's order


def period_substeps(period: float) -> int:
    """The number of `TIMESTEP` substeps in a control period `period` [s]: a whole number, at
    least `FILTER_STEPS` (the sensor's filter window lies inside the period)."""
    steps = round(period / TIMESTEP)
    if steps < FILTER_STEPS or not math.isclose(steps * TIMESTEP, period, rel_tol=1e-9):
        raise InvalidInputError(
            f"control_period {period} s; valid: a multiple of the {TIMESTEP * 1e3:g} ms "
            f"simulation step, at least {FILTER_STEPS * TIMESTEP * 1e3:g} ms"
        )
    return steps


def step_rise_time(stiffness: float, damping: float, mass: float) -> float:
    """[s] when a mass-spring-damper's response to a setpoint step first reaches 1 - 1/e
    (63.2 %) of the step: the time constant of its first-order approximation. stiffness
    [N/m or N m/rad], damping [N s/m or N m s/rad], mass [kg or kg m^2], all positive."""
    omega = math.sqrt(stiffness / mass)  # [rad/s] natural frequency
    zeta = damping / (2.0 * math.sqrt(stiffness * mass))

    def response(t: float) -> float:
        """The normalized step response at time t [s] (closed form)."""
        if abs(zeta - 1.0) < 1e-9:
            return 1.0 - (1.0 + omega * t) * math.exp(-omega * t)
        if zeta < 1.0:
            wd = omega * math.sqrt(1.0 - zeta * zeta)
            decay = math.exp(-zeta * omega * t)
            return 1.0 - decay * (
                math.cos(wd * t) + zeta / math.sqrt(1.0 - zeta * zeta) * math.sin(wd * t)
            )
        root = math.sqrt(zeta * zeta - 1.0)
        s1, s2 = -omega * (zeta - root), -omega * (zeta + root)
        return 1.0 - (s2 * math.exp(s1 * t) - s1 * math.exp(s2 * t)) / (s2 - s1)

    target = 1.0 - math.exp(-1.0)
    # the response rises monotonically up to its first crossing; bracket it, then bisect
    lo, hi = 0.0, 0.1 / omega
    while response(hi) < target:
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if response(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


class SimulatedRobot(ABC):
    """A MuJoCo hand on a compliant arm with a wrist F/T sensor, as the executor sees it.

    Subclasses set `model`, `data`, `task` and call `_bind_sensor(...)` in their constructor.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    task: TaskConfig
    _arm_act: FloatArray  # the arm's actuator ids (one per Cartesian axis for servo arms)
    _period_steps: int = round(CONTROL_PERIOD / TIMESTEP)
    settle_time: float = SETTLE_TIME  # [s] of each settling phase of the grasp (sim/grasp.py)
    _tracking_time_constant: float | None = None  # [s] fixed at reset (Embodiment.reset)

    def _bind_sensor(self, wrist_site: str, tcp_site: str, force: str, torque: str) -> None:
        """Resolve the sensor's names to ids once."""
        m = self.model
        self._wrist_site = m.site(wrist_site).id
        self._tcp_site = m.site(tcp_site).id
        fs, ts = m.sensor(force), m.sensor(torque)
        self._force_adr = slice(int(fs.adr[0]), int(fs.adr[0]) + 3)
        self._torque_adr = slice(int(ts.adr[0]), int(ts.adr[0]) + 3)
        self._filtered = np.zeros(6)
        self._touched = False
        self._next_pose: Pose | None = None

    # --- what an embodiment provides -------------------------------------------------------
    @abstractmethod
    def grasp_pose(self) -> Pose:
        """The TCP pose at which the hand holds the handle (object at joint position 0)."""

    @abstractmethod
    def _place(self, pose: Pose) -> None:
        """Put the arm's state at the grasp pose and the fingers at their grasp targets."""

    @abstractmethod
    def _apply_setpoint(self, pose: Pose) -> None:
        """Make `pose` the compliant controller's current TCP setpoint."""

    @abstractmethod
    def _rest_at_measured(self) -> None:
        """Set the setpoint to where the hand is (no preload from the grasp)."""

    @abstractmethod
    def commanded_pose(self) -> Pose:
        """The compliant controller's current setpoint."""

    @abstractmethod
    def in_contact(self) -> bool:
        """Whether the hand touches the object now."""

    @property
    @abstractmethod
    def translational_stiffness(self) -> float:
        """[N/m] the arm's Cartesian impedance stiffness along the motion."""

    def _axis_dynamics(self, data: mujoco.MjData) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Each Cartesian axis of the tool (x, y, z, then rotations about x, y, z) as a
        mass-spring-damper at `data`'s configuration (positions computed): (stiffness (6,)
        [N/m, N m/rad], damping (6,) [N s/m, N m s/rad], apparent mass (6,) [kg, kg m^2]).

        This default is for an arm of position servos, one per Cartesian axis (`_arm_dofs`,
        `_arm_act`: three slide joints, then three hinges): each servo's own gains (MuJoCo's
        kp, kv, plus the joint's damping) against its joint-space inertia (armature included).
        """
        m = self.model
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, data, full)
        acts = np.asarray(self._arm_act, dtype=int)
        dofs = m.jnt_dofadr[m.actuator_trnid[acts, 0]]
        stiffness = m.actuator_gainprm[acts, 0].copy()
        damping = -m.actuator_biasprm[acts, 2] + m.dof_damping[dofs]
        return stiffness, damping, full[dofs, dofs].copy()

    def axis_time_constants(self) -> FloatArray:
        """(6,) [s] each Cartesian axis's tracking time constant in free space at the current
        configuration, from the linear model (`step_rise_time` of `_axis_dynamics`)."""
        scratch = mujoco.MjData(self.model)  # the episode's own data stays untouched
        scratch.qpos[:] = self.data.qpos
        mujoco.mj_forward(self.model, scratch)
        axes = zip(*self._axis_dynamics(scratch), strict=True)
        return np.array([step_rise_time(*axis) for axis in axes])

    def _free_space_time_constant(self) -> float:
        """[s] the mean of the three translational axes' time constants at the current
        configuration. This default is exact for linear servos (the hook hand's); an arm with
        dry friction or coupled axes measures step responses instead (sim/jaco.py)."""
        return float(np.mean(self.axis_time_constants()[:3]))

    @property
    def tracking_time_constant(self) -> float:
        """[s] the time constant with which the tool point settles onto a commanded position
        in free space (the Robot protocol's optional member): the 63.2 % rise time of a step,
        averaged over the three translational axes (world x, y, z), at the grasp configuration,
        from the robot's own gains and masses (fixed when the embodiment is reset; before
        that, at the current state). One number for an anisotropic arm: the mean, because the
        executor credits tau x the hand's velocity to the lag along whatever direction it
        moves; the slowest axis over-credited it along faster ones (the Jaco's plate: 0.19 s
        reported, 0.12 s along the motion; the lag-aware self-check then saw F against the
        credited deflection). Rotations are not included: per-axis values of the linear model
        are in `axis_time_constants`."""
        if self._tracking_time_constant is None:
            return self._free_space_time_constant()
        return float(self._tracking_time_constant)

    #: whether the interpolator hands each piece to `_apply_setpoint_matrix` (a controller
    #: that works on matrices: no Rotation objects per piece) instead of `_apply_setpoint`
    setpoint_as_matrix: bool = False

    def _apply_setpoint_matrix(self, position: FloatArray, rotation: FloatArray) -> None:
        """`_apply_setpoint` from a position (3,) [m] and a rotation matrix (3, 3)."""
        self._apply_setpoint(Pose(position, Rotation.from_matrix(rotation)))

    def _step(self, n: int) -> None:
        """Advance the physics `n` substeps (override to run a control law per substep)."""
        mujoco.mj_step(self.model, self.data, nstep=n)

    def _set_setpoint_velocity(self, twist: FloatArray) -> None:
        """(6,) [m/s, rad/s] the interpolator's setpoint velocity (world frame) while it moves;
        zeros once it rests. Override when the controller damps relative to it."""
        del twist  # servo-driven joints (the hook hand's) damp against absolute velocity

    # --- Robot protocol ----------------------------------------------------------------------
    @property
    def control_period_s(self) -> float:
        """[s] the control period: exactly the time one `advance` simulates."""
        return self._period_steps * TIMESTEP

    @control_period_s.setter
    def control_period_s(self, period: float) -> None:
        self._period_steps = period_substeps(period)

    @property
    def control_period(self) -> float:
        return self.control_period_s

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
        self._filter_start()
        for _ in range(FILTER_STEPS):
            self._filter_step()
        self._filter_end()

    def _filter_start(self) -> None:
        self._acc = np.zeros(6)
        self._acc_touched = False
        self._acc_n = 0

    def _filter_step(self) -> None:
        """One substep inside the filter window: step, then sample wrench and contact."""
        self._step(1)
        self._acc += self._sample_wrench()
        self._acc_touched = self._acc_touched or self.in_contact()
        self._acc_n += 1

    def _filter_end(self) -> None:
        self._filtered = self._acc / self._acc_n
        self._touched = self._acc_touched

    def set_sensor_noise(
        self, rng: np.random.Generator, noise: float, bias: FloatArray | None = None
    ) -> None:
        """Gaussian noise `noise` [N] std per force axis (torque: noise / 10 [N m]) and a
        constant force bias (3,) [N] on every reading from now on."""
        self._noise_rng = rng
        self._noise = float(noise)
        self._bias = np.zeros(3) if bias is None else np.asarray(bias, dtype=float)

    def true_wrench(self) -> Wrench:
        """The wrist wrench averaged over the last 20 ms, without the sensor's noise and bias
        and without drawing from its noise generator (ground truth for fault studies)."""
        w = self._filtered
        return Wrench(force=w[:3].copy(), torque=w[3:].copy())

    def read_wrench(self) -> Wrench:
        """The wrist wrench averaged over the last 20 ms (a sensor's low-pass filter), with the
        sensor's noise and bias (`set_sensor_noise`)."""
        true = self.true_wrench()
        rng = getattr(self, "_noise_rng", None)
        if rng is None or (self._noise == 0.0 and not np.any(self._bias)):
            return true
        return Wrench(
            force=true.force + self._bias + self._noise * rng.normal(size=3),
            torque=true.torque + 0.1 * self._noise * rng.normal(size=3),
        )

    def read_pose(self) -> Pose:
        d = self.data
        rot = rotation_from_matrix(d.site_xmat[self._tcp_site])
        return Pose(d.site_xpos[self._tcp_site].copy(), rot)

    def command_pose(self, pose: Pose) -> None:
        self._next_pose = pose

    def hold(self) -> None:
        """Stop: hold the current measured pose (the executor calls this on every stop)."""
        self._next_pose = None
        self._rest_at_measured()

    def grasp_contact(self) -> bool | None:
        """The hand's contact sensing: any hand-object contact during the last 20 ms (a bar
        held loosely chatters, so one instant is not enough)."""
        return self._touched

    def advance(self) -> None:
        """One control period, exactly `control_period_s` of simulated time: the TCP pose
        setpoint moves along a straight line (orientation by slerp: about one fixed axis) from
        the last setpoint to the commanded one in `RAMP_CHUNKS` equal pieces, as an arm's
        Cartesian interpolator does, reaching the goal at the start of the last piece; the
        wrench is filtered over the period's last `FILTER_STEPS` substeps (20 ms)."""
        start = self.commanded_pose()
        goal = self._next_pose if self._next_pose is not None else start
        fractions = [i / RAMP_CHUNKS for i in range(1, RAMP_CHUNKS + 1)]
        if not self.setpoint_as_matrix:
            pair = Rotation.concatenate([start.orientation, goal.orientation])
            orientations = Slerp([0.0, 1.0], pair)(fractions)  # one call: slow per call
        steps = self._period_steps
        # substep at which each piece starts (equal pieces, to the nearest substep), and the end
        bounds = [round(i * steps / RAMP_CHUNKS) for i in range(RAMP_CHUNKS + 1)]
        filter_from = steps - FILTER_STEPS
        turn = (goal.orientation * start.orientation.inv()).as_rotvec()
        shift = goal.position - start.position
        first_rotation = start.orientation.as_matrix()
        self._set_setpoint_velocity(np.concatenate([shift, turn]) / (steps * TIMESTEP))
        self._filter_start()
        for i, f in enumerate(fractions, start=1):
            if i == RAMP_CHUNKS:
                self._set_setpoint_velocity(np.zeros(6))  # the setpoint rests at the goal
            position = start.position + f * shift
            if self.setpoint_as_matrix:
                # slerp: the turn's rotation vector scaled (the rotations of scipy's Slerp)
                self._apply_setpoint_matrix(position, rotation_matrix(f * turn) @ first_rotation)
            else:
                self._apply_setpoint(Pose(position, orientations[i - 1]))
            first, last = bounds[i - 1], bounds[i]
            plain = min(last, max(first, filter_from)) - first
            if plain > 0:
                self._step(plain)
            for _ in range(first + plain, last):
                self._filter_step()
        self._filter_end()
        self._next_pose = None
