"""The executor's `Robot` protocol on a simulated embodiment, shared by every embodiment.

`SimulatedRobot` owns what does not depend on the arm: the control period, the wrist sensor's
filter and sign convention, the Cartesian interpolation of each period's setpoint, and the
`read_*`/`command_*`/`advance` methods. An embodiment says only how a TCP pose setpoint reaches
its controller (`_apply_setpoint_matrix`, or a period's pieces all at once: `_ramp`), where
the setpoint is (`_setpoint`), how the physics advances (`_step`: plain `mj_step` for
servo-driven joints, a control law every few substeps for a torque-controlled arm), and how the
grasp is placed (`_place`, see sim/grasp.py).

The wrist sensor's filter is read from MuJoCo's own sensor history: the model carries, at the
tool point, force and torque sensors, the tool frame and the hand-object contacts as sensors
that keep their last `FILTER_STEPS` samples (`add_wrench_filter`), so a period is a few
`mj_step` calls and one read of that history, with no Python between the substeps. Rotations
are numpy matrices throughout; scipy's Rotation appears only where the `Robot` protocol's
`Pose` needs one.
"""

from __future__ import annotations

import functools
import math
from abc import ABC, abstractmethod

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import CapError, ConfigError, InvalidInputError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose, Wrench

TIMESTEP = 0.002  # [s]
CONTROL_PERIOD = 0.1  # [s] paper 5.1: the direction is updated every 100 ms
RAMP_CHUNKS = 10  # the commanded pose is interpolated over the period in this many pieces
SETTLE_TIME = 0.4  # [s] after placing the hand, and again after re-targeting the wrist
FILTER_STEPS = 10  # the wrench is averaged over the last 10 substeps (20 ms) of a period
#: where each piece of the period's setpoint ramp lies between the last setpoint and the goal
RAMP_FRACTIONS = np.arange(1, RAMP_CHUNKS + 1) / RAMP_CHUNKS


def rotation_matrix(rotvec: FloatArray) -> FloatArray:
    """(3, 3) the rotation of a rotation vector (3,) [rad] (Rodrigues)."""
    return rotation_matrices(np.asarray(rotvec, dtype=float).reshape(1, 3))[0]


def rotation_matrices(rotvecs: FloatArray) -> FloatArray:
    """(k, 3, 3) the rotations of k rotation vectors (k, 3) [rad] (Rodrigues, all at once)."""
    angles = np.sqrt(np.einsum("ki,ki->k", rotvecs, rotvecs))
    out = np.empty((len(rotvecs), 3, 3))
    out[:] = np.eye(3)
    turning = angles >= 1e-12
    if not turning.any():
        return out
    axes = rotvecs[turning] / angles[turning, None]
    x, y, z = axes.T
    zero = np.zeros_like(x)
    k = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=1).reshape(-1, 3, 3)
    sin = np.sin(angles[turning])[:, None, None]
    versine = (1.0 - np.cos(angles[turning]))[:, None, None]
    out[turning] += sin * k + versine * (k @ k)
    return out


