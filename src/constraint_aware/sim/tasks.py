"""Tasks from objects: `task_from_object(kind, object_config)` builds a task for any placement
of a drawer, plate, pole, door, crank, lid or window; the paper's five tasks are named presets
of it (`task_config(name, **overrides)`).

Everything geometric (hand mount, workplane normal) is derived from the ObjectConfig, so a
moved, mirrored or re-sized object carries its task with it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from constraint_aware.errors import (
    ConfigError,
    InvalidInputError,
    UnknownNameError,
    check_choice,
    check_int,
    check_number,
)
from constraint_aware.sim.hand import HandConfig
from constraint_aware.sim.objects import ObjectConfig, object_frame

#: Prefixes of `TaskConfig.with_overrides` keys that reach a nested config.
OVERRIDE_PREFIXES = ("object__", "hand__")

ForceExertionType = Literal["lazy_closure", "active_force_closure", "passive_force_closure"]


@dataclass(frozen=True)
class TaskConfig:
    """A task: an object, how the hand grasps it, and what counts as success or failure."""

    name: str
    object: ObjectConfig
    force_exertion_type: ForceExertionType
    fixed_orientation: bool = False  # the grasp fixes the hand-object orientation (handle)
    hand: HandConfig = field(default_factory=HandConfig)
    finger_angle: float = 0.0  # [rad] finger servo target while grasping (+ closes)
    press_depth: float = 0.0  # [m] TCP commanded into the object along the palm normal
    success_progress: float = 0.25  # [m] prismatic or [rad] revolute
    force_limit: float = 60.0  # [N] damage limit of the object
    slip_limit: float = 0.03  # [m] hand-object drift that counts as a lost grasp
    slip_angle_limit: float | None = 30.0  # [deg] hand-object rotation drift that counts as
    # lost; None for lazy closures, which let the hand turn about the bar by design
    max_steps: int = 60  # control steps before a timeout

    def __post_init__(self) -> None:
        n = "TaskConfig."
        if not isinstance(self.name, str) or not self.name:
            raise ConfigError(n + "name", self.name, "a non-empty string")
        if not isinstance(self.object, ObjectConfig):
            raise ConfigError(n + "object", self.object, "an ObjectConfig")
        if not isinstance(self.hand, HandConfig):
            raise ConfigError(n + "hand", self.hand, "a HandConfig")
        check_choice(
            n + "force_exertion_type",
            self.force_exertion_type,
            ("lazy_closure", "active_force_closure", "passive_force_closure"),
        )
        check_number(n + "finger_angle", self.finger_angle, low=-1.5, high=1.5, unit="rad")
        check_number(n + "press_depth", self.press_depth, low=0, high=0.05, unit="m")
        unit = "rad" if self.object.joint_type == "revolute" else "m"
        check_number(n + "success_progress", self.success_progress, low=0, low_open=True, unit=unit)
        check_number(n + "force_limit", self.force_limit, low=0, low_open=True, unit="N")
        check_number(n + "slip_limit", self.slip_limit, low=0, low_open=True, unit="m")
        if self.slip_angle_limit is not None:
            check_number(
                n + "slip_angle_limit", self.slip_angle_limit, low=0, low_open=True, unit="deg"
            )
        check_int(n + "max_steps", self.max_steps, low=1)

    @property
    def constraint_type(self) -> str:
        return self.object.joint_type

    @property
    def workplane_normal(self) -> tuple[float, float, float]:
        """(3,) unit normal of the plane the hand moves in, from the object and its grasp.

        Revolute: the hinge axis (the motion turns positively about it). A bar on a slide: the
        bar's direction, since a lazy hook encloses the bar in the plane across it and only
        there carries force both ways (along the bar, friction alone). Plates and poles: the
        horizontal plane (pressed from above / a vertical pole squeezed from the side).
        """
        o = self.object
        if o.joint_type == "revolute":
            n = np.asarray(o.axis, dtype=float)
        elif o.handle == "bar":
            n = object_frame(o)[:, 1]
        else:
            n = object_frame(o)[:, 2]
        return (float(n[0]), float(n[1]), float(n[2]))

    def hand_mount(self) -> np.ndarray:
        """(3, 3) hand orientation at the grasp, columns = hand local (x, y, z) in world;
        right-handed for every placement because `object_frame` is."""
        frame = object_frame(self.object)
        out, side, up = frame[:, 0], frame[:, 1], frame[:, 2]
        if self.object.handle == "bar" and self.object.joint_type == "prismatic":
            z, y = -out, up  # horizontal bar: fingers above and below it
        elif self.object.handle in ("bar", "pole"):
            z, y = -out, side  # vertical bar or pole: fingers either side
        else:
            z, y = -up, side  # pressing from above; fingers across `side`
        return np.stack([np.cross(y, z), y, z], axis=1)

    def with_overrides(self, **overrides: Any) -> TaskConfig:
        """A copy with fields replaced; `object__mass=3` style keys reach the object config.

        Valid prefixes: `object__`, `hand__`; an unknown prefix or field raises UnknownNameError
        listing the valid ones, and the new values are validated (ConfigError)."""
        for k in overrides:
            if "__" in k and k.split("__", 1)[0] not in ("object", "hand"):
                raise UnknownNameError(
                    "override prefix", k.split("__", 1)[0] + "__", OVERRIDE_PREFIXES
                )
        obj_over = {k[8:]: v for k, v in overrides.items() if k.startswith("object__")}
        hand_over = {k[6:]: v for k, v in overrides.items() if k.startswith("hand__")}
        top = {k: v for k, v in overrides.items() if "__" not in k}
        valid = {f.name for f in dataclasses.fields(self)}
        for key, fields_of in (
            (list(top), valid),
            (list(obj_over), {f.name for f in dataclasses.fields(ObjectConfig)}),
            (list(hand_over), {f.name for f in dataclasses.fields(HandConfig)}),
        ):
            for k in key:
                if k not in fields_of:
                    raise UnknownNameError("task parameter", k, sorted(fields_of))
        cfg = dataclasses.replace(self, **top)
        if obj_over:
            cfg = dataclasses.replace(cfg, object=dataclasses.replace(cfg.object, **obj_over))
        if hand_over:
            cfg = dataclasses.replace(cfg, hand=dataclasses.replace(cfg.hand, **hand_over))
        return cfg


#: Object kinds the builder knows: the constraint and handle each implies, and typical physics
#: (mass [kg], joint damping [N s/m or N m s/rad], dry friction [N or N m]). The first five are
#: the paper's objects with the presets' numbers; lid and window are documented choices:
#: - lid: a 1 kg chest or box lid, hinged horizontally, lifted by a bar at its front edge, with
#:   a lid stay (torsion spring) carrying half its weight (counterbalance 0.5), as stays are
#:   sized so that a lid neither slams nor springs open. Without the stay its weight at the
#:   handle (up to m g / 2 = 4.9 N, falling as the lid rises) loads the hand; the placement
#:   benchmark (benchmarks/placement.py) measures that variant too.
#: - window: a 4 kg vertical sliding sash with sash balances (counterbalance 1: the sash stays
#:   where it is left, which is what balances are for); its 3 N channel friction remains.
KIND_OBJECTS: dict[str, dict[str, Any]] = {
    "drawer": dict(
        joint_type="prismatic", handle="bar", mass=2.0, damping=1.0, frictionloss=0.5,
        joint_range=(-0.005, 0.4), panel_half=(0.2, 0.2, 0.08),
    ),
    "plate": dict(
        joint_type="prismatic", handle="plate", handle_half=(0.08, 0.08, 0.005), mass=0.5,
        damping=1.0, frictionloss=0.5, joint_range=(-0.005, 0.4), friction=0.8,
        rgba=(0.8, 0.8, 0.85, 1.0),
    ),
    "pole": dict(
        joint_type="prismatic", handle="pole", handle_radius=0.016, handle_length=0.2, mass=1.0,
        damping=1.0, frictionloss=0.5, joint_range=(-0.005, 0.4), rgba=(0.4, 0.4, 0.45, 1.0),
    ),
    "window": dict(
        joint_type="prismatic", handle="bar", mass=4.0, damping=2.0, frictionloss=3.0,
        counterbalance=1.0, joint_range=(-0.005, 0.5), panel_half=(0.02, 0.4, 0.3),
        rgba=(0.7, 0.8, 0.9, 1.0),
    ),
    "door": dict(
        joint_type="revolute", handle="bar", radius=0.5, handle_length=0.14, mass=5.0,
        damping=1.0, frictionloss=0.5, joint_range=(-0.02, 1.7), panel_half=(0.015, 0.3, 0.4),
    ),
    "lid": dict(
        joint_type="revolute", handle="bar", radius=0.35, handle_length=0.12, mass=1.0,
        damping=0.5, frictionloss=0.2, joint_range=(-0.02, 1.9), panel_half=(0.015, 0.2, 0.25),
        counterbalance=0.5, rgba=(0.5, 0.35, 0.2, 1.0),
    ),
    "crank": dict(
        joint_type="revolute", handle="knob", radius=0.12, handle_half=(0.02, 0.013, 0.012),
        mass=0.5, damping=0.05, frictionloss=0.1, joint_range=(-0.02, 3.0),
        rgba=(0.3, 0.3, 0.35, 1.0),
    ),
}  # fmt: skip
KINDS: tuple[str, ...] = tuple(KIND_OBJECTS)

#: The grasp each handle shape takes (paper 3.1 / Saito et al. 2022 force-exertion types):
#: a bar is hooked (lazy closure; the hand may turn about the bar), a pole squeezed (active),
#: a plate pressed by the finger pads, a crank's knob held by palm and fingers at a fixed
#: orientation (passive).
HANDLE_GRASPS: dict[str, dict[str, Any]] = {
    "bar": dict(force_exertion_type="lazy_closure", slip_angle_limit=None, finger_angle=0.0),
    "pole": dict(force_exertion_type="active_force_closure", finger_angle=0.25),
    # straight fingers: their tip pads press on the plate
    "plate": dict(force_exertion_type="passive_force_closure", finger_angle=0.0,
                  press_depth=0.012),
    # fingers straddle the knob: its orientation is locked to the hand's
    "knob": dict(force_exertion_type="passive_force_closure", fixed_orientation=True,
                 finger_angle=0.0, press_depth=0.01),
}  # fmt: skip

#: [m] or [rad]: what counts as done when nobody said (the paper's 25 cm, 60 deg door, 90 deg
#: crank; a lid like a door; a window like a drawer).
KIND_SUCCESS: dict[str, float] = {
    "drawer": 0.25, "plate": 0.25, "pole": 0.25, "window": 0.25,
    "door": float(np.radians(60.0)), "lid": float(np.radians(60.0)),
    "crank": float(np.radians(90.0)),
}  # fmt: skip


def object_for(kind: str, **fields: Any) -> ObjectConfig:
    """The kind's physics with the given geometry (position, axis, radial, radius, ...)."""
    if kind not in KIND_OBJECTS:
        raise UnknownNameError("object kind", kind, list(KINDS))
    return ObjectConfig(**{**KIND_OBJECTS[kind], **fields})


