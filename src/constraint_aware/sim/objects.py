"""Articulated objects (one prismatic or revolute joint) as MJCF from typed parameters.

Conventions: world z is up. A prismatic object slides along `axis` (its opening direction); a
revolute object turns about `axis` through `position` (right-handed: positive = opening), and
its handle sits `radius` from the axis along `radial` at joint angle 0. Any placement works:
any yaw, hinges on either side (a left-hinged door turns about -z), horizontal hinges (a lid
opened upwards) and vertical slides (a sash window); `object_frame` derives the handle's frame
from these fields alone, always right-handed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from constraint_aware.errors import (
    ConfigError,
    InvalidInputError,
    check_choice,
    check_number,
    check_vector,
)
from constraint_aware.geometry import unit

JointType = Literal["prismatic", "revolute"]
HandleShape = Literal["bar", "pole", "plate", "knob"]

OBJECT_BODY = "object"
OBJECT_JOINT = "object_joint"
HANDLE_SITE = "handle"
OBJECT_GEOM_PREFIX = "object_"


@dataclass(frozen=True)
class ObjectConfig:
    """One articulated object. Units: m, kg, N, rad; vectors in the world frame."""

    joint_type: JointType = "prismatic"
    handle: HandleShape = "bar"  # what the hand grasps
    position: tuple[float, float, float] = (0.0, 0.0, 0.8)  # prismatic: handle centre at q=0;
    # revolute: a point on the hinge axis
    axis: tuple[float, float, float] = (1.0, 0.0, 0.0)  # slide direction / hinge axis
    radial: tuple[float, float, float] = (0.0, -1.0, 0.0)  # revolute: hinge -> handle at q=0
    radius: float = 0.5  # [m] revolute: hinge axis to handle centre
    handle_radius: float = 0.0135  # [m] bar / pole radius (the hand's hook leaves ~1.5 mm)
    handle_length: float = 0.12  # [m] bar / pole length
    handle_half: tuple[float, float, float] = (0.013, 0.02, 0.012)  # [m] knob/plate half-sizes:
    # along (radial or the guide, the other horizontal, vertical)
    standoff: float = 0.04  # [m] bar: centre to the panel / drawer front
    mass: float = 2.0  # [kg] moving part
    damping: float = 2.0  # [N s/m] or [N m s/rad] joint damping
    frictionloss: float = 1.0  # [N] or [N m] dry friction of the joint
    joint_range: tuple[float, float] = (-0.01, 0.5)  # [m] or [rad]
    friction: float = 1.0  # [-] contact friction of the handle's surface
    panel_half: tuple[float, float, float] = (0.2, 0.2, 0.08)  # [m] drawer box / door / plate
    handle_axis: tuple[float, float, float] | None = None  # prismatic bar: the direction the
    # bar runs; None: horizontal and across the slide (for a vertical slide: world y)
    counterbalance: float = 0.0  # [-] share of the moving part's weight carried by a balance
    # (sash weights, spring balances, gas struts): MuJoCo's gravcomp on the moving body
    rgba: tuple[float, float, float, float] = (0.55, 0.4, 0.25, 1.0)

    def __post_init__(self) -> None:
        n = "ObjectConfig."
        check_choice(n + "joint_type", self.joint_type, ("prismatic", "revolute"))
        check_choice(n + "handle", self.handle, ("bar", "knob", "plate", "pole"))
        check_vector(n + "position", self.position, unit="m")
        axis = check_vector(n + "axis", self.axis, nonzero=True)
        if abs(np.linalg.norm(axis) - 1.0) > 1e-6:
            raise ConfigError(n + "axis", self.axis, "a unit vector")
        if self.joint_type == "revolute":
            radial = check_vector(n + "radial", self.radial, nonzero=True)
            if abs(float(np.dot(axis, radial))) > 1e-6:
                raise ConfigError(n + "radial", self.radial, "perpendicular to the hinge axis")
        for name in ("radius", "handle_radius", "handle_length", "mass"):
            check_number(n + name, getattr(self, name), low=0, low_open=True)
        for name in ("standoff", "damping", "frictionloss", "friction"):
            check_number(n + name, getattr(self, name), low=0)
        for name in ("handle_half", "panel_half"):
            half = check_vector(n + name, getattr(self, name), unit="m")
            if min(half) <= 0:
                raise ConfigError(n + name, getattr(self, name), "3 positive numbers [m]")
        lo, hi = check_vector(n + "joint_range", self.joint_range, size=2)
        if not (lo <= 0 <= hi and lo < hi):
            raise ConfigError(n + "joint_range", self.joint_range, "(low, high), low <= 0 <= high")
        check_vector(n + "rgba", self.rgba, size=4)
        check_number(n + "counterbalance", self.counterbalance, low=0, high=1)
        if self.handle_axis is not None:
            bar = check_vector(n + "handle_axis", self.handle_axis, nonzero=True)
            if abs(np.linalg.norm(bar) - 1.0) > 1e-6:
                raise ConfigError(n + "handle_axis", self.handle_axis, "a unit vector")
            if abs(float(np.dot(bar, axis))) > 0.99:
                raise ConfigError(n + "handle_axis", self.handle_axis, "not along the slide axis")

    @property
    def opening_direction(self) -> np.ndarray:
        """(3,) unit: the handle's direction of motion at joint position 0 (prismatic: axis;
        revolute: axis x radial, the opening tangent)."""
        axis = np.asarray(self.axis, dtype=float)
        if self.joint_type == "prismatic":
            return axis
        return np.cross(axis, np.asarray(self.radial, dtype=float))

    @property
    def handle_position(self) -> np.ndarray:
        """(3,) [m] world position of the handle's grasp centre at joint position 0."""
        p = np.asarray(self.position, dtype=float)
        if self.joint_type == "revolute":
            return p + self.radius * np.asarray(self.radial, dtype=float)
        return p


