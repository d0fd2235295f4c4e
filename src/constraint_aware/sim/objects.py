"""Articulated objects (one prismatic or revolute joint) as `mujoco.MjSpec`s from typed
parameters.

Conventions: world z is up. A prismatic object slides along `axis` (its opening direction); a
revolute object turns about `axis` through `position` (right-handed: positive = opening), and
its handle sits `radius` from the axis along `radial` at joint angle 0. Any placement works:
any yaw, hinges on either side (a left-hinged door turns about -z), horizontal hinges (a lid
opened upwards) and vertical slides (a sash window); `object_frame` derives the handle's frame
from these fields alone, always right-handed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from constraint_aware.errors import (
    ConfigError,
    InvalidInputError,
    check_choice,
    check_number,
    check_vector,
)
from constraint_aware.geometry import unit

if TYPE_CHECKING:
    from mujoco import MjsBody, MjsGeom, MjSpec

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


def object_frame(cfg: ObjectConfig) -> np.ndarray:
    """(3, 3) right-handed columns (out, side, up) at the handle, joint position 0.

    out points from the object toward the hand: the opening direction (prismatic: the axis;
    revolute: the opening tangent axis x radial). The rest follows the handle:
    - bar on a hinge (door, lid): up = the hinge axis (the bar runs along it), whatever its
      sign or tilt: a left-hinged door (axis -z) gets up = -z, a lid (horizontal hinge) a
      horizontal up;
    - bar on a slide (drawer, window): side = the bar (`handle_axis`, else horizontal and
      across the slide; for a vertical slide world y), signed so that up does not point
      below the horizon;
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
        if float(np.cross(out, side) @ z) < 0.0:
            # a bar has no direction: +-handle_axis is the same bar. Sign it so that up is not
            # below the horizon, as for the horizontal default (a demonstration's plane normal
            # comes with either sign; taken as given it hung the hand upside down)
            side = -side
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


# --- the object as an MjSpec ---------------------------------------------------------------
# Builders add elements in the order the compiled model lists them: the scenery (world body),
# then the moving body's joint, main part, handle site and handle geoms.

#: Scenes are built on a grid: positions [m], directions and colours to 1e-6, orientations
#: (quaternions) to 1e-8, the resolution the MJCF templates these builders replaced printed
#: with. On the grid a scene is the same to the bit however its numbers were computed (frame
#: products or sums), and that matters: the hand's squeeze grasps are sensitive to the last
#: bit (measured: moving a finger plate by 2e-18 m changes a sideways pole's wrist force by
#: 0.02 N within 27 steps; a door with a squeezed pole chatters, and 1e-10 m shifts its
#: phase), so off the grid every refactoring would change stored runs.
GRID_DECIMALS = 6
QUAT_DECIMALS = 8

#: Colours [rgba] of the parts that do not take the object's own colour.
METAL_RGBA = (0.75, 0.75, 0.78, 1.0)  # bars, poles, posts
PLATE_RGBA = (0.8, 0.8, 0.85, 1.0)
KNOB_RGBA = (0.8, 0.3, 0.3, 1.0)
STEM_RGBA = (0.6, 0.6, 0.6, 1.0)
HUB_RGBA = (0.3, 0.3, 0.3, 1.0)
SCENERY_RGBA = (0.8, 0.8, 0.78, 1.0)
VISUAL_GROUP = 1  # the visual parts (main part, furniture): no contact with a hand
#: Contact bit that robot-arm geoms carry and the hook hand's do not: dm-control's convention
#: (the Jaco's geoms: contype 3 = bits 1 | 2, conaffinity 2; the hook hand's: contype =
#: conaffinity = 1). An object built `solid_for_arms` gives its visual parts this
#: conaffinity (contype 0): an arm's links and fingers then touch the door panel, drawer box,
#: crank arm and the furniture, while the hook hand's contacts (and runs) stay as they are and
#: the object's parts never touch each other or the handle.
ARM_CONTACT_BIT = 2
POST_RADIUS = 0.005  # [m] the bar's standoff posts
KNOB_STEM = 0.06  # [m] knob: the stem from the knob down to the crank arm
PANEL_HALF_THICKNESS = 0.015  # [m] door / lid panel
PANEL_OVERHANG = 0.1  # [m] door / lid panel past the handle, away from the hinge
HANDLE_SITE_SIZE = 0.004  # [m]


