"""Embodiment 2: the Kinova Jaco arm and its three-finger hand (dm-control's models).

Models. `dm_control/third_party/kinova/jaco_arm.xml` and `jaco_hand.xml` are loaded unmodified
with `mujoco.MjSpec.from_file` (dm-control's own `mjcf.Physics` is not used: it fails on
mujoco 4). The composition adds only sites, sensors and actuators: the hand is attached at the
arm's `wristsite` (as dm-control's Jaco entity does), a force/torque sensor site at the flange
(the hand body's origin), a tool-point site at the grasp centre, one torque motor per arm joint
(limits from Kinova's datasheet, as dm-control states them: 30.5 N m large joints, 6.8 N m small
joints) and one position servo per finger (force limit 1 N m, dm-control's finger actuator
limit). The arm base is placed per task from the object's pose (`arm_base`).

Control. An operational-space impedance controller on MuJoCo's Jacobian and mass matrix runs
at 250 Hz, every second 2 ms substep, its torques held in between (`OscConfig`):

    tau = J^T (K e - D (v - f v_d)) + qfrc_bias + N^T tau_posture + c B qdd,
    within the motors' limits

e: (position, rotation-vector) error of the tool point from its setpoint, v = J qdot, v_d the
setpoint's velocity while the Cartesian interpolator moves it, f = `velocity_feedforward` (0:
the damping acts on the tool's own velocity); K = diag(k_t I3, k_r I3); D = 2 zeta sqrt(K)
sqrt(diag Lambda), Lambda = (J M_c^-1 J^T)^-1 the task-space inertia (each axis damped at
`damping_ratio` of its own apparent mass) of M_c = M - c B, the inertia left after the joint
torque loop hides the fraction c = `motor_inertia_compensation` of the rotor inertia B (the
model's armature) with c B qdd (qdd of the previous substep); qfrc_bias compensates gravity
(arm, hand) and Coriolis terms; N^T = I - J^T Lambda J M_c^-1 is the dynamically consistent
null-space projector carrying a joint-space posture spring (toward the grasp configuration) and
a repulsion within `limit_margin` of a joint limit; the joints' dry friction (dm-control's
model: 2 N m / 1 N m frictionloss) is fed forward in the direction of the joint's motion (of
the commanded torque while it sticks). The motors are torque sources (`motor` actuators); at the
motors' limits the rotational part of the task torque yields first, then the task torque is
scaled down as a whole (clipping joint by joint turns the force). The wrist sensor reads the
wrench between flange and hand, so the arm's remaining friction and reflected inertia show as
tracking error and lag, not as force: the tool settles with `tracking_time_constant` (measured
once per grasp posture, ~0.3 s at the default 1000 N/m). The law runs compiled (sim/osc.py,
with numba from the `arm` extra).
"""

from __future__ import annotations

import copy
import functools
import importlib.util
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from scipy.linalg.lapack import dposv
from scipy.spatial.transform import Rotation

from constraint_aware.errors import CapError, InvalidInputError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.base import Embodiment
from constraint_aware.sim.hand import HandConfig
from constraint_aware.sim.objects import OBJECT_BODY, object_frame
from constraint_aware.sim.robot_adapter import (
    CONTROL_PERIOD,
    FILTER_STEPS,
    TCP_COLUMNS,
    TIMESTEP,
    add_wrench_filter,
    consecutive,
    orientation_error,
    rotvec,
)
from constraint_aware.sim.scene import OBJECT_PREFIX, scene_spec
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose

ARM_PREFIX = "jaco/"
HAND_PREFIX = "hand/"  # inside the arm: the composed names are "jaco/hand/..."
ARM_JOINTS = tuple(f"{ARM_PREFIX}joint_{i}" for i in range(1, 7))
FINGER_JOINTS = tuple(f"{ARM_PREFIX}{HAND_PREFIX}finger_{i}" for i in range(1, 4))
FLANGE_SITE = f"{ARM_PREFIX}{HAND_PREFIX}flange_ft"
TCP_SITE = f"{ARM_PREFIX}{HAND_PREFIX}tcp"
FORCE_SENSOR = "jaco_wrist_force"
TORQUE_SENSOR = "jaco_wrist_torque"
HAND_BODY = f"{ARM_PREFIX}{HAND_PREFIX}hand"
LARGE_JOINT_TORQUE = 30.5  # [N m] Kinova datasheet peak torque (joints 1-3), via dm-control
SMALL_JOINT_TORQUE = 6.8  # [N m] joints 4-6
FINGER_TORQUE = 1.0  # [N m] dm-control's finger actuator force limit
# The tool point on the hand's approach axis, 139 mm from the flange: the centre of a bar the
# curled fingers hook (measured on the meshes' hulls: with the fingers at 1.25 rad a 27 mm bar
# centred here rests on the fingertips, ~4 mm clear of the palm; 3 mm nearer the palm it would
# have ~4 mm of slack before the fingertips catch it, and the hand would start out of contact).
TCP_FROM_FLANGE = 0.139  # [m]
_IK_CACHE: dict[tuple[float, ...], FloatArray] = {}  # grasp configurations, see _solve_ik
_TAU_CACHE: dict[tuple[float, ...], float] = {}  # tracking time constants, see below
TRACKING_STEP = 0.01  # [m] the free-space step measured for the tracking time constant
TRACKING_WINDOW = 3.0  # [s] the longest measured response (a slower axis reports this)


