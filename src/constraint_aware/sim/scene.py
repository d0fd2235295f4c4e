"""Scene assembly with `mujoco.MjSpec`: world options, floor, light, camera, the object.

An embodiment composes its arm and hand into this spec (`attach`), so a second embodiment adds
one module and no template. The object is built as its own spec by `sim/objects.py`'s
per-kind builders and attached whole under the name prefix `OBJECT_PREFIX` (MuJoCo needs a
non-empty prefix to keep the composed model savable).
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

from constraint_aware.sim import objects
from constraint_aware.sim.objects import OBJECT_BODY
from constraint_aware.sim.robot_adapter import TIMESTEP
from constraint_aware.sim.tasks import TaskConfig

OBJECT_PREFIX = "obj:"  # the object's names in a composed scene: "obj:object_joint", ...


def scene_spec(
    task: TaskConfig, robot: Callable[[mujoco.MjSpec], None] | None = None
) -> mujoco.MjSpec:
    """The world of a task: options, floor, light, the robot (`robot(spec)` composes it, before
    the object so that its bodies come first) and the object."""
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
    attach_object(spec, task)
    spec.worldbody.add_camera(
        name="overview",
        mode=mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODY,
        targetbody=OBJECT_PREFIX + OBJECT_BODY,
        pos=[focus[0] + 0.9, focus[1] - 0.9, focus[2] + 0.7],
    )
    return spec


def object_spec(task: TaskConfig) -> mujoco.MjSpec:
    """The task's object (moving body, joint, handle, scenery) as its own spec."""
    return objects.object_spec(task.object)


def attach_object(spec: mujoco.MjSpec, task: TaskConfig) -> None:
    """Compose the object into `spec` at the world origin (names prefixed `OBJECT_PREFIX`)."""
    frame = spec.worldbody.add_frame()
    spec.attach(object_spec(task), prefix=OBJECT_PREFIX, frame=frame)