def default_max_steps(obj: ObjectConfig, success_progress: float, step_length: float) -> int:
    """Steps to cover the goal's path at `step_length` [m] per step (the executor's), plus half
    again for steps spent correcting the direction and 20 for the start (the presets keep
    their own numbers)."""
    path = success_progress * (obj.radius if obj.joint_type == "revolute" else 1.0)
    return math.ceil(1.5 * path / step_length) + 20


def task_from_object(
    kind: str,
    obj: ObjectConfig,
    *,
    name: str | None = None,
    success_progress: float | None = None,
    max_steps: int | None = None,
    step_length: float | None = None,
    **fields: Any,
) -> TaskConfig:
    """A task for any placement of an object of `kind`: the grasp from its handle shape, the
    geometry (hand mount, workplane) from the object, the goal from `success_progress` (default:
    the kind's) and `max_steps`, or a timeout sized to the goal at `step_length` [m] per step
    (the executor's step: the caller knows it, the simulator does not)."""
    if kind not in KIND_OBJECTS:
        raise UnknownNameError("object kind", kind, list(KINDS))
    goal = KIND_SUCCESS[kind] if success_progress is None else float(success_progress)
    if max_steps is None:
        if step_length is None or step_length <= 0:
            raise InvalidInputError("task_from_object needs max_steps or a positive step_length")
        max_steps = default_max_steps(obj, goal, step_length)
    steps = max_steps
    grasp = {**HANDLE_GRASPS[obj.handle], **fields}
    return TaskConfig(
        name=name or kind,
        object=obj,
        success_progress=goal,
        max_steps=steps,
        **grasp,
    )