def _v(x: np.ndarray | tuple[float, ...]) -> str:
    return " ".join(f"{float(c):.6f}" for c in x)


def _handle_geoms(cfg: ObjectConfig, at: np.ndarray, frame: np.ndarray) -> str:
    """Handle geoms centred at `at` (body frame); frame columns: (out, side, up) unit vectors.

    out: from the object toward the hand; side: the other horizontal; up: vertical.
    """
    out, side, up = frame[:, 0], frame[:, 1], frame[:, 2]
    r, half = cfg.handle_radius, cfg.handle_length / 2
    fr = f'friction="{cfg.friction} 0.005 0.0001"'
    if cfg.handle == "bar":
        # the bar runs along `side` for a drawer, along `up` for a door: chosen by the caller
        a0, a1 = at - half * side, at + half * side
        p0 = a0 + 0.3 * half * side - cfg.standoff * out / 2
        p1 = a1 - 0.3 * half * side - cfg.standoff * out / 2
        post = f'type="capsule" size="0.005" {fr}'
        return f"""
      <geom name="object_handle" type="capsule" size="{r}" fromto="{_v(a0)} {_v(a1)}" {fr}
            rgba="0.75 0.75 0.78 1"/>
      <geom name="object_post0" {post} fromto="{_v(p0 - cfg.standoff * out / 2)} {_v(p0)}"
            rgba="0.75 0.75 0.78 1"/>
      <geom name="object_post1" {post} fromto="{_v(p1 - cfg.standoff * out / 2)} {_v(p1)}"
            rgba="0.75 0.75 0.78 1"/>"""
    if cfg.handle == "pole":
        a0, a1 = at - 2.5 * half * up, at + half * up
        return f"""
      <geom name="object_handle" type="cylinder" size="{r}" fromto="{_v(a0)} {_v(a1)}" {fr}
            rgba="0.75 0.75 0.78 1"/>"""
    hx, hy, hz = cfg.handle_half
    quat = _quat_from_frame(frame)
    if cfg.handle == "plate":
        return f"""
      <geom name="object_handle" type="box" size="{hx} {hy} {hz}" pos="{_v(at - hz * up)}"
            quat="{quat}" {fr} rgba="0.8 0.8 0.85 1"/>"""
    # knob: a box on a thin stem, its top face at `at`
    stem_len = 0.06
    top = at - hz * up
    return f"""
      <geom name="object_handle" type="box" size="{hx} {hy} {hz}" pos="{_v(top)}"
            quat="{quat}" {fr} rgba="0.8 0.3 0.3 1"/>
      <geom name="object_stem" type="cylinder" size="0.003"
            fromto="{_v(at - 2 * hz * up)} {_v(at - (2 * hz + stem_len) * up)}"
            rgba="0.6 0.6 0.6 1"/>"""


