"""Bad input, as a new user would give it: a clear error naming the field or a correct result.

One case (at least) per kind of input: demonstration files (`cap lfo`), the unit and glitch
diagnosis, the motion's sense, the Gymnasium task environments, the policy API, robot
variants, `cap export-onnx --parity`, `task_config` and `cap eval`'s report. CLI cases run
`cap` in-process (`cli.main`, which a console script calls) and check exit 2 with an `error:`
line and no traceback (an uncaught exception fails the test itself).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from constraint_aware.cli import main
from constraint_aware.errors import ConfigError, InvalidInputError, UnknownNameError
from constraint_aware.lfo.demo import DemoError, Demonstration, load, transformed
from constraint_aware.lfo.infer import infer_skill
from constraint_aware.lfo.plausibility import UNITS, UnitError
from constraint_aware.policy import ConstraintAwarePolicy

ROOT = Path(__file__).resolve().parents[1]
DRAWER = ROOT / "examples" / "drawer_demo.json"  # a 30 cm drawer, metres, no orientations
DOOR = ROOT / "examples" / "door_demo.json"
POLICY = ConstraintAwarePolicy.load()


def cap_error(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run `cap ARGS` in-process; it must exit 2 with an error line and no traceback."""
    code = main(list(args))
    err = capsys.readouterr().err
    assert code == 2, err
    assert "error:" in err and "Traceback" not in err
    return " ".join(err.split())


def demo_json(**fields: Any) -> dict[str, Any]:
    """The drawer demonstration's JSON with fields replaced (None: removed)."""
    data: dict[str, Any] = json.loads(DRAWER.read_text())
    data.update(fields)
    return {k: v for k, v in data.items() if v is not None}


def write(path: Path, data: Any) -> Path:
    path.write_text(json.dumps(data))
    return path


# --- demonstration files: read as untrusted input ----------------------------------------------
def test_a_demo_cannot_make_cap_lfo_read_a_file_outside_its_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "demo").mkdir()
    demo = tmp_path / "demo" / "d.json"
    write(demo, demo_json(t=None, position=None, trajectory_csv="../x"))
    secret = tmp_path / "x"
    secret.write_text("t,x,y,z\nSECRET-FIRST-LINE\n")
    err = cap_error(capsys, "lfo", str(demo))
    assert "outside the demonstration's folder" in err and "SECRET" not in err
    for target in ("/etc/passwd", "../../../../etc/passwd", str(secret)):
        with pytest.raises(DemoError, match="trajectory_csv"):
            load(write(demo, demo_json(t=None, position=None, trajectory_csv=target)))


def test_a_symlink_beside_the_demo_pointing_elsewhere_is_refused(tmp_path: Path) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    rows = ["t,x,y,z"] + [f"{i * 0.1},{i * 0.01},0,0.8" for i in range(40)]
    (elsewhere / "path.csv").write_text("\n".join(rows) + "\n")
    folder = tmp_path / "demo"
    folder.mkdir()
    (folder / "path.csv").symlink_to(elsewhere / "path.csv")
    demo = write(folder / "d.json", demo_json(t=None, position=None, trajectory_csv="path.csv"))
    with pytest.raises(DemoError, match="outside the demonstration's folder"):
        load(demo)
    # the same file given explicitly (the command line's --trajectory) is the user's choice
    assert len(load(demo, trajectory=elsewhere / "path.csv").t) == 40


def test_cap_lfo_trajectory_flag_reads_a_csv_from_anywhere(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(DRAWER.read_text())
    pairs = zip(data["t"], data["position"], strict=True)
    rows = ["t,x,y,z"] + [f"{t},{x},{y},{z}" for t, (x, y, z) in pairs]
    (tmp_path / "other").mkdir()
    csv_path = tmp_path / "other" / "path.csv"
    csv_path.write_text("\n".join(rows) + "\n")
    folder = tmp_path / "demo"
    folder.mkdir()
    demo = write(folder / "d.json", demo_json(t=None, position=None, trajectory_csv="../x.csv"))
    assert main(["lfo", str(demo), "--trajectory", str(csv_path), "--json", "-"]) == 0
    assert json.loads(capsys.readouterr().out)["skill"]["constraint_type"] == "prismatic"


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (demo_json(meta=[1, 2]), "field 'meta' must be a JSON object, got list"),
        (demo_json(meta="abc"), "field 'meta' must be a JSON object, got str"),
        (demo_json(t="0,1,2"), "field 't': expected a list, got str"),
        (demo_json(t=[True] * 108), r"field 't'\[0\]: True is not a number"),
        (demo_json(position=[[0, 0]] * 108), r"field 'position'\[0\]: expected a list of 3"),
        (demo_json(t=[10**400] * 108), "out of range"),
        (demo_json(instruction=["open"]), "field 'instruction' missing or not text"),
        (demo_json(grasp_hint=3), "field 'grasp_hint' must be text"),
        (demo_json(orientation=[[1, 0, 0]] * 108), r"field 'orientation'\[0\]"),
    ],
)
def test_wrong_types_name_the_file_and_the_field(
    tmp_path: Path, content: dict[str, Any], message: str
) -> None:
    with pytest.raises(DemoError, match=message):
        load(write(tmp_path / "d.json", content))


