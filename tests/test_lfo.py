"""Learning-from-Observation: fits against ground truth, bad inputs, words vs geometry."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from constraint_aware.lfo.demo import DemoError, Demonstration, load
from constraint_aware.lfo.fitting import (
    FitError,
    fit_circle,
    fit_line,
    fit_plane,
    initial_direction,
)
from constraint_aware.lfo.infer import InferenceError, angle_between_deg, infer_skill
from constraint_aware.lfo.lexicon import constraint_from_words, grasp_for
from constraint_aware.lfo.synthetic import KINDS, TrackingNoise, make_demo

ROOT = Path(__file__).resolve().parents[1]
QUIET = TrackingNoise(noise=0.0, tremor=0.0, outlier_fraction=0.0, speed_variation=0.0)


def _arc(
    radius: float,
    arc_deg: float,
    n: int = 200,
    normal: tuple[float, ...] | np.ndarray = (0.0, 0.0, 1.0),
) -> np.ndarray:
    a = np.radians(np.linspace(0, arc_deg, n))
    pts = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)], axis=1)
    z = np.asarray(normal, float) / np.linalg.norm(normal)
    if np.allclose(z, [0, 0, 1]):
        return pts
    from scipy.spatial.transform import Rotation

    rot, _ = Rotation.align_vectors([z], [[0.0, 0.0, 1.0]])
    return rot.apply(pts)


# --- fits against ground truth --------------------------------------------------------------
def test_plane_fit_recovers_a_tilted_plane_despite_outliers(rng: np.random.Generator) -> None:
    normal = np.array([0.3, -0.2, 0.93])
    normal /= np.linalg.norm(normal)
    pts = _arc(0.4, 120.0, normal=normal) + rng.normal(0, 0.005, (200, 3))
    pts[::20] += 0.2 * rng.normal(size=(10, 3))  # 5 % glitches far off the plane
    fit = fit_plane(pts)
    assert angle_between_deg(fit.normal, normal, unsigned_axis=True) < 1.5
    assert fit.inliers.sum() <= 195  # the glitches were set aside
    assert 0.0 < fit.normal_std_deg < 2.0


def test_line_fit_direction_and_residual(rng: np.random.Generator) -> None:
    u = np.array([0.6, 0.8, 0.0])
    pts = np.outer(np.linspace(0, 0.3, 100), u) + rng.normal(0, 0.002, (100, 3))
    fit = fit_line(pts)
    assert angle_between_deg(fit.direction, u) < 1.0  # oriented along the motion
    assert fit.rms == pytest.approx(0.002 * math.sqrt(2), rel=0.3)
    assert fit.length == pytest.approx(0.3, abs=0.01)


@pytest.mark.parametrize("radius", [0.1, 0.5])
def test_circle_fit_radius_centre_axis(radius: float, rng: np.random.Generator) -> None:
    pts = _arc(radius, 90.0) + rng.normal(0, 0.002, (200, 3)) + [1.0, 2.0, 0.5]
    fit = fit_circle(pts)
    assert fit.radius == pytest.approx(radius, rel=0.03)
    assert np.linalg.norm(fit.centre - [1.0, 2.0, 0.5]) < 0.02
    assert fit.axis @ [0, 0, 1] > 0.99  # counter-clockwise motion turns positively about +z
    assert fit.arc_deg == pytest.approx(90.0, abs=3.0)
    assert 0 < fit.radius_std < 0.01
    clockwise = fit_circle(pts[::-1])
    assert clockwise.axis @ [0, 0, 1] < -0.99


def test_initial_direction_skips_the_resting_hand() -> None:
    demo, truth = make_demo("drawer", np.random.default_rng(1), QUIET)
    d, rms = initial_direction(demo.position, demo.t)
    assert angle_between_deg(d, truth.initial_direction) < 0.5
    assert rms < 1e-3


@pytest.mark.parametrize("kind", KINDS)
def test_skill_from_a_5mm_demo_matches_ground_truth(kind: str) -> None:
    rng = np.random.default_rng(7)
    for _ in range(5):
        demo, truth = make_demo(kind, rng, TrackingNoise(noise=0.005))  # type: ignore[arg-type]
        skill = infer_skill(demo)
        assert skill.constraint_type == truth.constraint_type
        err = angle_between_deg(np.array(skill.workplane_normal), truth.workplane_normal, True)
        assert err < 8.0
        if truth.radius is not None:
            assert skill.radius is not None
            assert abs(skill.radius - truth.radius) / truth.radius < 0.25
            assert np.dot(skill.workplane_normal, truth.workplane_normal) > 0  # motion sense
        assert angle_between_deg(np.array(skill.initial_direction), truth.initial_direction) < 8


def test_grasp_from_table_hint_and_override() -> None:
    demo, _ = make_demo("handle", np.random.default_rng(3), QUIET)
    skill = infer_skill(demo)
    assert skill.grasp == "passive_force_closure" and skill.fixed_orientation
    skill = infer_skill(demo, grasp_override="lazy_closure")
    assert skill.grasp == "lazy_closure"
    assert skill.evidence["grasp_source"] == "user override"
    assert grasp_for("pole", "prismatic")[0] == "active_force_closure"
    assert grasp_for("thing", "revolute")[2].startswith("default")


# --- words vs geometry ----------------------------------------------------------------------
@pytest.mark.parametrize(
    ("words", "expected"),
    [
        ("open the drawer", "prismatic"),
        ("slide the plate to the left", "prismatic"),
        ("pull the pole", "prismatic"),
        ("open the sliding door", "prismatic"),
        ("open the fridge door", "revolute"),
        ("turn the handle", "revolute"),
        ("rotate it", "revolute"),
        ("open it", "unknown"),
        ("", "unknown"),
    ],
)
def test_lexicon(words: str, expected: str) -> None:
    assert constraint_from_words(words).constraint == expected


def _with_words(demo: Demonstration, instruction: str, obj: str) -> Demonstration:
    return Demonstration(instruction, obj, demo.t, demo.position)


def test_line_with_door_words_geometry_decides_and_says_so() -> None:
    demo, _ = make_demo("drawer", np.random.default_rng(4), TrackingNoise(noise=0.003))
    skill = infer_skill(_with_words(demo, "open the door", "door"))
    assert skill.constraint_type == "prismatic"
    assert any("words suggest revolute" in w for w in skill.warnings)
    assert skill.evidence["geometry"]["verdict"] == "line"


def test_arc_with_drawer_words_geometry_decides_and_says_so() -> None:
    demo, _ = make_demo("door", np.random.default_rng(5), TrackingNoise(noise=0.003))
    skill = infer_skill(_with_words(demo, "open the drawer", "drawer"))
    assert skill.constraint_type == "revolute"
    assert any("words suggest prismatic" in w for w in skill.warnings)


def test_ambiguous_geometry_defers_to_words() -> None:
    # 25 deg of a 12 cm crank: 3 mm of sagitta, inside the noise
    demo, _ = make_demo(
        "handle", np.random.default_rng(6), TrackingNoise(noise=0.005), arc_deg=25, radius=0.5
    )
    skill = infer_skill(demo)
    assert skill.evidence["geometry"]["verdict"] == "ambiguous"
    assert skill.constraint_type == "revolute"
    assert any("words decide" in w for w in skill.warnings)


def test_unknown_words_and_ambiguous_geometry_give_unknown() -> None:
    demo, _ = make_demo(
        "handle", np.random.default_rng(6), TrackingNoise(noise=0.005), arc_deg=25, radius=0.5
    )
    skill = infer_skill(_with_words(demo, "do it", "thing"))
    assert skill.constraint_type == "unknown"
    assert any("neither words" in w for w in skill.warnings)


# --- bad input ------------------------------------------------------------------------------
def _demo(t: np.ndarray, p: np.ndarray) -> Demonstration:
    return Demonstration("open the drawer", "drawer", t, p)


def test_too_few_points() -> None:
    with pytest.raises(DemoError, match="too few points"):
        _demo(np.arange(5.0), np.zeros((5, 3)))


def test_nan_positions() -> None:
    p = np.zeros((20, 3))
    p[7, 1] = np.nan
    with pytest.raises(DemoError, match=r"NaN.*sample 7"):
        _demo(np.arange(20.0), p)


def test_non_increasing_timestamps() -> None:
    t = np.arange(20.0)
    t[10] = t[9]
    with pytest.raises(DemoError, match="strictly increasing"):
        _demo(t, np.zeros((20, 3)))


def test_trajectory_too_short() -> None:
    p = np.outer(np.linspace(0, 0.01, 30), [1.0, 0.0, 0.0])
    with pytest.raises(InferenceError, match="too short"):
        infer_skill(_demo(np.arange(30.0), p))


def test_collinear_points_make_no_plane() -> None:
    p = np.outer(np.linspace(0, 0.3, 50), [1.0, 1.0, 0.0])
    with pytest.raises(FitError, match="collinear"):
        fit_plane(p)


def test_arc_too_short_for_a_circle() -> None:
    with pytest.raises(FitError, match="arc too short"):
        fit_circle(_arc(0.3, 10.0), normal=np.array([0.0, 0.0, 1.0]))
    with pytest.raises(FitError, match="too short for a plane"):
        fit_circle(_arc(0.3, 10.0))  # without a known plane, the plane fails first


def test_revolute_words_with_too_short_an_arc_is_a_clear_error() -> None:
    p = _arc(0.3, 8.0, n=60)
    with pytest.raises(InferenceError, match=r"arc too short|too short"):
        infer_skill(Demonstration("open the door", "door", np.arange(60.0) * 0.1, p))


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "malformed JSON"),
        ('{"format": "other/1"}', "format"),
        ('{"format": "cap-demo/1", "object": "drawer"}', "instruction"),
        ('{"format": "cap-demo/1", "instruction": "x", "object": "y"}', "'t' and 'position'"),
        (
            '{"format": "cap-demo/1", "instruction": "x", "object": "y", "t": [0, 1], '
            '"position": [["a", 0, 0], [0, 0, 0]]}',
            r"field 'position'\[0\]\[0\]: 'a' is not a number",
        ),
        ("[1, 2]", "JSON object"),
    ],
)
def test_malformed_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "demo.json"
    path.write_text(content)
    with pytest.raises(DemoError, match=message):
        load(path)


def test_csv_trajectories(tmp_path: Path) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,x,y\n0,1,2\n")
    with pytest.raises(DemoError, match="t,x,y,z"):
        load(bad)
    demo = load(ROOT / "examples" / "drawer_path.csv")
    assert demo.position.shape[1] == 3 and demo.instruction == ""
    assert infer_skill(demo).constraint_type == "prismatic"


def test_json_round_trip(tmp_path: Path) -> None:
    demo, _ = make_demo("door", np.random.default_rng(0), TrackingNoise())
    again = load(demo.save(tmp_path / "d.json"))
    np.testing.assert_allclose(again.position, demo.position, atol=1e-6)
    assert again.instruction == demo.instruction


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(DemoError, match="not found"):
        load(tmp_path / "nope.json")


# --- end to end -----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["drawer_demo.json", "door_demo.json", "handle_demo.json"])
def test_cap_lfo_execute_examples(name: str) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "lfo", str(ROOT / "examples" / name),
         "--execute", "--start", "at-grasp", "--json", "-"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr
    data = json.loads(out.stdout)
    assert data["execution"]["success"] is True
    assert data["execution"]["initial_direction_error_deg"] < 5.0


def test_cap_lfo_bad_file_is_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_text("{")
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "lfo", str(path)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2
    assert "malformed JSON" in out.stderr


def test_execute_on_another_robot_runs_that_embodiment(monkeypatch: pytest.MonkeyPatch) -> None:
    import constraint_aware.lfo.execute as lfo_execute
    from constraint_aware.sim.jaco import JacoSim

    built: list[object] = []
    real = lfo_execute.simulated_robot

    def spy(*args: Any, **kwargs: Any) -> Any:
        built.append(real(*args, **kwargs))
        return built[-1]

    monkeypatch.setattr(lfo_execute, "simulated_robot", spy)
    skill = infer_skill(load(ROOT / "examples" / "door_demo.json"))
    record, info = lfo_execute.execute(skill, controller="projection", robot="jaco")
    assert [type(s) for s in built] == [JacoSim]
    assert record.label["robot"] == info["robot"] == "jaco"
    assert record.steps  # the executor drove the arm (how far it got is the guards' business)


def test_the_drawer_demonstration_executes_on_the_arm() -> None:
    """The demonstration's plane normal (the drawer's bar) points along -y: taken with its sign
    it turned the object frame upside down and put the arm's base above the handle, out of
    reach (CapError). A bar has no direction: the frame stays upright and the arm succeeds."""
    from constraint_aware.lfo.execute import execute

    skill = infer_skill(load(ROOT / "examples" / "drawer_demo.json"))
    assert float(skill.workplane_normal[1]) < 0  # the sign that used to flip the frame
    record, _ = execute(skill, robot="jaco")
    assert record.outcome == "success", record.reason


def test_execute_unknown_robot_names_the_valid_ones() -> None:
    from constraint_aware.errors import InvalidInputError, UnknownNameError
    from constraint_aware.lfo.execute import execute

    skill = infer_skill(load(ROOT / "examples" / "door_demo.json"))
    with pytest.raises(UnknownNameError, match="hook-hand, jaco"):
        execute(skill, robot="nao")
    with pytest.raises(InvalidInputError, match="stiffness"):
        execute(skill, robot="jaco:stiffness=1")


def test_cap_lfo_execute_robot_flag() -> None:
    demo = str(ROOT / "examples" / "door_demo.json")
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "lfo", demo, "--execute",
         "--start", "at-grasp", "--robot", "jaco", "--json", "-"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert out.returncode in (0, 1), out.stderr  # 1: the run stopped (a guard), still recorded
    assert json.loads(out.stdout)["execution"]["robot"] == "jaco"
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "lfo", demo, "--execute", "--robot", "nao"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2 and "hook-hand, jaco" in out.stderr