def rotvec(rot: FloatArray) -> FloatArray:
    """(3,) rotation vector [rad] of a (3, 3) rotation matrix."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = rot.tolist()
    x, y, z = 0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)
    s = math.sqrt(x * x + y * y + z * z)
    angle = math.atan2(s, 0.5 * (r00 + r11 + r22 - 1.0))
    if s < 1e-9:
        return np.array([x, y, z])  # angle ~ 0: the rotation vector is v itself
    if angle > math.pi - 1e-3:
        return np.asarray(Rotation.from_matrix(rot).as_rotvec())  # near pi: v loses the axis
    f = angle / s
    return np.array([x * f, y * f, z * f])


def orientation_error(target: Rotation, matrix: FloatArray) -> FloatArray:
    """(3,) [rad] `(target * Rotation.from_matrix(matrix).inv()).as_rotvec()`: the world-frame
    rotation vector from an orientation `matrix` (9,) or (3, 3) to `target`, with the same floats.

    An inverse-kinematics iteration asks this once per step, where scipy's checks and
    dispatch cost ~100x the arithmetic: for a rotation matrix as MuJoCo computes them
    (orthonormal to far below scipy's 1e-12 test) the quaternion, the product and the rotation
    vector are computed in Python floats with scipy's formulas (its quaternion from an
    orthogonal matrix, its normalization, its small-angle series below 1e-3 rad); any other
    matrix goes to scipy, which orthonormalizes it first."""
    m = np.asarray(matrix, dtype=float).reshape(3, 3).tolist()
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = m
    gram_error = max(
        abs(m00 * m00 + m01 * m01 + m02 * m02 - 1.0),
        abs(m10 * m10 + m11 * m11 + m12 * m12 - 1.0),
        abs(m20 * m20 + m21 * m21 + m22 * m22 - 1.0),
        abs(m00 * m10 + m01 * m11 + m02 * m12),
        abs(m00 * m20 + m01 * m21 + m02 * m22),
        abs(m10 * m20 + m11 * m21 + m12 * m22),
    )
    det = (
        m00 * (m11 * m22 - m12 * m21)
        - m01 * (m10 * m22 - m12 * m20)
        + m02 * (m10 * m21 - m11 * m20)
    )
    if not (gram_error <= 1e-13 and det > 0.5):  # scipy decides (and orthonormalizes)
        current = Rotation.from_matrix(np.asarray(m))
        return np.asarray((target * current.inv()).as_rotvec())
    # the matrix's quaternion: scipy's case by the largest of the diagonal and the trace
    trace = m00 + m11 + m22
    decision = (m00, m11, m22, trace)
    choice = max(range(4), key=decision.__getitem__)  # the first largest, as np.argmax
    if choice == 3:
        r = [m21 - m12, m02 - m20, m10 - m01, 1 + trace]
    else:
        i = choice
        j = (i + 1) % 3
        k = (j + 1) % 3
        r = [0.0, 0.0, 0.0, 0.0]
        r[i] = 1 - trace + 2 * m[i][i]
        r[j] = m[j][i] + m[i][j]
        r[k] = m[k][i] + m[i][k]
        r[3] = m[k][j] - m[j][k]
    r0, r1, r2, r3 = _normalized(r)
    # target * the matrix's inverse (the conjugate quaternion): scipy's product, normalized
    p0, p1, p2, p3 = target.as_quat(canonical=False).tolist()
    q0, q1, q2, q3 = -r0, -r1, -r2, r3
    c0, c1, c2 = p1 * q2 - p2 * q1, p2 * q0 - p0 * q2, p0 * q1 - p1 * q0
    x, y, z, w = _normalized(
        [
            p3 * q0 + q3 * p0 + c0,
            p3 * q1 + q3 * p1 + c1,
            p3 * q2 + q3 * p2 + c2,
            p3 * q3 - p0 * q0 - p1 * q1 - p2 * q2,
        ]
    )
    # its rotation vector, from the quaternion with w >= 0
    if w < 0:
        x, y, z, w = -x, -y, -z, -w
    angle = 2 * math.atan2(math.sqrt(x * x + y * y + z * z), w)
    if angle <= 1e-3:  # scipy's series for angle / sin(angle / 2)
        angle2 = angle * angle
        scale = 2 + angle2 / 12 + 7 * angle2 * angle2 / 2880
    else:
        scale = angle / math.sin(angle / 2)
    return np.array([scale * x, scale * y, scale * z])


def _normalized(q: list[float]) -> tuple[float, float, float, float]:
    """A quaternion (4,) divided by its norm, as scipy normalizes."""
    x, y, z, w = q
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """(..., 3) a x b for (..., 3) vectors (np.cross's axis handling costs more than the
    product at this size)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def rotation_from_matrix(matrix: FloatArray) -> Rotation:
    """A Rotation from a MuJoCo rotation matrix (9,) or (3, 3), through MuJoCo's quaternion
    (scipy's from_matrix re-orthogonalizes and costs ~3x more; MuJoCo's are orthonormal)."""
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(matrix, dtype=float).reshape(9))
    return Rotation.from_quat(quat[[1, 2, 3, 0]])  # (x, y, z, w): scipy's order


#: The wrist sensor's filter reads these sensors, each keeping its last `FILTER_STEPS` samples:
#: (name suffix, MuJoCo sensor type). All sit at the tool point's site, on the hand's body:
#: the force and torque the arm exerts on the hand (about the tool point, in its frame), the
#: tool frame's axes and position (world), and then the hand-object contacts.
FILTER_SENSORS = (
    ("force", "FORCE"),
    ("torque", "TORQUE"),
    ("tcp_x", "FRAMEXAXIS"),
    ("tcp_y", "FRAMEYAXIS"),
    ("tcp_z", "FRAMEZAXIS"),
    ("tcp_pos", "FRAMEPOS"),
)
FILTER_CONTACT = "contact"  # name suffix of the hand-object contact sensor
FILTER_PREFIX = "filter_"  # the filter sensors' names: "filter_force", ...
#: Columns of `SimulatedRobot._filter_samples`: the sensors above in order (3 each), contacts
TCP_COLUMNS = slice(15, 18)  # the tool point's position
CONTACT_COLUMN = 18
#: The wrench in world frame as one product: R f = sum over a of f_a times the frame's axis a,
#: for force and torque; `_WRENCH_FACTORS` picks f_a, `_WRENCH_AXES` the axis' components.
_WRENCH_FACTORS = np.repeat(np.arange(6), 3)
_WRENCH_AXES = np.tile(np.arange(6, 15), 2)


