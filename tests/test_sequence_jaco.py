"""The Jaco in the execution sequence: where its base stands (inside the joint limits the
controller holds, where the perceived grasp is reachable, with the hand modelled as it
reaches, where its arm at home leaves the head camera its view) and leaving a pressed
knob."""

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
    base, _, _ = choose_base(place.task)
    planner = JacoPlanner(base)
    planner.set_object(place.task)
    grasp = _grasp(place.task)
    margin = OscConfig().limit_margin
    q = planner.solve_ik(grasp, np.zeros(6), handle=False, clearance=0.0, margin=margin)
    assert planner.limit_margin(q) >= margin
    with pytest.raises(PlanningError, match="inside the joint limits"):
        planner.solve_ik(grasp, q, handle=False, clearance=0.0, margin=3.0)  # no joint has it


def test_the_reach_targets_the_grasp_posture_that_follows_the_whole_motion() -> None:
    # a door (0.68 m) from the station its sequence stands at: the grasp posture farthest
    # from the joint limits at the grasp comes within 0.14 rad of a limit as the door opens,
    # inside the controller's repulsion band (the arm stops `not_following` there); the
    # posture motion_ik picks keeps the band's width and more over the whole motion, without
    # changing its arm configuration, and the pre-grasp lies on that configuration
    from constraint_aware.sim.jaco import JacoSim, OscConfig
    from constraint_aware.sim.reach import (
        BRANCH_JUMP,
        JACO_PRESHAPE,
        MOTION_PIECES,
        JacoPlanner,
        largest_turn,
        motion_poses,
    )

    place, _ = _placed("door", 6)
    task = place.task
    sim = JacoSim(task, base=np.array([0.785, -0.278, 0.782]))
    grasp = sim.grasp_pose()
    planner = JacoPlanner(sim.base)
    planner.fingers = JACO_PRESHAPE[task.object.handle]
    planner.set_object(task)
    fractions = tuple(i / MOTION_PIECES for i in range(MOTION_PIECES + 1))
    poses = motion_poses(task, grasp, fractions)
    band = OscConfig().limit_margin
    roomiest = planner._follow(planner.roomiest_ik(grasp), poses, fractions, task, 0.0, False)
    assert roomiest is not None and roomiest < band
    q, least = planner.motion_ik(grasp, clear=False)
    assert least > 2 * band
    for pose in poses:  # followed piece by piece: no joint jumps
        nxt = planner._ik_from(q, pose)
        assert nxt is not None and largest_turn(nxt, q) <= BRANCH_JUMP
        assert planner.limit_margin(nxt) >= least - 1e-9
        q = nxt
    start, _ = planner.motion_ik(grasp, clear=False)
    pre = grasp.moved(-0.1 * grasp.orientation.apply([0.0, 0.0, 1.0]))
    q_pre = planner.pre_grasp_ik(pre, start)
    assert largest_turn(q_pre, start) <= BRANCH_JUMP


def test_the_base_moves_when_the_perceived_grasp_is_out_of_reach() -> None:
    # a window demonstrated 4 cm off its bar: from the station the demonstration implies, the
    # true grasp lies beyond the arm's reach (the approach stopped 12 mm short, a shoulder
    # joint at its limit); a station chosen for the grasp where it is reaches it
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.sim.reach import choose_base, reaches_from

    place, skill = _placed("window", 7)
    demonstrated, _, _ = choose_base(scene_from_skill(skill).task)
    assert not reaches_from(place.task, demonstrated)
    perceived, _, _ = choose_base(place.task)  # reaches_from holds there
    assert float(np.linalg.norm(perceived - demonstrated)) > 0.01