def object_spec(cfg: ObjectConfig, solid_for_arms: bool = False) -> MjSpec:
    """The object as its own spec, ready to attach to a scene (sim/scene.py): static scenery in
    the world body and the moving body `OBJECT_BODY` with its joint, main part, handle site and
    handle, everything in world coordinates (the world origin is the scene's).

    solid_for_arms: the visual parts (main part, scenery) collide with geoms carrying
    `ARM_CONTACT_BIT` in their contype (a real arm's), still not with the hook hand's.
    """
    import mujoco  # here, not at import: sim.tasks (and so the package) must stay light

    spec = mujoco.MjSpec()
    spec.modelname = "object"
    spec.compiler.degree = False
    add_object(spec.worldbody, cfg)
    if solid_for_arms:
        for geom in spec.geoms:
            if geom.group == VISUAL_GROUP and geom.contype == 0 and geom.conaffinity == 0:
                geom.conaffinity = ARM_CONTACT_BIT
    return spec


def add_object(world: MjsBody, cfg: ObjectConfig) -> MjsBody:
    """Add the object's scenery and moving body to `world` (a spec's world body); returns the
    moving body. Its joint is the only constraint: the main part (box, panel, arm, carriage)
    and the scenery are visual, without contacts; only the handle's geoms touch a hand."""
    frame = object_frame(cfg)
    handle = cfg.handle_position
    SCENERY_BUILDERS[_scenery_kind(cfg)](world, cfg, frame)
    if cfg.joint_type == "prismatic":
        body_pos, local_handle = handle, np.zeros(3)  # the body origin is the handle at q = 0
    else:
        body_pos = np.asarray(cfg.position, dtype=float)  # ... the hinge point
        local_handle = handle - body_pos
    body = world.add_body(name=OBJECT_BODY, pos=on_grid(body_pos), gravcomp=cfg.counterbalance)
    _add_joint(body, cfg)
    MOVING_PART_BUILDERS[_moving_part_kind(cfg)](body, cfg, frame, local_handle)
    body.add_site(
        name=HANDLE_SITE,
        pos=on_grid(local_handle),
        size=[HANDLE_SITE_SIZE, 0.005, 0.005],
        rgba=[0.0, 1.0, 0.0, 1.0],
    )
    # the handle in its own frame: x out (toward the hand), y along a bar, z up
    if cfg.handle == "bar" and cfg.joint_type == "revolute":
        out, side, up = frame[:, 0], frame[:, 1], frame[:, 2]
        handle_axes = np.stack([out, up, -side], axis=1)  # a door's bar runs along its hinge
    else:
        handle_axes = frame  # a drawer's bar runs along `side`
    HANDLE_BUILDERS[cfg.handle](body, HandleFrame(local_handle, handle_axes), cfg)
    return body


def _add_joint(body: MjsBody, cfg: ObjectConfig) -> None:
    import mujoco

    joint = mujoco.mjtJoint
    kind = joint.mjJNT_SLIDE if cfg.joint_type == "prismatic" else joint.mjJNT_HINGE
    body.add_joint(
        name=OBJECT_JOINT,
        type=kind,
        axis=on_grid(cfg.axis),
        pos=[0.0, 0.0, 0.0],  # a hinge passes through the body origin, `position`
        damping=cfg.damping,
        frictionloss=cfg.frictionloss,
        range=list(cfg.joint_range),
        limited=mujoco.mjtLimited.mjLIMITED_TRUE,
        armature=0.01,
    )