def _quat_from_frame(frame: np.ndarray) -> str:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(frame).as_quat()
    return f"{w:.8f} {x:.8f} {y:.8f} {z:.8f}"


def object_frame(cfg: ObjectConfig) -> np.ndarray:
    """(3, 3) right-handed columns (out, side, up) at the handle, joint position 0.

    out points from the object toward the hand: the opening direction (prismatic: the axis;
    revolute: the opening tangent axis x radial). The rest follows the handle:
    - bar on a hinge (door, lid): up = the hinge axis (the bar runs along it), whatever its
      sign or tilt: a left-hinged door (axis -z) gets up = -z, a lid (horizontal hinge) a
      horizontal up;
    - bar on a slide (drawer, window): side = the bar (`handle_axis`, else horizontal and
      across the slide; for a vertical slide world y);
    - plate, pole: up = world z (pressed from above; a vertical pole);
    - knob: up = the hinge axis signed upward (the hand presses the crank from above
      whichever way it turns).
    """
    out = unit(cfg.opening_direction)
    axis = np.asarray(cfg.axis, dtype=float)
    z = np.array([0.0, 0.0, 1.0])
    if cfg.handle == "bar" and cfg.joint_type == "revolute":
        up_ref = axis
    elif cfg.handle == "knob" and cfg.joint_type == "revolute":
        up_ref = axis if float(axis @ z) >= 0.0 else -axis
    elif cfg.handle == "bar" and (cfg.handle_axis is not None or abs(float(out @ z)) > 0.9):
        bar = np.asarray(cfg.handle_axis if cfg.handle_axis is not None else (0.0, 1.0, 0.0))
        side = bar - float(bar @ out) * out
        if np.linalg.norm(side) < 1e-6:
            raise InvalidInputError("handle_axis must not be parallel to the slide axis")
        side = unit(side)
        return np.stack([out, side, np.cross(out, side)], axis=1)
    else:
        up_ref = z
    side = np.cross(up_ref, out)
    if np.linalg.norm(side) < 1e-9:
        raise InvalidInputError(
            f"the opening direction {tuple(np.round(out, 3))} must not be parallel to the "
            f"{'hinge axis' if up_ref is axis else 'vertical'} for a {cfg.handle} handle"
        )
    side = unit(side)
    up = np.cross(out, side)
    return np.stack([out, side, up], axis=1)


