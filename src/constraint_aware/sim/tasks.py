"""The paper's five tasks as typed presets, and the registry: `make(name, **overrides)`."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from constraint_aware.errors import (
    ConfigError,
    UnknownNameError,
    check_choice,
    check_int,
    check_number,
    check_unit_vector,
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
    workplane_normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

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
        normal = check_unit_vector(n + "workplane_normal", self.workplane_normal)
        object.__setattr__(self, "workplane_normal", normal)

    @property
    def constraint_type(self) -> str:
        return self.object.joint_type

    def hand_mount(self) -> np.ndarray:
        """(3, 3) hand orientation at the grasp, columns = hand local (x, y, z) in world."""
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


def drawer_opening() -> TaskConfig:
    return TaskConfig(
        name="drawer-opening",
        object=ObjectConfig(
            joint_type="prismatic",
            handle="bar",
            position=(0.0, 0.0, 0.8),
            axis=(1.0, 0.0, 0.0),
            mass=2.0,
            damping=1.0,
            frictionloss=0.5,
            joint_range=(-0.005, 0.4),
            panel_half=(0.2, 0.2, 0.08),
        ),
        force_exertion_type="lazy_closure",
        slip_angle_limit=None,
        finger_angle=0.0,
        success_progress=0.25,
        # a lazy hook encloses the horizontal bar in the vertical plane across it: only there
        # does the grasp carry force both ways (along the bar it carries friction alone)
        workplane_normal=(0.0, 1.0, 0.0),
    )


def plate_sliding() -> TaskConfig:
    return TaskConfig(
        name="plate-sliding",
        object=ObjectConfig(
            joint_type="prismatic",
            handle="plate",
            position=(0.0, 0.0, 0.75),
            axis=(1.0, 0.0, 0.0),
            handle_half=(0.08, 0.08, 0.005),
            mass=0.5,
            damping=1.0,
            frictionloss=0.5,
            joint_range=(-0.005, 0.4),
            friction=0.8,
            rgba=(0.8, 0.8, 0.85, 1.0),
        ),
        force_exertion_type="passive_force_closure",
        finger_angle=0.0,  # straight fingers: their tip pads press on the plate
        press_depth=0.012,
        success_progress=0.25,
    )


def pole_pulling() -> TaskConfig:
    return TaskConfig(
        name="pole-pulling",
        object=ObjectConfig(
            joint_type="prismatic",
            handle="pole",
            position=(0.0, 0.0, 0.9),
            axis=(1.0, 0.0, 0.0),
            handle_radius=0.016,
            handle_length=0.2,
            mass=1.0,
            damping=1.0,
            frictionloss=0.5,
            joint_range=(-0.005, 0.4),
            rgba=(0.4, 0.4, 0.45, 1.0),
        ),
        force_exertion_type="active_force_closure",
        finger_angle=0.25,  # closed past the pole's surface: a squeeze
        success_progress=0.25,
    )


def door_opening() -> TaskConfig:
    return TaskConfig(
        name="door-opening",
        object=ObjectConfig(
            joint_type="revolute",
            handle="bar",
            position=(0.0, 0.5, 1.0),
            axis=(0.0, 0.0, 1.0),
            radial=(0.0, -1.0, 0.0),
            radius=0.5,
            handle_length=0.14,
            mass=5.0,
            damping=1.0,
            frictionloss=0.5,
            joint_range=(-0.02, 1.7),
            panel_half=(0.015, 0.3, 0.4),
        ),
        force_exertion_type="lazy_closure",
        slip_angle_limit=None,
        success_progress=float(np.radians(60.0)),
        max_steps=90,
    )


def handle_rotating() -> TaskConfig:
    return TaskConfig(
        name="handle-rotating",
        object=ObjectConfig(
            joint_type="revolute",
            handle="knob",
            position=(0.0, 0.12, 0.8),
            axis=(0.0, 0.0, 1.0),
            radial=(0.0, -1.0, 0.0),
            radius=0.12,
            handle_half=(0.02, 0.013, 0.012),
            mass=0.5,
            damping=0.05,
            frictionloss=0.1,
            joint_range=(-0.02, 3.0),
            rgba=(0.3, 0.3, 0.35, 1.0),
        ),
        force_exertion_type="passive_force_closure",
        fixed_orientation=True,
        finger_angle=0.0,  # fingers straddle the knob: its orientation is locked to the hand's
        press_depth=0.01,
        success_progress=float(np.radians(90.0)),
        max_steps=60,
    )


TASKS: dict[str, Callable[[], TaskConfig]] = {
    "drawer-opening": drawer_opening,
    "plate-sliding": plate_sliding,
    "pole-pulling": pole_pulling,
    "door-opening": door_opening,
    "handle-rotating": handle_rotating,
}


def task_config(name: str, **overrides: Any) -> TaskConfig:
    """The preset `name` with overrides; unknown names raise an error listing the valid ones."""
    if name not in TASKS:
        raise UnknownNameError("task", name, list(TASKS))
    cfg = TASKS[name]()
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
