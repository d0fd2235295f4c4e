"""The robot profile in a run: its values become the run's inputs with their source, strict
inputs refuse a run that lacks one, and a dead or frozen sensor stops the run `sensor_dead`.

`Guide`: a hand on a guide along U that a spring of RESIST N/m pulls back (a spring-loaded
drawer), on an arm of stiffness K that settles within a period: along U the hand stops where
the arm's pull balances the spring, across U it stays on the guide, so the force on the hand
is K times the arm's deflection, growing with the travel. The hand senses contact. The
sensor adds Gaussian noise of SIGMA per axis and can fail after ONSET periods: "dead" (fresh
noise around the tare), "jitter" (the last reading held with 1e-9 N of jitter) or "frozen"
(the last reading held exactly). It reports nothing optional unless told to (a stripped
robot).
"""

from __future__ import annotations

import json
import logging
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.controllers import FixedDirection
from constraint_aware.control.executor import Executor, ExecutorConfig
from constraint_aware.control.executor_config import GoalConfig, LimitsConfig
from constraint_aware.control.profile import (
    QUANTITIES,
    QUANTITY_NAMES,
    Measurement,
    ProfileFileError,
    RobotProfile,
)
from constraint_aware.control.run_inputs import MissingInputError
from constraint_aware.control.sensor_health import (
    DEAD_PERIODS,
    QUIET_SIGMAS,
    QUIET_WINDOW,
    STALE_FRACTION,
)
from constraint_aware.geometry import rotate_about
from constraint_aware.spatial import Pose, Wrench

U = np.array([1.0, 0.0, 0.0])
Z = np.array([0.0, 0.0, 1.0])
K = 2000.0  # [N/m]
SIGMA = 0.1  # [N]
RESIST = 250.0  # [N/m]
ONSET = 14  # periods (the 10-sample F_d hold, then 4 moves)
LIMIT = 60.0  # [N]
GOAL = ExecutorConfig(
    limits=LimitsConfig(force_limit=LIMIT, max_steps=40), goal=GoalConfig(travel=0.15)
)


class Guide:
    """The module docstring's robot (Robot protocol + hold)."""

    control_period = 0.1

    def __init__(
        self,
        sensor: str = "ok",
        seed: int = 0,
        report_stiffness: bool = False,
        noise: float = SIGMA,
    ):
        self.sensor = sensor
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.report_stiffness = report_stiffness
        self.s = 0.0
        self.target = Pose(np.zeros(3), Rotation.identity())
        self.periods = 0
        self.holds = 0
        self.commands = 0
        self.peak_true_force = 0.0
        self.last: Wrench | None = None

    def __getattr__(self, name: str) -> float:
        if name == "translational_stiffness" and self.__dict__.get("report_stiffness"):
            return K
        raise AttributeError(name)

    def true_force(self) -> np.ndarray:
        return K * (self.s * U - self.target.position)

    def grasp_contact(self) -> bool:
        return True

    def read_wrench(self) -> Wrench:
        failed = self.periods >= ONSET and self.sensor != "ok"
        if failed and self.sensor in ("jitter", "frozen") and self.last is not None:
            jitter = 1e-9 * math.sin(self.periods) if self.sensor == "jitter" else 0.0
            return Wrench(self.last.force + jitter, self.last.torque)
        force = self.true_force() if not (failed and self.sensor == "dead") else np.zeros(3)
        self.last = Wrench(force + self.noise * self.rng.normal(size=3), np.zeros(3))
        return self.last

    def read_pose(self) -> Pose:
        return Pose(self.s * U, self.target.orientation)

    def commanded_pose(self) -> Pose:
        return self.target

    def command_pose(self, pose: Pose) -> None:
        self.commands += 1
        self.target = pose

    def advance(self) -> None:
        self.s = K * float(self.target.position @ U) / (K + RESIST)
        self.periods += 1
        self.peak_true_force = max(self.peak_true_force, float(np.linalg.norm(self.true_force())))

    def hold(self) -> None:
        self.holds += 1