# --- handles: one builder per shape, in the handle's frame (x out, y along a bar, z up) -----
@dataclass(frozen=True)
class HandleFrame:
    """The handle's frame in its body: origin (3,) [m] the grasp centre, axes (3, 3) columns =
    the frame's x (out, toward the hand), y (along a bar), z (up) in body coordinates.

    The builders place geoms through it in body coordinates rather than in an `MjsFrame`: a
    capsule or cylinder given by `fromto` inside a rotated frame compiles to the same axis
    but a different turn about it, and MuJoCo's convex collision of a cylinder depends on that
    turn (measured: the wrist force of a 30-step pole run moved by up to 0.05 N), which would
    change the hook hand's runs.
    """

    origin: np.ndarray
    axes: np.ndarray

    def point(self, x: float, y: float, z: float) -> list[float]:
        """(3,) [m] body coordinates of the handle-frame point (x, y, z), on the grid."""
        return on_grid(self.origin + self.axes @ np.array([x, y, z]))

    def segment(self, a: tuple[float, float, float], b: tuple[float, float, float]) -> list[float]:
        """A `fromto` (6,) [m] in body coordinates from two handle-frame points."""
        return [*self.point(*a), *self.point(*b)]

    @property
    def quat(self) -> list[float]:
        return _quat(self.axes)


def _handle_friction(cfg: ObjectConfig) -> list[float]:
    return [cfg.friction, 0.005, 0.0001]


def _bar_handle(body: MjsBody, at: HandleFrame, cfg: ObjectConfig) -> None:
    """A bar along y on two posts reaching back (-x) `standoff` to the panel; hooked (lazy
    closure)."""
    import mujoco

    capsule = mujoco.mjtGeom.mjGEOM_CAPSULE
    half, s = cfg.handle_length / 2, cfg.standoff
    body.add_geom(
        name="object_handle",
        type=capsule,
        size=[cfg.handle_radius, 0.0, 0.0],
        fromto=at.segment((0.0, -half, 0.0), (0.0, half, 0.0)),
        friction=_handle_friction(cfg),
        rgba=list(METAL_RGBA),
    )
    for i, y in enumerate((-0.7 * half, 0.7 * half)):
        body.add_geom(
            name=f"object_post{i}",
            type=capsule,
            size=[POST_RADIUS, 0.0, 0.0],
            fromto=at.segment((-s, y, 0.0), (-s / 2, y, 0.0)),
            friction=_handle_friction(cfg),
            rgba=list(METAL_RGBA),
        )


def _pole_handle(body: MjsBody, at: HandleFrame, cfg: ObjectConfig) -> None:
    """A vertical cylinder, most of it below the grasp centre; squeezed (active closure)."""
    import mujoco

    half = cfg.handle_length / 2
    body.add_geom(
        name="object_handle",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[cfg.handle_radius, 0.0, 0.0],
        fromto=at.segment((0.0, 0.0, -2.5 * half), (0.0, 0.0, half)),
        friction=_handle_friction(cfg),
        rgba=list(METAL_RGBA),
    )


def _top_box(body: MjsBody, at: HandleFrame, cfg: ObjectConfig, rgba: Sequence[float]) -> None:
    """The handle box of half sizes `cfg.handle_half` [m] whose top face is the grasp centre."""
    import mujoco

    body.add_geom(
        name="object_handle",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        size=list(cfg.handle_half),
        pos=at.point(0.0, 0.0, -cfg.handle_half[2]),
        quat=at.quat,
        friction=_handle_friction(cfg),
        rgba=list(rgba),
    )


def _plate_handle(body: MjsBody, at: HandleFrame, cfg: ObjectConfig) -> None:
    """A box whose top face is the grasp centre; pressed from above (passive closure)."""
    _top_box(body, at, cfg, PLATE_RGBA)


def _knob_handle(body: MjsBody, at: HandleFrame, cfg: ObjectConfig) -> None:
    """A box on a thin stem, its top face the grasp centre; held by palm and fingers at a fixed
    orientation (passive closure)."""
    import mujoco

    hz = cfg.handle_half[2]
    _top_box(body, at, cfg, KNOB_RGBA)
    body.add_geom(
        name="object_stem",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.003, 0.0, 0.0],
        fromto=at.segment((0.0, 0.0, -2 * hz), (0.0, 0.0, -(2 * hz + KNOB_STEM))),
        rgba=list(STEM_RGBA),
    )


