"""The setup-time sensor probe (control/probe.py): ground truth from a fake rail, fault
injection (sign, frame, stiffness report, NaN, exceptions, force limit), and the simulator."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.probe import (
    PROBE_VERDICTS,
    ProbeConfig,
    ProbeResult,
    probe_sensor,
    push_directions,
)
from constraint_aware.errors import ConfigError
from constraint_aware.spatial import Pose, Wrench

U = np.array([1.0, 0.0, 0.0])  # the rail
N = np.array([0.0, 0.0, 1.0])  # the workplane normal
WEIGHT = np.array([0.0, 0.0, -6.0])


@dataclass
class Rail:
    """A hand rigidly grasping a body on a frictionless rail along U; arm stiffness k [N/m].

    Each period the hand closes half of the way to its equilibrium (the target's projection on
    the rail, or the target itself when `free`), so settling takes several periods. The
    object's force on the hand is k (position - target) plus the hand's weight. Options inject
    faults: `rotation` turns the reported force, `sign` flips it, `reported` is the stiffness
    the robot claims, `nan_after`/`raise_after` break the wrench reading / the command after
    that many calls."""

    k: float = 2000.0
    reported: float | None = 2000.0
    free: bool = False
    rotation: Rotation = field(default_factory=Rotation.identity)
    sign: float = 1.0  # -1: the driver reports the wrench with the opposite sign
    play: float = 0.0  # [m] the grasp moves freely this far across the rail either way
    rail_stiffness: float | None = None  # [N/m] beyond the play the rail yields across like
    # a spring of this stiffness (None: rigid)
    nan_after: int | None = None
    raise_after: int | None = None
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    target: Pose = field(default_factory=lambda: Pose(np.zeros(3), Rotation.identity()))
    commands: list[Pose] = field(default_factory=list)
    reads: int = 0
    holds: int = 0

    control_period = 0.1

    @property
    def translational_stiffness(self) -> float | None:
        return self.reported

    def read_wrench(self) -> Wrench:
        self.reads += 1
        if self.nan_after is not None and self.reads > self.nan_after:
            return Wrench(np.full(3, np.nan), np.zeros(3))
        dither = 1e-9 * math.sin(self.reads)  # a fresh sample each read, as from any sensor
        force = self.k * (self.position - self.target.position) + WEIGHT + dither
        return Wrench(self.sign * self.rotation.apply(force), np.zeros(3))

    def read_pose(self) -> Pose:
        return Pose(self.position.copy(), self.target.orientation)

    def commanded_pose(self) -> Pose:
        return self.target

    def grasp_contact(self) -> bool | None:
        return None

    def command_pose(self, pose: Pose) -> None:
        if self.raise_after is not None and len(self.commands) >= self.raise_after:
            raise ConnectionError("comms lost (injected)")
        self.target = pose
        self.commands.append(pose)

    def advance(self) -> None:
        goal = self.target.position if self.free else float(self.target.position @ U) * U
        if not self.free and (self.play or self.rail_stiffness is not None):  # across the rail
            across = self.target.position - goal
            size = float(np.linalg.norm(across))
            reach = min(size, self.play)
            if self.rail_stiffness is not None and size > self.play:  # arm and rail in series
                reach += self.k / (self.k + self.rail_stiffness) * (size - self.play)
            goal = goal + across * (reach / size if size > 0 else 0.0)
        self.position = self.position + 0.5 * (goal - self.position)

    def hold(self) -> None:
        self.holds += 1


def test_directions_are_unit_and_in_the_plane() -> None:
    dirs = push_directions(8, N)
    assert len(dirs) == 8
    for u in dirs:
        assert math.isclose(float(np.linalg.norm(u)), 1.0)
        assert abs(float(u @ N)) < 1e-12
    assert np.allclose(sum(dirs), 0.0, atol=1e-12)  # evenly spaced
    assert len(push_directions(8, None)) == 6  # without a plane: +-x, +-y, +-z


def test_healthy_rail_is_consistent_and_measures_the_true_stiffness() -> None:
    robot = Rail()
    result = probe_sensor(robot, N)
    assert result.verdict == "consistent", result.reason
    assert result.passed
    assert result.median_cos == pytest.approx(-1.0, abs=1e-3)
    assert result.arm_stiffness == pytest.approx(2000.0, rel=0.01)
    judged = [p for p in result.pushes if p.judged]
    # every push with a component across the rail is blocked; the two along it are free
    assert len(judged) == 6
    for p in result.pushes:
        across = math.sqrt(max(0.0, 1.0 - float(np.asarray(p.direction) @ U) ** 2))
        # the rail blocks the across part only: the push's stiffness is k times its square
        assert p.push_stiffness == pytest.approx(2000.0 * across**2, abs=40.0)
    assert result.force_offset == pytest.approx(WEIGHT.tolist(), abs=1e-6)
    # completed: the setpoint is restored and kept (hold() would move it onto the measured
    # pose and release the grasp's preload before the run)
    assert np.allclose(robot.commands[-1].position, 0.0)
    assert robot.holds == 0


def test_every_command_stays_within_the_push_of_the_setpoint() -> None:
    robot = Rail()
    cfg = ProbeConfig(amplitude=0.002, play_amplitude=0.003)
    probe_sensor(robot, N, cfg)
    deepest = 0.0
    for pose in robot.commands:
        assert np.all(np.isfinite(pose.position))
        deepest = max(deepest, float(np.linalg.norm(pose.position)))
    assert deepest == pytest.approx(0.003)  # the deep pushes, no further
    assert np.allclose(robot.commands[-1].position, 0.0)  # the setpoint is restored


def test_a_flipped_sign_and_a_rotated_frame_are_named() -> None:
    flipped = probe_sensor(Rail(rotation=Rotation.from_rotvec(math.pi * U)), N)
    # a rotation by pi about U flips the force's across-rail part: the in-plane sign
    assert flipped.verdict == "flipped_sign", flipped.reason  # the rail's force is across
    negated = probe_sensor(Rail(sign=-1.0), N)
    assert negated.verdict == "flipped_sign", negated.reason
    assert negated.median_cos == pytest.approx(1.0, abs=1e-3)
    rotated = probe_sensor(Rail(rotation=Rotation.from_rotvec(math.pi / 2 * N)), N)
    assert rotated.verdict == "inconsistent", rotated.reason
    assert "90 deg" in rotated.reason


def test_a_wrong_stiffness_report_is_a_mismatch_and_none_is_fine() -> None:
    wrong = probe_sensor(Rail(reported=1000.0), N)
    assert wrong.verdict == "stiffness_mismatch", wrong.reason
    assert "2000 N/m" in wrong.reason and "1000 N/m" in wrong.reason
    unreported = probe_sensor(Rail(reported=None), N)
    assert unreported.verdict == "consistent"
    nan_report = probe_sensor(Rail(reported=math.nan), N)
    assert nan_report.verdict == "consistent"
    assert any("ignored translational_stiffness" in n for n in nan_report.notes)


def test_an_object_that_follows_every_push_is_inconclusive() -> None:
    result = probe_sensor(Rail(free=True), N)
    assert result.verdict == "inconclusive"
    assert "0 of 8" in result.reason
    assert not result.passed


def test_force_limit_stops_restores_the_setpoint_and_holds() -> None:
    robot = Rail(k=20000.0, reported=20000.0)  # 3 mm blocked: 60 N
    result = probe_sensor(robot, N)
    assert result.verdict == "force_limit", result.reason
    assert np.allclose(robot.commands[-1].position, 0.0)
    assert robot.holds == 1


def test_a_nan_reading_stops_with_a_named_reason_and_holds() -> None:
    robot = Rail(nan_after=12)
    result = probe_sensor(robot, N)
    assert result.verdict == "bad_reading"
    assert "not 3 finite numbers" in result.reason
    assert np.allclose(robot.commands[-1].position, 0.0)
    assert robot.holds == 1


def test_an_exception_keeps_the_result_and_holds() -> None:
    robot = Rail(raise_after=3)
    with pytest.raises(ConnectionError) as info:
        probe_sensor(robot, N)
    result = info.value.probe_result  # type: ignore[attr-defined]
    assert isinstance(result, ProbeResult)
    assert result.verdict == "error" and "comms lost" in result.reason
    assert len(result.pushes) == 2  # measured before the failure (push, home, push, home)
    assert robot.holds == 1


def test_config_errors_name_the_field_and_the_range() -> None:
    with pytest.raises(ConfigError, match=r"amplitude.*\[0\.0001, 0\.02\]"):
        ProbeConfig(amplitude=0.5)
    with pytest.raises(ConfigError, match="directions"):
        ProbeConfig(directions=1)
    with pytest.raises(ConfigError, match=r"ProbeConfig\.force_limit"):
        ProbeConfig(force_limit=math.nan)
    with pytest.raises(ConfigError, match=r"ProbeConfig.min_force.*\(0, 5\)"):
        ProbeConfig(force_limit=5.0, min_force=5.0)  # no push could ever be judged
    with pytest.raises(ConfigError, match="workplane_normal"):
        probe_sensor(Rail(), (0.0, 0.0, 0.0))


@dataclass
class Frozen(Rail):
    """Ignores every command (an e-stopped arm): its pose and setpoint stay put."""

    def command_pose(self, pose: Pose) -> None:
        self.commands.append(pose)


@dataclass
class Stale(Rail):
    """The driver returns the same sample over and over."""

    def read_wrench(self) -> Wrench:
        return Wrench(np.array([0.1, 0.2, -6.0]), np.zeros(3))


@dataclass
class Drifting(Rail):
    """The force reading drifts by 0.2 N per read along the rail."""

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        return Wrench(w.force + 0.2 * self.reads * U, w.torque)


@dataclass
class Lagging(Rail):
    """A slow arm: the hand closes a tenth of the way per period and reports tau = 1 s."""

    tracking_time_constant: float = 1.0

    def advance(self) -> None:
        goal = float(self.target.position @ U) * U
        self.position = self.position + 0.1 * (goal - self.position)


@dataclass
class SlowForce(Rail):
    """Where a push is blocked the hand hardly moves, but the force builds with the arm's lag
    (first order, a tenth per period): the setpoint the robot reports trails the command."""

    tracking_time_constant: float = 1.0
    setpoint: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def commanded_pose(self) -> Pose:
        return Pose(self.setpoint.copy(), self.target.orientation)

    def read_wrench(self) -> Wrench:
        self.reads += 1
        dither = 1e-9 * math.sin(self.reads)
        return Wrench(self.k * (self.position - self.setpoint) + WEIGHT + dither, np.zeros(3))

    def advance(self) -> None:
        self.setpoint = self.setpoint + 0.1 * (self.target.position - self.setpoint)
        self.position = float(self.setpoint @ U) * U


def test_a_frozen_arm_a_stale_driver_and_a_drifting_sensor_are_named_not_judged() -> None:
    frozen = probe_sensor(Frozen(), N)
    assert frozen.verdict == "not_following", frozen.reason
    stale = Stale()
    result = probe_sensor(stale, N)
    assert result.verdict == "bad_reading" and "stale" in result.reason
    assert stale.holds == 1
    drifting = probe_sensor(Drifting(), N)
    assert drifting.verdict == "unsteady", drifting.reason


@pytest.mark.parametrize("robot", [Lagging(), SlowForce()])
def test_a_slow_arm_is_waited_for(robot: Rail) -> None:
    result = probe_sensor(robot, N)
    assert result.verdict == "consistent", result.reason
    assert result.arm_stiffness == pytest.approx(2000.0, rel=0.02)


def test_a_non_finite_setpoint_is_never_commanded() -> None:
    robot = Rail(target=Pose(np.array([np.nan, 0.0, 0.0]), Rotation.identity()))
    result = probe_sensor(robot, N)
    assert result.verdict == "bad_reading"
    assert robot.commands == [] and robot.holds == 1


def test_ctrl_c_restores_holds_and_keeps_the_result() -> None:
    @dataclass
    class Interrupted(Rail):
        def advance(self) -> None:
            if len(self.commands) >= 2:
                raise KeyboardInterrupt
            super().advance()

    robot = Interrupted()
    with pytest.raises(KeyboardInterrupt) as info:
        probe_sensor(robot, N)
    assert info.value.probe_result.verdict == "error"  # type: ignore[attr-defined]
    assert np.allclose(robot.commands[-1].position, 0.0) and robot.holds == 1


def test_a_robot_without_optional_members_is_probed(required_only: type[Any]) -> None:
    result = probe_sensor(required_only(Rail(reported=None)), N)
    assert result.verdict == "consistent" and result.reported_stiffness is None


def test_every_verdict_is_produced_and_documented() -> None:
    scenarios: dict[str, Rail] = {
        "consistent": Rail(),
        "flipped_sign": Rail(sign=-1.0),
        "inconsistent": Rail(rotation=Rotation.from_rotvec(math.pi / 2 * N)),
        "stiffness_mismatch": Rail(reported=500.0),
        "inconclusive": Rail(free=True),
        "unsteady": Drifting(),
        "not_following": Frozen(),
        "force_limit": Rail(k=20000.0, reported=20000.0),
        "bad_reading": Rail(nan_after=12),
    }
    produced = {name: probe_sensor(robot, N).verdict for name, robot in scenarios.items()}
    assert produced == {name: name for name in scenarios}
    with pytest.raises(ConnectionError) as info:
        probe_sensor(Rail(raise_after=1), N)
    produced["error"] = info.value.probe_result.verdict  # type: ignore[attr-defined]
    assert set(produced.values()) == set(PROBE_VERDICTS)


# --- the simulator -------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("fault", "verdict"),
    [("none", "consistent"), ("flipped_sign", "flipped_sign"), ("rotated_90", "inconsistent")],
)
def test_the_hook_hands_drawer(fault: str, verdict: str) -> None:
    from constraint_aware.bench.faults import FaultyRobot
    from constraint_aware.control.simulate import RunSpec, probe

    wrap = None if fault == "none" else (lambda sim: FaultyRobot(sim, fault, 0))
    result, _sim = probe(RunSpec("drawer-opening", seed=0), wrap=wrap)
    assert result.verdict == verdict, result.reason
    if fault == "none":
        # the hook hand's arm is a 2000 N/m spring; the drawer's rail blocks the across pushes
        assert result.arm_stiffness == pytest.approx(2000.0, rel=0.1)


def test_a_run_after_the_probe_uses_the_measured_stiffness() -> None:
    from constraint_aware.control.simulate import RunSpec, run

    record, _sim = run(RunSpec("drawer-opening", seed=0, probe=True))
    assert record.success, record.reason
    assert record.label["probe"] == "consistent"
    assert record.notes[0].startswith("probe: consistent")
    measured = [n for n in record.notes if n.startswith("stiffness ")]
    assert measured and "robot reports 2000 N/m" in measured[0]
    # and the hook's play across the drawer's bar (about 1.5 mm, docs/forces.md)
    play = [n for n in record.notes if n.startswith("grasp play ")]
    assert play, record.notes
    assert 1.2 <= float(play[0].split()[2]) <= 1.8  # [mm]
    # an explicit setting wins over what the probe measured: the compensation turned off
    spec = RunSpec(
        "drawer-opening", seed=0, probe=True, overrides=(("executor__robot__grasp_play", 0.0),)
    )
    off, _sim = run(spec)
    assert any(n.startswith("stiffness ") for n in off.notes)  # still measured
    assert not any(n.startswith("grasp play ") for n in off.notes), off.notes


def test_a_probe_that_finds_a_flipped_sign_stops_the_run_before_it_moves() -> None:
    from constraint_aware.bench.faults import FaultyRobot
    from constraint_aware.control.simulate import RunSpec, run

    robots: list[FaultyRobot] = []

    def wrap(sim: object) -> FaultyRobot:
        robots.append(FaultyRobot(sim, "flipped_sign", 0))  # type: ignore[arg-type]
        return robots[-1]

    record, _sim = run(RunSpec("drawer-opening", seed=0, probe=True), wrap=wrap)
    assert record.outcome == "sensor_convention"
    assert record.reason.startswith("probe: flipped_sign")
    assert record.n_steps == 0
    twin, robot = robots  # the probe's twin, then the run's robot
    assert twin.commands and not robot.commands  # the run's robot was never moved
    assert robot.holds == 1


def test_executor_stop_names_the_outcome_and_holds() -> None:
    from constraint_aware.control.controllers import FixedDirection
    from constraint_aware.control.executor import Executor, ExecutorConfig
    from constraint_aware.errors import InvalidInputError

    robot = Rail()
    executor = Executor(robot, FixedDirection(), ExecutorConfig())
    with pytest.raises(InvalidInputError, match="start"):
        executor.stop("timeout", "too early")
    executor.start(U)
    with pytest.raises(ConfigError, match="outcome"):
        executor.stop("success", "not a stop")
    with pytest.raises(InvalidInputError, match="reason"):
        executor.stop("timeout", "")
    record = executor.stop("sensor_convention", "operator")
    assert (record.outcome, record.reason) == ("sensor_convention", "operator")
    assert robot.holds == 1


def test_a_probe_force_limit_above_the_objects_is_refused() -> None:
    from constraint_aware.control.simulate import RunSpec, probe

    with pytest.raises(ConfigError, match=r"ProbeConfig.force_limit.*object's limit 60"):
        probe(RunSpec("drawer-opening"), ProbeConfig(force_limit=100.0))


def test_a_setup_probe_that_raises_still_gives_the_runs_record() -> None:
    from constraint_aware.control.simulate import RunSpec, run

    class Failing:
        def __init__(self, sim: object) -> None:
            self._sim = sim
            self.calls = 0

        def __getattr__(self, name: str) -> object:
            return getattr(self._sim, name)

        def command_pose(self, pose: Pose) -> None:
            self.calls += 1
            if self.calls >= 3:
                raise ConnectionError("comms lost (injected)")
            self._sim.command_pose(pose)  # type: ignore[attr-defined]

    with pytest.raises(ConnectionError) as info:
        run(RunSpec("drawer-opening", probe=True), wrap=Failing)  # type: ignore[arg-type]
    record = info.value.run_record  # type: ignore[attr-defined]
    assert record.outcome == "error" and "setup probe: ConnectionError" in record.reason


def test_stale_samples_midway_and_a_hand_that_never_settles_are_named() -> None:
    @dataclass
    class StaleLater(Rail):
        def read_wrench(self) -> Wrench:
            w = super().read_wrench()
            return Wrench(np.array([1.0, 2.0, -6.0]), w.torque) if self.reads > 40 else w

    later = probe_sensor(StaleLater(), N)
    assert later.verdict == "bad_reading" and "stale" in later.reason
    assert later.pushes  # it measured before the driver went stale

    @dataclass
    class Creeping(Rail):
        """The grasped body creeps along the rail, 0.5 mm per period: never at rest."""

        creep: float = 0.0

        def advance(self) -> None:
            self.creep += 0.0005
            goal = (float(self.target.position @ U) + self.creep) * U
            self.position = self.position + 0.5 * (goal - self.position)

    creeping = probe_sensor(Creeping(), N)
    assert creeping.verdict == "unsteady" and "did not settle" in creeping.reason


def test_a_wait_longer_than_the_cap_is_noted() -> None:
    result = probe_sensor(Lagging(tracking_time_constant=10.0), N)  # 300 periods wanted
    assert any("max_settle_periods" in n for n in result.notes), result.notes


def test_the_probe_force_limit_follows_a_lower_object_limit() -> None:
    from constraint_aware.control.simulate import RunSpec, _probe_config, build_task

    task = build_task(RunSpec("drawer-opening", overrides=(("force_limit", 10.0),)))
    assert _probe_config(task).force_limit == 10.0
    assert _probe_config(build_task(RunSpec("drawer-opening"))).force_limit == 20.0


def test_the_probe_plot_is_written(tmp_path: Path) -> None:
    from constraint_aware.control.plots import plot_probe

    out = plot_probe(probe_sensor(Rail(), N), tmp_path / "probe.png")
    assert out.stat().st_size > 10_000
    unplanar = plot_probe(probe_sensor(Rail(), None), tmp_path / "probe3d.png")  # no plane
    assert unplanar.exists()


def test_the_give_measures_the_play_of_the_grasp() -> None:
    rigid = probe_sensor(Rail(), N)
    assert rigid.give == pytest.approx(0.0, abs=2e-5)
    loose = probe_sensor(Rail(play=0.001), N)
    assert loose.verdict == "consistent", loose.reason
    assert loose.give == pytest.approx(0.001, abs=5e-5)  # the play
    assert loose.arm_stiffness == pytest.approx(2000.0, rel=0.02)  # the spring is the same
    across = [p for p in loose.pushes if abs(float(np.dot(p.direction, U))) < 1e-9]
    for p in across:  # 3 mm pushes, 1 mm of them free: k (a - p) / a
        assert p.push_stiffness == pytest.approx(2000.0 * 2 / 3, rel=0.02)


@pytest.mark.parametrize("play", [0.0, 0.0005, 0.0015])
def test_two_push_depths_separate_the_play_from_the_rails_compliance(play: float) -> None:
    # beyond the play the rail yields like a 12,000 N/m spring: the give is play + |dF| / k_rail
    robot = Rail(play=play, rail_stiffness=12000.0)
    cfg = ProbeConfig(amplitude=0.003, play_amplitude=0.0045)
    result = probe_sensor(robot, N, cfg)
    assert result.verdict == "consistent", result.reason
    assert result.give is not None and result.give > play + 1e-4  # the give alone overstates it
    # within what settling leaves: the hand stops when it moves < settle_tolerance x amplitude
    # per period, and this rail closes half its distance each period
    assert result.play == pytest.approx(play, abs=cfg.settle_tolerance * cfg.amplitude)
    assert len(result.play_pushes) == sum(p.judged for p in result.pushes)
    assert np.allclose(robot.commands[-1].position, 0.0)  # the setpoint is restored


def test_without_a_deep_push_the_play_is_not_measured() -> None:
    result = probe_sensor(Rail(play=0.001), N, ProbeConfig(play_amplitude=None))
    assert result.verdict == "consistent"
    assert result.play is None and result.play_pushes == []
    with pytest.raises(ConfigError, match="play_amplitude"):
        ProbeConfig(amplitude=0.003, play_amplitude=0.002)  # must be deeper than the push


def test_a_deep_push_that_would_pass_the_force_limit_is_not_made() -> None:
    # a 5000 N/m arm blocked across the rail: 15 N at 3 mm, about 22.5 N expected at 4.5 mm
    robot = Rail(k=5000.0, reported=5000.0)
    result = probe_sensor(robot, N)
    assert result.verdict == "consistent", result.reason  # the ring's verdict stands
    assert result.arm_stiffness == pytest.approx(5000.0, rel=0.02)
    skipped = [n for n in result.notes if "not made" in n and "20 N limit" in n]
    assert len(skipped) == 2, result.notes  # the two straight across the rail (15 N at 3 mm)
    # the four diagonal ones (10.6 N at 3 mm, about 16 N deep) were made, below the limit
    assert len(result.play_pushes) == 4
    assert all(math.hypot(*p.force_change) < 20.0 for p in result.play_pushes)
    assert result.play == pytest.approx(0.0, abs=3e-5)  # a rigid rail


@dataclass
class CreepingRail(Rail):
    """A rail whose grasp slips on a deep push: afterwards the reading at the setpoint is
    3 N off (the object or the grasp moved)."""

    slip_on: int = 1  # the deep push that slips
    slipped: bool = False
    deep: int = 0

    def command_pose(self, pose: Pose) -> None:
        super().command_pose(pose)
        if float(np.linalg.norm(pose.position)) > 0.004:
            self.deep += 1
            self.slipped = self.slipped or self.deep == self.slip_on

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        return Wrench(w.force + (3.0 * U if self.slipped else 0.0), w.torque)


def test_a_deep_push_that_moves_the_grasp_is_not_used_for_the_play() -> None:
    robot = CreepingRail(play=0.001)
    result = probe_sensor(robot, N)
    assert result.verdict == "consistent", result.reason  # the ring's verdict stands
    # the first deep push slipped the grasp: it is dropped, and no pair is left before it
    assert result.play_pushes == [] and result.play is None
    assert any(n.startswith("deep pushes stopped") and "deep push" in n for n in result.notes)
    assert np.allclose(robot.commands[-1].position, 0.0)  # the setpoint is restored
    assert robot.holds == 0
    # a slip on the third: the two before it give the play, the slipped one is not used
    later = probe_sensor(CreepingRail(play=0.001, slip_on=3), N)
    assert len(later.play_pushes) == 2
    assert later.play == pytest.approx(0.001, abs=6e-5)


def test_the_deep_ring_is_skipped_when_the_convention_is_wrong() -> None:
    flipped = probe_sensor(Rail(sign=-1.0), N)
    assert flipped.verdict == "flipped_sign"
    assert flipped.play_pushes == [] and flipped.play is None


def test_probed_settings_carry_the_measured_stiffness_and_capped_play() -> None:
    from constraint_aware.control import ExecutorConfig, max_grasp_play, probed_settings

    result = probe_sensor(Rail(play=0.0015, rail_stiffness=12000.0), N)
    cfg = ExecutorConfig()
    settings = probed_settings(result, cfg)
    assert settings["robot__stiffness"] == result.arm_stiffness
    assert settings["robot__grasp_play"] == result.play
    probed = cfg.with_overrides(**settings)
    assert probed.robot.stiffness == result.arm_stiffness
    assert probed.robot.grasp_play == result.play
    short = ExecutorConfig(step_length=0.002)  # half a 2 mm step is less than the play
    assert probed_settings(result, short)["robot__grasp_play"] == max_grasp_play(0.002) == 0.001
    assert probed_settings(probe_sensor(Rail(sign=-1.0), N), cfg) == {}  # convention wrong
