"""Run a demonstration's skill on a simulated object, with the demonstration's estimates
(workplane, initial direction, radius, constraint type, grasp, goal) in charge.

`execute_from_home` runs the whole execution sequence (lfo/sequence.py): the robot starts at
its home, sees the object, reaches, grasps, manipulates, releases and returns home; `cap lfo
--execute` runs it. `execute` starts with the hand placed at the simulated handle's grasp
(`cap lfo --execute --start at-grasp`), for experiments on the manipulation alone.

By default the object itself is built from the demonstration (lfo/scene.py): placed, oriented
and sized where the hand moved. `task=` runs on a given object instead (the placement
benchmark's ground truth), still with the estimates in charge and the demonstrated goal.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from constraint_aware.control.controllers import driving_policy
from constraint_aware.control.executor import Executor
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.record import RunRecord
from constraint_aware.control.simulate import observed, simulated_robot
from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray, angle_deg
from constraint_aware.lfo.infer import SkillParameters
from constraint_aware.lfo.manipulation import (
    SENSOR_NOISE,
    goal_label,
    manipulation_setup,
)
from constraint_aware.lfo.plausibility import check_certainty
from constraint_aware.lfo.scene import scene_from_skill, with_goal
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import DEFAULT_ROBOT, parse_robot
from constraint_aware.sim.tasks import TaskConfig


def _check_skill(skill: SkillParameters) -> None:
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


def execute_from_home(
    skill: SkillParameters,
    controller: str = "policy",
    seed: int = 0,
    task: TaskConfig | None = None,
    policy: ConstraintAwarePolicy | None = None,
    sensor_noise: float = SENSOR_NOISE,
    robot: str = DEFAULT_ROBOT,
    recognizer: str = "cnn",
    on_phase: Callable[[str, Any], None] | None = None,
    on_period: Callable[[Any], None] | None = None,
    profile: RobotProfile | None = None,
    strict_inputs: bool = False,
) -> tuple[Any, dict[str, Any]]:
    """The execution sequence (lfo/sequence.py) from the robot's home on the simulated object
    (built from the demonstration unless `task` is given); returns the `SimulatedSequence`
    and what was built. recognizer: "cnn" (the shipped weights) or "geometric". Raises as
    `execute` does before anything moves; an exception during the sequence carries its
    record as `sequence_record`. profile, strict_inputs: as `execute`, for the manipulation."""
    from constraint_aware.lfo.sequence import SequenceConfig, run_in_simulation
    from constraint_aware.recognizer import make_recognizer

    parse_robot(robot)
    _check_skill(skill)
    notes: list[str] = []
    if task is None:
        scene = scene_from_skill(skill)
        task, kind, notes = scene.task, scene.kind, list(scene.notes)
    else:
        kind = task.name
        task = with_goal(task, float(skill.goal or 0.0))
    check_certainty(
        skill.constraint_type,
        skill.uncertainty.get("normal_std_deg"),
        skill.uncertainty.get("path_length_m", 0.0),
        task.slip_limit,
    )
    found = make_recognizer(recognizer)
    result = run_in_simulation(
        skill, task, robot, controller, policy, seed, sensor_noise, found,
        SequenceConfig(recognizer=recognizer, profile=profile, strict_inputs=strict_inputs),
        on_phase, on_period,
    )  # fmt: skip
    record = result.record
    # scored afterwards against the simulated object (the sequence never read it)
    sim = result.sim
    d0 = np.asarray(skill.initial_direction, dtype=float)
    info = {
        "task": task.name,
        "kind": kind,
        "robot": robot,
        "start": "home",
        "notes": notes,
        "object": dataclasses.asdict(task.object),
        **goal_label(skill.constraint_type, float(skill.goal or 0.0)),
        "success": record.success,
        "failed_phase": record.failed_phase,
        "reason": record.reason,
        "progress": float(sim.progress()),
        "peak_force_N": record.peak_force,
        "initial_direction_error_deg": float(angle_deg(d0, task.object.opening_direction)),
    }
    return result, info


def execute(
    skill: SkillParameters,
    controller: str = "policy",
    seed: int = 0,
    task: TaskConfig | None = None,
    policy: ConstraintAwarePolicy | None = None,
    sensor_noise: float = SENSOR_NOISE,
    robot: str = DEFAULT_ROBOT,
    profile: RobotProfile | None = None,
    strict_inputs: bool = False,
    on_period: Callable[[Any], None] | None = None,
) -> tuple[RunRecord, dict[str, Any]]:
    """Run the skill; returns the record and what was built and how the estimates compare
    with the simulated object's truth.

    robot: the embodiment that executes it, a robot spec (sim.embodiment: "hook-hand", "jaco",
    "jaco:stiffness=2000,period=0.1"); an unknown name or variant raises UnknownNameError or
    InvalidInputError naming the valid ones, before anything is built.
    profile: the robot's calibration (`Executor.profile`); strict_inputs: refuse to run when
    an input a controller stage needs is missing (`ExecutorConfig.strict_inputs`).
    on_period(sim): called once at the start and after every control period (scoring, video).
    Raises CapError (UncertainEstimateError) before anything moves when the constraint is
    unknown or the estimates are too uncertain for the grasp (lfo/plausibility.py).
    """
    parse_robot(robot)
    _check_skill(skill)
    assert skill.goal is not None  # _check_skill
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
    cfg = dataclasses.replace(cfg, strict_inputs=strict_inputs)
    d0 = np.asarray(skill.initial_direction, dtype=float)
    truth_d = sim.admissible_direction()
    label = {
        "task": task.name,
        "kind": kind,
        "controller": ctrl.name,
        "offset_deg": float(angle_deg(d0, truth_d)),
        "seed": seed,
        "torque_policy": cfg.torque_policy.enabled,
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
    driven = sim if on_period is None else observed(sim, on_period)
    record = Executor(driven, ctrl, cfg, monitor=sim, profile=profile).run(d0, label)
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
