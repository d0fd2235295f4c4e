"""Scene assembly with `mujoco.MjSpec`: world options, floor, light, camera, the object.

An embodiment composes its arm and hand into this spec (`attach`), so a second embodiment adds
one module and no template. The object is built as its own spec by `sim/objects.py`'s
per-kind builders and attached whole under the name prefix `OBJECT_PREFIX` (MuJoCo needs a
non-empty prefix to keep the composed model savable).

The object's main part (drawer box, door panel, crank arm, carriage) and the furniture are
visual: the joint is the constraint. The hook hand does not reach them (tests/test_scene.py:
over the five presets' seed-0 runs from 30 deg the least clearance is 2.0 mm, on the door).
A real arm can: `intrusions` measures how deep a robot's geoms are inside them, and
`scene_spec(..., solid_for_arms=True)` makes them collide with arm geoms
(sim.objects.ARM_CONTACT_BIT) without touching the hook hand's physics.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import mujoco
import numpy as np

from constraint_aware.sim import objects
from constraint_aware.sim.objects import OBJECT_BODY, VISUAL_GROUP
from constraint_aware.sim.robot_adapter import TIMESTEP
from constraint_aware.sim.tasks import TaskConfig

OBJECT_PREFIX = "obj:"  # the object's names in a composed scene: "obj:object_joint", ...


def scene_spec(
    task: TaskConfig,
    robot: Callable[[mujoco.MjSpec], None] | None = None,
    *,
    solid_for_arms: bool = False,
) -> mujoco.MjSpec:
    """The world of a task: options, floor, light, the robot (`robot(spec)` composes it, before
    the object so that its bodies come first) and the object (`solid_for_arms`: see
    `sim.objects.object_spec`)."""
    spec = mujoco.MjSpec()
    spec.modelname = task.name
    spec.compiler.degree = False
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 5.0
    spec.visual.global_.offwidth = 640
    spec.visual.global_.offheight = 480
    spec.visual.quality.shadowsize = 2048
    spec.add_texture(
        name="grid",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.85, 0.85, 0.85],
        rgb2=[0.75, 0.75, 0.75],
        width=256,
        height=256,
    )
    grid = spec.add_material(name="grid", texrepeat=[8.0, 8.0])
    grid.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    focus = np.asarray(task.object.handle_position, dtype=float)
    spec.worldbody.add_light(
        pos=[focus[0] + 1.0, focus[1] - 1.0, 3.0],
        dir=[-0.3, 0.3, -1.0],
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
    )
    spec.worldbody.add_geom(
        name="scene_floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[3.0, 3.0, 0.1],
        material="grid",
        contype=0,
        conaffinity=0,
    )
    if robot is not None:
        robot(spec)
    attach_object(spec, task, solid_for_arms=solid_for_arms)
    spec.worldbody.add_camera(
        name="overview",
        mode=mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODY,
        targetbody=OBJECT_PREFIX + OBJECT_BODY,
        pos=[focus[0] + 0.9, focus[1] - 0.9, focus[2] + 0.7],
    )
    return spec


def object_spec(task: TaskConfig, *, solid_for_arms: bool = False) -> mujoco.MjSpec:
    """The task's object (moving body, joint, handle, scenery) as its own spec."""
    return objects.object_spec(task.object, solid_for_arms=solid_for_arms)


def attach_object(spec: mujoco.MjSpec, task: TaskConfig, *, solid_for_arms: bool = False) -> None:
    """Compose the object into `spec` at the world origin (names prefixed `OBJECT_PREFIX`)."""
    frame = spec.worldbody.add_frame()
    spec.attach(object_spec(task, solid_for_arms=solid_for_arms), prefix=OBJECT_PREFIX, frame=frame)


class Intrusion(NamedTuple):
    """A robot geom inside one of the object's visual parts."""

    depth: float  # [m] > 0: how far inside (MuJoCo's signed distance, negated)
    part: str  # the object's geom, e.g. "obj:object_panel"
    robot_geom: str  # the robot's geom (its body's name if the geom has none)


def intrusions(model: mujoco.MjModel, data: mujoco.MjData, robot_prefix: str) -> list[Intrusion]:
    """The robot's geoms (bodies named `robot_prefix`...) inside the object's visual parts (main
    part and furniture, contacts or not: see `solid_for_arms`), deepest first, at `data`'s
    state (after `mj_kinematics` or a step): what a solid object would have stopped."""
    parts = [
        g
        for g in range(model.ngeom)
        if model.geom(g).name.startswith(OBJECT_PREFIX) and model.geom_group[g] == VISUAL_GROUP
    ]
    robot = [
        g
        for g in range(model.ngeom)
        if model.body(model.geom_bodyid[g]).name.startswith(robot_prefix)
    ]
    found = []
    for part in parts:
        for g in robot:
            distance = mujoco.mj_geomDistance(model, data, part, g, 0.0, None)
            if distance < 0.0:
                name = model.geom(g).name or model.body(model.geom_bodyid[g]).name
                found.append(Intrusion(-distance, model.geom(part).name, name))
    return sorted(found, reverse=True)
