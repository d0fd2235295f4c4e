"""The free-space calibration (control.free_space.calibrate_free_space) and a grasp's calibration
taking its tracking time constant (`calibrate(..., free_space_profile=...)`)."""

from __future__ import annotations

import copy
import itertools
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.calibrate import calibrate
from constraint_aware.control.free_space import FreeSpaceConfig, calibrate_free_space
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.tracking_fit import step_rise_time
from constraint_aware.deadband import threshold_from_noise
from constraint_aware.errors import ConfigError, InvalidInputError
from constraint_aware.spatial import Pose, Wrench


class ImpedanceArm:
    """A tool point obeying m x'' = k (s - x) - c x' + F_wall per axis, the setpoint s moved
    along a straight line over each control period; optionally a wall (a stiff spring) the
    hand meets at `wall` [m] from the start along +y; optionally dry friction per axis (a real
    arm's joints'). The wrench is the wall's action on the hand (the Robot protocol's sign)
    plus Gaussian noise. Records commands and holds."""

    control_period = 0.1
    substeps = 200

    def __init__(
        self,
        k: float = 1000.0,
        c: float = 150.0,
        m: float = 2.0,
        noise: float = 0.1,
        wall: float | None = None,
        wall_stiffness: float = 20_000.0,
        seed: int = 0,
        friction: float = 0.0,
    ) -> None:
        self.k, self.c, self.m = k, c, m
        self.friction = friction  # [N] dry friction against the hand's motion (smoothed)
        self.noise = noise
        self.wall, self.wall_stiffness = wall, wall_stiffness
        self.rng = np.random.default_rng(seed)
        self.start = np.array([0.4, 0.0, 0.5])
        self.x = self.start.copy()
        self.v = np.zeros(3)
        self.s = self.start.copy()
        self.goal = self.start.copy()
        self.commands: list[np.ndarray] = []
        self.true_forces: list[float] = []
        self.holds = 0

    def wall_force(self) -> np.ndarray:
        f = np.zeros(3)
        if self.wall is not None:
            depth = (self.x - self.start)[1] - self.wall
            if depth > 0:
                f[1] = -self.wall_stiffness * depth
        return f

    def read_wrench(self) -> Wrench:
        return Wrench(self.wall_force() + self.noise * self.rng.normal(size=3), np.zeros(3))

    def read_pose(self) -> Pose:
        return Pose(self.x.copy(), Rotation.identity())

    def commanded_pose(self) -> Pose:
        return Pose(self.s.copy(), Rotation.identity())

    def command_pose(self, pose: Pose) -> None:
        self.goal = np.asarray(pose.position, dtype=float).copy()
        self.commands.append(self.goal.copy())

    def advance(self) -> None:
        dt = self.control_period / self.substeps
        origin = self.s.copy()
        for i in range(self.substeps):
            setpoint = origin + (self.goal - origin) * (i + 1) / self.substeps
            drag = self.friction * self.v / (np.abs(self.v) + 1e-4)
            a = (self.k * (setpoint - self.x) - self.c * self.v - drag + self.wall_force()) / self.m
            self.v = self.v + a * dt
            self.x = self.x + self.v * dt
        self.s = self.goal.copy()
        self.true_forces.append(float(np.linalg.norm(self.wall_force())))

    def grasp_contact(self) -> bool | None:
        return None  # the Robot protocol's "cannot tell"

    def hold(self) -> None:
        self.holds += 1

    def rise_time(self) -> float:
        """[s] the truth: the 63.2 % rise time of a step."""
        b = self.c / self.k
        return step_rise_time(b, b / (2.0 * math.sqrt(self.m / self.k)))


