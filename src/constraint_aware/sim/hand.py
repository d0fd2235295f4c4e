"""The project's robot hand and compliant wrist, written as MJCF from typed parameters.

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

if TYPE_CHECKING:
    from mujoco import MjSpec

# MuJoCo names, kept in one place: resolve them to ids once (see sim/world.py).
ARM_JOINTS = ("arm_x", "arm_y", "arm_z", "arm_yaw", "arm_pitch", "arm_roll")
FINGER_JOINTS = ("finger_left", "finger_right")
HAND_BODY = "hand"
WRIST_SITE = "wrist_site"
TCP_SITE = "tcp"
FORCE_SENSOR = "wrist_force"
TORQUE_SENSOR = "wrist_torque"
HAND_GEOM_PREFIX = "hand_"


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

    def arm_damping(self, inertia: float, stiffness: float) -> float:
        return 2.0 * self.damping_ratio * (stiffness * inertia) ** 0.5


def _finger(cfg: HandConfig, side: str) -> str:
    sign = 1.0 if side == "left" else -1.0
    t, w = cfg.finger_thickness, cfg.finger_half_width
    l1, l2 = cfg.proximal_length, cfg.distal_length
    # opening rotates the finger away from the centre line (outward, toward sign*y)
    lo, hi = (-1.2, 0.45) if side == "left" else (-0.45, 1.2)  # [rad]
    return f"""
        <body name="finger_{side}" pos="0 {sign * cfg.finger_offset:.5f} 0" gravcomp="1">
          <joint name="finger_{side}" type="hinge" axis="1 0 0" range="{lo} {hi}"
                 damping="0.01" armature="0.001"/>
          <geom name="hand_{side}_proximal" type="box" mass="0.03"
                size="{w} {t} {l1 / 2 + t / 2:.5f}" pos="0 0 {l1 / 2 - t / 2:.5f}"/>
          <geom name="hand_{side}_distal" type="box" mass="0.02"
                size="{w} {l2 / 2 + t / 2:.5f} {t}"
                pos="0 {-sign * (l2 / 2 - t / 2):.5f} {l1:.5f}"/>
        </body>"""


def hand_mjcf(cfg: HandConfig, mount_quat: tuple[float, float, float, float]) -> str:
    """The arm chain and hand as a <body> tree rooted at the world origin.

    mount_quat (w, x, y, z): the hand's orientation when all arm hinges are at zero.
    """
    px, py, pz = cfg.palm_half
    q = " ".join(f"{v:.8f}" for v in mount_quat)
    return f"""
    <body name="arm_x" gravcomp="1">
      <joint name="arm_x" type="slide" axis="1 0 0" armature="0.01"/>
      <inertial pos="0 0 0" mass="0.01" diaginertia="1e-5 1e-5 1e-5"/>
      <body name="arm_y" gravcomp="1">
        <joint name="arm_y" type="slide" axis="0 1 0" armature="0.01"/>
        <inertial pos="0 0 0" mass="0.01" diaginertia="1e-5 1e-5 1e-5"/>
        <body name="arm_z" gravcomp="1">
          <joint name="arm_z" type="slide" axis="0 0 1" armature="0.01"/>
          <inertial pos="0 0 0" mass="0.01" diaginertia="1e-5 1e-5 1e-5"/>
          <body name="arm_yaw" gravcomp="1">
            <joint name="arm_yaw" type="hinge" axis="0 0 1" armature="0.001"/>
            <inertial pos="0 0 0" mass="0.05" diaginertia="1e-5 1e-5 1e-5"/>
            <body name="arm_pitch" gravcomp="1">
              <joint name="arm_pitch" type="hinge" axis="0 1 0" armature="0.001"/>
              <inertial pos="0 0 0" mass="0.05" diaginertia="1e-5 1e-5 1e-5"/>
              <body name="arm_roll" gravcomp="1">
                <joint name="arm_roll" type="hinge" axis="1 0 0" armature="0.001"/>
                <inertial pos="0 0 0" mass="0.01" diaginertia="1e-5 1e-5 1e-5"/>
                <body name="{HAND_BODY}" quat="{q}" gravcomp="1">
                  <site name="{WRIST_SITE}" size="0.005"/>
                  <site name="{TCP_SITE}" pos="0 0 {cfg.tcp_depth}" size="0.004" rgba="1 0 0 1"/>
                  <geom name="hand_palm" type="box" size="{px} {py} {pz}" pos="0 0 {-pz}"
                        mass="{cfg.hand_mass}"/>
                  <geom name="hand_wrist" type="cylinder" size="0.025 0.02" pos="0 0 -0.04"
                        mass="0.001" contype="0" conaffinity="0" rgba="0.3 0.3 0.35 1"/>
                  {_finger(cfg, "left")}
                  {_finger(cfg, "right")}
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>"""


def hand_actuators(cfg: HandConfig) -> str:
    """Position actuators: the wrist impedance (arm joints) and the finger servos."""
    m = cfg.moving_mass
    kt, kr = cfg.translational_stiffness, cfg.rotational_stiffness
    ct = cfg.arm_damping(m, kt)
    cr = cfg.arm_damping(2e-3, kr)
    lines = [
        f'<position name="{j}" joint="{j}" kp="{kt}" kv="{ct:.4f}" ctrlrange="-5 5"/>'
        for j in ARM_JOINTS[:3]
    ]
    lines += [
        f'<position name="{j}" joint="{j}" kp="{kr}" kv="{cr:.5f}" ctrlrange="-6.3 6.3"/>'
        for j in ARM_JOINTS[3:]
    ]
    lines += [
        f'<position name="{j}" joint="{j}" kp="{cfg.finger_stiffness}" '
        f'kv="{cfg.finger_damping}" ctrlrange="-1.5 1.5"/>'
        for j in FINGER_JOINTS
    ]
    return "\n    ".join(lines)


def hand_sensors() -> str:
    return (
        f'<force name="{FORCE_SENSOR}" site="{WRIST_SITE}"/>\n'
        f'    <torque name="{TORQUE_SENSOR}" site="{WRIST_SITE}"/>'
    )


def hand_defaults(cfg: HandConfig) -> str:
    """Contact parameters of the hand's geoms (class "hand")."""
    return (
        f'<geom friction="{cfg.friction} {cfg.torsional_friction} 0.0001" condim="4" '
        f'solref="0.004 1" solimp="0.95 0.99 0.001" rgba="0.85 0.7 0.55 1"/>'
    )


def hand_spec(cfg: HandConfig, mount_quat: tuple[float, float, float, float]) -> MjSpec:
    """The arm chain, hand, actuators and wrist sensors as one spec, to attach to a scene.

    mount_quat (w, x, y, z): the hand's orientation when all arm hinges are at zero.
    """
    body = hand_mjcf(cfg, mount_quat).replace(
        f'name="{HAND_BODY}"', f'name="{HAND_BODY}" childclass="hand"'
    )
    xml = f"""<mujoco model="hook-hand">
  <compiler angle="radian"/>
  <default><default class="hand">{hand_defaults(cfg)}</default></default>
  <worldbody>{body}</worldbody>
  <actuator>{hand_actuators(cfg)}</actuator>
  <sensor>{hand_sensors()}</sensor>
</mujoco>"""
    import mujoco  # here, not at import: sim.tasks (and so the package) must stay light

    return mujoco.MjSpec.from_string(xml)
