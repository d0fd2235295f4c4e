"""The manipulation phase's setup from a demonstration: the executor's goal, configuration
and direction controller with the skill's estimates in charge (lfo/execute.py runs it on a
hand placed at the grasp, lfo/sequence.py after seeing, reaching and grasping)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from constraint_aware.control.controllers import DirectionController, make_controller
from constraint_aware.control.executor_config import ExecutorConfig, GoalConfig
from constraint_aware.control.simulate import RunSpec, executor_config
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import TaskConfig

SENSOR_NOISE = RunSpec.sensor_noise  # [N] std of the simulated force reading, as `cap run`


def robot_goal(skill: SkillParameters) -> tuple[float | None, float | None]:
    """The executor's stop from the demonstration, measured by the robot on its own poses:
    prismatic: the demonstrated travel (goal_travel); revolute with a fixed-orientation grasp:
    the demonstrated angle (goal_rotation: the hand turns with the object); other revolute
    grasps let the hand turn about the handle (a hooked bar), so the hand's orientation does not
    measure the hinge's angle, but its distance from the start does: the chord
    2 r sin(angle / 2) of the fitted radius (monotonic up to 180 deg; beyond, no robot-side
    goal and the simulated object's progress decides). The simulated task's success criterion
    is the same goal, measured on the object. Returns (goal_travel [m], goal_rotation [rad])."""
    goal = float(skill.goal or 0.0)
    if skill.constraint_type == "prismatic":
        return goal, None
    if skill.fixed_orientation:
        return None, goal
    if skill.radius is not None and goal < math.pi:
        return 2.0 * skill.radius * math.sin(goal / 2.0), None
    return None, None


def goal_label(constraint: str, goal: float) -> dict[str, Any]:
    if constraint == "revolute":
        return {"goal_rotation_deg": math.degrees(goal), "goal_source": "demonstration"}
    return {"goal_travel_m": goal, "goal_source": "demonstration"}


def manipulation_setup(
    skill: SkillParameters,
    task: TaskConfig,
    control_period: float,
    controller: str = "policy",
    policy: ConstraintAwarePolicy | None = None,
) -> tuple[ExecutorConfig, DirectionController]:
    """The executor's configuration and the direction controller for manipulating with the
    skill's estimates in charge: `task`'s settings (sim.control.executor_config: force limit,
    timeout, hinge point) with the skill's constraint, workplane, torque policy, radius and
    goal; control_period [s] sizes the torque policy's rate."""
    base = executor_config(task, skill.fixed_orientation)
    goal_travel, goal_rotation = robot_goal(skill)
    radius = skill.radius if skill.constraint_type == "revolute" else None
    cfg = dataclasses.replace(
        base,
        constraint_type=skill.constraint_type,  # type: ignore[arg-type]
        workplane_normal=(
            float(skill.workplane_normal[0]),
            float(skill.workplane_normal[1]),
            float(skill.workplane_normal[2]),
        ),
        torque_policy=dataclasses.replace(
            base.torque_policy,
            enabled=bool(skill.fixed_orientation) and skill.constraint_type == "revolute",
        ),
        rotation_radius=radius,
        goal=GoalConfig(travel=goal_travel, rotation=goal_rotation),
    )
    rate = None
    if cfg.constraint_type == "revolute" and radius:
        rate = cfg.step_length / control_period / radius  # w_d = v_d / r
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    return cfg, make_controller(controller, policy, rate, normal)