@pytest.mark.parametrize(("k", "c", "m"), [(1000.0, 150.0, 2.0), (4000.0, 300.0, 1.5)])
def test_free_space_recovers_the_step_rise_time_and_the_noise(k: float, c: float, m: float) -> None:
    arm = ImpedanceArm(k=k, c=c, m=m)
    profile = calibrate_free_space(arm, "arm")
    assert profile.outcome == "complete"
    tau = profile.quantities["tracking_time_constant"]
    assert tau.value == pytest.approx(arm.rise_time(), rel=0.05)
    assert tau.value is not None and tau.uncertainty is not None
    assert tau.uncertainty < 0.2 * tau.value
    assert profile.value("force_noise") == pytest.approx(0.1, rel=0.2)
    for name in ("stiffness", "grasp_play", "deflection_error", "sensor_convention"):
        assert "free-space" in profile.quantities[name].reason
    # never further than the ramp's travel from the start; the starting setpoint back, held
    offsets = [float(np.linalg.norm(p - arm.start)) for p in arm.commands]
    assert max(offsets) <= FreeSpaceConfig().travel * (1 + 1e-9)
    assert np.allclose(arm.commands[-1], arm.start)
    assert arm.holds == 1


def _steady_trail(arm: ImpedanceArm, ramp_step: float, periods: int = 30) -> float:
    """[m] the truth: how far the hand trails a setpoint ramping `ramp_step` per period along
    +x once the hand's speed is steady (a fresh copy of the arm, no noise)."""
    twin = ImpedanceArm(k=arm.k, c=arm.c, m=arm.m, noise=0.0, friction=arm.friction)
    for i in range(1, periods + 1):
        twin.command_pose(Pose(twin.start + np.array([i * ramp_step, 0, 0]), Rotation.identity()))
        twin.advance()
    return float((twin.s - twin.x)[0])


@pytest.mark.parametrize(
    ("k", "c", "m", "friction"),
    [(1000.0, 150.0, 2.0, 0.0), (4000.0, 300.0, 1.5, 0.0), (1000.0, 150.0, 2.0, 0.5)],
)
def test_free_space_ramps_measure_the_lag_error_at_the_executors_speed(
    k: float, c: float, m: float, friction: float
) -> None:
    """The lag error per speed covers what a ramp at the executor's speed leaves beyond the lag
    credit (at most tau v) once the hand's speed is steady, and not much more (a tenth of tau:
    the hand still settling into its speed): on a linear arm tau v is the trail; with dry
    friction the 1 cm step rises slower than the ramp's trail, and the credit is capped at
    the trail."""
    arm = ImpedanceArm(k=k, c=c, m=m, friction=friction)
    cfg = FreeSpaceConfig()
    profile = calibrate_free_space(arm, "arm", cfg)
    assert profile.outcome == "complete"
    tau = profile.value("tracking_time_constant")
    lag = profile.quantities["lag_error"]
    assert tau is not None and lag.value is not None and lag.count >= 6
    speed = cfg.ramp_step / arm.control_period
    truth = max(0.0, _steady_trail(arm, cfg.ramp_step) - tau * speed) / speed  # [s]
    assert truth <= lag.value <= truth + 0.1 * tau
    # the setpoint ramped at the configured step per period, never past the travel
    steps = [float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(arm.commands)]
    assert max(steps) <= cfg.step * (1 + 1e-9)
    assert sum(math.isclose(x, cfg.ramp_step, rel_tol=1e-6) for x in steps) >= 9 * 3


def test_every_valid_ramp_travel_runs_and_the_setpoint_stays_within_it() -> None:
    """The session holds the robot to the free-space config's own travel: a ramp of 8 cm (a
    valid FreeSpaceConfig) runs to the end, and no setpoint goes further."""
    arm = ImpedanceArm(k=2000.0, c=40.0, m=1.0)
    cfg = FreeSpaceConfig(ramp_travel=0.08, max_periods=1200)
    profile = calibrate_free_space(arm, "arm", cfg)
    assert profile.outcome == "complete", profile.notes
    start = arm.commands[0]
    assert max(float(np.max(np.abs(c - start))) for c in arm.commands) <= 0.08 * (1 + 1e-9)


def test_a_contact_during_a_free_space_ramp_stops_it_and_holds() -> None:
    """Something enters the cleared path once the ramps begin (a soft obstacle 25 mm out along
    +y): the ramp stops with 'contact' at contact_force, within the force limit; the start is
    commanded back and the robot told to hold; the lag error is not reached."""

    class Intruded(ImpedanceArm):
        def command_pose(self, pose: Pose) -> None:
            offset = np.asarray(pose.position) - self.start
            past_step = offset[1] > FreeSpaceConfig().step + 1e-9
            # a setpoint move of more than 5 mm past the step: the ramp, not a stair
            if (
                self.wall is None
                and past_step
                and np.linalg.norm(offset - self.goal + self.start) > 0.005
            ):
                self.wall = 0.025
            super().command_pose(pose)

    arm = Intruded(wall_stiffness=300.0)
    cfg = FreeSpaceConfig()
    profile = calibrate_free_space(arm, "arm", cfg)
    assert arm.wall is not None
    assert profile.outcome == "contact"
    assert max(arm.true_forces) < cfg.force_limit
    assert np.allclose(arm.commands[-1], arm.start)
    assert arm.holds == 1
    assert profile.value("lag_error") is None


