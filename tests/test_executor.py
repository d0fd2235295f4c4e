"""The executor's logic against a fake robot: no MuJoCo anywhere in this file."""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.controllers import (
    ControlInput,
    FixedDirection,
    PolicyController,
    ProjectionController,
)
from constraint_aware.control.executor import Executor, ExecutorConfig
from constraint_aware.control.executor_config import (
    GoalConfig,
    GuardsConfig,
    LimitsConfig,
    RobotOverrides,
    TorquePolicyConfig,
)
from constraint_aware.control.record import OUTCOME_MEANINGS, OUTCOMES, RunRecord
from constraint_aware.control.robot import reported_stiffness
from constraint_aware.control.run_inputs import INPUT_NAMES
from constraint_aware.control.torque_policy import TorquePolicy
from constraint_aware.deadband import MIN_THRESHOLD
from constraint_aware.errors import ConfigError, InvalidInputError
from constraint_aware.geometry import angle_deg, rotate_about
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.spatial import Pose, Wrench

U = np.array([1.0, 0.0, 0.0])
# the executor holds for offset_samples periods to sample F_d; the last sample is also the
# first step's reading, so the first move is the command after HOLD hold commands
HOLD = ExecutorConfig().timing.offset_samples - 1
WEIGHT = np.array([0.0, 0.0, -6.0])  # the hand's own weight in the raw reading


@dataclass
class FakeGuide:
    """Hand rigidly holding a body on a frictionless guide along U, arm stiffness k.

    Quasi-static: after a command the body slides to the target's projection on the guide and
    the object's force on the hand is k (body - target). Also its own TaskMonitor. Each reading
    is a fresh sample, as from any real sensor: its last bits differ (1e-9 N dither), so the
    executor's stale-reading guard (identical samples) does not fire on this noise-free fake.
    """

    k: float = 2000.0
    goal: float = 0.25
    nan_after: int | None = None
    lose_contact_after: int | None = None
    torque: np.ndarray = field(default_factory=lambda: np.zeros(3))
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    target: Pose = field(default_factory=lambda: Pose(np.zeros(3), Rotation.identity()))
    commands: list[Pose] = field(default_factory=list)
    steps: int = 0
    reads: int = 0

    control_period = 0.1

    def read_wrench(self) -> Wrench:
        if self.nan_after is not None and self.steps > self.nan_after:
            return Wrench(np.full(3, np.nan), np.zeros(3))
        self.reads += 1
        dither = 1e-9 * math.sin(self.reads)
        force = self.k * (self.position - self.target.position) + WEIGHT + dither
        return Wrench(force, self.torque.copy())

    def read_pose(self) -> Pose:
        return Pose(self.position.copy(), self.target.orientation)

    def commanded_pose(self) -> Pose:
        return self.target

    def grasp_contact(self) -> bool | None:
        return not (self.lose_contact_after is not None and self.steps > self.lose_contact_after)

    def command_pose(self, pose: Pose) -> None:
        self.target = pose
        self.commands.append(pose)

    def advance(self) -> None:
        self.position = float(self.target.position @ U) * U
        self.steps += 1

    # TaskMonitor
    def admissible_direction(self) -> np.ndarray:
        return U.copy()

    def progress(self) -> float:
        return float(self.position @ U)

    def succeeded(self) -> bool:
        return self.progress() >= self.goal

    def grasp_failure(self) -> str | None:
        return None

    def slip(self) -> tuple[float, float]:
        return 0.0, 0.0

    def handle_position(self) -> np.ndarray:
        return self.position.copy()


def d0(offset_deg: float) -> np.ndarray:
    return rotate_about(U, np.array([0.0, 0.0, 1.0]), math.radians(offset_deg))


def test_projection_converges_and_succeeds() -> None:
    robot = FakeGuide()
    rec = Executor(robot, ProjectionController(), ExecutorConfig(), monitor=robot).run(d0(30))
    assert rec.outcome == "success"
    assert rec.angles[0] == pytest.approx(30.0)
    assert rec.angles[2] < 1e-6  # one update after the first measured force
    assert rec.progress >= 0.25


def test_policy_stops_correcting_below_the_threshold() -> None:
    robot = FakeGuide()
    rec = Executor(robot, PolicyController(), ExecutorConfig(threshold=3.0), monitor=robot).run(
        d0(-30)
    )
    assert rec.success
    # below the threshold the direction is left alone: angles under asin(thr / (k step))
    floor = math.degrees(math.asin(3.0 / (robot.k * 0.01)))
    assert max(rec.angles[4:]) < floor + 1.0


def test_policy_on_a_frictionless_guide_keeps_the_median_friction_bias() -> None:
    """(F^, d) fixes only error + atan(mu): on a frictionless guide the paper's policy, trained
    on mu ~ U(0, 0.15), corrects for the tilt of a typical mu that is not there."""
    robot = FakeGuide()
    cfg = ExecutorConfig(threshold=0.2)
    paper = PolicyController(ConstraintAwarePolicy.load("paper"))
    rec = Executor(robot, paper, cfg, monitor=robot).run(d0(-30))
    mean_mu = float(np.mean(paper.policy.card["env_config"]["friction"]))
    assert rec.angles[-1] == pytest.approx(math.degrees(math.atan(mean_mu)), abs=1.5)


