"""The calibration (control/calibrate.py) and the robot profile file (control/profile.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.calibrate import CalibrationConfig, calibrate
from constraint_aware.control.profile import (
    PROFILE_FORMAT,
    QUANTITY_NAMES,
    ProfileFileError,
    RobotProfile,
)
from constraint_aware.errors import ConfigError, InvalidInputError
from constraint_aware.spatial import Pose, Wrench


@pytest.fixture(scope="module")
def hook_hand_drawer() -> tuple[Any, RobotProfile, dict[str, Any]]:
    """One calibration of the hook hand holding the drawer, through the required members
    only, with the simulator's truth and every command the calibration sent."""
    from conftest import RequiredOnly
    from constraint_aware.control.simulate import RunSpec, grasped

    task, sim = grasped(RunSpec("drawer-opening", seed=0, sensor_noise=0.1))
    robot = Recorder(RequiredOnly(sim))
    profile = calibrate(robot, "hook hand", task.workplane_normal)
    truth = {
        "stiffness": _force_per_step(profile),
        "tracking_time_constant": sim.tracking_time_constant,
        "force_noise": 0.1,
        "grasp_play": task.hand.finger_offset
        - task.hand.finger_thickness
        - task.object.handle_radius,
    }
    return robot, profile, truth


def _force_per_step(profile: RobotProfile) -> float:
    """[N/m] the truth of the calibrated stiffness: the force per setpoint step with the
    drawer locked, between held levels at about 3 N and 6 N (noise-free force), averaged over
    the directions the calibration found blocked (its profile note)."""
    import re

    from constraint_aware.control.simulate import RunSpec, grasped

    locked = (("object__joint_range", (-1e-5, 1e-5)), ("object__frictionloss", 1000.0))
    _task, sim = grasped(RunSpec("drawer-opening", seed=0, sensor_noise=0.0, overrides=locked))
    home = sim.commanded_pose()

    def hold(depth: float, u: np.ndarray, periods: int) -> np.ndarray:
        for _ in range(periods):
            sim.command_pose(Pose(home.position + depth * u, home.orientation))
            sim.advance()
        return np.asarray(sim.true_wrench().force, dtype=float)

    note = next(n for n in profile.notes if n.startswith("stiffness by blocked direction"))
    values = []
    for d in re.findall(r"\(([^)]*)\) \d+", note):
        u = np.array([float(x) for x in d.split(",")])
        rest = hold(0.0, u, 10)
        depth = 0.0
        while np.linalg.norm(hold(depth, u, 3) - rest) < 3.0:
            depth += 2.5e-4
        f_a = hold(depth, u, 5)
        f_b = hold(depth + 1.5e-3, u, 5)
        values.append(float(np.linalg.norm(f_b - f_a)) / 1.5e-3)
        hold(0.0, u, 10)
    return float(np.mean(values))