HANDLE_BUILDERS: dict[str, Callable[[MjsBody, HandleFrame, ObjectConfig], None]] = {
    "bar": _bar_handle,
    "pole": _pole_handle,
    "plate": _plate_handle,
    "knob": _knob_handle,
}


# --- the moving part's main body: visual, carries the object's mass -------------------------
# Body coordinates (axes = world axes); `handle` is the handle's centre in them, `frame` the
# object frame (out, side, up).
def _visual(geom: MjsGeom) -> None:
    geom.contype = 0  # the joint is the constraint; the part only shows and weighs
    geom.conaffinity = 0
    geom.group = VISUAL_GROUP


def _drawer_front(body: MjsBody, cfg: ObjectConfig, frame: np.ndarray, handle: np.ndarray) -> None:
    """Prismatic bar (drawer, window): the drawer box / sash behind the bar's posts."""
    import mujoco

    px = cfg.panel_half[0]
    _visual(
        body.add_geom(
            name="object_box",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=list(cfg.panel_half),
            pos=on_grid(handle - (cfg.standoff + px) * frame[:, 0]),
            quat=_quat(frame),
            rgba=on_grid(cfg.rgba),
            mass=cfg.mass,
        )
    )


def _door_panel(body: MjsBody, cfg: ObjectConfig, frame: np.ndarray, handle: np.ndarray) -> None:
    """Revolute bar (door, lid): a panel from the hinge to `PANEL_OVERHANG` past the handle,
    behind the bar's posts."""
    import mujoco

    out, up = frame[:, 0], frame[:, 2]
    radial = np.asarray(cfg.radial, dtype=float)
    length = cfg.radius + PANEL_OVERHANG
    t = PANEL_HALF_THICKNESS
    centre = handle - (cfg.standoff + t) * out - (cfg.radius - length / 2) * radial
    panel_frame = np.stack([out, -radial, up], axis=1)  # right-handed: up is the hinge axis
    _visual(
        body.add_geom(
            name="object_panel",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[t, length / 2, cfg.panel_half[2]],
            pos=on_grid(centre),
            quat=_quat(panel_frame),
            rgba=on_grid(cfg.rgba),
            mass=cfg.mass,
        )
    )


def _crank_arm(body: MjsBody, cfg: ObjectConfig, frame: np.ndarray, handle: np.ndarray) -> None:
    """Revolute knob or pole (crank): an arm from the hub to below the handle's stem."""
    import mujoco

    below = handle - (2 * cfg.handle_half[2] + KNOB_STEM) * frame[:, 2]
    hub = below - cfg.radius * np.asarray(cfg.radial, dtype=float)
    _visual(
        body.add_geom(
            name="object_arm",
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            size=[0.008, 0.0, 0.0],
            fromto=on_grid([*hub, *below]),
            rgba=on_grid(cfg.rgba),
            mass=cfg.mass,
        )
    )
    _visual(
        body.add_geom(
            name="object_hub",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[0.02, 0.01, 0.0],
            pos=on_grid(hub),
            rgba=list(HUB_RGBA),
            mass=0.01,
        )
    )


def _pole_carriage(body: MjsBody, cfg: ObjectConfig, frame: np.ndarray, handle: np.ndarray) -> None:
    """Prismatic pole: a carriage on the rail below the pole."""
    import mujoco

    _visual(
        body.add_geom(
            name="object_carriage",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.04, 0.04, 0.02],
            pos=on_grid(handle - 0.2 * frame[:, 2]),
            rgba=on_grid(cfg.rgba),
            mass=cfg.mass,
        )
    )


def _plate_carriage(
    body: MjsBody, cfg: ObjectConfig, frame: np.ndarray, handle: np.ndarray
) -> None:
    """Prismatic plate or knob: a carriage just below it (the handle geom is the plate
    itself; the carriage gives the part the object's mass)."""
    import mujoco

    _visual(
        body.add_geom(
            name="object_carriage",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.03, 0.03, 0.005],
            pos=on_grid(handle - (2 * cfg.handle_half[2] + 0.005) * frame[:, 2]),
            rgba=on_grid(cfg.rgba),
            mass=cfg.mass,
        )
    )