def drawer_opening() -> TaskConfig:
    obj = object_for("drawer", position=(0.0, 0.0, 0.8), axis=(1.0, 0.0, 0.0))
    return task_from_object("drawer", obj, name="drawer-opening", max_steps=60)


def plate_sliding() -> TaskConfig:
    obj = object_for("plate", position=(0.0, 0.0, 0.75), axis=(1.0, 0.0, 0.0))
    return task_from_object("plate", obj, name="plate-sliding", max_steps=60)


def pole_pulling() -> TaskConfig:
    obj = object_for("pole", position=(0.0, 0.0, 0.9), axis=(1.0, 0.0, 0.0))
    return task_from_object("pole", obj, name="pole-pulling", max_steps=60)


def door_opening() -> TaskConfig:
    obj = object_for(
        "door", position=(0.0, 0.5, 1.0), axis=(0.0, 0.0, 1.0), radial=(0.0, -1.0, 0.0)
    )
    return task_from_object("door", obj, name="door-opening", max_steps=90)


def handle_rotating() -> TaskConfig:
    obj = object_for(
        "crank", position=(0.0, 0.12, 0.8), axis=(0.0, 0.0, 1.0), radial=(0.0, -1.0, 0.0)
    )
    return task_from_object("crank", obj, name="handle-rotating", max_steps=60)