def object_mjcf(cfg: ObjectConfig) -> str:
    """The object's <body> tree (moving part, handle, joint) plus static visual scenery."""
    frame = object_frame(cfg)
    out, side, up = frame[:, 0], frame[:, 1], frame[:, 2]
    handle = cfg.handle_position
    px, py, pz = cfg.panel_half
    lo, hi = cfg.joint_range
    joint_common = (
        f'name="{OBJECT_JOINT}" damping="{cfg.damping}" frictionloss="{cfg.frictionloss}" '
        f'range="{lo} {hi}" limited="true" armature="0.01"'
    )
    if cfg.joint_type == "prismatic":
        body_pos = handle
        joint = f'<joint {joint_common} type="slide" axis="{_v(cfg.axis)}"/>'
        local_handle = np.zeros(3)
    else:
        body_pos = np.asarray(cfg.position, dtype=float)
        joint = f'<joint {joint_common} type="hinge" axis="{_v(cfg.axis)}" pos="0 0 0"/>'
        local_handle = handle - body_pos
    quat = _quat_from_frame(frame)
    if cfg.handle == "bar" and cfg.joint_type == "prismatic":
        bar_frame = frame  # horizontal bar along `side`
    elif cfg.handle == "bar":
        bar_frame = np.stack([out, up, -side], axis=1)  # vertical bar on a door
    else:
        bar_frame = frame
    handle_xml = _handle_geoms(cfg, local_handle, bar_frame)
    # the moving part's main body (visual, no collisions: the joint is the constraint)
    vis = 'contype="0" conaffinity="0" group="1"'
    if cfg.handle == "bar" and cfg.joint_type == "prismatic":
        centre = local_handle - (cfg.standoff + px) * out
        main = (
            f'<geom name="object_box" type="box" size="{px} {py} {pz}" pos="{_v(centre)}" '
            f'quat="{quat}" {vis} rgba="{_v(cfg.rgba)}" mass="{cfg.mass}"/>'
        )
    elif cfg.joint_type == "revolute" and cfg.handle == "bar":
        # door panel from the hinge to past the handle, behind the bar
        length = cfg.radius + 0.1
        centre = (
            local_handle - cfg.standoff * out - (cfg.radius - length / 2) * np.asarray(cfg.radial)
        )
        door_frame = np.stack([out, -np.asarray(cfg.radial, float), up], axis=1)  # right-handed:
        # up follows the hinge axis (object_frame), so a left-hinged door's up is -z
        main = (
            f'<geom name="object_panel" type="box" size="0.015 {length / 2} {pz}" '
            f'pos="{_v(centre - 0.015 * out)}" quat="{_quat_from_frame(door_frame)}" {vis} '
            f'rgba="{_v(cfg.rgba)}" mass="{cfg.mass}"/>'
        )
    elif cfg.joint_type == "revolute":
        # crank arm from the hub to the knob, below the knob's stem
        below = local_handle - (2 * cfg.handle_half[2] + 0.06) * up
        hub = below - cfg.radius * np.asarray(cfg.radial, float)
        main = (
            f'<geom name="object_arm" type="capsule" size="0.008" fromto="{_v(hub)} '
            f'{_v(below)}" {vis} rgba="{_v(cfg.rgba)}" mass="{cfg.mass}"/>\n'
            f'      <geom name="object_hub" type="cylinder" size="0.02 0.01" pos="{_v(hub)}" '
            f'{vis} rgba="0.3 0.3 0.3 1" mass="0.01"/>'
        )
    elif cfg.handle == "pole":
        main = (
            f'<geom name="object_carriage" type="box" size="0.04 0.04 0.02" '
            f'pos="{_v(local_handle - 0.2 * up)}" {vis} rgba="{_v(cfg.rgba)}" '
            f'mass="{cfg.mass}"/>'
        )
    else:  # plate: the handle geom is the plate itself; give it the object's mass
        main = (
            f'<geom name="object_carriage" type="box" size="0.03 0.03 0.005" '
            f'pos="{_v(local_handle - (2 * cfg.handle_half[2] + 0.005) * up)}" {vis} '
            f'rgba="{_v(cfg.rgba)}" mass="{cfg.mass}"/>'
        )
    scenery = _scenery(cfg, frame)
    return f"""
    {scenery}
    <body name="{OBJECT_BODY}" pos="{_v(body_pos)}" gravcomp="{cfg.counterbalance}">
      {joint}
      {main}
      <site name="{HANDLE_SITE}" pos="{_v(local_handle)}" size="0.004" rgba="0 1 0 1"/>
      {handle_xml}
    </body>"""


def _scenery(cfg: ObjectConfig, frame: np.ndarray) -> str:
    """Static, non-colliding context: a cabinet, a rail, a wall, a table."""
    out, up = frame[:, 0], frame[:, 2]
    vis = 'contype="0" conaffinity="0" group="1" rgba="0.8 0.8 0.78 1"'
    h = cfg.handle_position
    if cfg.joint_type == "prismatic" and cfg.handle == "bar":
        px, py, pz = cfg.panel_half
        c = h - (cfg.standoff + px + 0.02) * out
        q = _quat_from_frame(frame)
        return (
            f'<geom name="scene_cabinet" type="box" size="{px} {py + 0.03} {pz + 0.03}" '
            f'pos="{_v(c)}" quat="{q}" {vis}/>'
        )
    if cfg.joint_type == "prismatic":
        rail = h - 0.25 * up if cfg.handle == "pole" else h - (2 * cfg.handle_half[2] + 0.02) * up
        a0, a1 = rail - 0.1 * out, rail + 0.4 * out
        return (
            f'<geom name="scene_rail" type="capsule" size="0.01" fromto="{_v(a0)} {_v(a1)}" {vis}/>'
        )
    p = np.asarray(cfg.position, float)
    a0, a1 = p - 0.3 * up, p + 0.3 * up
    return (
        f'<geom name="scene_hinge" type="cylinder" size="0.012" fromto="{_v(a0)} {_v(a1)}" {vis}/>'
    )
