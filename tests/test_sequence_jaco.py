"""The Jaco in the execution sequence: where its base stands (inside the joint limits the
controller holds, where the perceived grasp is reachable) and leaving a pressed knob."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest


def _placed(kind: str, index: int) -> tuple[Any, Any]:
    """The end-to-end benchmark's placement `index` of `kind` and its offset demonstration's
    skill (bench/endtoend.py)."""
    from constraint_aware.bench.endtoend import _demo_skill
    from constraint_aware.lfo.synthetic import HandOffset, random_placement
    from constraint_aware.sim.tasks import KINDS

    k = KINDS.index(kind)
    place = random_placement(kind, np.random.default_rng([0, k, index]))
    return place, _demo_skill(place, np.random.default_rng([0, k, index, 2]), HandOffset())


def test_inverse_kinematics_keeps_the_asked_joint_limit_margin() -> None:
    from constraint_aware.sim.jaco import OscConfig
    from constraint_aware.sim.reach import JacoPlanner, PlanningError, _grasp, choose_base

    place, _ = _placed("drawer", 0)
    base, _ = choose_base(place.task)
    planner = JacoPlanner(base)
    planner.set_object(place.task)
    grasp = _grasp(place.task)
    margin = OscConfig().limit_margin
    q = planner.solve_ik(grasp, np.zeros(6), handle=False, clearance=0.0, margin=margin)
    assert planner.limit_margin(q) >= margin
    with pytest.raises(PlanningError, match="inside the joint limits"):
        planner.solve_ik(grasp, q, handle=False, clearance=0.0, margin=3.0)  # no joint has it


def test_the_base_moves_when_the_perceived_grasp_is_out_of_reach() -> None:
    # a window demonstrated 4 cm off its bar: from the station the demonstration implies, the
    # true grasp lies beyond the arm's reach (the approach stopped 12 mm short, a shoulder
    # joint at its limit); a station chosen for the grasp where it is reaches it
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.sim.reach import choose_base, reaches_from

    place, skill = _placed("window", 7)
    demonstrated, _ = choose_base(scene_from_skill(skill).task)
    assert not reaches_from(place.task, demonstrated)
    perceived, _ = choose_base(place.task)  # reaches_from holds there
    assert float(np.linalg.norm(perceived - demonstrated)) > 0.01


def test_leaving_a_pressed_knob_is_not_a_contact() -> None:
    # opening the fingers around a crank's knob pushes the hand; the wrist rests where it was
    # pushed before the retreat, whose guard would otherwise read the unloading as a contact
    from constraint_aware.lfo.sequence import SequenceConfig, run_in_simulation
    from constraint_aware.policy import ConstraintAwarePolicy

    place, skill = _placed("crank", 8)
    record = run_in_simulation(
        skill, place.task, "jaco", policy=ConstraintAwarePolicy.load(), seed=8
    ).record
    assert record.phase("release").outcome == "ok"
    retreat = record.phase("retreat")
    assert retreat.outcome == "ok", retreat.reason
    assert retreat.peak_force < SequenceConfig().leave.contact_limit