class Recorder:
    """Forwards the required members, recording every command, reading and hold."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.control_period = inner.control_period
        self.commands: list[Pose] = []
        self.forces: list[np.ndarray] = []
        self.periods = 0
        self.holds = 0
        self.start = inner.commanded_pose()

    def read_wrench(self) -> Wrench:
        w = self.inner.read_wrench()
        self.forces.append(np.asarray(w.force, dtype=float))
        return w

    def read_pose(self) -> Pose:
        return self.inner.read_pose()

    def commanded_pose(self) -> Pose:
        return self.inner.commanded_pose()

    def grasp_contact(self) -> bool | None:
        return None  # the Robot protocol's "cannot tell": as if the member were absent

    def command_pose(self, pose: Pose) -> None:
        self.commands.append(pose)
        self.inner.command_pose(pose)

    def advance(self) -> None:
        self.periods += 1
        self.inner.advance()

    def hold(self) -> None:
        self.holds += 1


# --- measured against the simulator's truth ------------------------------------------------
def test_hook_hand_recovers_stiffness_time_constant_and_noise(
    hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]],
) -> None:
    _robot, profile, truth = hook_hand_drawer
    assert profile.outcome == "complete"
    for name, tolerance in (
        ("stiffness", 0.10),
        ("tracking_time_constant", 0.20),
        ("force_noise", 0.20),
    ):
        value = profile.value(name)
        assert value is not None, profile.quantities[name].reason
        assert value == pytest.approx(truth[name], rel=tolerance), name
    # the hook's fingers leave 1.5 mm beside the bar
    play = profile.value("grasp_play")
    assert play is not None
    assert play == pytest.approx(truth["grasp_play"], abs=0.3e-3)
    assert profile.convention == "consistent"
    sigma = profile.value("force_noise")
    assert sigma is not None
    assert profile.value("dead_band") == pytest.approx(4 * sigma)


def test_the_calibration_is_short_and_stays_within_its_limits(
    hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]],
) -> None:
    robot, profile, _truth = hook_hand_drawer
    cfg = CalibrationConfig()
    assert profile.periods == robot.periods
    assert profile.robot_time < 5.0
    start = robot.start.position
    reach = max(np.linalg.norm(c.position - start) for c in robot.commands)
    assert reach <= cfg.travel_limit + 1e-12
    rest = np.mean(robot.forces[: cfg.rest_periods], axis=0)
    assert max(np.linalg.norm(f - rest) for f in robot.forces) < cfg.force_limit
    # it ends where it started, told to hold
    assert np.allclose(robot.commands[-1].position, start)
    assert robot.holds == 1


def test_reported_values_are_notes_not_inputs(
    hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]],
) -> None:
    """A robot reporting a wrong stiffness and time constant gets the same measurement."""
    from conftest import RequiredOnly
    from constraint_aware.control.simulate import RunSpec, grasped

    _robot, plain, _truth = hook_hand_drawer
    task, sim = grasped(RunSpec("drawer-opening", seed=0, sensor_noise=0.1))
    robot: Any = RequiredOnly(sim)
    robot.translational_stiffness = 1e5
    robot.tracking_time_constant = 3.0
    reporting = calibrate(robot, "hook hand", task.workplane_normal)
    for name in ("stiffness", "tracking_time_constant", "force_noise", "grasp_play"):
        assert reporting.value(name) == plain.value(name), name
    assert any("100000" in note for note in reporting.notes)


# --- what cannot be measured is said, with the reason ---------------------------------------
class FrozenArm:
    """An arm that never moves, whose sensor gives noise around a constant: nothing it does
    can show a stiffness, a time constant or the sensor's convention."""

    control_period = 0.1

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.pose = Pose(np.array([0.3, 0.0, 0.8]), Rotation.identity())
        self.setpoint = self.pose
        self.holds = 0
        self.periods = 0

    def read_wrench(self) -> Wrench:
        return Wrench(np.array([0.0, 0.0, -6.0]) + 0.1 * self.rng.normal(size=3), np.zeros(3))

    def read_pose(self) -> Pose:
        return self.pose

    def commanded_pose(self) -> Pose:
        return self.setpoint

    def grasp_contact(self) -> bool | None:
        return None  # the hand cannot tell

    def command_pose(self, pose: Pose) -> None:
        self.setpoint = pose

    def advance(self) -> None:
        self.periods += 1

    def hold(self) -> None:
        self.holds += 1


def test_a_robot_that_never_moves_is_reported_unmeasured_with_reasons() -> None:
    robot = FrozenArm()
    profile = calibrate(robot, "frozen", (0.0, 0.0, 1.0))
    assert profile.value("force_noise") == pytest.approx(0.1, rel=0.3)
    for name in ("stiffness", "tracking_time_constant", "grasp_play", "sensor_convention"):
        m = profile.quantities[name]
        assert m.value is None and m.uncertainty is None, name
        assert m.reason, name
    assert "nothing to push against" in profile.quantities["stiffness"].reason
    assert profile.convention in ("not_following", "inconclusive")
    assert profile.periods <= CalibrationConfig().max_periods
    assert robot.holds == 1