def _spd_solve(a: FloatArray, b: FloatArray) -> FloatArray:
    """x with a x = b for a symmetric positive definite (n, n), b (n, k): LAPACK's Cholesky
    solver, called directly (numpy's solve and inv cost 3-4x more per call at this size)."""
    _, x, info = dposv(a, b)
    if info != 0:  # not positive definite (numerically): the general solver
        return np.asarray(np.linalg.solve(a, b), dtype=float)
    return np.asarray(x, dtype=float)


def jaco_model_dir() -> Path:
    """The directory of dm-control's Kinova models (installed with the `arm` extra)."""
    spec = importlib.util.find_spec("dm_control")
    if spec is None or not spec.submodule_search_locations:
        raise CapError(
            "the Jaco embodiment needs dm-control's models: pip install 'constraint-aware[arm]'"
        )
    path = Path(next(iter(spec.submodule_search_locations))) / "third_party" / "kinova"
    if not (path / "jaco_arm.xml").is_file():
        raise CapError(f"dm-control's Kinova models not found under {path}")
    return path


@dataclass(frozen=True)
class OscConfig:
    """The arm's operational-space impedance controller. Units in brackets."""

    translational_stiffness: float = 1000.0  # [N/m] k_t, each axis (the step force: k_t x 1 cm)
    rotational_stiffness: float = HandConfig.rotational_stiffness  # [N m/rad] k_r: the hook
    # hand's wrist value (embodiment 1, 5 N m/rad): the hooks and the knob grasp let the
    # object turn the hand, and a stiffer wrist fought it. Measured at 30 N m/rad (k_t x
    # (0.17 m)^2), default policy, door at +15 deg: the commanded turns (the executor turns
    # the hand with d) were not followed, the wrist neared its singularity (Lambda_xx 10 ->
    # 71,000 kg at 5 deg of door) and the run ended on the force limit; at 10 N m/rad a
    # timeout at 36 deg; at 5 it opens (60 deg). The price: against the wrist joints' 1 N m
    # dry friction, free-space turns under 1/k_r (11 deg) are followed only in part

    damping_ratio: float = 1.0  # [-] zeta of each task-space axis against its apparent mass
    velocity_feedforward: float = 0.0  # [-] f: the damping acts on v - f v_d. 0 (damping
    # against the tool's own velocity, as the hook hand's servos): at f = 1 the damping pushed
    # D v_d into any constraint the setpoint moved against (D ~ 170 N s/m: 17 N at 1 cm per
    # period, on top of k x 1 cm = 10 N) and its kick at each period's start and end made the
    # forces across the pole and the drawer's bar flip sign every period (measured, paper
    # offsets, default policy, guards off: pole, door and handle failed at f = 1, 0.5; the
    # pole, handle, drawer and plate succeed at 0; the free-space ramp lag is D v / k, ~17 mm
    # at 10 cm/s)
    posture_stiffness: float = 5.0  # [N m/rad] null-space spring toward the grasp posture
    posture_damping: float = 1.0  # [N m s/rad]
    limit_margin: float = 0.15  # [rad] joint-limit repulsion starts this far from a limit
    limit_stiffness: float = 50.0  # [N m/rad] of the repulsion
    friction_compensation: float = 1.0  # [-] fraction of each joint's model frictionloss fed
    # forward, as torque-controlled arms do: in the direction of the joint's motion while it
    # moves (faster than `friction_velocity_scale`), of the commanded torque while it sticks
    # (tanh over `friction_torque_scale`), blended in between. Without it the joints' dry
    # friction leaves a dead zone (measured in free space at 1000 N/m: 12 mm and 4 deg of a
    # 20 mm / 6 deg step remain after 4 s; with it 1.8 mm and 1.5 deg). By the commanded
    # torque alone, a moving joint whose torque changes sign (a turning arm) lost it: the hand
    # lagged its target with no force at the sensor (default policy, paper offsets: the
    # plate's drag, the executor's arm-deflection guard stopped it; peak forces 12-21 N)
    friction_torque_scale: float = 0.2  # [N m]
    friction_velocity_scale: float = 0.01  # [rad/s]
    motor_inertia_compensation: float = 0.9  # [-] c: the fraction of each joint's reflected
    # rotor inertia (the model's armature B, 4 / 2 kg m^2) that the joint torque loop hides:
    # tau_m = tau_d + c B qdd (qdd from the previous substep, as a joint torque sensor sees it
    # one sample late), i.e. torque feedback of gain c / (1 - c) (9 at c = 0.9; the range
    # of torque-controlled arms, e.g. DLR's LWR); the arm then shows (1 - c) B. Without it
    # the armature dominates the tool's apparent mass (58-82 kg of Lambda's translational
    # diagonal at the drawer's grasp, 1.4-1.9 kg of it links and hand) and the tool settles
    # with a ~0.9 s time constant at 1000 N/m, nine control periods.
    apparent_mass_cap: float = 30.0  # [kg, kg m^2] Lambda = (J M^-1 J^T + I / cap)^-1, the
    # singularity-robust (damped) inverse: at the grasps Lambda's translational diagonal is
    # 5-13 kg (c = 0.9), near the wrist singularity it grew past 1500 kg and the damping
    # 2 zeta sqrt(k Lambda) froze the arm (default policy, door at +15 deg: q5 -> -pi at 42
    # deg of door, the hand 4-5 cm behind its setpoint, force limit at step 72). Two values
    # were tried: 100 kg opened the door with the shipped executor but stopped on the lag-
    # aware guards (not_following, step 51); 30 kg passed both
    control_substeps: int = 2  # the OSC's torques are updated every this many 2 ms substeps:
    # 250 Hz (Kinova's torque interface takes 100 Hz-1 kHz); at 4 ms the fastest axis of the
    # stiffest variant (1e5 N/m) still has omega_n T < 1. Measured against 500 Hz (1): the five
    # paper tasks end alike (default policy, same steps +-1, peaks within 3 N), at 2/3 the cost
    finger_stiffness: float = 5.0  # [N m/rad] finger position servo
    finger_damping: float = 0.05  # [N m s/rad]

    def __post_init__(self) -> None:
        if not 100.0 <= self.translational_stiffness <= 1e5:
            raise InvalidInputError(
                f"translational_stiffness {self.translational_stiffness} N/m; valid: 100-1e5"
            )
        if not 1.0 <= self.rotational_stiffness <= 1e4:
            raise InvalidInputError(
                f"rotational_stiffness {self.rotational_stiffness} N m/rad; valid: 1-1e4"
            )
        if not 0.1 <= self.damping_ratio <= 5.0:
            raise InvalidInputError(f"damping_ratio {self.damping_ratio}; valid: 0.1-5")
        if not 1 <= self.control_substeps <= 5:
            raise InvalidInputError(f"control_substeps {self.control_substeps}; valid: 1-5")
        if not 0.0 <= self.motor_inertia_compensation <= 0.95:
            raise InvalidInputError(
                f"motor_inertia_compensation {self.motor_inertia_compensation}; valid: 0-0.95"
            )


