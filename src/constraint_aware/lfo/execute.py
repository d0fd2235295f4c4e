"""Run a demonstration's skill on a simulated object, with the demonstration's estimates
(workplane, initial direction, radius, constraint type, grasp, goal) in charge.

By default the object itself is built from the demonstration (lfo/scene.py): placed, oriented
and sized where the hand moved. `task=` runs on a given object instead (the placement
benchmark's ground truth), still with the estimates in charge and the demonstrated goal.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from constraint_aware.control.controllers import (
    DirectionController,
    driving_policy,
    make_controller,
)
from constraint_aware.control.executor import Executor, ExecutorConfig
from constraint_aware.control.record import RunRecord
from constraint_aware.control.simulate import RunSpec, executor_config, simulated_robot
from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray, angle_deg
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.lfo.plausibility import check_certainty
from constraint_aware.lfo.scene import scene_from_skill, with_goal
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import DEFAULT_ROBOT, parse_robot
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
        torque_policy=bool(skill.fixed_orientation) and skill.constraint_type == "revolute",
        rotation_radius=radius,
        goal_travel=goal_travel,
        goal_rotation=goal_rotation,
    )
    rate = None
    if cfg.constraint_type == "revolute" and radius:
        rate = cfg.step_length / control_period / radius  # w_d = v_d / r
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    return cfg, make_controller(controller, policy, rate, normal)


def execute(
    skill: SkillParameters,
    controller: str = "policy",
    seed: int = 0,
    task: TaskConfig | None = None,
    policy: ConstraintAwarePolicy | None = None,
    sensor_noise: float = SENSOR_NOISE,
    robot: str = DEFAULT_ROBOT,
) -> tuple[RunRecord, dict[str, Any]]:
    """Run the skill; returns the record and what was built and how the estimates compare
    with the simulated object's truth.

    robot: the embodiment that executes it, a robot spec (sim.embodiment: "hook-hand", "jaco",
    "jaco:stiffness=5000,period=0.05"); an unknown name or variant raises UnknownNameError or
    InvalidInputError naming the valid ones, before anything is built.
    Raises CapError (UncertainEstimateError) before anything moves when the constraint is
    unknown or the estimates are too uncertain for the grasp (lfo/plausibility.py).
    """
    parse_robot(robot)
    if skill.constraint_type not in ("prismatic", "revolute"):
        raise CapError(
            f"no simulated object for constraint {skill.constraint_type!r}: the demonstration "
            "did not decide prismatic or revolute"
        )
    if skill.goal is None or skill.goal <= 0:
        raise CapError(
            f"the demonstrated motion has no positive travel or angle (goal {skill.goal}): "
            "nothing to execute"
        )
    notes: list[str] = []
    if task is None:
        scene = scene_from_skill(skill)
        task, kind, notes = scene.task, scene.kind, list(scene.notes)
    else:
        kind = task.name
        task = with_goal(task, float(skill.goal))
    check_certainty(
        skill.constraint_type,
        skill.uncertainty.get("normal_std_deg"),
        skill.uncertainty.get("path_length_m", 0.0),
        task.slip_limit,
    )
    sim = simulated_robot(robot, task, np.random.default_rng(seed + 7919), sensor_noise)
    sim.reset()
    cfg, ctrl = manipulation_setup(skill, task, sim.control_period, controller, policy)
    d0 = np.asarray(skill.initial_direction, dtype=float)
    truth_d = sim.admissible_direction()
    label = {
        "task": task.name,
        "kind": kind,
        "controller": ctrl.name,
        "offset_deg": float(angle_deg(d0, truth_d)),
        "seed": seed,
        "torque_policy": cfg.torque_policy,
        "sensor_noise_N": sensor_noise,
        "success_progress": task.success_progress,
        "constraint_type": task.constraint_type,
        "force_exertion_type": task.force_exertion_type,
        "force_limit_N": task.force_limit,
        "command_from": cfg.command_from,
        "robot": robot,
        **goal_label(skill.constraint_type, float(skill.goal)),
    }
    driver = driving_policy(ctrl)
    if driver is not None:
        label["policy"] = driver.name  # which policy drove the run (the card's name)
    record = Executor(sim, ctrl, cfg, monitor=sim).run(d0, label)
    info = {
        "task": task.name,
        "kind": kind,
        "robot": robot,
        "notes": notes,
        "object": dataclasses.asdict(task.object),
        **goal_label(skill.constraint_type, float(skill.goal)),
        "initial_direction_error_deg": float(angle_deg(d0, truth_d)),
        "task_radius_m": task.object.radius if task.constraint_type == "revolute" else None,
    }
    return record, info


def path_deviation(record: RunRecord, demonstrated: FloatArray) -> float:
    """[m] the largest distance from the run's handle positions to the demonstrated path
    (its polyline, glitches included: use a cleaned path for a tight figure)."""
    path = np.asarray(demonstrated, dtype=float)
    a, b = path[:-1], path[1:]
    ab = b - a
    denom = np.maximum(np.sum(ab * ab, axis=1), 1e-18)
    worst = 0.0
    for step in record.steps:
        if step.handle_position is None:
            continue
        p = np.asarray(step.handle_position)
        s = np.clip(np.sum((p - a) * ab, axis=1) / denom, 0.0, 1.0)
        nearest = a + s[:, None] * ab
        worst = max(worst, float(np.min(np.linalg.norm(nearest - p, axis=1))))
    return worst