@pytest.mark.parametrize(
    ("name", "raw", "message"),
    [
        ("binary.json", bytes(range(256)) * 4, "not UTF-8 text"),
        ("deep.json", b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
        ("latin1.csv", "t,x,y,z\n0,1,2,3\n# caf\xe9\n".encode("latin-1"), "not UTF-8 text"),
        ("nul.csv", b"t,x,y,z\n0,1\x00,2,3\n", "column 'x': '1\\x00' is not a number"),
        ("header.csv", b"time,x,y\n0,1,2\n", "header must contain t,x,y,z"),
        ("cell.csv", b"t,x,y,z\n0,1,2,3\n0.1,one,2,3\n", "data row 2, column 'x'"),
    ],
    ids=["binary", "deep", "latin1", "nul", "header", "cell"],
)
def test_malformed_files_are_exit_2_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, raw: bytes, message: str
) -> None:
    path = tmp_path / name
    path.write_bytes(raw)
    err = cap_error(capsys, "lfo", str(path))
    assert message in err and name in err


def test_a_file_above_the_size_limit_is_refused_unread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import constraint_aware.lfo.demo as demo_module

    monkeypatch.setattr(demo_module, "MAX_FILE_BYTES", 1000)
    with pytest.raises(DemoError, match="at most 1,000 bytes"):
        load(DRAWER)
    with pytest.raises(DemoError, match="not a regular file"):
        load(tmp_path)


def test_execution_flags_without_execute_are_an_input_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = cap_error(capsys, "lfo", str(DRAWER), "--record", str(tmp_path / "r.json"))
    assert "--record without --execute" in err
    err = cap_error(capsys, "lfo", str(DRAWER), "--seed", "3", "--robot", "jaco")
    assert "--seed, --robot without --execute" in err
    assert not (tmp_path / "r.json").exists()


# --- the unit and glitch diagnosis -------------------------------------------------------------
def scaled(factor: float) -> Demonstration:
    return transformed(load(DRAWER), factor * np.eye(3))


def test_inches_are_not_called_centimetres() -> None:
    """A 30 cm drawer in inches reads as a 13 cm drawer in centimetres: both plausible."""
    with pytest.raises(UnitError, match="does not tell") as err:
        infer_skill(scaled(UNITS["inches"]))
    assert err.value.suspected_unit is None
    assert set(err.value.candidates) == {"centimetres", "inches"}
    # converting with the tracker's unit gives the demonstrated drawer back
    truth = infer_skill(load(DRAWER)).goal
    back = infer_skill(transformed(scaled(UNITS["inches"]), np.eye(3) / UNITS["inches"]))
    assert back.goal == pytest.approx(truth, rel=1e-3)


@pytest.mark.parametrize("unit", ["centimetres", "millimetres"])
def test_a_suggested_conversion_yields_the_demonstrated_skill(unit: str) -> None:
    with pytest.raises(UnitError, match=f"look like {unit}") as err:
        infer_skill(scaled(UNITS[unit]))
    assert err.value.suspected_unit == unit and err.value.candidates == (unit,)
    advice = 1.0 / UNITS[unit]  # "divide by ..."
    converted = infer_skill(transformed(scaled(UNITS[unit]), advice * np.eye(3)))
    assert converted.goal == pytest.approx(infer_skill(load(DRAWER)).goal, rel=1e-3)