@dataclass(frozen=True)
class JacoGrasp:
    """How the three-finger hand holds one handle kind.

    finger_start: [rad] finger angle when placed (contact-free); finger_target: [rad] servo
    target (above the contact angle: the fingers squeeze with up to `FINGER_TORQUE`);
    contact: where the handle meets the hand: "centre" (the TCP at the handle's centre),
    "front" (the hand's foremost surface on the handle's top face: pressing) or "palm" (the
    palm on the handle's top face, the fingers around its sides).
    """

    finger_start: float
    finger_target: float
    contact: str


# One grasp per handle kind (the paper's force-exertion types, see README "Second embodiment").
JACO_GRASPS: dict[str, JacoGrasp] = {
    "bar": JacoGrasp(1.25, 1.25, "centre"),  # lazy closure: curled fingers hook the bar
    "pole": JacoGrasp(1.0, 1.35, "centre"),  # active-force closure: a squeeze
    "plate": JacoGrasp(1.35, 1.35, "front"),  # passive-force closure: a fist pressing down
    "knob": JacoGrasp(0.6, 1.35, "palm"),  # palm on top, the fingers close on its sides
}


def _hand_spec(model_dir: Path) -> mujoco.MjSpec:
    hand = mujoco.MjSpec.from_file(str(model_dir / "jaco_hand.xml"))
    body = hand.body("hand")
    body.add_site(name="flange_ft", size=[0.005, 0.0, 0.0])
    # tool point: z along the approach (the hand body's -z), fingers spread along y
    body.add_site(name="tcp", pos=[0.0, 0.0, -TCP_FROM_FLANGE], quat=[0.0, 1.0, 0.0, 0.0])
    for j in ("finger_1", "finger_2", "finger_3"):
        act = hand.add_actuator(name=j, target=j, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        act.set_to_position(kp=OscConfig.finger_stiffness, kv=OscConfig.finger_damping)
        act.forcelimited = 1
        act.forcerange = [-FINGER_TORQUE, FINGER_TORQUE]
        act.ctrlrange = [0.0, 1.5]
    return hand


def _arm_spec(model_dir: Path) -> mujoco.MjSpec:
    arm = mujoco.MjSpec.from_file(str(model_dir / "jaco_arm.xml"))
    arm.site("wristsite").attach_body(_hand_spec(model_dir).body("hand"), HAND_PREFIX, "")
    for i in range(1, 7):
        limit = LARGE_JOINT_TORQUE if i <= 3 else SMALL_JOINT_TORQUE
        act = arm.add_actuator(
            name=f"joint_{i}", target=f"joint_{i}", trntype=mujoco.mjtTrn.mjTRN_JOINT
        )
        act.set_to_motor()
        act.ctrllimited = 1
        act.ctrlrange = [-limit, limit]
    return arm


#: Where the base stands relative to the handle's mid-motion position, per (joint type, handle):
#: (horizontal distance [m], azimuth from the pull direction toward `side` [deg], height [m]).
#: The azimuth is the one (of 0, +-15, +-45, +-90 deg) whose inverse kinematics keeps the
#: largest joint-limit margin along the motion (0-120 % of success; a controller-independent
#: workspace criterion): drawer 0.59 rad, plate 1.08, pole 1.00, door 1.30, knob 1.06.
BASE_PLACEMENT: dict[tuple[str, str], tuple[float, float, float]] = {
    ("prismatic", "bar"): (0.55, 45.0, -0.3),
    ("prismatic", "pole"): (0.55, 45.0, -0.3),
    ("prismatic", "plate"): (0.45, -90.0, -0.1),
    ("revolute", "bar"): (0.55, 90.0, -0.3),
    ("revolute", "knob"): (0.45, -90.0, -0.1),
}


def arm_base(task: TaskConfig, placement: tuple[float, float, float] | None = None) -> FloatArray:
    """(3,) [m] where the arm's base stands, from the object's pose: `placement` (default
    `BASE_PLACEMENT` of the object kind) from the handle's position half-way to success, in
    that position's (pull direction, side, up) frame."""
    obj = task.object
    frame = object_frame(obj)
    out, side, up = frame[:, 0], frame[:, 1], frame[:, 2]
    handle = obj.handle_position
    half = 0.5 * min(task.success_progress, obj.joint_range[1])  # the joint cannot go further
    if obj.joint_type == "prismatic":
        mid = handle + half * np.asarray(obj.axis, float)
        turn = Rotation.identity()
    else:
        turn = Rotation.from_rotvec(half * np.asarray(obj.axis, float))
        pivot = np.asarray(obj.position, float)
        mid = pivot + turn.apply(handle - pivot)
    out, side = turn.apply(out), turn.apply(side)
    kind = (obj.joint_type, obj.handle)
    if placement is None and kind not in BASE_PLACEMENT:
        raise InvalidInputError(f"no Jaco base placement for a {kind[0]} {kind[1]}")
    reach, azimuth, height = placement or BASE_PLACEMENT[kind]
    a = np.radians(azimuth)
    return mid + reach * (np.cos(a) * out + np.sin(a) * side) + height * up


class JacoSim(Embodiment):
    """A task with the Jaco arm and hand, driven by the operational-space controller.

    Same API as `ManipulationSim`: `reset()` grasps; the Robot and TaskMonitor methods follow.
    """

    # the fingers' own damping (0.75 N m s/rad) against their 1 N m limit lets them close at
    # ~1.3 rad/s at most: each settling phase of the grasp lasts 1 s
    settle_time = 1.0

    def __init__(
        self,
        task: TaskConfig,
        osc: OscConfig | None = None,
        control_period: float = CONTROL_PERIOD,
        base: FloatArray | None = None,
        model: mujoco.MjModel | None = None,
    ) -> None:
        """model: the compiled scene (`build_spec(task, base)` with more composed in, e.g. a
        camera); None: built here."""
        if task.object.handle not in JACO_GRASPS:
            raise InvalidInputError(
                f"handle {task.object.handle!r}; the Jaco hand grasps: {sorted(JACO_GRASPS)}"
            )
        self.task = task
        self.osc = osc or OscConfig()
        self.control_period_s = control_period
        self.grasp_kind = JACO_GRASPS[task.object.handle]
        self.base = arm_base(task) if base is None else np.asarray(base, dtype=float)
        self.model = build_model(task, self.base) if model is None else model
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._arm_dof = np.array([m.jnt_dofadr[m.joint(j).id] for j in ARM_JOINTS])
        self._arm_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in ARM_JOINTS])
        self._finger_qpos = np.array([m.jnt_qposadr[m.joint(j).id] for j in FINGER_JOINTS])
        self._arm_act = np.array([m.actuator(ARM_PREFIX + f"joint_{i}").id for i in range(1, 7)])
        self._finger_act = np.array(
            [m.actuator(f"{ARM_PREFIX}{HAND_PREFIX}finger_{i}").id for i in range(1, 4)]
        )
        self._torque_limit = m.actuator_ctrlrange[self._arm_act, 1].copy()
        jids = [m.joint(j).id for j in ARM_JOINTS]
        self._limited = np.array([bool(m.jnt_limited[j]) for j in jids])
        self._range = np.array([m.jnt_range[j] for j in jids])
        self._bind_sensor(FLANGE_SITE, TCP_SITE, FORCE_SENSOR, TORQUE_SENSOR)
        hand_body = m.body(HAND_BODY).id
        hand_geoms = {
            g for g in range(m.ngeom) if self._is_in_subtree(int(m.geom_bodyid[g]), hand_body)
        }
        self._bind_monitor(hand_geoms, OBJECT_PREFIX)
        self._sp_pos = np.zeros(3)
        self._sp_mat = np.eye(3)
        self._sp_vel = np.zeros(6)  # [m/s, rad/s] the setpoint's velocity (interpolator)
        self._jac = np.zeros((6, m.nv))
        self._jacp, self._jacr = self._jac[:3], self._jac[3:]  # views: mj_jacSite fills _jac
        self._minv_jt = np.zeros((6, m.nv))
        osc = self.osc
        self._k = np.repeat([osc.translational_stiffness, osc.rotational_stiffness], 3)
        self._damp_gain = 2.0 * osc.damping_ratio * np.sqrt(self._k)
        # joint-limit repulsion band (unlimited joints: an empty band at +-inf)
        self._lo = np.where(self._limited, self._range[:, 0] + osc.limit_margin, -np.inf)
        self._hi = np.where(self._limited, self._range[:, 1] - osc.limit_margin, np.inf)
        self._act_slice = consecutive(self._arm_act, "the Jaco's arm motors")
        self._dof_slice = consecutive(self._arm_dof, "the Jaco's arm dofs")
        self._qpos_slice = consecutive(self._arm_qpos, "the Jaco's arm joint positions")
        fric = self.osc.friction_compensation * m.dof_frictionloss[self._dof_slice]
        self._friction = fric if np.any(fric) else None
        # Lambda = (J M^-1 J^T + I / cap)^-1: its eigenvalues stay below the cap (OscConfig)
        self._eps = np.eye(6) / self.osc.apparent_mass_cap
        comp = self.osc.motor_inertia_compensation * m.dof_armature[self._dof_slice]
        self._rotor_comp = comp if np.any(comp) else None  # [kg m^2] c B per arm joint
        self._full_m = np.zeros((m.nv, m.nv))
        self._full_flat = self._full_m.reshape(-1)  # a view
        self._arm_diag_flat = self._arm_dof * (m.nv + 1)  # the arm joints' diagonal of M
        self._control_every = self.osc.control_substeps
        self._phase = 0  # substeps since the last torque update
        self._osc_data: mujoco.MjData | None = None  # the MjData `_osc_state` views
        self._osc_state: tuple[FloatArray, ...] = ()
        self._osc_torques, self._osc_index, self._osc_gains, self._osc_joint = self._osc_law()
        self._posture = self._osc_joint[0]  # a view: the law's posture row (`_set_posture`)

    def _osc_law(self) -> tuple[Callable[..., None], np.ndarray, FloatArray, FloatArray]:
        """The compiled OSC law (sim/osc.py) and its fixed arguments: indices, gains, the
        per-joint parameters."""
        try:
            import constraint_aware.sim.osc as law
        except ImportError as exc:  # numba, in the `arm` extra
            raise CapError(
                f"the Jaco embodiment needs {exc.name}: pip install 'constraint-aware[arm]'"
            ) from exc
        cfg = self.osc
        index = np.zeros(4, dtype=np.int64)
        index[[law.DOF0, law.QPOS0, law.ACT0, law.TOOL_SITE]] = (
            self._dof_slice.start, self._qpos_slice.start, self._act_slice.start, self._tcp_site,
        )  # fmt: skip
        gains = np.zeros(law.N_GAINS)
        gains[law.POSTURE_STIFFNESS] = cfg.posture_stiffness
        gains[law.POSTURE_DAMPING] = cfg.posture_damping
        gains[law.LIMIT_STIFFNESS] = cfg.limit_stiffness
        gains[law.VELOCITY_FEEDFORWARD] = cfg.velocity_feedforward
        gains[law.FRICTION_VELOCITY_SCALE] = cfg.friction_velocity_scale
        gains[law.FRICTION_TORQUE_SCALE] = cfg.friction_torque_scale
        gains[law.INVERSE_MASS_CAP] = 1.0 / cfg.apparent_mass_cap
        joint = np.zeros((8, 6))
        joint[law.LOW], joint[law.HIGH] = self._lo, self._hi
        joint[law.STIFFNESS], joint[law.DAMPING_GAIN] = self._k, self._damp_gain
        joint[law.TORQUE_LIMIT] = self._torque_limit
        if self._friction is not None:
            joint[law.FRICTION] = self._friction
        if self._rotor_comp is not None:
            joint[law.ROTOR] = self._rotor_comp
        return law.osc_torques, index, gains, joint

    def _set_posture(self, q: FloatArray) -> None:
        """(6,) [rad] the null-space posture spring's target (the grasp configuration)."""
        self._posture[:] = q

    def _is_in_subtree(self, body: int, root: int) -> bool:
        while body > 0:
            if body == root:
                return True
            body = int(self.model.body_parentid[body])
        return False

    # --- the operational-space impedance controller ----------------------------------------
    def _control(self) -> None:
        """Motor torques for this substep from the OSC law (module docstring; compiled:
        sim/osc.py)."""
        m, d = self.model, self.data
        if d is not self._osc_data:
            # the state's arrays are views into this MjData's buffers, fixed for its lifetime:
            # made once per MjData rather than seven times per call
            self._osc_data = d
            self._osc_state = (d.qpos, d.qvel, d.qacc, d.qfrc_bias, d.site_xpos, d.site_xmat)
        mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self._tcp_site)
        mujoco.mj_fullM(m, d, self._full_m)
        qpos, qvel, qacc, qfrc_bias, site_xpos, site_xmat = self._osc_state
        self._osc_torques(
            self._jac, self._full_m, qpos, qvel, qacc, qfrc_bias, site_xpos, site_xmat, d.ctrl,
            self._osc_index, self._sp_pos, self._sp_mat, self._sp_vel, self._osc_joint,
            self._osc_gains,
        )  # fmt: skip

    def _minv_jt_arm(self, d: mujoco.MjData) -> FloatArray:
        """(6, 6) the arm dofs' rows of M^-1 J^T (`self._jac`) for the inertia the controller
        shapes: M less the rotor inertia its torque loop hides
        (OscConfig.motor_inertia_compensation)."""
        dofs = self._dof_slice
        if self._rotor_comp is None:
            mujoco.mj_solveM(self.model, d, self._minv_jt, self._jac)
            return self._minv_jt[:, dofs].T
        full = self._full_m
        mujoco.mj_fullM(self.model, d, full)
        self._full_flat[self._arm_diag_flat] -= self._rotor_comp
        return _spd_solve(full, self._jac.T)[dofs]

    def _axis_dynamics(self, data: mujoco.MjData) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Each task-space axis as the OSC makes it (module docstring): stiffness K_ii, damping
        D_ii = 2 zeta sqrt(K_ii Lambda_ii), apparent mass Lambda_ii at `data`'s configuration
        (the arm's M less the rotor inertia the torque loop hides; the fingers ride along)."""
        mujoco.mj_jacSite(self.model, data, self._jacp, self._jacr, self._tcp_site)
        inverse = self._jac[:, self._dof_slice] @ self._minv_jt_arm(data) + self._eps
        lam = np.asarray(np.linalg.inv(inverse).diagonal(), dtype=float)
        damping = np.asarray(self._damp_gain * np.sqrt(lam), dtype=float)
        return np.asarray(self._k, dtype=float), damping, lam

    def _free_space_time_constant(self) -> float:
        """[s] the tool point's tracking time constant, measured: the mean over three
        `TRACKING_STEP` setpoint steps (world x, y, z) from rest at the grasp posture, with
        contacts off (free space), of the time to 63.2 % of the step. Measured rather than
        computed because the joints' dry friction, fed forward only in part at rest, slows the
        linear response (`axis_time_constants`) at low stiffness (500 N/m: ~1 s). Runs on its
        own MjData, so the episode's state is untouched; cached per base, posture and
        controller gains."""
        key = (*np.round(self.base, 9), *np.round(self._posture, 9), *vars(self.osc).values())
        cached = _TAU_CACHE.get(key)
        if cached is not None:
            return cached
        # contacts off on a copy of the model: the (shared) model stays as it is
        m = copy.copy(self.model)
        m.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        episode = (self.model, self.data, self._sp_pos, self._sp_mat, self._sp_vel, self._phase)
        reached = (1.0 - math.exp(-1.0)) * TRACKING_STEP
        window = round(TRACKING_WINDOW / TIMESTEP)
        rises = []
        try:
            self.model = m
            for axis in np.eye(3):
                self.data = scratch = mujoco.MjData(m)
                self._phase = 0
                scratch.qpos[self._arm_qpos] = self._posture
                scratch.qpos[self._finger_qpos] = episode[1].qpos[self._finger_qpos]
                scratch.ctrl[:] = episode[1].ctrl
                mujoco.mj_forward(m, scratch)
                start = self.read_pose()
                self._sp_vel = np.zeros(6)
                self._apply_setpoint(start.moved(TRACKING_STEP * axis))
                rise, done = TRACKING_WINDOW, 0
                while done < window:
                    n = min(FILTER_STEPS, window - done)
                    self._step(n)
                    # the tool point at the start of each of these substeps, oldest first
                    tool = self._filter_samples()[FILTER_STEPS - n :, TCP_COLUMNS]
                    hit = np.flatnonzero((tool - start.position) @ axis >= reached)
                    if hit.size:
                        rise = (done + int(hit[0]) + 1) * TIMESTEP
                        break
                    done += n
                rises.append(rise)
        finally:
            self.model, self.data, pos, mat, self._sp_vel, self._phase = episode
            self._apply_setpoint_matrix(pos, mat)
        tau = float(np.mean(rises))
        _TAU_CACHE[key] = tau
        return tau

    def _step(self, n: int) -> None:
        """n substeps; the OSC's torques are updated every `OscConfig.control_substeps` of them
        and held in between (zero-order hold, as a sampled torque interface)."""
        m, d, every = self.model, self.data, self._control_every
        while n > 0:
            if self._phase == 0:
                self._control()
            run = min(n, every - self._phase)
            mujoco.mj_step(m, d, nstep=run)
            self._phase = (self._phase + run) % every
            n -= run

    # --- SimulatedRobot -------------------------------------------------------------------
    @property
    def translational_stiffness(self) -> float:
        """[N/m] the OSC's Cartesian stiffness (each axis)."""
        return self.osc.translational_stiffness

    def _set_setpoint_velocity(self, twist: FloatArray) -> None:
        self._sp_vel = np.asarray(twist, dtype=float)

    def _apply_setpoint_matrix(self, position: FloatArray, rotation: FloatArray) -> None:
        self._sp_pos = position
        self._sp_mat = rotation

    def _setpoint(self) -> tuple[FloatArray, FloatArray]:
        return self._sp_pos, self._sp_mat

    def _rest_at_measured(self) -> None:
        self._apply_setpoint(self.read_pose())

    def _hand_extent(self, finger_angle: float, palm_only: bool = False) -> float:
        """[m] how far the hand (or its palm alone) reaches along its approach axis beyond the
        tool point with the fingers at `finger_angle` (mesh vertices, posed on a scratch copy
        of the state: the episode's is untouched)."""
        m, d = self.model, mujoco.MjData(self.model)
        d.qpos[self._finger_qpos] = finger_angle
        mujoco.mj_kinematics(m, d)
        tcp = self._tcp_site
        rot, origin = d.site_xmat[tcp].reshape(3, 3), d.site_xpos[tcp]
        reach = -np.inf
        for g in self._hand_geoms:
            if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or m.geom_contype[g] == 0:
                continue
            if palm_only and m.geom_bodyid[g] != m.body(HAND_BODY).id:
                continue
            mesh = int(m.geom_dataid[g])
            start, count = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
            verts = m.mesh_vert[start : start + count]
            world = d.geom_xpos[g] + verts @ d.geom_xmat[g].reshape(3, 3).T
            reach = max(reach, float(np.max((world - origin) @ rot[:, 2])))
        return reach

    def grasp_pose(self) -> Pose:
        """The TCP pose at which the hand holds the handle (object at joint position 0)."""
        mount = Rotation.from_matrix(self.task.hand_mount())
        pos = self.task.object.handle_position.copy()
        if self.grasp_kind.contact != "centre":
            # the hand's foremost surface (or the palm's) on the handle's top face
            palm = self.grasp_kind.contact == "palm"
            reach = self._hand_extent(self.grasp_kind.finger_start, palm_only=palm)
            pos = pos - mount.apply([0.0, 0.0, reach])
        return Pose(pos, mount)

    def grasp_pose_at(self, point: FloatArray, orientation: Rotation, handle: str) -> Pose:
        """The TCP pose that holds a `handle` shape (`JACO_GRASPS`) whose grasp centre is
        `point` (3,) [m] with the hand at `orientation`, as `grasp_pose` does for the task's
        own handle (the hand's extent is measured on a scratch copy of the state)."""
        kind = JACO_GRASPS[handle]
        pos = np.array(point, dtype=float)
        if kind.contact != "centre":
            reach = self._hand_extent(kind.finger_start, palm_only=kind.contact == "palm")
            pos = pos - orientation.apply([0.0, 0.0, reach])
        return Pose(pos, orientation)

    def set_fingers(self, angle: float) -> None:
        """The three finger servos' target [rad] (0 open, 1.5 closed)."""
        self.data.ctrl[self._finger_act] = angle

    def set_posture(self, q: FloatArray) -> None:
        """(6,) [rad] the null-space posture the controller holds the arm near."""
        self._set_posture(np.asarray(q, dtype=float))

    def joint_positions(self) -> FloatArray:
        """(6,) [rad] the arm's joint angles."""
        return np.asarray(self.data.qpos[self._arm_qpos], dtype=float).copy()

    def start_at_joints(self, q: FloatArray, finger_angle: float) -> None:
        """Reset the physics (object at rest at joint position 0) with the arm at joint angles
        `q` (6,) [rad] (also its posture) and the fingers at `finger_angle` [rad], the TCP
        setpoint where the tool is; then settle for `settle_time`."""
        d = self.data
        mujoco.mj_resetData(self.model, d)
        self._phase = 0
        d.qpos[self._arm_qpos] = q
        self.set_posture(q)
        d.qpos[self._finger_qpos] = finger_angle
        self.set_fingers(finger_angle)
        mujoco.mj_forward(self.model, d)
        self._apply_setpoint(self.read_pose())
        self._step(round(self.settle_time / TIMESTEP))
        self._settle_filter()

    def _solve_ik(self, pose: Pose) -> FloatArray:
        """(6,) arm joint angles putting the TCP at `pose` (damped least squares from several
        seeds; the solution farthest from the joint limits among the converged ones). Solutions
        are cached per base and pose: randomized tasks share their geometry."""
        key = (*np.round(self.base, 9), *np.round(pose.position, 9), *pose.orientation.as_quat())
        cached = _IK_CACHE.get(key)
        if cached is not None:
            return cached.copy()
        q = self._search_ik(pose)
        _IK_CACHE[key] = q.copy()
        return q

    def _search_ik(self, pose: Pose) -> FloatArray:
        m, d = self.model, self.data
        best, best_score = None, -np.inf
        yaw0 = np.arctan2(*(pose.position - self.base)[1::-1])
        for dyaw in (0.0, 0.8, -0.8, 1.6, -1.6, np.pi):
            for q2, q3 in ((2.6, 1.2), (3.6, 5.0), (2.9, 1.7)):
                q = np.array([-yaw0 + dyaw, q2, q3, 4.0, 0.0, 0.0])
                q = self._ik_from(q, pose)
                d.qpos[self._arm_qpos] = q
                mujoco.mj_kinematics(m, d)
                pos_err = np.linalg.norm(d.site_xpos[self._tcp_site] - pose.position)
                rot = d.site_xmat[self._tcp_site].reshape(3, 3)
                rot_err = np.linalg.norm(rotvec(pose.orientation.as_matrix() @ rot.T))
                if pos_err > 1e-4 or rot_err > 1e-3:
                    continue
                margin = np.where(
                    self._limited,
                    np.minimum(q - self._range[:, 0], self._range[:, 1] - q),
                    np.pi,
                )
                score = float(np.min(margin))
                if score > best_score:
                    best, best_score = q, score
        if best is None:
            raise CapError(f"the Jaco cannot reach the grasp of {self.task.name} from {self.base}")
        return best

    def _ik_from(self, q: FloatArray, pose: Pose) -> FloatArray:
        m, d = self.model, self.data
        for _ in range(200):
            d.qpos[self._arm_qpos] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            pos = d.site_xpos[self._tcp_site]
            turn = orientation_error(pose.orientation, d.site_xmat[self._tcp_site])
            err = np.concatenate([pose.position - pos, turn])
            if np.linalg.norm(err) < 1e-7:
                break
            mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self._tcp_site)
            jac = np.vstack([self._jacp, self._jacr])[:, self._arm_dof]
            step = jac.T @ np.linalg.solve(jac @ jac.T + 1e-4 * np.eye(6), err)
            q = q + np.clip(step, -0.3, 0.3)
            q = np.where(self._limited, np.clip(q, *self._range.T), q)
        return q

    def _place(self, pose: Pose) -> None:
        d = self.data
        q = self._solve_ik(pose)
        mujoco.mj_resetData(self.model, d)
        self._phase = 0
        d.qpos[self._arm_qpos] = q
        self._set_posture(q)
        d.qpos[self._finger_qpos] = self.grasp_kind.finger_start
        d.ctrl[self._finger_act] = self.grasp_kind.finger_target
        self._apply_setpoint(pose)