def test_offset_is_subtracted_before_the_controller_sees_the_force() -> None:
    seen: list[ControlInput] = []

    class Spy(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            seen.append(inp)
            return inp.direction

    robot = FakeGuide()
    Executor(robot, Spy(), ExecutorConfig(limits=LimitsConfig(max_steps=3))).run(U)
    assert np.allclose(seen[0].force, 0.0)  # the weight is in F_d, not in F
    assert np.allclose(seen[1].force, 0.0)  # aligned: no constraint force either


def test_force_limit_stops_the_run() -> None:
    robot = FakeGuide(k=20000.0)
    rec = Executor(robot, FixedDirection(), ExecutorConfig(), monitor=robot).run(d0(40))
    assert rec.outcome == "force_limit"
    assert rec.peak_force > 60.0


def test_nan_sensor_stops_without_raising() -> None:
    robot = FakeGuide(nan_after=HOLD + 3)
    rec = Executor(robot, PolicyController(), ExecutorConfig(), monitor=robot).run(d0(10))
    assert rec.outcome == "nan"
    assert len(rec.steps) == 5  # four good steps, then the non-finite reading that ended it
    assert not math.isfinite(rec.steps[-1].force_norm)
    assert rec.peak_force < 60.0  # summaries skip the non-finite reading


def test_lost_contact_stops_after_the_configured_steps() -> None:
    robot = FakeGuide(lose_contact_after=HOLD + 2)
    cfg = ExecutorConfig(guards=GuardsConfig(lost_contact_steps=4))
    rec = Executor(robot, FixedDirection(), cfg, monitor=robot).run(U)
    assert rec.outcome == "contact_lost"
    assert rec.steps[-1].step == 2 + 4  # contact gone from step 3; the 4th such step stops


def test_commands_stay_in_the_workplane() -> None:
    class Upward(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            return np.array([1.0, 0.0, 1.0]) / math.sqrt(2)

    robot = FakeGuide()
    Executor(robot, Upward(), ExecutorConfig(limits=LimitsConfig(max_steps=4))).run(U)
    for pose in robot.commands:
        assert abs(pose.position[2]) < 1e-12
    step = robot.commands[HOLD + 1].position - robot.commands[HOLD].position
    assert np.linalg.norm(step) == pytest.approx(0.01)


def test_revolute_hand_turns_with_the_direction() -> None:
    class TurnTen(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            return rotate_about(inp.direction, np.array([0.0, 0.0, 1.0]), math.radians(10))

    robot = FakeGuide()
    cfg = ExecutorConfig(constraint_type="revolute", limits=LimitsConfig(max_steps=3))
    Executor(robot, TurnTen(), cfg).run(U)
    rotvec = robot.commands[HOLD].orientation.as_rotvec()
    np.testing.assert_allclose(rotvec, [0.0, 0.0, math.radians(10)], atol=1e-12)
    total = robot.commands[-1].orientation.as_rotvec()
    np.testing.assert_allclose(total, [0.0, 0.0, math.radians(30)], atol=1e-12)


def test_torque_policy_rotates_by_v_over_r_then_adapts() -> None:
    robot = FakeGuide(torque=np.array([0.0, 0.0, 0.5]))  # the object drags the hand round
    cfg = ExecutorConfig(
        constraint_type="revolute",
        rotation_radius=0.1,
        limits=LimitsConfig(max_steps=3),
        torque_policy=TorquePolicyConfig(enabled=True),
    )
    rec = Executor(robot, FixedDirection(), cfg).run(U)
    w0 = 0.01 / 0.1
    # the torque is offset-corrected: a constant torque is part of tau_d, so w stays v/r
    assert [s.rotation_rate for s in rec.steps[:3]] == pytest.approx([w0, w0, w0])
    angle = robot.commands[HOLD].orientation.magnitude()
    assert angle == pytest.approx(w0)


def test_torque_policy_rule() -> None:
    tp = TorquePolicy(radius=0.12, alpha=0.1, beta=math.radians(1))
    n = np.array([0.0, 0.0, 1.0])
    w0 = tp.w
    assert tp.update(np.array([0.0, 0.0, 0.05]), n) == pytest.approx(w0)
    assert tp.update(np.array([0.0, 0.0, 0.2]), n) == pytest.approx(w0 + math.radians(1))
    assert tp.update(np.array([0.0, 0.0, -0.2]), n) == pytest.approx(w0)
    with pytest.raises(InvalidInputError):
        TorquePolicy(radius=0.0)


def test_bad_config_is_rejected_with_valid_names() -> None:
    with pytest.raises(InvalidInputError, match="prismatic, revolute"):
        ExecutorConfig(constraint_type="spherical")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match="rotation_radius"):
        ExecutorConfig(constraint_type="revolute", torque_policy=TorquePolicyConfig(enabled=True))


def test_a_configured_stiffness_replaces_the_report_and_is_noted() -> None:
    with pytest.raises(InvalidInputError, match=r"stiffness.*\(0, 1e\+06\] \[N/m\]"):
        ExecutorConfig(robot=RobotOverrides(stiffness=-5.0))
    with pytest.raises(InvalidInputError, match="stiffness"):
        ExecutorConfig(robot=RobotOverrides(stiffness=2e6))
    seen: list[float | None] = []

    class Recording(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            seen.append(inp.step_force)
            return super().next_direction(inp)

    cfg = ExecutorConfig(limits=LimitsConfig(max_steps=3), robot=RobotOverrides(stiffness=2500.0))
    rec = Executor(Stiff(), Recording(), cfg).run(d0(0))
    assert seen and all(f == pytest.approx(25.0) for f in seen)  # 2500 N/m x 1 cm
    assert "stiffness 2500 N/m from the configuration (robot reports 2000 N/m)" in rec.notes


def test_a_configured_grasp_play_gives_the_controller_the_force_it_hides() -> None:
    with pytest.raises(InvalidInputError, match=r"grasp_play.*\[0, 0\.005\] \[m\]"):
        ExecutorConfig(robot=RobotOverrides(grasp_play=0.006))  # more than half a 1 cm step
    with pytest.raises(InvalidInputError, match="grasp_play"):
        ExecutorConfig(robot=RobotOverrides(grasp_play=math.nan))
    seen: list[float | None] = []

    class Recording(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            seen.append(inp.play_force)
            return super().next_direction(inp)

    rec = Executor(
        Stiff(),
        Recording(),
        ExecutorConfig(limits=LimitsConfig(max_steps=3), robot=RobotOverrides(grasp_play=0.0015)),
    ).run(d0(0))
    assert seen and all(f == pytest.approx(3.0) for f in seen)  # 2000 N/m x 1.5 mm
    assert "grasp play 1.50 mm from the configuration" in rec.notes
    seen.clear()
    Executor(Stiff(), Recording(), ExecutorConfig(limits=LimitsConfig(max_steps=3))).run(d0(0))
    assert seen and all(f is None for f in seen)  # no play configured: nothing to add


def test_executor_module_never_imports_mujoco() -> None:
    code = (
        "import sys\n"
        "import constraint_aware.control.executor, constraint_aware.control.controllers\n"
        "import constraint_aware.control.probe\n"
        "assert 'mujoco' not in sys.modules, 'mujoco imported'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_angle_helper_matches_ground_truth() -> None:
    assert angle_deg(U, d0(25.0)) == pytest.approx(25.0)


# --- step API, exceptions, records ----------------------------------------------------------
def test_step_api_gives_the_same_run_as_run() -> None:
    a = FakeGuide()
    rec_a = Executor(a, ProjectionController(), ExecutorConfig(), monitor=a).run(d0(30))
    b = FakeGuide()
    ex = Executor(b, ProjectionController(), ExecutorConfig(), monitor=b)
    ex.start(d0(30))
    while True:
        out = ex.step(b.read_wrench(), b.read_pose())
        if not isinstance(out, Pose):
            break
        b.command_pose(out)
        b.advance()
    assert out.to_dict() == rec_a.to_dict()
    assert [c.position.tolist() for c in b.commands] == [c.position.tolist() for c in a.commands]


@dataclass
class Holding(FakeGuide):
    """FakeGuide with the optional hold(), and a comms failure after some commands."""

    holds: int = 0
    fail_after: int | None = None
    interrupt_after: int | None = None

    def hold(self) -> None:
        self.holds += 1

    def command_pose(self, pose: Pose) -> None:
        if self.fail_after is not None and len(self.commands) >= self.fail_after:
            raise ConnectionError("robot comms lost")
        super().command_pose(pose)

    def advance(self) -> None:
        if self.interrupt_after is not None and self.steps >= self.interrupt_after:
            raise KeyboardInterrupt
        super().advance()


def test_comms_exception_keeps_the_record_and_holds() -> None:
    robot = Holding(fail_after=HOLD + 5)
    with pytest.raises(ConnectionError) as info:
        Executor(robot, FixedDirection(), ExecutorConfig(), monitor=robot).run(d0(10))
    rec = info.value.run_record  # type: ignore[attr-defined]
    assert rec.outcome == "error" and "comms lost" in rec.reason
    assert len(rec.steps) == 6 and robot.holds == 1
    json.dumps(rec.to_dict(), allow_nan=False)


def test_keyboard_interrupt_keeps_the_record_and_holds() -> None:
    robot = Holding(interrupt_after=HOLD + 3)
    with pytest.raises(KeyboardInterrupt) as info:
        Executor(robot, FixedDirection(), ExecutorConfig(), monitor=robot).run(U)
    rec = info.value.run_record  # type: ignore[attr-defined]
    assert rec.outcome == "error" and rec.reason.startswith("KeyboardInterrupt")
    assert robot.holds == 1


def test_every_stop_calls_hold() -> None:
    robot = Holding()
    rec = Executor(robot, ProjectionController(), ExecutorConfig(), monitor=robot).run(d0(30))
    assert rec.success and robot.holds == 1


def test_goal_travel_stops_a_robot_without_monitor_or_optional_members(
    required_only: type[Any],
) -> None:
    robot = required_only(FakeGuide())  # only the required members
    # without contact sensing the executor judges contact from |F|, which on this frictionless
    # fake is 0 once aligned: switch that judgement off
    cfg = ExecutorConfig(goal=GoalConfig(travel=0.1), guards=GuardsConfig(lost_contact_force=0.0))
    rec = Executor(robot, ProjectionController(), cfg).run(d0(30))
    assert rec.outcome == "success" and rec.reason.startswith("goal: travel")
    assert rec.goal is not None and rec.goal["reached"] >= 0.1
    assert math.isnan(rec.progress)  # no monitor: no ground truth in the record
    json.dumps(rec.to_dict(), allow_nan=False)


def test_without_contact_sensing_contact_is_judged_from_the_force(
    required_only: type[Any],
) -> None:
    """|F| above guards.contact_force once (the 30 deg error's first reading), then below
    guards.lost_contact_force (aligned on the frictionless guide) for lost_contact_steps."""
    robot = required_only(FakeGuide())
    rec = Executor(robot, ProjectionController(), ExecutorConfig()).run(d0(30))
    assert rec.outcome == "contact_lost" and rec.reason == "no hand-object contact for 5 steps"
    forces = [s.force_norm for s in rec.steps]
    assert forces[1] > 1.0 and all(f < 0.25 for f in forces[-5:])


def test_success_on_the_last_allowed_move_is_success() -> None:
    robot = FakeGuide()
    cfg = ExecutorConfig(goal=GoalConfig(travel=0.05), limits=LimitsConfig(max_steps=5))
    rec = Executor(robot, FixedDirection(), cfg).run(U)
    assert rec.outcome == "success" and rec.n_steps == 5
    rec = Executor(
        FakeGuide(),
        FixedDirection(),
        ExecutorConfig(goal=GoalConfig(travel=0.06), limits=LimitsConfig(max_steps=5)),
    ).run(U)
    assert rec.outcome == "timeout" and rec.n_steps == 5


def test_force_limit_comes_before_success() -> None:
    robot = FakeGuide(k=20000.0, goal=0.001)  # the first move both succeeds and passes 60 N
    rec = Executor(robot, FixedDirection(), ExecutorConfig(), monitor=robot).run(d0(40))
    assert rec.outcome == "force_limit" and not rec.success


@dataclass
class Stiff(FakeGuide):
    """FakeGuide that reports its stiffness (the optional Robot member)."""

    @property
    def translational_stiffness(self) -> float:
        return self.k


def test_predicted_force_stops_before_the_limit() -> None:
    robot = Stiff(k=20000.0)
    rec = Executor(robot, FixedDirection(), ExecutorConfig(), monitor=robot).run(d0(40))
    assert rec.outcome == "force_limit" and "refused" in rec.reason
    assert rec.peak_force <= 60.0 * 1.1


def test_derived_threshold_is_recorded() -> None:
    robot = FakeGuide()
    rec = Executor(
        robot, FixedDirection(), ExecutorConfig(threshold=None, limits=LimitsConfig(max_steps=2))
    ).run(U)
    assert rec.threshold == pytest.approx(MIN_THRESHOLD)  # a noise-free fake: the floor
    rec = Executor(
        FakeGuide(), FixedDirection(), ExecutorConfig(limits=LimitsConfig(max_steps=2))
    ).run(U)
    assert rec.threshold == pytest.approx(MIN_THRESHOLD)  # derived is the default
    cfg = ExecutorConfig(threshold=3.0, limits=LimitsConfig(max_steps=2))
    assert Executor(FakeGuide(), FixedDirection(), cfg).run(U).threshold == 3.0


def test_record_is_strict_json_and_round_trips(tmp_path: Path) -> None:
    robot = FakeGuide(nan_after=HOLD + 2)
    rec = Executor(robot, FixedDirection(), ExecutorConfig()).run(U)
    path = rec.save(tmp_path / "r.json")
    text = path.read_text()
    assert "NaN" not in text and "null" in text
    back = RunRecord.load(path)
    assert back.outcome == "nan" and math.isnan(back.steps[-1].force_norm)
    assert back.to_dict() == rec.to_dict()


def test_revolute_normal_is_oriented_from_the_hinge_point() -> None:
    class TurnTen(FixedDirection):
        def next_direction(self, inp: ControlInput) -> np.ndarray:
            return rotate_about(inp.direction, np.array([0.0, 0.0, 1.0]), math.radians(10))

    # hand at the origin, hinge at -y: moving along +x turns negatively about +z, so the
    # given normal +z is flipped to -z and the torque policy turns the hand the right way
    robot = FakeGuide()
    cfg = ExecutorConfig(
        constraint_type="revolute",
        rotation_radius=0.5,
        hinge_point=(0.0, -0.5, 0.0),
        limits=LimitsConfig(max_steps=2),
        torque_policy=TorquePolicyConfig(enabled=True),
    )
    rec = Executor(robot, TurnTen(), cfg).run(U)
    assert any("flipped" in n for n in rec.notes)
    assert robot.commands[HOLD].orientation.as_rotvec()[2] < 0


@dataclass
class Flipped(FakeGuide):
    """FakeGuide whose driver reports the wrench with the opposite sign."""

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        return Wrench(-w.force, -w.torque)


def test_self_check_names_a_flipped_sign() -> None:
    rec = Executor(Flipped(), FixedDirection(), ExecutorConfig()).run(d0(30))
    assert rec.outcome == "sensor_convention" and "sign flipped" in rec.reason
    rec = Executor(
        FakeGuide(), FixedDirection(), ExecutorConfig(limits=LimitsConfig(max_steps=10))
    ).run(d0(30))
    assert rec.outcome == "timeout"
    assert any(n.startswith("self-check passed") for n in rec.notes)


class Holds(FixedDirection):
    """Keeps d and commands a zero-length step (a hold, as the `DirectionController` protocol
    allows) on the calls `holds(call)` names (call 1 is the reading at rest, before the first
    move)."""

    def __init__(self, holds: Callable[[int], bool]) -> None:
        self.holds = holds

    def reset(self, direction: np.ndarray) -> None:
        self.calls = 0

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        self.calls += 1
        return inp.direction

    def step_length(self, nominal: float) -> float:
        return 0.0 if self.holds(self.calls) else nominal


def test_a_hold_does_not_hide_a_flipped_sign() -> None:
    """The reading after a hold and the one after the hand starts again are compared with the
    deflection only (control.self_check.SETTLE_MOVES); a flipped sign is still caught, within the
    self-check's moves, and a healthy run passes."""
    cfg = ExecutorConfig()
    rec = Executor(Flipped(), Holds(lambda call: call == 2), cfg).run(d0(30))
    assert rec.outcome == "sensor_convention" and "sign flipped" in rec.reason
    assert rec.n_steps <= cfg.self_check.steps + 1
    healthy = Executor(
        FakeGuide(),
        Holds(lambda call: call == 2),
        ExecutorConfig(limits=LimitsConfig(max_steps=10)),
    )
    rec = healthy.run(d0(30))
    assert rec.outcome == "timeout"
    assert any(n.startswith("self-check passed") for n in rec.notes), rec.notes


def test_holds_on_every_other_step_do_not_hide_a_flipped_sign() -> None:
    """Every reading then follows a hold or a restart, which the F.d test and the half-lag
    confirmation skip (control.self_check.SETTLE_MOVES); the cosine with the deflection still takes
    them, and a flipped sign reads ~ -1 there whatever the hand does."""
    every_other = Holds(lambda call: call % 2 == 0)
    rec = Executor(Flipped(), every_other, ExecutorConfig(limits=LimitsConfig(max_steps=40))).run(
        d0(30)
    )
    assert rec.outcome == "sensor_convention" and "sign flipped" in rec.reason
    rec = Executor(FakeGuide(), every_other, ExecutorConfig(limits=LimitsConfig(max_steps=40))).run(
        d0(30)
    )
    assert rec.outcome == "timeout", rec.reason


class Inputs(FixedDirection):
    """Keeps d and records what it was given each step."""

    def reset(self, direction: np.ndarray) -> None:
        self.inputs: list[ControlInput] = []

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        self.inputs.append(inp)
        return inp.direction


def test_the_controller_is_told_the_last_move_and_the_hand_travel() -> None:
    """Before the first move neither is known; after it, the move (1 cm) and the hand's
    travel from the pose at that command: on the guide along U, 1 cm x cos(30 deg)."""
    ctrl = Inputs()
    Executor(FakeGuide(), ctrl, ExecutorConfig(limits=LimitsConfig(max_steps=3))).run(d0(30))
    first, second = ctrl.inputs[:2]
    assert first.last_move is None and first.hand_travel is None
    assert second.last_move == pytest.approx(0.01)
    assert second.hand_travel == pytest.approx(0.01 * math.cos(math.radians(30)))


def test_wrench_from_sensor_frame_sign_lever_and_weight() -> None:
    rot = Rotation.from_rotvec([0.0, 0.0, math.pi / 2])  # sensor x = world y
    w = Wrench.from_sensor(
        [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], rot, [0.0, 0.0, 0.1], [0.0, 0.0, 0.0], sign=-1.0
    )
    np.testing.assert_allclose(w.force, [0.0, -1.0, 0.0], atol=1e-12)
    # the force acts at the sensor, 10 cm above the tool point: r x F = (0,0,0.1) x (0,-1,0)
    np.testing.assert_allclose(w.torque, [0.1, 0.0, 0.0], atol=1e-12)
    # a 1 kg hand hanging at rest reads its weight; compensation removes it
    w = Wrench.from_sensor(
        [0.0, 0.0, -9.81], [0.0, 0.0, 0.0], np.eye(3), np.zeros(3), np.zeros(3), hand_mass=1.0
    )
    np.testing.assert_allclose(w.force, 0.0, atol=1e-12)
    with pytest.raises(InvalidInputError, match="sign"):
        Wrench.from_sensor(np.zeros(3), np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3), sign=2)


class NumpyDrawer:
    """A Robot written outside the package against the protocol only (numpy, no MuJoCo, no
    TaskMonitor): a drawer on a guide along U with dry friction, rigidly held by a hand on a
    compliant arm (stiffness k, quasi-static), a noisy wrist sensor that also reads the hand's
    weight, and hold()."""

    control_period = 0.1

    def __init__(self, k: float = 2000.0, friction: float = 4.0, seed: int = 0) -> None:
        self.k = k
        self.friction = friction  # [N] Coulomb friction of the guide
        self.rng = np.random.default_rng(seed)
        self.s = 0.0  # [m] drawer opening
        self.target = Pose(np.zeros(3), Rotation.identity())
        self.next: Pose | None = None
        self.held = 0

    @property
    def translational_stiffness(self) -> float:  # optional member: policies may use k delta
        return self.k

    def _hand(self) -> np.ndarray:
        return self.s * U

    def read_wrench(self) -> Wrench:
        force = self.k * (self._hand() - self.target.position) + WEIGHT
        return Wrench(force + self.rng.normal(0.0, 0.05, 3), self.rng.normal(0.0, 0.005, 3))

    def read_pose(self) -> Pose:
        return Pose(self._hand(), self.target.orientation)

    def commanded_pose(self) -> Pose:
        return self.target

    def command_pose(self, pose: Pose) -> None:
        self.next = pose

    def advance(self) -> None:
        if self.next is not None:
            self.target, self.next = self.next, None
        pull = self.k * (float(self.target.position @ U) - self.s)  # spring force along U
        if abs(pull) > self.friction:  # slides until the spring balances the friction
            self.s += (abs(pull) - self.friction) / self.k * math.copysign(1.0, pull)

    def hold(self) -> None:
        self.held += 1
        self.next = Pose(self._hand(), self.target.orientation)


@pytest.mark.parametrize("offset", [-30.0, 20.0])
def test_an_outside_robot_reaches_a_goal_without_simulator(offset: float) -> None:
    robot = NumpyDrawer()
    cfg = ExecutorConfig(workplane_normal=(0.0, 0.0, 1.0), goal=GoalConfig(travel=0.2))
    rec = Executor(robot, PolicyController(), cfg).run(d0(offset))  # type: ignore[arg-type]
    assert rec.outcome == "success" and rec.reason.startswith("goal: travel")
    assert robot.s >= 0.2 - 1e-9 and robot.held == 1
    assert rec.peak_force < 60.0
    final = np.array(rec.steps[-1].direction)
    assert angle_deg(final, U) < 10.0  # the policy found the guide from the forces alone


class Broken(FixedDirection):
    """A controller that fails after two steps: a NaN direction or a 1 m step."""

    def __init__(self, kind: str) -> None:
        self.kind = kind
        self.calls = 0

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        self.calls += 1
        if self.kind == "nan" and self.calls > 2:
            return np.array([np.nan, 0.0, 0.0])
        return inp.direction

    def step_length(self, nominal: float) -> float:
        return 1.0 if self.kind == "long" and self.calls > 2 else nominal


@pytest.mark.parametrize("kind", ["nan", "long"])
def test_a_bad_command_is_never_sent(kind: str) -> None:
    robot = Holding()
    rec = Executor(robot, Broken(kind), ExecutorConfig()).run(U)
    assert rec.outcome == "bad_command" and rec.reason
    assert robot.holds == 1
    for a, b in zip(robot.commands, robot.commands[1:], strict=False):
        assert np.all(np.isfinite(b.position))
        assert np.linalg.norm(b.position - a.position) <= 0.01 + 1e-12


def test_a_pose_glitch_is_not_acted_on() -> None:
    @dataclass
    class Glitchy(FakeGuide):
        def read_pose(self) -> Pose:
            p = super().read_pose()
            if self.steps == HOLD + 3:  # one reading 50 cm off across the guide
                return Pose(p.position + np.array([0.0, 0.5, 0.0]), p.orientation)
            return p

    robot = Glitchy()
    rec = Executor(robot, ProjectionController(), ExecutorConfig(), monitor=robot).run(d0(20))
    assert rec.outcome == "success"
    assert rec.peak_force < 20.0  # the glitch never became a command
    steps = [
        np.linalg.norm(b.position - a.position)
        for a, b in zip(robot.commands, robot.commands[1:], strict=False)
    ]
    assert max(steps) <= 0.03


class StepForceSeen(FixedDirection):
    """Keeps d0 and remembers the step force k*delta the executor hands the controller."""

    def __init__(self) -> None:
        self.seen: list[float | None] = []

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        self.seen.append(inp.step_force)
        return inp.direction


@pytest.mark.parametrize("report", [math.nan, math.inf, -2000.0, 0.0, "stiff"])
def test_an_invalid_reported_stiffness_is_ignored_and_named(report: object) -> None:
    @dataclass
    class Reports(FakeGuide):
        translational_stiffness: object = report

    note = f"ignored translational_stiffness {report!r} (valid: finite, > 0 [N/m])"
    assert reported_stiffness(Reports()) == (None, note)
    ctrl = StepForceSeen()
    rec = Executor(Reports(), ctrl, ExecutorConfig(limits=LimitsConfig(max_steps=3))).run(d0(0))
    assert note in rec.notes
    assert ctrl.seen and all(s is None for s in ctrl.seen)


def test_a_valid_reported_stiffness_gives_the_controller_k_delta() -> None:
    @dataclass
    class Reports(FakeGuide):
        translational_stiffness: float = 2000.0

    assert reported_stiffness(Reports()) == (2000.0, "")
    assert reported_stiffness(FakeGuide()) == (None, "")  # reports none: nothing to name
    ctrl = StepForceSeen()
    cfg = ExecutorConfig(limits=LimitsConfig(max_steps=3))
    rec = Executor(Reports(), ctrl, cfg).run(d0(0))
    assert not any("ignored" in n for n in rec.notes)
    assert ctrl.seen and all(s == pytest.approx(2000.0 * cfg.step_length) for s in ctrl.seen)


@dataclass
class PressingGuide(FakeGuide):
    """FakeGuide whose hand, once moving, also presses 12 N down on the workplane while the arm
    sags 1 mm up along its normal: a force along the normal that the wrist spring does not
    explain (on the Jaco's plate it swings by 8 N). In the plane it is the healthy FakeGuide:
    judged in 3-D, F and the deflection point apart (cos about -0.2)."""

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        press = np.array([0.0, 0.0, -12.0]) if self.steps > HOLD else np.zeros(3)
        return Wrench(w.force + press, w.torque)

    def advance(self) -> None:
        super().advance()
        if self.steps > HOLD:
            self.position = self.position + np.array([0.0, 0.0, 0.001])


def test_the_self_check_judges_the_workplane_only() -> None:
    cfg = ExecutorConfig(workplane_normal=(0.0, 0.0, 1.0), limits=LimitsConfig(max_steps=10))
    rec = Executor(PressingGuide(), FixedDirection(), cfg).run(d0(10))
    assert rec.outcome == "timeout", rec.reason  # healthy in the plane: not stopped
    assert any(n.startswith("self-check passed") for n in rec.notes), rec.notes

    # the same reading with its sign flipped is still caught from its in-plane part
    @dataclass
    class FlippedPressing(PressingGuide):
        def read_wrench(self) -> Wrench:
            w = super().read_wrench()
            return Wrench(-w.force, -w.torque)

    rec = Executor(FlippedPressing(), FixedDirection(), cfg).run(d0(10))
    assert rec.outcome == "sensor_convention", rec.outcome


def test_too_few_judged_moves_leave_the_self_check_inconclusive() -> None:
    # aligned with the guide: no force in the plane, so no move is judged, only the press
    cfg = ExecutorConfig(workplane_normal=(0.0, 0.0, 1.0), limits=LimitsConfig(max_steps=10))
    rec = Executor(PressingGuide(), FixedDirection(), cfg).run(d0(0))
    assert rec.outcome == "timeout", rec.reason
    assert any(n.startswith("self-check inconclusive") for n in rec.notes), rec.notes
    assert not any(n.startswith("self-check passed") for n in rec.notes)


# --- the run's inputs and the controller's stages -------------------------------------------
class Staged(FixedDirection):
    """A stand-in for a controller with stages: each needs some of the run's inputs."""

    def __init__(self, rotation_rate: float | None = None) -> None:
        self.rotation_rate = rotation_rate
        self.asked: list[str] = []

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        self.asked.append(constraint_type)
        return {
            "magnitude_input": ("step_force",),
            "mirror_average": ("workplane_normal", "step_force"),
            "feed_forward": ("rotation_rate",),
            "lag_undo": ("tracking_time_constant",),
            "play": ("play_force",),
        }


@dataclass
class Lagging(Stiff):
    """Stiff, also reporting its tracking time constant."""

    tracking_time_constant: float = 0.05


def constraint_aware_warnings(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [
        r.getMessage()
        for r in caplog.records
        if r.name == "constraint_aware" and r.levelno == logging.WARNING
    ]


def test_the_record_lists_each_input_with_its_source() -> None:
    rec = Executor(
        FakeGuide(), FixedDirection(), ExecutorConfig(limits=LimitsConfig(max_steps=2))
    ).run(U)
    assert list(rec.inputs) == list(INPUT_NAMES)
    missing = {"value": None, "source": "missing"}
    assert rec.inputs["step_force"] == missing  # the fake reports no stiffness
    assert rec.inputs["tracking_time_constant"] == missing
    assert rec.inputs["workplane_normal"] == {"value": [0.0, 0.0, 1.0], "source": "config"}
    assert rec.inputs["rotation_rate"] == missing  # FixedDirection has none
    assert rec.inputs["play_force"] == missing  # no grasp play configured
    assert rec.stages == {}  # a controller without stage_inputs has no stages

    cfg = ExecutorConfig(limits=LimitsConfig(max_steps=2), robot=RobotOverrides(grasp_play=0.0015))
    rec = Executor(Lagging(), Staged(rotation_rate=0.4), cfg).run(U)
    assert rec.inputs["step_force"] == {"value": pytest.approx(20.0), "source": "robot"}
    assert rec.inputs["tracking_time_constant"] == {"value": 0.05, "source": "robot"}
    assert rec.inputs["rotation_rate"] == {"value": 0.4, "source": "controller"}
    assert rec.inputs["play_force"] == {"value": pytest.approx(3.0), "source": "config"}

    override = ExecutorConfig(
        limits=LimitsConfig(max_steps=2), robot=RobotOverrides(stiffness=2500.0)
    )
    rec = Executor(FakeGuide(), FixedDirection(), override).run(U)
    assert rec.inputs["step_force"] == {"value": pytest.approx(25.0), "source": "config"}
    play_unknown = ExecutorConfig(
        limits=LimitsConfig(max_steps=2), robot=RobotOverrides(grasp_play=0.001)
    )
    rec = Executor(FakeGuide(), FixedDirection(), play_unknown).run(U)  # no stiffness to use it
    assert rec.inputs["play_force"] == missing


def test_stages_are_recorded_and_each_missing_input_warned_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING, logger="constraint_aware")
    ctrl = Staged()
    cfg = ExecutorConfig(limits=LimitsConfig(max_steps=3), constraint_type="revolute")
    rec = Executor(FakeGuide(), ctrl, cfg).run(U)
    assert ctrl.asked == ["revolute"]
    assert rec.stages == {
        "magnitude_input": "off: missing step_force",
        "mirror_average": "off: missing step_force",
        "feed_forward": "off: missing rotation_rate",
        "lag_undo": "off: missing tracking_time_constant",
        "play": "off: missing play_force",
    }
    lines = constraint_aware_warnings(caplog)
    assert len(lines) == 4  # one per missing input, not per stage nor per step
    step_force = [line for line in lines if line.startswith("step_force missing")]
    assert step_force == [
        "step_force missing (the robot reports no translational_stiffness and "
        "ExecutorConfig.robot.stiffness is not set): stages magnitude_input, mirror_average off"
    ]
    assert any(line.startswith("rotation_rate missing (") for line in lines)

    caplog.clear()
    flat = ExecutorConfig(limits=LimitsConfig(max_steps=3), workplane_normal=None)
    rec = Executor(FakeGuide(), Staged(), flat).run(U)
    assert rec.stages["mirror_average"] == "off: missing workplane_normal, step_force"
    assert rec.inputs["workplane_normal"] == {"value": None, "source": "missing"}

    caplog.clear()
    complete = ExecutorConfig(
        limits=LimitsConfig(max_steps=3), robot=RobotOverrides(grasp_play=0.001)
    )
    rec = Executor(Lagging(), Staged(rotation_rate=0.4), complete).run(U)
    assert set(rec.stages.values()) == {"active"}
    assert constraint_aware_warnings(caplog) == []


def test_inputs_and_stages_survive_json(tmp_path: Path) -> None:
    rec = Executor(FakeGuide(), Staged(), ExecutorConfig(limits=LimitsConfig(max_steps=2))).run(U)
    back = RunRecord.load(rec.save(tmp_path / "r.json"))
    assert back.inputs == rec.inputs and back.stages == rec.stages
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["stages"]["lag_undo"] == "off: missing tracking_time_constant"


@pytest.mark.parametrize(
    "answer",
    [["step_force"], {"magnitude_input": ("stiffness",)}, {"magnitude_input": "step_force"}],
)
def test_a_bad_stage_declaration_is_named_and_the_robot_held(answer: object) -> None:
    class BadStages(FixedDirection):
        def stage_inputs(self, constraint_type: str) -> object:  # type: ignore[override]
            return answer

    robot = Holding()
    with pytest.raises(InvalidInputError, match=r"stage_inputs") as info:
        Executor(robot, BadStages(), ExecutorConfig()).run(U)
    rec = info.value.run_record  # type: ignore[attr-defined]
    assert rec.outcome == "error" and "stage_inputs" in rec.reason
    assert robot.holds == 1 and robot.commands == []


# --- the step API never trusts its arguments -------------------------------------------------
GOOD_WRENCH = Wrench(np.zeros(3), np.zeros(3))
GOOD_POSE = Pose(np.zeros(3), Rotation.identity())
BAD_STEPS: list[tuple[object, object, str]] = [
    ([0.0, 0.0, 0.0], GOOD_POSE, r"wrench: expected a Wrench"),
    ((np.zeros(3), np.zeros(3)), GOOD_POSE, r"wrench: expected a Wrench"),
    (Wrench(np.zeros(2), np.zeros(3)), GOOD_POSE, r"wrench\.force: expected shape \(3,\)"),
    (Wrench(np.array([1j, 0, 0]), np.zeros(3)), GOOD_POSE, r"wrench\.force: .*complex"),
    (Wrench(np.zeros(3), "abc"), GOOD_POSE, r"wrench\.torque"),  # type: ignore[arg-type]
    (Wrench(np.array([None, 0, 0]), np.zeros(3)), GOOD_POSE, r"wrench\.force"),
    (Wrench(np.ones(3, dtype=bool), np.zeros(3)), GOOD_POSE, r"wrench\.force"),
    (GOOD_WRENCH, np.zeros(3), r"pose: expected a Pose"),
    (GOOD_WRENCH, Pose(np.zeros(4), Rotation.identity()), r"pose\.position: expected shape"),
    (GOOD_WRENCH, Pose(np.zeros((1, 3)), Rotation.identity()), r"pose\.position: expected shape"),
    (GOOD_WRENCH, Pose(np.zeros(3), np.eye(3)), r"pose\.orientation"),
    (
        GOOD_WRENCH,
        Pose(np.zeros(3), Rotation.from_quat([[0, 0, 0, 1], [0, 0, 0, 1]])),
        r"pose\.orientation: expected a single",
    ),
]


@pytest.mark.parametrize("moving", [False, True], ids=["sampling", "moving"])
@pytest.mark.parametrize(("wrench", "pose", "match"), BAD_STEPS)
def test_a_malformed_step_argument_is_named_the_record_kept_and_the_robot_held(
    wrench: object, pose: object, match: str, moving: bool
) -> None:
    robot = Holding()
    ex = Executor(robot, FixedDirection(), ExecutorConfig())
    record = ex.start(U)
    for _ in range(HOLD + 3 if moving else 2):  # good periods first
        out = ex.step(robot.read_wrench(), robot.read_pose())
        assert isinstance(out, Pose)
        robot.command_pose(out)
        robot.advance()
    sent = len(robot.commands)
    with pytest.raises(InvalidInputError, match=match) as info:
        ex.step(wrench, pose)  # type: ignore[arg-type]
    assert info.value.run_record is record  # type: ignore[attr-defined]
    assert record.outcome == "error" and "InvalidInputError" in record.reason
    assert robot.holds == 1
    assert ex.step(robot.read_wrench(), robot.read_pose()) is record  # finished: no command
    assert len(robot.commands) == sent


def test_a_non_finite_reading_is_a_sensor_fault_not_an_input_error() -> None:
    """NaN readings are well-formed: the guards stop on them with a named outcome."""
    robot = Holding(nan_after=HOLD + 2)
    rec = Executor(robot, FixedDirection(), ExecutorConfig()).run(U)
    assert rec.outcome == "nan" and robot.holds == 1

    @dataclass
    class NanPose(Holding):
        def read_pose(self) -> Pose:
            return Pose(np.full(3, np.nan), self.target.orientation)

    rec = Executor(NanPose(), FixedDirection(), ExecutorConfig()).run(U)
    assert rec.outcome == "bad_pose"


@pytest.mark.parametrize(
    ("d0", "match"),
    [
        ([1.0, math.nan, 0.0], r"initial_direction: contains NaN"),
        ([1.0, math.inf, 0.0], r"initial_direction: contains NaN or inf"),
        (np.array([1.0 + 1j, 0.0, 0.0]), r"initial_direction: .*complex"),
        ([1.0, 0.0], r"initial_direction: expected shape \(3,\)"),
        ([0.0, 0.0, 0.0], r"initial_direction: must be a non-zero vector"),
        ("x", r"initial_direction"),
    ],
)
def test_a_bad_initial_direction_is_named_and_the_robot_held(d0: object, match: str) -> None:
    robot = Holding()
    ex = Executor(robot, FixedDirection(), ExecutorConfig())
    with pytest.raises(InvalidInputError, match=match) as info:
        ex.start(d0)  # type: ignore[arg-type]
    record = info.value.run_record  # type: ignore[attr-defined]
    assert record.outcome == "error" and record is ex.record
    assert robot.holds == 1
    assert ex.step(robot.read_wrench(), robot.read_pose()) is record
    assert robot.commands == []


def test_a_label_that_is_not_a_dict_is_named() -> None:
    with pytest.raises(InvalidInputError, match="label: expected a dict"):
        Executor(Holding(), FixedDirection(), ExecutorConfig()).start(U, ["task"])  # type: ignore[arg-type]


def test_a_non_finite_commanded_pose_at_the_start_is_never_sent() -> None:
    @dataclass
    class Lost(Holding):
        def commanded_pose(self) -> Pose:
            return Pose(np.array([0.0, math.nan, 0.0]), Rotation.identity())

    robot = Lost()
    rec = Executor(robot, FixedDirection(), ExecutorConfig()).run(U)
    assert rec.outcome == "bad_pose" and "commanded pose" in rec.reason
    assert robot.commands == [] and robot.holds == 1


def test_a_second_start_aborts_the_run_in_progress() -> None:
    robot = Holding()
    ex = Executor(robot, FixedDirection(), ExecutorConfig())
    first = ex.start(U, {"run": 1})
    for _ in range(HOLD + 3):
        out = ex.step(robot.read_wrench(), robot.read_pose())
        assert isinstance(out, Pose)
        robot.command_pose(out)
        robot.advance()
    second = ex.start(U, {"run": 2})
    assert first.outcome == "aborted" and "start() was called again" in first.reason
    assert "aborted" in OUTCOMES and OUTCOME_MEANINGS["aborted"]
    assert robot.holds == 1  # told to hold when the first run ended
    assert second is ex.record and not second.finished and second.label == {"run": 2}
    held = ex.step(robot.read_wrench(), robot.read_pose())  # sampling F_d again: the hold pose
    assert isinstance(held, Pose) and held.position.tolist() == robot.target.position.tolist()
    # a finished run is not aborted: starting after it ends nothing
    done = Executor(robot, FixedDirection(), ExecutorConfig(limits=LimitsConfig(max_steps=1))).run(
        U
    )
    assert done.outcome == "timeout"


# --- 3-D motion: no workplane normal ---------------------------------------------------------
THREE_D = ExecutorConfig(workplane_normal=None, limits=LimitsConfig(max_steps=6))


@pytest.mark.parametrize(
    "controller",
    [FixedDirection(), ProjectionController(), PolicyController(), Staged()],
    ids=["fixed", "projection", "policy", "staged"],
)
def test_3d_motion_runs_every_controller(controller: Any) -> None:
    up = np.array([1.0, 0.0, 1.0]) / math.sqrt(2)  # out of any workplane: kept in 3-D
    robot = FakeGuide()
    rec = Executor(robot, controller, THREE_D, monitor=robot).run(up)
    assert rec.outcome == "timeout", rec.reason
    assert rec.steps[0].direction == pytest.approx(up.tolist())
    assert rec.inputs["workplane_normal"]["source"] == "missing"


def test_3d_motion_revolute_and_goals() -> None:
    robot = FakeGuide()
    revolute = dataclasses.replace(THREE_D, constraint_type="revolute")
    rec = Executor(robot, ProjectionController(), revolute).run(d0(20))
    assert rec.outcome == "timeout", rec.reason
    travel = dataclasses.replace(THREE_D, goal=GoalConfig(travel=0.03))
    assert Executor(FakeGuide(), FixedDirection(), travel).run(U).outcome == "success"
    with pytest.raises(ConfigError, match=r"ExecutorConfig\.workplane_normal"):
        dataclasses.replace(THREE_D, goal=GoalConfig(rotation=1.0))
    with pytest.raises(ConfigError, match=r"ExecutorConfig\.workplane_normal"):
        dataclasses.replace(
            THREE_D, rotation_radius=0.1, torque_policy=TorquePolicyConfig(enabled=True)
        )