class StickyArm(FrozenArm):
    """A door-like grasp: the hand follows the setpoint along +y and -x (the object gives
    way), and is blocked along -y and +x by an arm whose joints stick: the force stays at
    rest until the setpoint is `gap` [m] away, jumps by `breakaway` [N] there (static
    friction giving way) and rises by `spring` [N/m] per metre beyond. The slope at contact
    is far steeper than the spring after it (the simulated Jaco on the door)."""

    gap = 0.002
    breakaway = 2.9
    spring = 600.0
    free = (np.array([0.0, 1.0, 0.0]), np.array([-1.0, 0.0, 0.0]))

    def read_pose(self) -> Pose:
        offset = np.asarray(self.setpoint.position, dtype=float) - self.home
        followed = sum(max(float(offset @ u), 0.0) * u for u in self.free)
        return Pose(self.home + followed, self.pose.orientation)

    def read_wrench(self) -> Wrench:
        held = np.asarray(self.setpoint.position - self.read_pose().position, dtype=float)
        depth = float(np.linalg.norm(held))
        push = np.zeros(3)
        if depth >= self.gap:
            push = (self.breakaway + self.spring * (depth - self.gap)) * held / depth
        base = super().read_wrench()
        return Wrench(base.force - push, base.torque)

    @property
    def home(self) -> np.ndarray:
        return np.asarray(self.pose.position, dtype=float)


def test_an_arm_whose_joints_stick_gets_its_spring_measured_within_the_limits() -> None:
    """The first stair past contact, sized from the steep breakaway, adds little force: the
    level above it is reached in further stairs, sized from the force they add, within the
    force limit, the travel limit and the budget."""
    arm = StickyArm()
    robot = Recorder(arm)
    cfg = CalibrationConfig()
    profile = calibrate(robot, "sticky", (0.0, 0.0, 1.0), cfg)
    assert profile.outcome == "complete"
    k = profile.value("stiffness")
    assert k is not None, profile.quantities["stiffness"].reason
    assert k == pytest.approx(arm.spring, rel=0.1)
    assert profile.robot_time < 5.0
    start = robot.start.position
    assert max(np.linalg.norm(c.position - start) for c in robot.commands) <= cfg.travel_limit
    rest = np.mean(robot.forces[: cfg.rest_periods], axis=0)
    assert max(np.linalg.norm(f - rest) for f in robot.forces) < cfg.force_limit
    assert np.allclose(robot.commands[-1].position, start)
    assert robot.holds == 1


# --- every stop holds, an exception included --------------------------------------------------
class Failing(Recorder):
    """Raises in `advance` from period `at` on, or returns a bad reading from then on."""

    def __init__(self, inner: Any, at: int, how: str) -> None:
        super().__init__(inner)
        self.at = at
        self.how = how

    def advance(self) -> None:
        if self.how == "raise" and self.periods >= self.at:
            raise RuntimeError("the arm's driver died")
        super().advance()

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        late = self.periods >= self.at
        if late and self.how == "nan":
            return Wrench(np.array([math.nan, 0.0, 0.0]), w.torque)
        if late and self.how == "spike":
            return Wrench(w.force + np.array([80.0, 0.0, 0.0]), w.torque)
        if late and self.how == "stale":
            return Wrench(np.array([1.0, 2.0, 3.0]), np.zeros(3))
        return w


