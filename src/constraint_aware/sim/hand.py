"""The project's robot hand and compliant wrist, built as a `mujoco.MjSpec` from typed parameters.

Frames. The hand's local z axis is the palm normal (pointing at the object), the two fingers
spread along local +-y, local x = y cross z. The tool point (TCP) is on the palm normal,
`tcp_depth` in front of the palm face: the centre of the grasp.

Arm. The wrist is carried by a chain of three slide joints (world x, y, z) and three hinges
(yaw about world z, then pitch, then roll: intrinsic ZYX), each driven by a position actuator
with stiffness and damping: a joint-space impedance controller that is Cartesian in
translation, as a real arm under impedance control. Every arm body is gravity-compensated, so
only the hand's weight shows at the sensor (and F_d removes it).

Fingers. Each finger is one actuated hinge at the palm's edge (axis local x) carrying a rigid
L-shaped link: a proximal plate along +z and a distal plate bent toward the palm's centre line.
Opened, the hooks clear a handle; closed to 0 rad, they enclose a bar (lazy closure); closed
past the object's surface, they squeeze it (active-force closure); left open, the palm can press
on a surface (passive-force closure).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

from constraint_aware.errors import ConfigError, check_number, check_vector
from constraint_aware.sim.objects import QUAT_DECIMALS, on_grid

if TYPE_CHECKING:
    from mujoco import MjsBody, MjsDefault, MjSpec

#: The virtual arm: (joint = body name, slide or hinge, axis, armature [kg or kg m^2], link
#: mass [kg]), from the world outwards: x, y, z slides, then yaw, pitch, roll (intrinsic ZYX).
ARM_CHAIN = (
    ("arm_x", "slide", (1.0, 0.0, 0.0), 0.01, 0.01),
    ("arm_y", "slide", (0.0, 1.0, 0.0), 0.01, 0.01),
    ("arm_z", "slide", (0.0, 0.0, 1.0), 0.01, 0.01),
    ("arm_yaw", "hinge", (0.0, 0.0, 1.0), 0.001, 0.05),
    ("arm_pitch", "hinge", (0.0, 1.0, 0.0), 0.001, 0.05),
    ("arm_roll", "hinge", (1.0, 0.0, 0.0), 0.001, 0.01),
)

# MuJoCo names, kept in one place: resolve them to ids once (see sim/world.py).
ARM_JOINTS = tuple(link[0] for link in ARM_CHAIN)
FINGER_JOINTS = ("finger_left", "finger_right")
HAND_BODY = "hand"
WRIST_SITE = "wrist_site"
TCP_SITE = "tcp"
FORCE_SENSOR = "wrist_force"
TORQUE_SENSOR = "wrist_torque"
HAND_GEOM_PREFIX = "hand_"
HAND_CLASS = "hand"  # the default class of the hand's geoms (contact parameters)
GAIN_DECIMALS = 4  # the impedance gains' resolution [N/m, N s/m, ...]; geometry: on_grid
LINK_INERTIA = 1e-5  # [kg m^2] each axis, of the virtual arm's links (they carry no geoms)


@dataclass(frozen=True)
class HandConfig:
    """Geometry, mass and control gains of the hand and the wrist impedance."""

    palm_half: tuple[float, float, float] = (0.03, 0.035, 0.01)  # [m] palm box half-sizes
    finger_offset: float = 0.021  # [m] |y| of each finger's hinge
    finger_half_width: float = 0.015  # [m] finger half-size along local x
    finger_thickness: float = 0.006  # [m] half-thickness of the finger plates
    proximal_length: float = 0.035  # [m] hinge to the distal plate's centre line
    distal_length: float = 0.016  # [m] inward reach of the distal plate
    tcp_depth: float = 0.015  # [m] TCP in front of the palm face
    hand_mass: float = 0.6  # [kg] palm (each finger adds 0.05 kg)
    friction: float = 1.0  # [-] sliding friction of the hand's surfaces (rubber pads)
    torsional_friction: float = 0.005  # [m] torsional friction of the pads (condim 4)
    translational_stiffness: float = 2000.0  # [N/m] wrist impedance, each axis
    rotational_stiffness: float = 5.0  # [N m/rad] wrist impedance, each axis
    damping_ratio: float = 2.0  # [-] of each arm joint, against the hand's mass: ~critical
    # with a typical object attached (hand + 2 kg rings at ~2 control periods otherwise)
    finger_stiffness: float = 5.0  # [N m/rad] finger position servo
    finger_damping: float = 0.05  # [N m s/rad]

    def __post_init__(self) -> None:
        half = check_vector("HandConfig.palm_half", self.palm_half, unit="m")
        if min(half) <= 0:
            raise ConfigError("HandConfig.palm_half", self.palm_half, "3 positive numbers [m]")
        for f in fields(self):
            if f.name == "palm_half":
                continue
            low_open = f.name not in ("friction", "torsional_friction", "tcp_depth")
            check_number(f"HandConfig.{f.name}", getattr(self, f.name), low=0, low_open=low_open)

    @property
    def moving_mass(self) -> float:
        """[kg] mass carried by the translational joints (hand, fingers, wrist bodies)."""
        return self.hand_mass + 0.1 + 3 * 0.01

    def bar_gap(self, handle_radius: float) -> float:
        """[m] the gap each finger leaves beside a bar of `handle_radius` [m] held between
        them: the grasp's play, the hand's free travel across the bar before it meets it."""
        return self.finger_offset - self.finger_thickness - handle_radius

    def arm_damping(self, inertia: float, stiffness: float) -> float:
        return 2.0 * self.damping_ratio * (stiffness * inertia) ** 0.5


def hand_spec(cfg: HandConfig, mount_quat: tuple[float, float, float, float]) -> MjSpec:
    """The arm chain, hand, actuators and wrist sensors as one spec, to attach to a scene.

    mount_quat (w, x, y, z): the hand's orientation when all arm hinges are at zero.
    """
    import mujoco  # here, not at import: sim.tasks (and so the package) must stay light

    spec = mujoco.MjSpec()
    spec.modelname = "hook-hand"
    spec.compiler.degree = False
    hand_class = _add_hand_class(spec, cfg)
    hand = _add_arm(spec.worldbody)
    _add_hand(hand, cfg, hand_class, mount_quat)
    _add_actuators(spec, cfg)
    for name, kind in (
        (FORCE_SENSOR, mujoco.mjtSensor.mjSENS_FORCE),
        (TORQUE_SENSOR, mujoco.mjtSensor.mjSENS_TORQUE),
    ):
        spec.add_sensor(name=name, type=kind, objtype=mujoco.mjtObj.mjOBJ_SITE, objname=WRIST_SITE)
    return spec


def _add_hand_class(spec: MjSpec, cfg: HandConfig) -> MjsDefault:
    """Contact parameters of the hand's geoms: rubber pads (condim 4: torsional friction),
    stiff contacts (solref 4 ms, critically damped)."""
    default = spec.add_default(HAND_CLASS, spec.default)
    geom = default.geom
    geom.friction = [cfg.friction, cfg.torsional_friction, 0.0001]
    geom.condim = 4
    geom.solref = [0.004, 1.0]
    geom.solimp = [0.95, 0.99, 0.001, 0.5, 2.0]
    geom.rgba = [0.85, 0.7, 0.55, 1.0]
    return default


def _add_arm(world: MjsBody) -> MjsBody:
    """The six-joint chain from the world origin; returns its last link (the roll body).
    Every link is gravity-compensated: only the hand's weight shows at the wrist sensor."""
    import mujoco

    types = {"slide": mujoco.mjtJoint.mjJNT_SLIDE, "hinge": mujoco.mjtJoint.mjJNT_HINGE}
    parent = world
    for name, kind, axis, armature, mass in ARM_CHAIN:
        link = parent.add_body(name=name, gravcomp=1.0)
        link.add_joint(name=name, type=types[kind], axis=list(axis), armature=armature)
        link.explicitinertial = True
        link.mass = mass
        link.ipos = [0.0, 0.0, 0.0]
        link.inertia = [LINK_INERTIA] * 3
        parent = link
    return parent


