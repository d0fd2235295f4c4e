"""The simulated object built from a demonstration: kind from the words (geometry overrules
them), pose from the fits, grasp from the table, goal from the demonstrated travel or angle.

- prismatic: the handle at the path's resting start, the slide axis along the fitted line (the
  skill's initial direction), a bar across the skill's workplane (a hooked bar runs along the
  plane's normal);
- revolute: the hinge axis through the fitted centre along the fitted normal (its sign from the
  sense of the motion, so opening turns positively), the handle at the resting start, the
  radius from the fit;
- the handle shape from the grasp (lazy closure: a bar, active: a pole, passive: a plate on a
  slide or a crank's knob on a hinge); mass, damping and friction from the kind
  (sim.tasks.KIND_OBJECTS).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.executor import ExecutorConfig
from constraint_aware.geometry import unit
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.lfo.lexicon import NOUN_KINDS
from constraint_aware.sim.objects import HandleShape
from constraint_aware.sim.tasks import (
    KIND_OBJECTS,
    TaskConfig,
    default_max_steps,
    object_for,
    task_from_object,
)

STEP_LENGTH = ExecutorConfig().step_length  # [m] the executor's step (sizes the timeouts)
#: |axis . z| above this is a vertical slide (window) or a vertical hinge (door, crank)
VERTICAL_COSINE = 0.7
#: margins beyond the demonstrated goal before the joint's end stop [m] / [rad]
TRAVEL_MARGIN = 0.1
ROTATION_MARGIN = 0.3


@dataclass(frozen=True)
class DemonstratedScene:
    kind: str
    task: TaskConfig
    notes: list[str] = field(default_factory=list)


def handle_for(grasp: str, constraint: str) -> HandleShape:
    if grasp == "lazy_closure":
        return "bar"
    if grasp == "active_force_closure":
        return "pole"
    return "knob" if constraint == "revolute" else "plate"


def kind_for(skill: SkillParameters) -> tuple[str, list[str]]:
    """The object kind: the words' noun when its constraint agrees with the skill's (which the
    geometry decided whenever it could), else from the geometry and the grasp; with notes."""
    constraint = skill.constraint_type
    noun = skill.evidence.get("words", {}).get("noun")
    notes: list[str] = []
    word_kind = NOUN_KINDS.get(noun) if noun else None
    if word_kind is not None and KIND_OBJECTS[word_kind]["joint_type"] == constraint:
        return word_kind, notes
    handle = handle_for(skill.grasp, constraint)
    axis = np.asarray(skill.axis if constraint == "revolute" else skill.initial_direction)
    vertical = abs(float(axis[2])) > VERTICAL_COSINE
    if constraint == "prismatic":
        kind = {"pole": "pole", "plate": "plate"}.get(handle, "window" if vertical else "drawer")
    else:
        kind = "crank" if handle == "knob" else ("door" if vertical else "lid")
    if word_kind is not None:
        notes.append(
            f"the words name a {noun} ({KIND_OBJECTS[word_kind]['joint_type']}) but the hand "
            f"moved {'along a line' if constraint == 'prismatic' else 'on an arc'}: geometry "
            f"decides, executed as a {kind} ({constraint})"
        )
    else:
        notes.append(f"no known object in the words: a {kind} from the geometry")
    return kind, notes


def scene_from_skill(skill: SkillParameters) -> DemonstratedScene:
    """The task whose object is placed, oriented and sized as the demonstration says."""
    if skill.constraint_type not in ("prismatic", "revolute"):
        raise ValueError(f"no object for constraint {skill.constraint_type!r}")
    if skill.start_position is None or skill.goal is None:
        raise ValueError("the skill has no start position or goal (inferred by an old version?)")
    kind, notes = kind_for(skill)
    handle = handle_for(skill.grasp, skill.constraint_type)
    start = np.asarray(skill.start_position, dtype=float)
    goal = float(skill.goal)
    base = KIND_OBJECTS[kind]
    lo, hi = base["joint_range"]
    if skill.constraint_type == "prismatic":
        axis = unit(np.asarray(skill.initial_direction, dtype=float))
        obj = object_for(
            kind,
            handle=handle,
            position=_t(start),
            axis=_t(axis),
            handle_axis=_t(np.asarray(skill.workplane_normal)) if handle == "bar" else None,
            joint_range=(lo, max(hi, goal + TRAVEL_MARGIN)),
        )
    else:
        assert skill.axis is not None and skill.centre is not None and skill.radius is not None
        axis = unit(np.asarray(skill.axis, dtype=float))
        centre = np.asarray(skill.centre, dtype=float)
        rel = start - centre
        radial = unit(rel - float(rel @ axis) * axis)
        # the hinge line through the fitted centre, at the start point's height along it
        position = centre + float(rel @ axis) * axis
        obj = object_for(
            kind,
            handle=handle,
            position=_t(position),
            axis=_t(axis),
            radial=_t(radial),
            radius=float(skill.radius),
            joint_range=(lo, max(hi, goal + ROTATION_MARGIN)),
        )
    task = task_from_object(
        kind, obj, name=f"{kind} (from the demonstration)", success_progress=goal,
        step_length=STEP_LENGTH,
    )  # fmt: skip
    return DemonstratedScene(kind, task, notes)


def _t(v: np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def with_goal(task: TaskConfig, goal: float) -> TaskConfig:
    """`task` with the demonstrated goal as its success criterion (and a timeout sized to it)."""
    return dataclasses.replace(
        task,
        success_progress=goal,
        max_steps=max(task.max_steps, default_max_steps(task.object, goal, STEP_LENGTH)),
    )