def test_the_station_models_the_hand_pre_shaped_as_it_reaches(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the station checks its clearances with the hand as it reaches, pre-shaped for the
    # handle (a knob: 0.6 rad), not open: at this crank's pre-grasp the open fingers stand
    # over 2 cm farther from the object than the pre-shaped ones
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.sim import reach
    from constraint_aware.sim.jaco import arm_base

    _, skill = _placed("crank", 1)
    believed = scene_from_skill(skill).task
    base = arm_base(believed, reach.BASE_PLACEMENT[("revolute", "knob")])
    grasp = reach._grasp(believed)
    pre = grasp.moved(-0.10 * grasp.orientation.apply([0.0, 0.0, 1.0]))
    planner = reach.JacoPlanner(base)
    planner.set_object(believed)
    q = planner.solve_ik(pre, reach.facing(base, pre.position), clearance=-1.0)
    planner.fingers = reach.JACO_PRESHAPE["knob"]
    shaped = planner.clearance(q)
    planner.fingers = reach.JACO_PRESHAPE["bar"]  # open
    assert planner.clearance(q) > shaped + 0.02

    shapes: list[float] = []

    class Watched(reach.JacoPlanner):
        def clearance(self, q: Any, handle: bool = True) -> float:
            shapes.append(self.fingers)
            return super().clearance(q, handle)

    monkeypatch.setattr(reach, "JacoPlanner", Watched)
    assert reach.reaches_from(believed, base)
    assert shapes and set(shapes) == {reach.JACO_PRESHAPE["knob"]}


def test_a_knob_near_its_hub_is_held_across_its_mount() -> None:
    # this crank's knob is 79 mm from its hinge: with the hand at the knob's mount the finger
    # curled toward the hub meets it at the grasp from every base placement; held turned a
    # quarter about the approach, the fingers off that line, the arm reaches the whole motion
    import math

    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.sim.reach import choose_base, reaches_from

    _, skill = _placed("crank", 2)
    believed = scene_from_skill(skill).task
    base, _, roll = choose_base(believed)
    assert roll == pytest.approx(0.5 * math.pi)
    assert not reaches_from(believed, base)
    assert reaches_from(believed, base, roll=roll)


def test_the_arm_at_home_leaves_the_head_camera_its_view() -> None:
    # what the head camera must see from home (here: points just beyond the arm's largest
    # link, as the camera sees it at the first station's home) decides the station: the robot
    # stands where its arm at home hides none of them
    import mujoco

    from constraint_aware.lfo.perception import head_camera
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.lfo.sequence import SequenceConfig
    from constraint_aware.sim.reach import (
        JACO_PRESHAPE,
        JacoPlanner,
        View,
        _grasp,
        choose_base,
        facing,
        home_pose,
        reaches_from,
        rolled,
    )

    _, skill = _placed("crank", 1)
    believed = scene_from_skill(skill).task
    cfg = SequenceConfig()
    home = (cfg.jaco_home_forward, cfg.jaco_home_up)
    eye = np.asarray(head_camera("jaco", skill).pose.position, dtype=float)
    blind, _, roll = choose_base(believed, cfg.pre_grasp, home)  # no view asked

    def at_home(base: np.ndarray) -> tuple[JacoPlanner, np.ndarray]:
        planner = JacoPlanner(base)
        planner.fingers = JACO_PRESHAPE["knob"]
        planner.set_object(believed)
        tool = home_pose(base, rolled(_grasp(believed), roll), home)
        return planner, planner.solve_ik(tool, facing(base, tool.position))

    planner, q = at_home(blind)
    m, d = planner.model, planner._scratch
    d.qpos[:] = planner._full(q)
    mujoco.mj_kinematics(m, d)
    link = max(planner._robot_geoms, key=lambda g: float(m.geom_rbound[g]))
    centre = d.geom_xpos[link].copy()
    sight = (centre - eye) / np.linalg.norm(centre - eye)
    points = centre + 0.3 * sight + 0.003 * np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    view = View(eye, points)
    assert planner.hidden(q, eye, points) == len(points)
    assert not reaches_from(believed, blind, cfg.pre_grasp, home, view=view, roll=roll)
    seen, _, roll = choose_base(believed, cfg.pre_grasp, home, view)
    assert float(np.linalg.norm(seen - blind)) > 0.1
    planner, q = at_home(seen)
    assert planner.hidden(q, eye, points) == 0


def test_the_end_to_end_benchmark_names_an_unknown_kind() -> None:
    from constraint_aware.bench.endtoend import run_end_to_end
    from constraint_aware.errors import UnknownNameError

    with pytest.raises(UnknownNameError, match="crnk"):
        run_end_to_end(1, ("jaco",), kinds=("crank", "crnk"))


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


def test_the_approach_turns_the_hand_to_the_grasp_before_contact() -> None:
    # the Jaco's wrist (5 N m/rad against its joints' dry friction) arrives from the reach
    # some degrees off the grasp's orientation; a fist pressed on a plate keeps that tilt,
    # so the approach turns the hand back before it touches
    from constraint_aware.geometry import angle_deg
    from constraint_aware.lfo.sequence import run_in_simulation
    from constraint_aware.policy import ConstraintAwarePolicy

    place, skill = _placed("plate", 0)
    tilt: list[float] = []

    def on_phase(name: str, sim: Any) -> None:
        if name == "grasp":  # scoring only: the true grasp's axis against the hand's
            axis = np.array([0.0, 0.0, 1.0])
            grasp, hand = sim.grasp_pose(), sim.read_pose()
            tilt.append(
                float(angle_deg(grasp.orientation.apply(axis), hand.orientation.apply(axis)))
            )

    record = run_in_simulation(
        skill, place.task, "jaco", policy=ConstraintAwarePolicy.load(), seed=0, on_phase=on_phase
    ).record
    assert record.success, record.reason
    errors = record.phase("approach").details["hand_turn_error_deg"]
    assert errors[0] > 3.0  # arrived turned
    assert errors[-1] < errors[0] / 2
    assert tilt[0] < 2.5  # 5.2 deg without the turn