MovingPartBuilder = Callable[["MjsBody", ObjectConfig, np.ndarray, np.ndarray], None]
MOVING_PART_BUILDERS: dict[str, MovingPartBuilder] = {
    "drawer_front": _drawer_front,
    "door_panel": _door_panel,
    "crank_arm": _crank_arm,
    "pole_carriage": _pole_carriage,
    "plate_carriage": _plate_carriage,
}


def _moving_part_kind(cfg: ObjectConfig) -> str:
    if cfg.joint_type == "revolute":
        return "door_panel" if cfg.handle == "bar" else "crank_arm"
    return {"bar": "drawer_front", "pole": "pole_carriage"}.get(cfg.handle, "plate_carriage")


# --- static scenery in the world body: visual context --------------------------------------
def _scenery_geom(world: MjsBody, name: str) -> MjsGeom:
    geom = world.add_geom(name=name, rgba=list(SCENERY_RGBA))
    _visual(geom)
    return geom


def _cabinet(world: MjsBody, cfg: ObjectConfig, frame: np.ndarray) -> None:
    """Prismatic bar: the cabinet (or window frame) around the drawer box."""
    import mujoco

    px, py, pz = cfg.panel_half
    geom = _scenery_geom(world, "scene_cabinet")
    geom.type = mujoco.mjtGeom.mjGEOM_BOX
    geom.size = [px, py + 0.03, pz + 0.03]
    geom.pos = on_grid(cfg.handle_position - (cfg.standoff + px + 0.02) * frame[:, 0])
    geom.quat = _quat(frame)


def _rail(world: MjsBody, cfg: ObjectConfig, frame: np.ndarray) -> None:
    """Prismatic pole or plate: the rail the carriage runs on."""
    import mujoco

    out, up = frame[:, 0], frame[:, 2]
    h = cfg.handle_position
    rail = h - 0.25 * up if cfg.handle == "pole" else h - (2 * cfg.handle_half[2] + 0.02) * up
    geom = _scenery_geom(world, "scene_rail")
    geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
    geom.size = [0.01, 0.0, 0.0]
    geom.fromto = on_grid([*(rail - 0.1 * out), *(rail + 0.4 * out)])


def _hinge_post(world: MjsBody, cfg: ObjectConfig, frame: np.ndarray) -> None:
    """Revolute: a post along the hinge axis, from 0.3 m below the handle's height: a door's or
    a lid's along the hinged edge to 0.3 m above it; a crank's (a knob or a pole on a hinge)
    shaft up to its hub only (the crank is turned from above its handle, where a shaft would
    stand in the hand's way)."""
    import mujoco

    p, up = np.asarray(cfg.position, dtype=float), frame[:, 2]
    geom = _scenery_geom(world, "scene_hinge")
    geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
    geom.size = [0.012, 0.0, 0.0]
    top = p + 0.3 * up
    if cfg.handle in ("knob", "pole"):
        top = p - (2 * cfg.handle_half[2] + KNOB_STEM) * up  # the hub, as `_crank_arm` has it
    geom.fromto = on_grid([*(p - 0.3 * up), *top])


SCENERY_BUILDERS: dict[str, Callable[[MjsBody, ObjectConfig, np.ndarray], None]] = {
    "cabinet": _cabinet,
    "rail": _rail,
    "hinge_post": _hinge_post,
}


def _scenery_kind(cfg: ObjectConfig) -> str:
    if cfg.joint_type == "revolute":
        return "hinge_post"
    return "cabinet" if cfg.handle == "bar" else "rail"


def _quat(frame: np.ndarray) -> list[float]:
    """(4,) quaternion (w, x, y, z) of a (3, 3) rotation whose columns are the rotated frame's
    axes, on the orientation grid (MuJoCo normalizes it)."""
    import mujoco

    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(frame, dtype=float).reshape(9))
    return [round(float(c), QUAT_DECIMALS) for c in q]


def on_grid(v: np.ndarray | tuple[float, ...] | list[float]) -> list[float]:
    """The numbers of a position [m], direction or colour on the scene's grid (`GRID_DECIMALS`)."""
    return [round(float(c), GRID_DECIMALS) for c in v]