def build_model(task: TaskConfig, base: FloatArray) -> mujoco.MjModel:
    """The task's scene with the Jaco arm standing at `base` (3,) [m], hand on its flange, and
    the wrist sensor's filter (sim.robot_adapter.add_wrench_filter). Built once per task
    configuration, base and process and shared: do not modify it (copy it:
    `copy.copy(model)`)."""
    return _compiled(task, (float(base[0]), float(base[1]), float(base[2])))


@functools.lru_cache(maxsize=32)
def _compiled(task: TaskConfig, base: tuple[float, float, float]) -> mujoco.MjModel:
    return build_spec(task, np.asarray(base, dtype=float)).compile()


def build_spec(
    task: TaskConfig, base: FloatArray, *, solid_for_arms: bool = False
) -> mujoco.MjSpec:
    """`build_model`'s spec, before compiling (more can be composed in: a camera)."""
    spec = scene_spec(task, solid_for_arms=solid_for_arms)
    model_dir = jaco_model_dir()
    frame = spec.worldbody.add_frame(pos=[float(v) for v in base])
    spec.attach(_arm_spec(model_dir), prefix=ARM_PREFIX, frame=frame)
    for name, kind in (
        (FORCE_SENSOR, mujoco.mjtSensor.mjSENS_FORCE),
        (TORQUE_SENSOR, mujoco.mjtSensor.mjSENS_TORQUE),
    ):
        spec.add_sensor(name=name, type=kind, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=FLANGE_SITE)
    add_wrench_filter(
        spec, tcp_site=TCP_SITE, hand_body=HAND_BODY, object_body=OBJECT_PREFIX + OBJECT_BODY
    )
    return spec