TASKS: dict[str, Callable[[], TaskConfig]] = {
    "drawer-opening": drawer_opening,
    "plate-sliding": plate_sliding,
    "pole-pulling": pole_pulling,
    "door-opening": door_opening,
    "handle-rotating": handle_rotating,
}


def task_config(preset: str | None = None, /, **overrides: Any) -> TaskConfig:
    """The preset (`TASKS`) with overrides (`TaskConfig.with_overrides` keys).

    The preset is the first argument, or `name=` when given alone. Unknown presets raise
    UnknownNameError listing the valid ones; a preset given both ways raises InvalidInputError
    naming `name` (rename a task with `.with_overrides(name=...)`)."""
    if preset is None:
        if "name" not in overrides:
            raise InvalidInputError(f"task_config: name the preset ({', '.join(TASKS)})")
        preset = overrides.pop("name")
    elif "name" in overrides:
        raise InvalidInputError(
            f"task_config({preset!r}, name={overrides['name']!r}): name is the preset, "
            "already given as the first argument; rename a task with "
            "task_config(...).with_overrides(name=...)"
        )
    if not isinstance(preset, str) or preset not in TASKS:
        raise UnknownNameError("task", str(preset), list(TASKS))
    cfg = TASKS[preset]()
    return cfg.with_overrides(**overrides) if overrides else cfg


def randomized(name: str, rng: np.random.Generator) -> TaskConfig:
    """The preset with friction, mass and damping drawn from documented ranges.

    Each of the joint's dry friction, the moving mass and the joint damping is scaled by a
    factor drawn uniformly from [0.5, 1.5] (log-uniform would favour light objects); the handle's
    contact friction is drawn from [0.7, 1.0].
    """
    base = task_config(name)
    o = base.object
    scale = rng.uniform(0.5, 1.5, size=3)
    return dataclasses.replace(
        base,
        object=dataclasses.replace(
            o,
            frictionloss=o.frictionloss * float(scale[0]),
            mass=o.mass * float(scale[1]),
            damping=o.damping * float(scale[2]),
            friction=float(rng.uniform(0.7, 1.0)),
        ),
    )