def profile(period: float = 0.1, **values: float | None) -> RobotProfile:
    """A profile with every quantity measured (the Guide's truth) unless given as None."""
    truth: dict[str, float | None] = {
        "force_noise": SIGMA,
        "dead_band": 0.4,
        "force_offset_x": 0.0,
        "force_offset_y": 0.0,
        "force_offset_z": 0.0,
        "stiffness": K,
        "tracking_time_constant": 0.02,
        "grasp_play": 0.0,
        "sensor_convention": -1.0,
        "deflection_error": None,
        "deflection_error_per_speed": None,
        "lag_error": None,
    }
    truth.update(values)
    quantities = {
        name: Measurement(truth[name], 0.0, QUANTITIES[name][0], "test", 10)
        if truth[name] is not None
        else Measurement.unmeasured(name, "not measured in this test")
        for name in QUANTITY_NAMES
    }
    return RobotProfile("guide", quantities, control_period=period, periods=40)


def d0(offset_deg: float) -> np.ndarray:
    return rotate_about(U, Z, math.radians(offset_deg))


def warnings_of(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [
        r.getMessage()
        for r in caplog.records
        if r.name == "constraint_aware" and r.levelno == logging.WARNING
    ]


class Staged(FixedDirection):
    """A controller whose stages need the robot's values."""

    rotation_rate = 0.5

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        return {
            "magnitude": ("step_force",),
            "lag": ("tracking_time_constant",),
            "play": ("play_force",),
        }


# --- values and sources ---------------------------------------------------------------------
def test_the_profile_supplies_the_stripped_robots_inputs_with_their_source() -> None:
    rec = Executor(Guide(), FixedDirection(), GOAL, profile=profile(grasp_play=0.001)).run(d0(0))
    assert rec.outcome == "success", rec.reason
    assert rec.inputs["step_force"] == {"value": pytest.approx(K * 0.01), "source": "profile"}
    assert rec.inputs["tracking_time_constant"] == {"value": 0.02, "source": "profile"}
    assert rec.inputs["play_force"] == {"value": pytest.approx(K * 0.001), "source": "profile"}
    assert rec.inputs["dead_band"] == {"value": 0.4, "source": "profile"}
    assert rec.threshold == 0.4


def test_without_a_profile_the_dead_band_is_measured_from_the_offset_samples() -> None:
    rec = Executor(Guide(), FixedDirection(), GOAL).run(d0(0))
    assert rec.inputs["dead_band"]["source"] == "measured"
    assert rec.inputs["dead_band"]["value"] == rec.threshold > 0
    assert rec.inputs["step_force"]["source"] == "missing"


def test_precedence_config_then_the_robots_report_then_the_profile() -> None:
    robot = Guide(report_stiffness=True)
    rec = Executor(robot, FixedDirection(), GOAL, profile=profile(stiffness=1800.0)).run(d0(0))
    assert rec.inputs["step_force"] == {"value": pytest.approx(K * 0.01), "source": "robot"}
    assert any("the robot profile measured 1800 N/m" in n for n in rec.notes)
    assert rec.inputs["tracking_time_constant"]["source"] == "profile"  # the robot has none
    cfg = GOAL.with_overrides(robot__stiffness=2500.0, threshold=1.0)
    rec = Executor(Guide(report_stiffness=True), FixedDirection(), cfg, profile=profile()).run(
        d0(0)
    )
    assert rec.inputs["step_force"] == {"value": pytest.approx(25.0), "source": "config"}
    assert rec.inputs["dead_band"] == {"value": 1.0, "source": "config"}
    assert "stiffness 2500 N/m from the configuration (robot reports 2000 N/m)" in rec.notes
    unmeasured = profile(stiffness=None)
    rec = Executor(Guide(), FixedDirection(), GOAL, profile=unmeasured).run(d0(0))
    assert rec.inputs["step_force"]["source"] == "missing"
    assert any(n.startswith("profile: stiffness unmeasured") for n in rec.notes)


def test_a_profile_for_another_control_period_is_refused_before_moving() -> None:
    robot = Guide()
    with pytest.raises(ProfileFileError, match=r"control_period_s 0\.2 s differs") as info:
        Executor(robot, FixedDirection(), GOAL, profile=profile(period=0.2)).run(d0(0))
    assert info.value.run_record.outcome == "error"  # type: ignore[attr-defined]
    assert robot.commands == 0 and robot.holds == 1


# --- no silent degradation ------------------------------------------------------------------
def test_a_missing_input_warns_once_and_the_profile_silences_it(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level(logging.WARNING, logger="constraint_aware")
    rec = Executor(Guide(), Staged(), GOAL).run(d0(0))
    lines = warnings_of(caplog)
    assert sorted(line.split(" ")[0] for line in lines) == [
        "play_force",
        "step_force",
        "tracking_time_constant",
    ]
    assert rec.stages == {
        "magnitude": "off: missing step_force",
        "lag": "off: missing tracking_time_constant",
        "play": "off: missing play_force",
    }
    caplog.clear()
    rec = Executor(Guide(), Staged(), GOAL, profile=profile()).run(d0(0))
    assert warnings_of(caplog) == []
    assert set(rec.stages.values()) == {"active"}


def test_strict_inputs_refuses_to_run_without_an_input_a_stage_needs() -> None:
    robot = Guide()
    strict = GOAL.with_overrides(strict_inputs=True)
    with pytest.raises(MissingInputError, match=r"step_force missing") as info:
        Executor(robot, Staged(), strict).run(d0(0))
    assert robot.commands == 0 and robot.holds == 1
    assert info.value.run_record.outcome == "error"  # type: ignore[attr-defined]
    rec = Executor(Guide(), Staged(), strict, profile=profile()).run(d0(0))
    assert rec.outcome == "success", rec.reason


# --- a dead or frozen sensor ----------------------------------------------------------------
@pytest.mark.parametrize("report_stiffness", [False, True])
def test_a_dead_sensor_reading_noise_around_its_tare_stops_sensor_dead(
    report_stiffness: bool,
) -> None:
    """The hand pushes into the guide at 40 deg; the sensor dies after 4 moves. With the
    profile's stiffness the deflection shows it, whether or not the robot reports one."""
    robot = Guide("dead", report_stiffness=report_stiffness)
    rec = Executor(robot, FixedDirection(), GOAL, profile=profile()).run(d0(40))
    assert rec.outcome == "sensor_dead", rec.reason
    assert robot.peak_true_force < LIMIT and robot.holds == 1


def test_the_calibrated_deflection_error_catches_a_dead_sensor_below_the_arm_force_allowance() -> (
    None
):
    """Pushing along the guide (250 N/m) the force grows slowly: the arm-force check's
    allowance (0.75 step forces, 15 N here) hides it for many steps. The profile's measured
    deflection error (a + b |v|) bounds the model far tighter, so the dead sensor is seen
    within a few newtons. (The reference run's profile has no noise sigma, so that the
    quiet-sensor test, which would also see this sensor, stays off.)"""
    without = Guide("dead")
    late = Executor(without, FixedDirection(), GOAL, profile=profile(force_noise=None)).run(d0(0))
    robot = Guide("dead")
    model = profile(deflection_error=0.3, deflection_error_per_speed=5.0)
    rec = Executor(robot, FixedDirection(), GOAL, profile=model).run(d0(0))
    assert rec.outcome == "sensor_dead", rec.reason
    assert "calibrated model's error" in rec.reason and not rec.success
    # the sensor fails after 4 moves: seen DEAD_PERIODS moves later, at half the force or less
    assert rec.n_steps <= 4 + DEAD_PERIODS + 1 < late.n_steps
    assert robot.peak_true_force < 0.5 * without.peak_true_force and robot.holds == 1


class LightDrag(Guide):
    """The guide without its spring: the object slides once pushed with more than
    `resistance` [N] (dry friction), far below the dead band and any deflection model's error
    (the arm deflects by resistance / K, 0.15 mm at 0.3 N)."""

    def __init__(self, sensor: str = "ok", seed: int = 0, resistance: float = 0.3) -> None:
        super().__init__(sensor, seed)
        self.resistance = resistance

    def true_force(self) -> np.ndarray:
        return K * (self.s * U - self.target.position)

    def advance(self) -> None:
        ahead = float(self.target.position @ U) - self.resistance / K
        self.s = max(self.s, ahead)
        self.periods += 1
        self.peak_true_force = max(self.peak_true_force, float(np.linalg.norm(self.true_force())))


def test_a_dead_sensor_on_an_object_resisting_below_the_dead_band_stops_sensor_dead() -> None:
    """Dragging a 0.3 N object along its guide: the deflection implies less than any model's
    error, but a live sensor's mean reading stands clear of the noise; a dead one's does not.
    Without a calibrated sigma there is no noise to compare with, and the run ends success."""
    live = Executor(LightDrag(), FixedDirection(), GOAL, profile=profile()).run(d0(0))
    assert live.outcome == "success", live.reason
    robot = LightDrag("dead")
    rec = Executor(robot, FixedDirection(), GOAL, profile=profile()).run(d0(0))
    assert rec.outcome == "sensor_dead" and "reads only noise" in rec.reason, rec.reason
    assert not rec.success and robot.holds == 1
    # caught within a few windows of QUIET_WINDOW moves after the failure (4 moves in)
    assert rec.n_steps <= 4 + 4 * QUIET_WINDOW
    unseen = Executor(LightDrag("dead"), FixedDirection(), GOAL, profile=profile(force_noise=None))
    assert unseen.run(d0(0)).outcome == "success"


@pytest.mark.parametrize("seed", range(12))
def test_a_live_sensor_on_a_light_object_is_not_judged_quiet(seed: int) -> None:
    """A 0.3 N resistance at sigma = 0.1 N, along the guide and across it: no false stop."""
    for offset in (0.0, 25.0):
        rec = Executor(LightDrag(seed=seed), FixedDirection(), GOAL, profile=profile()).run(
            d0(offset)
        )
        assert rec.outcome != "sensor_dead", rec.reason


def test_quiet_sigmas_is_the_median_of_the_chi_distribution_with_three_dof() -> None:
    from scipy.stats import chi

    assert pytest.approx(chi.median(3), abs=1e-3) == QUIET_SIGMAS


def test_without_any_stiffness_a_dead_sensor_goes_unseen() -> None:
    """Why the profile matters: nothing tells the executor the hand is pushing, and the run
    ends `success` on a dead sensor."""
    robot = Guide("dead")
    rec = Executor(robot, FixedDirection(), GOAL).run(d0(40))
    assert rec.outcome == "success"
    assert robot.peak_true_force > 30.0


def test_a_reading_frozen_with_tiny_jitter_stops_sensor_dead() -> None:
    """Jitter of 1e-9 N passes the exact-repeat guard; its spread is far below the
    calibrated sigma. Without a calibration there is no noise floor to compare with."""
    rec = Executor(Guide("jitter"), FixedDirection(), GOAL, profile=profile()).run(d0(0))
    assert rec.outcome == "sensor_dead", rec.reason
    assert "frozen force reading" in rec.reason and not rec.success
    rec = Executor(Guide("jitter"), FixedDirection(), GOAL).run(d0(0))
    assert rec.outcome != "sensor_dead"


def test_a_noise_free_reading_is_not_frozen_without_a_calibration() -> None:
    """A simulated sensor without noise spreads at rest only by the hand's micro-motion: no
    reference for the frozen test, so a steady pull is not judged frozen."""
    rec = Executor(Guide(noise=0.0), FixedDirection(), GOAL).run(d0(0))
    assert rec.outcome == "success", rec.reason


def test_a_reading_frozen_from_the_start_is_caught_before_moving_with_a_profile() -> None:
    class FrozenFromStart(Guide):
        def read_wrench(self) -> Wrench:
            return Wrench(np.array([0.3, -0.2, 1.0 + 1e-9 * math.sin(self.periods)]), np.zeros(3))

    robot = FrozenFromStart()
    rec = Executor(robot, FixedDirection(), GOAL, profile=profile()).run(d0(0))
    assert rec.outcome == "sensor_dead" and "before moving" in rec.reason
    assert rec.n_steps <= 1 and robot.s == 0.0


def test_an_exactly_repeated_reading_is_still_a_stale_wrench() -> None:
    rec = Executor(Guide("frozen"), FixedDirection(), GOAL, profile=profile()).run(d0(0))
    assert rec.outcome == "stale_wrench", rec.reason


@pytest.mark.parametrize("seed", range(12))
def test_a_healthy_sensor_is_never_judged_dead(seed: int) -> None:
    """Noise at the calibrated sigma, pushing into the guide or along it: no false stop."""
    model = profile(deflection_error=0.3, deflection_error_per_speed=5.0)
    for offset in (0.0, 25.0):
        for given in (profile(), model):
            rec = Executor(Guide(seed=seed), FixedDirection(), GOAL, profile=given).run(d0(offset))
            assert rec.outcome != "sensor_dead", rec.reason


def test_a_quieter_sensor_than_calibrated_is_not_frozen_until_far_below() -> None:
    """The frozen test is relative to sigma: a sensor at a third of the calibrated noise is
    still read as alive (3 x above STALE_FRACTION)."""
    assert STALE_FRACTION < 1 / 3
    quiet = profile(force_noise=3 * SIGMA)
    rec = Executor(Guide(), FixedDirection(), GOAL, profile=quiet).run(d0(0))
    assert rec.outcome == "success", rec.reason


# --- where users give a profile -------------------------------------------------------------
def test_the_gym_task_env_passes_its_profile_to_every_episode() -> None:
    from constraint_aware.envs.task import TaskEnv
    from constraint_aware.errors import ConfigError

    env = TaskEnv("drawer-opening", profile=profile(grasp_play=0.001))
    env.reset(seed=0)
    assert env.executor is not None and env.executor.profile is env.profile
    assert env._record is not None
    assert env._record.inputs["dead_band"] == {"value": 0.4, "source": "profile"}
    assert env._record.inputs["play_force"]["source"] == "profile"
    assert env._record.inputs["step_force"]["source"] == "robot"  # the simulator reports k
    with pytest.raises(ConfigError, match=r"TaskEnv\.profile"):
        TaskEnv("drawer-opening", profile="hook.json")  # type: ignore[arg-type]


def cap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_cap_run_profile_and_strict_inputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from test_cli import cap_here

    good = profile(stiffness=1900.0).save(tmp_path / "hook.json")
    out = tmp_path / "rec.json"
    proc = cap("run", "drawer-opening", "--profile", str(good), "--json", str(out))
    assert proc.returncode in (0, 1), proc.stderr
    rec = json.loads(out.read_text())
    assert rec["inputs"]["dead_band"] == {"value": 0.4, "source": "profile"}
    assert rec["inputs"]["step_force"]["source"] == "robot"  # the simulator reports k
    assert any("the robot profile measured 1900 N/m" in n for n in rec["notes"])
    bad = tmp_path / "bad.json"
    bad.write_text(good.read_text().replace('"guide"', '""'))
    # refused before any work: checked in this process
    proc = cap_here(capsys, "run", "drawer-opening", "--profile", str(bad))
    assert proc.returncode == 2 and "field 'robot'" in proc.stderr
    proc = cap_here(
        capsys, "run", "drawer-opening", "--robot", "hook-hand:period=0.2", "--profile", str(good)
    )
    assert proc.returncode == 2 and "control_period_s" in proc.stderr
    proc = cap_here(capsys, "lfo", "demo.json", "--profile", str(good))
    assert proc.returncode == 2 and "--profile without --execute" in proc.stderr
    proc = cap_here(capsys, "lfo", "demo.json", "--strict-inputs")
    assert proc.returncode == 2 and "--strict-inputs without --execute" in proc.stderr


def test_cap_lfo_from_home_hands_the_profile_to_the_manipulation(tmp_path: Path) -> None:
    good = profile(dead_band=0.45).save(tmp_path / "hook.json")
    demo = Path(__file__).resolve().parents[1] / "examples" / "drawer_demo.json"
    out = tmp_path / "seq.json"
    proc = cap("lfo", str(demo), "--execute", "--profile", str(good), "--record", str(out))
    assert proc.returncode in (0, 1), proc.stderr
    manipulation = json.loads(out.read_text())["manipulation"]
    assert manipulation["inputs"]["dead_band"] == {"value": 0.45, "source": "profile"}