@pytest.mark.parametrize(("factor", "units"), [(1000.0, "millimetres"), (100.0, "centimetres")])
def test_mixed_units_are_named(factor: float, units: str) -> None:
    demo = load(DRAWER)
    pos = demo.position.copy()
    pos[len(pos) // 2 :] *= factor
    with pytest.raises(UnitError, match=f"mixed units.*metres and {units}") as err:
        infer_skill(Demonstration(demo.instruction, demo.object, demo.t, pos))
    assert err.value.suspected_unit is None


def test_a_jump_that_does_not_come_back_is_refused() -> None:
    demo = load(DRAWER)
    pos = demo.position.copy()
    pos[len(pos) // 2 :] += [2.0, 0.0, 0.0]
    with pytest.raises(DemoError, match="do not come back"):
        infer_skill(Demonstration(demo.instruction, demo.object, demo.t, pos))


@pytest.mark.parametrize(("jump", "run"), [(10.0, 1), (0.8, 3)])
def test_a_tracker_glitch_is_removed_and_named(jump: float, run: int) -> None:
    demo = load(DRAWER)
    pos = demo.position.copy()
    middle = len(pos) // 2
    pos[middle : middle + run] += [jump, 0.0, 0.0]
    skill = infer_skill(Demonstration(demo.instruction, demo.object, demo.t, pos))
    clean = infer_skill(demo)
    assert skill.goal == pytest.approx(clean.goal, rel=0.01)
    assert any(f"{run} tracker glitch sample" in w for w in skill.warnings), skill.warnings
    assert skill.evidence["geometry"]["glitches_removed"] >= run


def test_a_closing_door_said_to_open_is_warned_about_without_orientations() -> None:
    door = load(DOOR)
    backwards = Demonstration(door.instruction, door.object, door.t, door.position[::-1].copy())
    warnings = infer_skill(backwards).warnings
    assert any("does not show which way the object moved" in w for w in warnings), warnings


def test_a_closing_door_said_to_open_is_named_with_orientations() -> None:
    from constraint_aware.lfo.synthetic import TrackingNoise, demo_of_object
    from constraint_aware.sim.tasks import task_config

    demo = demo_of_object(task_config("door-opening"), math.radians(60),
                          np.random.default_rng(1), TrackingNoise(noise=0.005),
                          words=("open the door", "door"), closing=True)  # fmt: skip
    assert any("closes: check the demonstration" in w for w in infer_skill(demo).warnings)


# --- the Gymnasium task environments -----------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"task_config": "drawer-opening"}, "TaskEnv.task_config"),
        ({"offset_deg": 1e9}, "TaskEnv.offset_deg"),
        ({"offset_deg": "30"}, "TaskEnv.offset_deg"),
        ({"offset_deg": (10.0, 200.0)}, "TaskEnv.offset_deg[1]"),
        ({"sensor_noise": -1.0}, "TaskEnv.sensor_noise"),
        ({"width": -5}, "TaskEnv.width"),
        ({"height": 2.5}, "TaskEnv.height"),
        ({"width": 4000}, "TaskEnv.width"),
        ({"randomize": "yes"}, "TaskEnv.randomize"),
        ({"executor": [("threshold", 1.0)]}, "TaskEnv.executor"),
        ({"robot": 3}, "TaskEnv.robot"),
    ],
)
def test_task_env_keywords_are_checked_at_construction(kwargs: dict[str, Any], field: str) -> None:
    from constraint_aware.envs.task import TaskEnv

    with pytest.raises(ConfigError) as err:
        TaskEnv("drawer-opening", **kwargs)
    assert err.value.field == field


def test_task_env_unknown_executor_setting_lists_the_valid_ones() -> None:
    from constraint_aware.envs.task import TaskEnv

    with pytest.raises(UnknownNameError, match="force_limit"):
        TaskEnv("drawer-opening", executor={"force_limt": 3.0})


def test_a_non_finite_or_misshapen_action_is_refused_and_moves_nothing() -> None:
    from constraint_aware.envs.task import TaskEnv

    env = TaskEnv("drawer-opening")
    env.reset(seed=0)
    assert env.sim is not None
    before = env.sim.read_pose().position
    for action in ([math.nan, 0, 0], [0, math.inf, 0], [1.0, 0.0], np.ones((3, 1)), "abc",
                   [1j, 0, 0], None):  # fmt: skip
        with pytest.raises(InvalidInputError, match="action"):
            env.step(action)  # type: ignore[arg-type]
    np.testing.assert_array_equal(env.sim.read_pose().position, before)
    _obs, _r, terminated, _t, info = env.step(np.array([1.0, 0.0, 0.0]))
    assert info["outcome"] == "running" and not terminated  # a valid action still steps


# --- the policy API ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"force": [1e300, 1e300, 1e300]}, "force"),
        ({"direction": [1e308, 1e308, 0.0]}, "direction"),
        ({"force": [1 + 1j, 0, 0]}, "force"),
        ({"force": [1.0, math.nan, 0.0]}, "force"),
        ({"force_offset": [-1e154, 0, 0], "force": [1e154, 0, 0]}, "force - force_offset"),
        ({"threshold": "a"}, "threshold"),
        ({"threshold": -1.0}, "threshold"),
        ({"step_force": math.inf}, "step_force"),
        ({"workplane_normal": [1e300, 1e300, 1e300]}, "workplane_normal"),
    ],
)
def test_policy_inputs_are_errors_naming_the_argument(kwargs: dict[str, Any], name: str) -> None:
    args: dict[str, Any] = {"force": [0.0, 3.0, 0.0], "direction": [1.0, 0.0, 0.0], **kwargs}
    with pytest.raises(InvalidInputError, match=name):
        POLICY.session().update_direction(**args)