def test_a_fitted_stall_is_friction_not_slowness() -> None:
    """An arm held short of each step by dry friction: the rise time to 63.2 % of the step is
    what the model with the stall gives, not the linear model's slower fit."""
    b, zeta, stall = 0.15, 1.2, 0.12
    level = (1.0 - math.exp(-1.0)) / (1.0 - stall)
    assert step_rise_time(b, zeta, level) > step_rise_time(b, zeta)
    assert step_rise_time(b, zeta, 1.5) == math.inf


def test_a_contact_during_a_free_space_move_stops_it_and_holds() -> None:
    """A stiff wall 3 mm away along +y: the clearance staircase meets it, the calibration
    stops with 'contact' before the step, the force stays within the force limit, the start
    is commanded back and the robot told to hold."""
    arm = ImpedanceArm(wall=0.003, wall_stiffness=20_000.0)
    cfg = FreeSpaceConfig()
    profile = calibrate_free_space(arm, "arm", cfg)
    assert profile.outcome == "contact"
    assert any("contact" in note for note in profile.notes)
    assert max(arm.true_forces) < cfg.force_limit
    assert np.allclose(arm.commands[-1], arm.start)
    assert arm.holds == 1
    tau = profile.quantities["tracking_time_constant"]
    assert tau.value is None and "contact" in tau.reason
    # no step at once into the wall: along +y only stairs before the stop
    ys = [float((p - arm.start)[1]) for p in arm.commands]
    stair = 0.8 * (cfg.force_limit - cfg.contact_force) / cfg.max_stiffness
    assert max(ys) < cfg.step
    assert all(b - a <= stair * (1 + 1e-9) for a, b in itertools.pairwise(ys) if b > a)


def test_an_exception_during_the_free_space_calibration_holds_and_carries_the_profile() -> None:
    class Dying(ImpedanceArm):
        def advance(self) -> None:
            if len(self.true_forces) >= 30:
                raise RuntimeError("the arm's driver died")
            super().advance()

    arm = Dying()
    with pytest.raises(RuntimeError, match="driver died") as info:
        calibrate_free_space(arm, "arm")
    assert arm.holds == 1
    assert np.allclose(arm.commands[-1], arm.start)
    partial = info.value.robot_profile  # type: ignore[attr-defined]
    assert partial.outcome == "error" and partial.value("force_noise") is not None


def test_free_space_config_names_the_field() -> None:
    with pytest.raises(ConfigError, match=r"FreeSpaceConfig\.step"):
        FreeSpaceConfig(step=0.2)
    with pytest.raises(ConfigError, match=r"FreeSpaceConfig\.contact_force"):
        FreeSpaceConfig(contact_force=30.0)
    with pytest.raises(ConfigError, match=r"FreeSpaceConfig\.ramp_travel"):
        FreeSpaceConfig(ramp_travel=0.5)
    with pytest.raises(InvalidInputError, match="name"):
        calibrate_free_space(ImpedanceArm(), " ")


# --- a grasp's calibration taking the free-space tau -----------------------------------------
@pytest.fixture(scope="module")
def free_profile() -> RobotProfile:
    return calibrate_free_space(ImpedanceArm(), "arm")