@pytest.mark.parametrize(
    ("how", "outcome"),
    [("nan", "bad_reading"), ("spike", "force_limit"), ("stale", "stale_wrench")],
)
def test_a_named_stop_restores_the_start_and_holds(how: str, outcome: str) -> None:
    # the fault comes during the pushes, after the readings at rest
    robot = Failing(FrozenArm(), at=CalibrationConfig().rest_periods + 3, how=how)
    profile = calibrate(robot, "faulty", (0.0, 0.0, 1.0))
    assert profile.outcome == outcome
    assert robot.holds == 1
    assert np.allclose(robot.commands[-1].position, robot.start.position)
    assert profile.value("force_noise") is not None  # measured before the stop
    stopped = profile.quantities["stiffness"]
    assert stopped.value is None and outcome in stopped.reason


def test_an_exception_mid_calibration_holds_and_carries_the_profile() -> None:
    robot = Failing(FrozenArm(), at=20, how="raise")
    with pytest.raises(RuntimeError, match="driver died") as info:
        calibrate(robot, "faulty", (0.0, 0.0, 1.0))
    assert robot.holds == 1
    assert np.allclose(robot.commands[-1].position, robot.start.position)
    partial = info.value.robot_profile  # type: ignore[attr-defined]
    assert isinstance(partial, RobotProfile)
    assert partial.outcome == "error"
    assert partial.value("force_noise") is not None
    assert partial.periods == 20


def test_a_flipped_sensor_is_named() -> None:
    from constraint_aware.bench.faults import FaultyRobot
    from constraint_aware.control.simulate import RunSpec, grasped

    task, sim = grasped(RunSpec("handle-rotating", seed=0, sensor_noise=0.1))
    profile = calibrate(FaultyRobot(sim, "flipped_sign", 0), "flipped", task.workplane_normal)
    assert profile.convention == "flipped_sign"
    cos = profile.value("sensor_convention")
    assert cos is not None and cos > 0.5


def test_bad_arguments_name_the_field() -> None:
    with pytest.raises(ConfigError, match=r"CalibrationConfig\.push_force"):
        CalibrationConfig(contact_force=5.0, push_force=4.0)
    with pytest.raises(ConfigError, match=r"CalibrationConfig\.travel_limit"):
        CalibrationConfig(travel_limit=0.2)
    with pytest.raises(ConfigError, match="workplane_normal"):
        calibrate(FrozenArm(), "x", (0.0, 0.0, 0.0))
    with pytest.raises(InvalidInputError, match="name"):
        calibrate(FrozenArm(), "  ")


# --- the profile file -------------------------------------------------------------------------
def test_profile_round_trip(
    tmp_path: Path, hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]]
) -> None:
    _robot, profile, _truth = hook_hand_drawer
    path = profile.save(tmp_path / "robot.json")
    loaded = RobotProfile.load(path)
    assert loaded.to_dict() == profile.to_dict()
    assert set(loaded.quantities) == set(QUANTITY_NAMES)
    assert json.loads(path.read_text())["format"] == PROFILE_FORMAT


def test_a_profile_file_without_the_deflection_error_reads_it_as_unmeasured(
    tmp_path: Path, hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]]
) -> None:
    _robot, profile, _truth = hook_hand_drawer
    data = profile.to_dict()
    for name in ("deflection_error", "deflection_error_per_speed"):
        del data["quantities"][name]
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(data))
    loaded = RobotProfile.load(path)
    assert loaded.value("stiffness") == profile.value("stiffness")
    assert loaded.value("deflection_error") is None
    assert "calibrate again" in loaded.quantities["deflection_error_per_speed"].reason


def test_the_deflection_error_bounds_the_models_misses_during_the_pushes(
    hook_hand_drawer: tuple[Any, RobotProfile, dict[str, Any]],
) -> None:
    """The calibration measures its own deflection model's error: at rest within a few
    newtons (the noise of |F| and the grasp's give), per speed a bounded excess."""
    _robot, profile, _truth = hook_hand_drawer
    a = profile.value("deflection_error")
    b = profile.value("deflection_error_per_speed")
    assert a is not None and 0.0 <= a < 3.0
    assert b is not None and b >= 0.0
    assert profile.quantities["deflection_error"].count >= 5