def test_act_batch_validates_its_batch() -> None:
    width = len(POLICY.observation_layout)
    obs = np.zeros((4, width))
    obs[2, 1] = math.nan
    with pytest.raises(InvalidInputError, match=r"obs: NaN or inf in 1 row.*row 2"):
        POLICY.act_batch(obs)
    with pytest.raises(InvalidInputError, match=rf"obs: expected shape \(N, {width}\)"):
        POLICY.act_batch(np.zeros((4, width + 1)))
    with pytest.raises(InvalidInputError, match="obs: complex"):
        POLICY.act_batch(np.zeros((1, width), dtype=complex))
    with pytest.raises(InvalidInputError, match="extra"):
        POLICY.act([1.0, 0, 0], [0, 1.0, 0], 0.1, 1.0, 5.0)
    assert POLICY.act_batch(np.zeros((2, width))).shape == (2, 3)


def test_policy_files_are_bounded_before_they_are_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    import constraint_aware.policy as policy_module
    from constraint_aware.policy import shipped_policy_path

    source = shipped_policy_path()
    for suffix in (".npz", ".json"):
        shutil.copy(source.with_suffix(suffix), tmp_path / f"p{suffix}")
    monkeypatch.setattr(policy_module, "MAX_WEIGHT_BYTES", 1000)
    err = cap_error(capsys, "eval", "--policy", str(tmp_path / "p.npz"))
    assert "bytes of weights; at most 1,000" in err
    monkeypatch.setattr(policy_module, "MAX_CARD_BYTES", 1000)
    err = cap_error(
        capsys, "export-onnx", "--policy", str(tmp_path / "p.npz"), str(tmp_path / "x.onnx")
    )
    assert "a card has at most 1,000" in err
    (tmp_path / "p.json").write_bytes(bytes(range(256)))
    monkeypatch.setattr(policy_module, "MAX_CARD_BYTES", 2**20)
    assert "not UTF-8" in cap_error(capsys, "eval", "--policy", str(tmp_path / "p.npz"))


# --- robot variants ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("jaco:stiffness=100", "valid range for jaco is 700-4000 N/m"),
        ("jaco:stiffness=500", "valid range for jaco is 700-4000 N/m"),
        ("jaco:stiffness=100000", "valid range for jaco is 700-4000 N/m"),
        ("hook-hand:stiffness=100000", "valid range for hook-hand is 200-10000 N/m"),
        ("jaco:period=0.05", "valid range for jaco is 0.06-0.5 s"),
        ("jaco:stiffness=2000,stiffness=800", "stiffness given twice"),
        ("jaco:stiffness=nan", "valid range"),
        ("jaco:stiffness", "needs a value"),
        ("jaco:", "an empty variant"),
    ],
)
def test_robot_variants_outside_their_measured_range_are_refused(
    capsys: pytest.CaptureFixture[str], spec: str, message: str
) -> None:
    from constraint_aware.sim.embodiment import parse_robot

    with pytest.raises(InvalidInputError, match=message):
        parse_robot(spec)
    assert message in cap_error(capsys, "run", "drawer-opening", "--robot", spec)


# --- elsewhere ---------------------------------------------------------------------------------
def test_export_onnx_parity_is_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = cap_error(capsys, "export-onnx", str(tmp_path / "p.onnx"), "--parity", "1000000000")
    assert "--parity 1,000,000,000: valid 0 (skip) to 1,000,000" in err
    assert not (tmp_path / "p.onnx").exists()


def test_task_config_name_twice_names_the_argument() -> None:
    from constraint_aware.sim.tasks import task_config

    with pytest.raises(InvalidInputError, match="name is the preset"):
        task_config("door-opening", name="my-door")
    assert task_config(name="door-opening").name == "door-opening"


def test_cap_eval_names_the_training_environment_and_the_standard_evaluation(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["eval", "--episodes", "200"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "training environment (the policy card's env_config)" in out
    assert "standard evaluation (the paper's environment" in out
    card = POLICY.card["standard_evaluation"]["mean_final_angle_deg"]
    assert f"the card's standard evaluation: mean {card:.2f} deg" in out
    for args in (["--episodes", "0"], ["--seed", "-1"]):
        cap_error(capsys, "eval", *args)
