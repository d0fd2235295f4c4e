"""Run a demonstration's skill on the matching simulated task, with the demonstration's
estimates (workplane, initial direction, radius, constraint type, grasp) in charge."""

from __future__ import annotations

from typing import Any

import numpy as np

from constraint_aware.control.record import RunRecord
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.errors import CapError
from constraint_aware.geometry import angle_deg
from constraint_aware.lfo.infer import SkillParameters

#: Which simulated task a demonstrated object maps to (first match in the words wins).
OBJECT_TASKS = {
    "drawer": "drawer-opening",
    "plate": "plate-sliding",
    "tray": "plate-sliding",
    "pole": "pole-pulling",
    "rod": "pole-pulling",
    "door": "door-opening",
    "handle": "handle-rotating",
    "crank": "handle-rotating",
    "knob": "handle-rotating",
}
DEFAULT_TASK = {"prismatic": "drawer-opening", "revolute": "door-opening"}


def task_for(skill: SkillParameters) -> str:
    noun = skill.evidence.get("words", {}).get("noun")
    if noun in OBJECT_TASKS:
        return OBJECT_TASKS[noun]
    if skill.constraint_type in DEFAULT_TASK:
        return DEFAULT_TASK[skill.constraint_type]
    raise CapError(
        f"no simulated task for constraint {skill.constraint_type!r}: "
        "the demonstration did not decide prismatic or revolute"
    )


def execute(
    skill: SkillParameters, controller: str = "policy", seed: int = 0
) -> tuple[RunRecord, dict[str, Any]]:
    """Run the skill; returns the record and how the estimates compare with the task's truth."""
    task = task_for(skill)
    overrides: dict[str, Any] = {
        "constraint_type": skill.constraint_type,
        "workplane_normal": tuple(skill.workplane_normal),
        "torque_policy": bool(skill.fixed_orientation),
        "rotation_radius": skill.radius,
    }
    spec = RunSpec(task=task, controller=controller, offset_deg=0.0, seed=seed)
    record, sim = run(
        spec,
        initial_direction=np.asarray(skill.initial_direction),
        executor_overrides=overrides,
    )
    truth_d = record.steps[0].admissible_direction if record.steps else None
    info = {
        "task": task,
        "initial_direction_error_deg": (
            float(angle_deg(np.asarray(skill.initial_direction), np.asarray(truth_d)))
            if truth_d is not None
            else None
        ),
        "task_radius_m": sim.task.object.radius if skill.constraint_type == "revolute" else None,
    }
    return record, info