def _profile_file(tmp_path: Path, change: Any) -> Path:
    profile = calibrate(FrozenArm(), "frozen", (0.0, 0.0, 1.0))
    data = profile.to_dict()
    change(data)
    path = tmp_path / "robot.json"
    path.write_text(json.dumps(data))
    return path


def _set(data: dict[str, Any], dotted: str, value: Any) -> None:
    *parents, last = dotted.split(".")
    for key in parents:
        data = data[key]
    data[last] = value


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("format", "constraint-aware-robot-profile/0", "'format'"),
        ("robot", "", "'robot'"),
        ("measured_at", "yesterday", "'measured_at'"),
        ("outcome", "fine", "'outcome'"),
        ("control_period_s", -0.1, "'control_period_s'"),
        ("robot_time_s", 99.0, "'robot_time_s'"),
        ("workplane_normal", [0.0, 0.0, 2.0], "'workplane_normal'"),
        ("quantities.force_noise.unit", "mN", "'quantities.force_noise.unit'"),
        ("quantities.force_noise.value", -1.0, "'quantities.force_noise.value'"),
        ("quantities.force_noise.value", "0.1", "'quantities.force_noise.value'"),
        ("quantities.force_noise.uncertainty", None, "'quantities.force_noise.uncertainty'"),
        ("quantities.stiffness.reason", "", "'quantities.stiffness.reason'"),
        ("quantities.stiffness.count", 1.5, "'quantities.stiffness.count'"),
        ("quantities.sensor_convention.value", 3.0, "'quantities.sensor_convention.value'"),
        ("extra", 1, "'extra'"),
        ("quantities.mass", {}, "'quantities.mass'"),
    ],
)
def test_profile_validation_names_the_file_and_field(
    tmp_path: Path, field: str, value: Any, message: str
) -> None:
    path = _profile_file(tmp_path, lambda d: _set(d, field, value))
    with pytest.raises(ProfileFileError) as info:
        RobotProfile.load(path)
    assert str(path) in str(info.value)
    assert message in str(info.value)


def test_profile_files_that_are_not_profiles(tmp_path: Path) -> None:
    with pytest.raises(ProfileFileError, match="not found"):
        RobotProfile.load(tmp_path / "missing.json")
    bad = tmp_path / "nan.json"
    bad.write_text('{"format": "constraint-aware-robot-profile/1", "robot": NaN}')
    with pytest.raises(ProfileFileError, match="NaN"):
        RobotProfile.load(bad)
    bad.write_text("[1, 2]")
    with pytest.raises(ProfileFileError, match="JSON object"):
        RobotProfile.load(bad)
    with pytest.raises(ProfileFileError, match="a directory"):
        RobotProfile.load(tmp_path)
    with pytest.raises(ProfileFileError, match=r"\.json"):
        RobotProfile(robot="x", quantities={}).save(tmp_path / "robot.txt")


# --- cap calibrate ----------------------------------------------------------------------------
def test_cli_calibrate_writes_a_profile(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from constraint_aware.cli import main

    out = tmp_path / "hook.json"
    code = main(["calibrate", "plate-sliding", "--out", str(out), "--name", "hook"])
    assert code == 0
    profile = RobotProfile.load(out)
    assert profile.robot == "hook" and profile.setup == "plate-sliding"
    assert profile.value("stiffness") is not None
    assert "translational_stiffness 2000" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--out", "profile.txt"], "--out"),
        (["--contact-force", "9", "--push-force", "6"], "push_force"),
        (["--noise", "-1"], "--noise"),
        (["--robot", "jaco:stiffness=1"], "stiffness"),
    ],
)
def test_cli_calibrate_rejects_bad_input(
    args: list[str], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    assert main(["calibrate", "drawer-opening", *args]) == 2
    assert named in capsys.readouterr().err