def test_a_grasp_calibration_takes_the_free_space_tau_where_its_own_is_unmeasured(
    free_profile: RobotProfile, tmp_path: Path
) -> None:
    from test_calibrate import FrozenArm

    path = free_profile.save(tmp_path / "free.json")
    loaded = RobotProfile.load(path)
    alone = calibrate(FrozenArm(), "frozen", (0.0, 0.0, 1.0))
    assert alone.value("tracking_time_constant") is None
    given = calibrate(FrozenArm(), "frozen", (0.0, 0.0, 1.0), free_space_profile=loaded)
    tau = given.quantities["tracking_time_constant"]
    assert tau.value == free_profile.value("tracking_time_constant")
    assert str(path) in tau.source and "'arm'" in tau.source
    assert any(n.startswith("tracking_time_constant from the calibration") for n in given.notes)
    assert given.quantities["stiffness"].source == ""  # measured (or not) by this one
    # the record survives the file
    again = RobotProfile.load(given.save(tmp_path / "grasp.json"))
    assert again.quantities["tracking_time_constant"].source == tau.source


def test_a_grasp_calibration_takes_the_free_space_lag_error_where_its_pushes_leave_it(
    free_profile: RobotProfile, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Pushes that move the hand at a steady speed measure the deflection error per speed
    themselves; pushes that never do (the staircases of a crank or a sliding plate) take the
    stiffness times the free-space ramps' lag error, its source named."""
    calibration = sys.modules[calibrate.__module__]
    lag = free_profile.quantities["lag_error"]
    assert lag.value is not None
    normal = (0.0, 0.0, 1.0)
    own = calibrate(ImpedanceArm(wall=0.001), "arm", normal, free_space_profile=free_profile)
    assert own.value("deflection_error_per_speed") is not None
    assert own.quantities["deflection_error_per_speed"].source == ""
    assert own.quantities["lag_error"].source != ""  # carried as a record
    # no push reading counts as a steady speed: the pushes leave the per-speed error unmeasured
    monkeypatch.setattr(calibration, "steady_speed", lambda velocity, previous: False)
    alone = calibrate(ImpedanceArm(wall=0.001), "arm", normal)
    assert alone.value("deflection_error_per_speed") is None
    assert "steady speed" in alone.quantities["deflection_error_per_speed"].reason
    given = calibrate(ImpedanceArm(wall=0.001), "arm", normal, free_space_profile=free_profile)
    per_speed = given.quantities["deflection_error_per_speed"]
    k = given.value("stiffness")
    assert k is not None and per_speed.value == pytest.approx(k * lag.value)
    assert per_speed.source and "'arm'" in per_speed.source
    assert "lag_error" in per_speed.method
    assert any(n.startswith("deflection_error_per_speed from the calibration") for n in given.notes)


def test_a_grasp_calibration_pools_its_noise_with_the_free_space_readings(
    free_profile: RobotProfile,
) -> None:
    """The noise is the sensor's: a grasp whose readings at rest spread as in free space pools
    them with the free-space ones, weighted by their degrees of freedom; a grasp that spreads
    more (something held adds spread its dead band must cover) keeps its own, noted."""
    free = free_profile.quantities["force_noise"]
    assert free.value is not None and free.uncertainty is not None
    normal = (0.0, 0.0, 1.0)
    alone = calibrate(ImpedanceArm(wall=0.001, seed=3), "arm", normal)
    given = calibrate(
        ImpedanceArm(wall=0.001, seed=3), "arm", normal, free_space_profile=free_profile
    )
    own, pooled = alone.quantities["force_noise"], given.quantities["force_noise"]
    assert own.value is not None and own.uncertainty is not None
    assert pooled.value is not None and pooled.uncertainty is not None
    assert pooled.count == own.count + free.count
    assert min(own.value, free.value) < pooled.value < max(own.value, free.value)
    assert pooled.uncertainty < min(own.uncertainty, free.uncertainty)
    assert "pooled with the" in pooled.method and "'arm'" in pooled.method
    assert given.value("dead_band") == threshold_from_noise(pooled.value)
    # a grasp three times as noisy keeps its own sigma
    noisy = calibrate(
        ImpedanceArm(wall=0.001, noise=0.3, seed=3), "arm", normal, free_space_profile=free_profile
    )
    assert noisy.value("force_noise") == pytest.approx(0.3, rel=0.25)
    assert noisy.quantities["force_noise"].count < pooled.count
    assert sum("free-space calibration's noise" in n for n in noisy.notes) == 2


def test_a_grasp_window_still_settling_is_left_out_of_the_noise(
    free_profile: RobotProfile,
) -> None:
    """A window at rest that spreads unlike the free-space noise (the grasp still creeping
    when the calibration starts) is left out; the other window is pooled with free space."""
    free = free_profile.quantities["force_noise"]
    assert free.value is not None

    class SettlingArm(ImpedanceArm):
        """Reads twice its noise for its first 12 readings (the grasp settling)."""

        reads = 0

        def read_wrench(self) -> Wrench:
            self.reads += 1
            scale = 2.0 if self.reads <= 12 else 1.0
            return Wrench(
                self.wall_force() + scale * self.noise * self.rng.normal(size=3), np.zeros(3)
            )

    normal = (0.0, 0.0, 1.0)
    given = calibrate(
        SettlingArm(wall=0.001, seed=3), "arm", normal, free_space_profile=free_profile
    )
    noise = given.quantities["force_noise"]
    assert noise.value == pytest.approx(0.1, rel=0.2)
    assert "one window" in noise.method and "pooled with the" in noise.method
    assert any(n.startswith("the readings at rest before the pushes spread") for n in given.notes)
    # without the free-space reference the settling window is the one kept
    alone = calibrate(SettlingArm(wall=0.001, seed=3), "arm", normal)
    assert alone.value("force_noise") == pytest.approx(0.2, rel=0.3)


def test_a_free_space_profile_at_another_control_period_is_refused(
    free_profile: RobotProfile,
) -> None:
    from test_calibrate import FrozenArm

    other = copy.deepcopy(free_profile)
    other.control_period = 0.05
    with pytest.raises(InvalidInputError, match=r"free_space_profile.*control period"):
        calibrate(FrozenArm(), "frozen", (0.0, 0.0, 1.0), free_space_profile=other)


def test_a_grasps_profile_is_refused_as_the_free_space_profile(
    free_profile: RobotProfile,
) -> None:
    """A grasp's profile already pooled the free-space readings into its noise and took its
    tau: given again as the free-space profile it would count them twice."""
    normal = (0.0, 0.0, 1.0)
    grasp = calibrate(ImpedanceArm(wall=0.001), "arm", normal, free_space_profile=free_profile)
    assert grasp.value("stiffness") is not None
    with pytest.raises(InvalidInputError, match=r"free_space_profile: a calibration holding"):
        calibrate(ImpedanceArm(wall=0.001), "arm", normal, free_space_profile=grasp)


# --- on the simulated robots -------------------------------------------------------------------
@pytest.mark.parametrize("robot", ["hook-hand:stiffness=1000", "jaco:stiffness=1000"])
def test_free_space_tau_on_the_simulated_robots(robot: str) -> None:
    from conftest import RequiredOnly
    from constraint_aware.control.simulate import RunSpec, grasped

    _task, sim = grasped(RunSpec("drawer-opening", seed=3, robot=robot, sensor_noise=0.1))
    truth = sim.tracking_time_constant
    stripped: Any = RequiredOnly(sim.in_free_space())
    profile = calibrate_free_space(stripped, robot)
    assert profile.outcome == "complete"
    assert profile.value("tracking_time_constant") == pytest.approx(truth, rel=0.2)


def test_cli_free_space_then_with(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from constraint_aware.cli import main

    free = tmp_path / "free.json"
    assert main(["calibrate", "drawer-opening", "--free-space", "--out", str(free)]) == 0
    profile = RobotProfile.load(free)
    assert profile.value("tracking_time_constant") is not None
    assert profile.value("stiffness") is None and profile.setup.startswith("free space")
    grasp = tmp_path / "grasp.json"
    code = main(["calibrate", "plate-sliding", "--with", str(free), "--out", str(grasp)])
    assert code == 0
    assert RobotProfile.load(grasp).value("stiffness") is not None
    capsys.readouterr()


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--free-space", "--push-force", "7"], "--push-force"),
        (["--step", "0.02"], "--step"),
        (["--free-space", "--with", "x.json"], "--with"),
        (["--with", "missing.json"], "missing.json"),
        (["--free-space", "--step", "0.2"], "step"),
        (["--free-space", "--ramp-step", "0.05"], "ramp_step"),
    ],
)
def test_cli_free_space_rejects_bad_input(
    args: list[str], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    assert main(["calibrate", "drawer-opening", *args]) == 2
    assert named in capsys.readouterr().err