def _add_hand(
    link: MjsBody,
    cfg: HandConfig,
    hand_class: MjsDefault,
    mount_quat: tuple[float, float, float, float],
) -> None:
    """The palm with the wrist sensor and tool-point sites and two fingers, on the arm's last
    link at `mount_quat`."""
    import mujoco

    px, py, pz = cfg.palm_half
    hand = link.add_body(
        name=HAND_BODY, quat=[round(v, QUAT_DECIMALS) for v in mount_quat], gravcomp=1.0
    )
    hand.childclass = HAND_CLASS
    hand.add_site(name=WRIST_SITE, size=[0.005, 0.005, 0.005])
    hand.add_site(
        name=TCP_SITE,
        pos=[0.0, 0.0, cfg.tcp_depth],
        size=[0.004, 0.005, 0.005],
        rgba=[1.0, 0.0, 0.0, 1.0],
    )
    box = mujoco.mjtGeom.mjGEOM_BOX
    hand.add_geom(
        hand_class, name="hand_palm", type=box, size=[px, py, pz], pos=[0.0, 0.0, -pz],
        mass=cfg.hand_mass,
    )  # fmt: skip
    hand.add_geom(
        hand_class,
        name="hand_wrist",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.025, 0.02, 0.0],
        pos=[0.0, 0.0, -0.04],
        mass=0.001,
        contype=0,  # the flange only shows
        conaffinity=0,
        rgba=[0.3, 0.3, 0.35, 1.0],
    )
    for side in ("left", "right"):
        _add_finger(hand, cfg, hand_class, side)