def add_wrench_filter(
    spec: mujoco.MjSpec, *, tcp_site: str, hand_body: str, object_body: str
) -> None:
    """Give a composed robot-and-object spec the sensors the wrist sensor's filter reads
    (`FILTER_SENSORS` at the site `tcp_site`, which must be on the hand's body, and the number
    of contacts between the hand, `hand_body` and every body below it, and the object,
    `object_body`), each keeping its last `FILTER_STEPS` samples (MuJoCo's sensor history).
    Names are the composed spec's."""
    sensor = mujoco.mjtSensor
    for suffix, kind in FILTER_SENSORS:
        spec.add_sensor(
            name=FILTER_PREFIX + suffix,
            type=getattr(sensor, "mjSENS_" + kind),
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname=tcp_site,
            nsample=FILTER_STEPS,
        )
    spec.add_sensor(
        name=FILTER_PREFIX + FILTER_CONTACT,
        type=sensor.mjSENS_CONTACT,
        objtype=mujoco.mjtObj.mjOBJ_XBODY,  # the hand's subtree
        objname=hand_body,
        reftype=mujoco.mjtObj.mjOBJ_BODY,
        refname=object_body,
        intprm=[1, 0, 1],  # data "found" (the number of matching contacts), no reduction, 1
        nsample=FILTER_STEPS,
    )


def consecutive(index: FloatArray, what: str) -> slice:
    """A slice for consecutive indices (views instead of copies in the control loop);
    CapError naming `what` if they are not consecutive."""
    first = int(index[0])
    if not np.array_equal(index, np.arange(first, first + len(index))):
        raise CapError(f"{what} are not consecutive: {index}")
    return slice(first, first + len(index))


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


@functools.lru_cache(maxsize=1024)
def step_rise_time(stiffness: float, damping: float, mass: float) -> float:
    """[s] when a mass-spring-damper's response to a setpoint step first reaches 1 - 1/e
    (63.2 %) of the step: the time constant of its first-order approximation. stiffness
    [N/m or N m/rad], damping [N s/m or N m s/rad], mass [kg or kg m^2], all positive.

    Cached (a pure function of its three numbers, solved by bisection): every run of a task
    asks it for the same arm at the same grasp."""
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


def _history_index(model: mujoco.MjModel, names: list[str]) -> tuple[np.ndarray, int]:
    """Where the last `FILTER_STEPS` samples of the sensors `names` are in `MjData.history`:
    an index array (FILTER_STEPS, FILTER_STEPS, sum of the sensors' dims) [cursor, sample
    (oldest first), column] and the history address of the first sensor's cursor.

    MuJoCo keeps each sensor's samples in a ring: at its `sensor_historyadr` the last tick
    time, the cursor (the newest sample's slot), the samples' times, then the samples
    (`nsample` x dim). Every filter sensor records at every `mj_step`, so their cursors move
    together and one read of the first one locates all."""
    values, dims = [], []
    for name in names:
        try:
            sensor = model.sensor(name)
        except KeyError:
            raise ConfigError(
                "model",
                f"no sensor {name!r}",
                "a model built with sim.robot_adapter.add_wrench_filter",
            ) from None
        i = sensor.id
        n = int(model.sensor_history[i, 0])
        if n != FILTER_STEPS or model.sensor_delay[i] != 0 or model.sensor_interval[i, 0] != 0:
            raise ConfigError(
                f"model sensor {name}",
                f"nsample {n}, delay {model.sensor_delay[i]}, interval {model.sensor_interval[i]}",
                f"nsample {FILTER_STEPS}, no delay, no interval (add_wrench_filter)",
            )
        # the samples follow the last tick time, the cursor and the samples' times
        values.append(int(model.sensor_historyadr[i]) + 2 + FILTER_STEPS)
        dims.append(int(model.sensor_dim[i]))
    # per column: its sensor's samples' address, the sensor's dim, the column's place in it
    start = np.repeat(values, dims)
    dim = np.repeat(dims, dims)
    within = np.concatenate([np.arange(k) for k in dims])
    cursor = np.arange(FILTER_STEPS)[:, None, None]
    slot = (cursor + 1 + np.arange(FILTER_STEPS)[None, :, None]) % FILTER_STEPS  # oldest first
    index = start + slot * dim + within
    return index.astype(np.intp), values[0] - FILTER_STEPS - 1


