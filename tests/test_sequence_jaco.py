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
    base, _ = choose_base(place.task)
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
    demonstrated, _ = choose_base(scene_from_skill(skill).task)
    assert not reaches_from(place.task, demonstrated)
    perceived, _ = choose_base(place.task)  # reaches_from holds there
    assert float(np.linalg.norm(perceived - demonstrated)) > 0.01


def test_the_station_models_the_hand_pre_shaped_as_it_reaches() -> None:
    # a crank's knob 12 cm from its hinge post: at the pre-grasp above the knob the hand
    # pre-shaped for it keeps the planner's clearance from the post, the open hand does not;
    # a station checked with the open hand refused a crank the reach then clears
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.sim.jaco import arm_base
    from constraint_aware.sim.reach import (
        BASE_PLACEMENT,
        JACO_PRESHAPE,
        JacoPlanner,
        _grasp,
        choose_base,
        facing,
    )

    _, skill = _placed("crank", 1)
    believed = scene_from_skill(skill).task
    base = arm_base(believed, BASE_PLACEMENT[("revolute", "knob")])
    grasp = _grasp(believed)
    pre = grasp.moved(-0.10 * grasp.orientation.apply([0.0, 0.0, 1.0]))
    planner = JacoPlanner(base)
    planner.set_object(believed)
    q = planner.solve_ik(pre, facing(base, pre.position), clearance=-1.0)
    planner.fingers = JACO_PRESHAPE["knob"]
    shaped = planner.clearance(q)
    planner.fingers = JACO_PRESHAPE["bar"]  # open
    assert planner.clearance(q) < planner.config.clearance <= shaped
    choose_base(believed)  # some placement reaches it


def test_the_arm_at_home_leaves_the_head_camera_its_view() -> None:
    # the first placement from which the arm reaches this crank puts its home posture between
    # the head camera and the knob (the recognizer then refuses a crop it barely sees); the
    # station is one from which the camera sees the crop's central half
    from scipy.spatial.transform import Rotation

    from constraint_aware.lfo.perception import nominal_frame
    from constraint_aware.lfo.scene import scene_from_skill
    from constraint_aware.lfo.sequence import SequenceConfig, home_view, station_for
    from constraint_aware.sim.reach import (
        JACO_PRESHAPE,
        JacoPlanner,
        choose_base,
        facing,
        home_pose,
    )
    from constraint_aware.spatial import Pose

    _, skill = _placed("crank", 1)
    believed = scene_from_skill(skill).task
    cfg = SequenceConfig()
    home = (cfg.jaco_home_forward, cfg.jaco_home_up)
    station = station_for("jaco", skill, cfg)
    assert station.base is not None and station.home_joints is not None
    _, frame = nominal_frame(skill)
    view = home_view(station.camera, frame)
    blind, _ = choose_base(believed, cfg.pre_grasp, home)  # no view asked
    assert float(np.linalg.norm(station.base - blind)) > 0.1

    def hidden(base: np.ndarray, q: np.ndarray | None = None) -> int:
        planner = JacoPlanner(base)
        planner.fingers = JACO_PRESHAPE["knob"]
        planner.set_object(believed)
        if q is None:
            grasp = Pose(frame.origin, Rotation.from_matrix(frame.rotation))
            tool = home_pose(base, grasp, home)
            q = planner.solve_ik(tool, facing(base, tool.position))
        return planner.hidden(q, view.eye, view.points)

    assert hidden(station.base, station.home_joints) == 0
    assert hidden(blind) > len(view.points) // 2


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