def _add_finger(hand: MjsBody, cfg: HandConfig, hand_class: MjsDefault, side: str) -> None:
    """One finger: a hinge at the palm's edge (axis local x) carrying a rigid L-shaped link,
    a proximal plate along +z and a distal plate bent toward the palm's centre line."""
    import mujoco

    sign = 1.0 if side == "left" else -1.0
    t, w = cfg.finger_thickness, cfg.finger_half_width
    l1, l2 = cfg.proximal_length, cfg.distal_length
    # opening rotates the finger away from the centre line (outward, toward sign*y)
    lo, hi = (-1.2, 0.45) if side == "left" else (-0.45, 1.2)  # [rad]
    finger = hand.add_body(name=f"finger_{side}", pos=on_grid([0.0, sign * cfg.finger_offset, 0.0]))
    finger.gravcomp = 1.0
    finger.add_joint(
        name=f"finger_{side}",
        type=mujoco.mjtJoint.mjJNT_HINGE,
        axis=[1.0, 0.0, 0.0],
        range=[lo, hi],
        limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        damping=0.01,
        armature=0.001,
    )
    box = mujoco.mjtGeom.mjGEOM_BOX
    finger.add_geom(
        hand_class,
        name=f"hand_{side}_proximal",
        type=box,
        mass=0.03,
        size=on_grid([w, t, l1 / 2 + t / 2]),
        pos=on_grid([0.0, 0.0, l1 / 2 - t / 2]),
    )
    finger.add_geom(
        hand_class,
        name=f"hand_{side}_distal",
        type=box,
        mass=0.02,
        size=on_grid([w, l2 / 2 + t / 2, t]),
        pos=on_grid([0.0, -sign * (l2 / 2 - t / 2), l1]),
    )


def _add_actuators(spec: MjSpec, cfg: HandConfig) -> None:
    """Position actuators: the wrist impedance (arm joints: stiffness, damping ratio against
    the moving mass / a nominal 2e-3 kg m^2) and the finger servos."""
    import mujoco

    kt, kr = cfg.translational_stiffness, cfg.rotational_stiffness
    gains = [(kt, cfg.arm_damping(cfg.moving_mass, kt), 5.0)] * 3
    gains += [(kr, cfg.arm_damping(2e-3, kr), 6.3)] * 3
    gains += [(cfg.finger_stiffness, cfg.finger_damping, 1.5)] * 2
    for joint, (kp, kv, limit) in zip(ARM_JOINTS + FINGER_JOINTS, gains, strict=True):
        actuator = spec.add_actuator(
            name=joint,
            trntype=mujoco.mjtTrn.mjTRN_JOINT,
            target=joint,
            ctrlrange=[-limit, limit],
        )
        actuator.set_to_position(kp=kp, kv=round(kv, GAIN_DECIMALS))