class SimulatedRobot(ABC):
    """A MuJoCo hand on a compliant arm with a wrist F/T sensor, as the executor sees it.

    Subclasses set `model`, `data`, `task` and call `_bind_sensor(...)` in their constructor.
    """

    model: mujoco.MjModel
    data: mujoco.MjData
    task: TaskConfig
    _arm_act: FloatArray  # the arm's actuator ids (one per Cartesian axis for servo arms)
    _period_steps: int = round(CONTROL_PERIOD / TIMESTEP)
    _piece_steps: np.ndarray  # (RAMP_CHUNKS,) int: substeps of each of the period's pieces
    settle_time: float = SETTLE_TIME  # [s] of each settling phase of the grasp (sim/grasp.py)
    _tracking_time_constant: float | None = None  # [s] fixed at reset (Embodiment.reset)

    def _bind_sensor(self, wrist_site: str, tcp_site: str, force: str, torque: str) -> None:
        """Resolve the sensor's names to ids once, and where the filter's samples are in
        MuJoCo's history buffer (the model needs `add_wrench_filter`'s sensors)."""
        m = self.model
        self._wrist_site = m.site(wrist_site).id
        self._tcp_site = m.site(tcp_site).id
        fs, ts = m.sensor(force), m.sensor(torque)
        self._force_adr = slice(int(fs.adr[0]), int(fs.adr[0]) + 3)
        self._torque_adr = slice(int(ts.adr[0]), int(ts.adr[0]) + 3)
        names = [FILTER_PREFIX + f[0] for f in FILTER_SENSORS] + [FILTER_PREFIX + FILTER_CONTACT]
        self._filter_index, self._filter_cursor = _history_index(m, names)
        tcp_body, wrist_body = m.site_bodyid[self._tcp_site], m.site_bodyid[self._wrist_site]
        # the sensor carries its body's subtree: the hand's weight is in every reading
        self._hand_weight = float(m.body_subtreemass[wrist_body]) * np.array(m.opt.gravity)
        if m.sensor(names[0]).objid[0] != self._tcp_site or tcp_body != wrist_body:
            raise ConfigError(
                "model",
                f"the filter's sensors are not at {tcp_site!r} on the wrist sensor's body",
                "add_wrench_filter(spec, tcp_site=<the tool point on the hand's body>, ...)",
            )
        self._wrench_factors = self._filter_index[:, :, _WRENCH_FACTORS]
        self._wrench_axes = self._filter_index[:, :, _WRENCH_AXES]
        self._contact_index = self._filter_index[:, :, CONTACT_COLUMN]
        self._filtered = np.zeros(6)
        self._touched = False
        self._next_pose: Pose | None = None
        self._last_rotation: Rotation | None = None
        self._last_matrix = np.eye(3)

    # --- what an embodiment provides -------------------------------------------------------
    @abstractmethod
    def grasp_pose(self) -> Pose:
        """The TCP pose at which the hand holds the handle (object at joint position 0)."""

    @abstractmethod
    def _place(self, pose: Pose) -> None:
        """Put the arm's state at the grasp pose and the fingers at their grasp targets."""

    @abstractmethod
    def _apply_setpoint_matrix(self, position: FloatArray, rotation: FloatArray) -> None:
        """Make the TCP pose (position (3,) [m], rotation matrix (3, 3)) the compliant
        controller's current setpoint."""

    @abstractmethod
    def _setpoint(self) -> tuple[FloatArray, FloatArray]:
        """The compliant controller's current setpoint: position (3,) [m] and rotation matrix
        (3, 3), as the interpolator starts from it."""

    @abstractmethod
    def _rest_at_measured(self) -> None:
        """Set the setpoint to where the hand is (no preload from the grasp)."""

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

    def _apply_setpoint(self, pose: Pose) -> None:
        """Make `pose` the compliant controller's current TCP setpoint."""
        self._apply_setpoint_matrix(
            np.asarray(pose.position, dtype=float), pose.orientation.as_matrix()
        )

    def commanded_pose(self) -> Pose:
        """The compliant controller's current setpoint."""
        position, rotation = self._setpoint()
        return Pose(position.copy(), rotation_from_matrix(rotation))

    def _ramp(
        self, start: FloatArray, shift: FloatArray, start_rotation: FloatArray, turn: FloatArray
    ) -> None:
        """Run one period's setpoint ramp: piece i (of `RAMP_CHUNKS`) holds the setpoint
        start + f_i shift, rotated by f_i turn from start_rotation (f_i = `RAMP_FRACTIONS`[i];
        start, shift (3,) [m], start_rotation (3, 3), turn (3,) [rad] a world-frame rotation
        vector) for `_piece_steps`[i] substeps; the setpoint velocity drops to zero for the
        last piece (it rests at the goal). Override to hand the controller every piece at
        once."""
        fractions = RAMP_FRACTIONS[:, None]
        positions = start + fractions * shift
        rotations = rotation_matrices(fractions * turn) @ start_rotation
        last = RAMP_CHUNKS - 1
        for i, n in enumerate(self._piece_steps.tolist()):
            if i == last:
                self._set_setpoint_velocity(np.zeros(6))
            self._apply_setpoint_matrix(positions[i], rotations[i])
            self._step(n)

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
        self._period_steps = steps = period_substeps(period)
        # substeps of each piece: equal pieces, each starting at the nearest substep
        bounds = [round(i * steps / RAMP_CHUNKS) for i in range(RAMP_CHUNKS + 1)]
        self._piece_steps = np.diff(bounds)

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
        """Step `FILTER_STEPS` substeps and read the wrench as the sensor's filter does."""
        self._step(FILTER_STEPS)
        self._read_filter()

    def _filter_samples(self) -> FloatArray:
        """(FILTER_STEPS, 19) the filter sensors' samples of the last `FILTER_STEPS` substeps,
        oldest first, each as the data reads after that substep's `mj_step` (computed at its
        start). Columns: `FILTER_SENSORS` (3 each), then the number of hand-object contacts."""
        history = self.data.history
        return history[self._filter_index[int(history[self._filter_cursor])]]

    def _read_filter(self) -> None:
        """The sensor's filter over the last `FILTER_STEPS` substeps, from MuJoCo's history:
        the mean of the instantaneous wrench (`_sample_wrench` of each substep) and whether the
        hand touched the object in any of them."""
        history = self.data.history
        cursor = int(history[self._filter_cursor])
        terms = history[self._wrench_factors[cursor]] * history[self._wrench_axes[cursor]]
        # [sample, force or torque, the frame's axis, world component]; MuJoCo reports the
        # arm's action on the hand: F_s is its opposite
        total = terms.reshape(FILTER_STEPS, 2, 3, 3).sum(axis=2).sum(axis=0)
        self._filtered = total.reshape(6) / -FILTER_STEPS
        self._touched = bool(history[self._contact_index[cursor]].any())

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

    def object_force(self) -> FloatArray:
        """(3,) [N] world frame: the force the hand's surroundings (the held object, anything
        it touches) exert on it, ground truth for scoring: `true_wrench`'s force less the
        weight of the hand below the sensor. Quasi-static: the hand's own acceleration is
        neglected. Unlike F = F_s - F_d it does not depend on what the hand carried when F_d
        was read."""
        return self._filtered[:3] - self._hand_weight

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
        start, start_rotation = self._setpoint()
        goal = self._next_pose
        if goal is None:
            shift, turn = np.zeros(3), np.zeros(3)
        else:
            shift = np.asarray(goal.position, dtype=float) - start
            # slerp: about the one axis of the world-frame turn from the start to the goal
            turn = rotvec(self._rotation_matrix(goal.orientation) @ start_rotation.T)
        steps = self._period_steps
        self._set_setpoint_velocity(np.concatenate([shift, turn]) / (steps * TIMESTEP))
        self._ramp(start, shift, start_rotation, turn)
        self._read_filter()
        self._next_pose = None

    def _rotation_matrix(self, rotation: Rotation) -> FloatArray:
        """(3, 3) of a commanded orientation; the last one's is kept, since a command that
        does not turn the hand hands the same (immutable) Rotation back period after period."""
        if rotation is not self._last_rotation:
            self._last_rotation, self._last_matrix = rotation, rotation.as_matrix()
        return self._last_matrix
