"""Bad configuration values fail at construction with an error naming the field and its range."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from constraint_aware.bench.run import check_out_dir, run_bench
from constraint_aware.control.executor import ExecutorConfig
from constraint_aware.control.executor_config import LimitsConfig
from constraint_aware.control.settings import parse_settings
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.errors import CapError, ConfigError, InvalidInputError, UnknownNameError
from constraint_aware.sim.hand import HandConfig
from constraint_aware.sim.objects import ObjectConfig
from constraint_aware.sim.tasks import task_config

NAN, INF = math.nan, math.inf

# (`ExecutorConfig.with_overrides` key, bad value): the error names the dotted field
EXECUTOR_BAD: list[tuple[str, Any]] = [
    ("limits__force_limit", NAN),
    ("limits__force_limit", INF),
    ("limits__force_limit", 0.0),
    ("limits__force_limit", 0.1),  # below the derived dead band's 0.2 N floor
    ("step_length", NAN),
    ("step_length", 0.5),
    ("step_length", -0.01),
    ("step_length", 0.0),
    ("threshold", NAN),
    ("threshold", -1.0),
    ("limits__max_steps", 0),
    ("limits__max_steps", -5),
    ("limits__max_steps", 2.5),
    ("timing__offset_samples", 0),
    ("timing__offset_samples", 1),
    ("workplane_normal", (0.0, 0.0, 0.0)),
    ("workplane_normal", (0.0, NAN, 1.0)),
    ("workplane_normal", (0.0, 1.0)),
    ("goal__travel", -0.1),
    ("goal__travel", NAN),
    ("goal__rotation", 0.0),
    ("hinge_point", (0.0, INF, 0.0)),
    ("rotation_radius", 0.0),
    ("guards__lost_contact_steps", 0),
    ("guards__contact_force", NAN),
    ("guards__lost_contact_force", -0.1),
    ("guards__pose_jump_margin", 0.0),
    ("guards__pose_fault_steps", 0),
    ("guards__max_lead", -0.01),
    ("guards__follow_patience", 0),
    ("guards__stale_steps", 1),
    ("guards__predictive_force", 1),
    ("guards__min_step_fraction", 1.5),
    ("self_check__steps", -1),
    ("robot__stiffness", 0.0),
    ("robot__grasp_play", -0.001),
    ("robot__grasp_play", 0.006),  # more than half a 1 cm step
    ("torque_policy__enabled", "yes"),
    ("torque_policy__alpha", 0.0),
    ("torque_policy__beta_deg", 91.0),
    ("constraint_type", "spherical"),
    ("command_from", "guess"),
]


@pytest.mark.parametrize(("key", "value"), EXECUTOR_BAD)
def test_bad_executor_config_names_the_dotted_field(key: str, value: Any) -> None:
    with pytest.raises(ConfigError) as info:
        ExecutorConfig().with_overrides(**{key: value})
    assert info.value.field == "ExecutorConfig." + key.replace("__", ".")
    assert "must be" in str(info.value)
    assert isinstance(info.value, InvalidInputError) and isinstance(info.value, CapError)


@pytest.mark.parametrize(
    ("fields", "named"),
    [
        # the torque policy needs a radius and a normal to turn about
        ({"torque_policy__enabled": True}, "ExecutorConfig.rotation_radius"),
        (
            {"torque_policy__enabled": True, "rotation_radius": 0.1, "workplane_normal": None},
            "ExecutorConfig.workplane_normal",
        ),
        ({"goal__rotation": 1.0, "workplane_normal": None}, "ExecutorConfig.workplane_normal"),
        ({"goal__travel": 0.2, "goal__rotation": 1.0}, "ExecutorConfig.goal.rotation"),
        ({"step_length": 0.002, "robot__grasp_play": 0.002}, "ExecutorConfig.robot.grasp_play"),
    ],
)
def test_fields_that_depend_on_each_other_name_the_field(
    fields: dict[str, Any], named: str
) -> None:
    with pytest.raises(ConfigError) as info:
        ExecutorConfig().with_overrides(**fields)
    assert info.value.field == named


def test_a_group_of_the_wrong_type_is_named() -> None:
    with pytest.raises(ConfigError, match=r"ExecutorConfig\.limits = 40: must be a LimitsConfig"):
        ExecutorConfig(limits=40)  # type: ignore[arg-type]


def test_unknown_override_keys_list_the_valid_ones() -> None:
    for key in ("force_limit", "limits", "limits__force", "ramp_up_steps"):
        with pytest.raises(UnknownNameError, match="limits__force_limit"):
            ExecutorConfig().with_overrides(**{key: 1})
    cfg = ExecutorConfig().with_overrides(limits__force_limit=40, step_length=0.005)
    assert cfg.limits.force_limit == 40 and cfg.step_length == 0.005
    assert cfg.limits.max_steps == ExecutorConfig().limits.max_steps  # the rest kept


def test_message_states_the_valid_range() -> None:
    with pytest.raises(ConfigError, match=r"step_length = 0\.5: must be a finite number in "
                       r"\(0, 0\.05\] \[m\]"):  # fmt: skip
        ExecutorConfig(step_length=0.5)
    with pytest.raises(ConfigError, match=r"force_limit = 2\.0: must be > threshold \(3 N\)"):
        ExecutorConfig(threshold=3.0, limits=LimitsConfig(force_limit=2.0))


def test_workplane_normal_is_normalized() -> None:
    cfg = ExecutorConfig(workplane_normal=(0.0, 0.0, 2.0))
    assert cfg.workplane_normal == (0.0, 0.0, 1.0)
    # a task's workplane normal is derived from its object (sim.tasks), a unit vector
    assert task_config("drawer-opening").workplane_normal == (0.0, 1.0, 0.0)


def test_derived_threshold_allows_any_positive_limit() -> None:
    assert ExecutorConfig(threshold=None, limits=LimitsConfig(force_limit=1.0)).threshold is None


TASK_BAD: list[tuple[str, dict[str, Any], str]] = [
    ("drawer-opening", {"object__mass": NAN}, "ObjectConfig.mass"),
    ("drawer-opening", {"object__mass": -1.0}, "ObjectConfig.mass"),
    ("door-opening", {"object__radius": NAN}, "ObjectConfig.radius"),
    ("door-opening", {"object__radius": 0.0}, "ObjectConfig.radius"),
    ("drawer-opening", {"object__frictionloss": NAN}, "ObjectConfig.frictionloss"),
    ("drawer-opening", {"object__damping": -0.1}, "ObjectConfig.damping"),
    ("drawer-opening", {"object__joint_range": (0.1, 0.4)}, "ObjectConfig.joint_range"),
    ("drawer-opening", {"object__axis": (1.0, 1.0, 0.0)}, "ObjectConfig.axis"),
    ("drawer-opening", {"object__position": (0.0, NAN, 0.8)}, "ObjectConfig.position"),
    ("drawer-opening", {"success_progress": -1.0}, "TaskConfig.success_progress"),
    ("drawer-opening", {"success_progress": NAN}, "TaskConfig.success_progress"),
    ("drawer-opening", {"force_limit": NAN}, "TaskConfig.force_limit"),
    ("drawer-opening", {"max_steps": 0}, "TaskConfig.max_steps"),
    ("drawer-opening", {"slip_limit": 0.0}, "TaskConfig.slip_limit"),
    ("drawer-opening", {"press_depth": -0.01}, "TaskConfig.press_depth"),
    ("drawer-opening", {"object__counterbalance": 1.5}, "ObjectConfig.counterbalance"),
    ("drawer-opening", {"object__handle_axis": (1.0, 0.0, 0.0)}, "ObjectConfig.handle_axis"),
    ("drawer-opening", {"force_exertion_type": "glue"}, "TaskConfig.force_exertion_type"),
    (
        "drawer-opening",
        {"hand__translational_stiffness": NAN},
        "HandConfig.translational_stiffness",
    ),
    ("drawer-opening", {"hand__hand_mass": 0.0}, "HandConfig.hand_mass"),
    ("drawer-opening", {"hand__palm_half": (0.03, 0.0, 0.01)}, "HandConfig.palm_half"),
]


@pytest.mark.parametrize(("task", "overrides", "field"), TASK_BAD)
def test_bad_task_values_fail_at_construction(
    task: str, overrides: dict[str, Any], field: str
) -> None:
    with pytest.raises(ConfigError) as info:
        task_config(task, **overrides)
    assert info.value.field == field
    assert field in str(info.value)


def test_direct_construction_is_validated_too() -> None:
    with pytest.raises(ConfigError, match=r"ObjectConfig\.mass"):
        ObjectConfig(mass=NAN)
    with pytest.raises(ConfigError, match=r"HandConfig\.friction"):
        HandConfig(friction=-1.0)


@pytest.mark.parametrize("key", ["objet__mass", "hnd__friction", "object_mass__x"])
def test_misspelled_override_prefix_lists_the_valid_ones(key: str) -> None:
    with pytest.raises(UnknownNameError, match="valid names: hand__, object__"):
        task_config("drawer-opening", **{key: 50.0})


@pytest.mark.parametrize("key", ["object__mas", "hand__stiffness", "forcelimit"])
def test_unknown_override_field_lists_the_valid_ones(key: str) -> None:
    with pytest.raises(UnknownNameError, match="valid names"):
        task_config("drawer-opening", **{key: 1.0})


RUNSPEC_BAD: list[tuple[dict[str, Any], type[Exception]]] = [
    ({"task": "drawer"}, UnknownNameError),
    ({"controller": "magic"}, UnknownNameError),
    ({"offset_deg": NAN}, ConfigError),
    ({"offset_deg": 400.0}, ConfigError),
    ({"seed": -1}, ConfigError),
    ({"sensor_noise": -0.1}, ConfigError),
    ({"sensor_noise": NAN}, ConfigError),
    ({"sensor_bias": (0.0, INF, 0.0)}, ConfigError),
    ({"overrides": (("object__mass",),)}, ConfigError),
]


@pytest.mark.parametrize(("fields", "error"), RUNSPEC_BAD)
def test_bad_run_spec_fails_at_construction(fields: dict[str, Any], error: type[Exception]) -> None:
    with pytest.raises(error):
        RunSpec(**fields)


# --- cap bench --out -----------------------------------------------------------------------
def test_bench_refuses_a_directory_with_user_files(tmp_path: Path) -> None:
    (tmp_path / "report.md").write_text("my notes\n")
    with pytest.raises(CapError, match=str(tmp_path)):
        run_bench(tmp_path, quick=True)
    assert (tmp_path / "report.md").read_text() == "my notes\n"  # untouched
    (tmp_path / "results.json").write_text("{not json")  # a corrupted or foreign results.json
    with pytest.raises(CapError, match="--force"):
        check_out_dir(tmp_path)
    check_out_dir(tmp_path, force=True)  # the user said so


def test_bench_accepts_new_empty_or_previous_bench_directories(tmp_path: Path) -> None:
    check_out_dir(tmp_path / "new")
    check_out_dir(tmp_path)
    (tmp_path / "results.json").write_text(
        json.dumps({"meta": {"quick": True, "paper_figures": {}}})
    )
    (tmp_path / "report.md").write_text("old report\n")
    check_out_dir(tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(CapError, match="not a directory"):
        check_out_dir(tmp_path / "file")


# --- --set KEY=VALUE -------------------------------------------------------------------------
def test_settings_map_dotted_keys_and_parse_values() -> None:
    s = parse_settings(
        [
            "object.frictionloss=2",
            "object.radius=0.08",
            "hand.translational_stiffness=8000",
            "executor.threshold=1",
            "executor.goal.travel=2e-1",
            "executor.guards.predictive_force=false",
            "executor.guards.max_lead=none",
            "executor.limits.force_limit=40",
            "force_limit=40",
            "object.axis=0,1,0",  # the task's workplane normal follows the object (sim.tasks)
        ]
    )
    assert dict(s.task_overrides) == {
        "object__frictionloss": 2,
        "object__radius": 0.08,
        "hand__translational_stiffness": 8000,
        "force_limit": 40,
        "object__axis": (0, 1, 0),
    }
    assert dict(s.executor_overrides) == {
        "threshold": 1,
        "goal__travel": 0.2,
        "guards__predictive_force": False,
        "guards__max_lead": None,
        "limits__force_limit": 40,
    }


@pytest.mark.parametrize(
    ("item", "match"),
    [
        ("objet.mass=3", "valid names: executor, hand, object"),
        ("object.mas=3", "valid names: .*object.mass"),
        ("executor.treshold=1", "executor.threshold"),
        ("executor.force_limit=1", "executor.limits.force_limit"),  # a group's field
        ("executor.limits=1", "executor.limits.max_steps"),  # a group is not a field
        ("executor.limits__max_steps=1", "executor.limits.max_steps"),  # dots, not __
        ("executor.ramp_up_steps=1", "executor.goal.travel"),
        ("forcelimit=1", "force_limit"),
        ("object=3", "unknown setting 'object'"),
    ],
)
def test_unknown_settings_list_the_valid_ones(item: str, match: str) -> None:
    with pytest.raises(UnknownNameError, match=match):
        parse_settings([item])


@pytest.mark.parametrize("items", [["object.mass"], ["=3"], ["force_limit=1", "force_limit=2"]])
def test_malformed_settings_are_rejected(items: list[str]) -> None:
    with pytest.raises(InvalidInputError):
        parse_settings(items)


def test_settings_reach_the_run_and_bad_values_fail_before_moving() -> None:
    spec = RunSpec("drawer-opening", "fixed", 0.0).with_settings(
        parse_settings(["max_steps=3", "executor.threshold=1", "object.mass=3"])
    )
    record, sim = run(spec)
    assert record.outcome == "timeout" and record.n_steps == 3
    assert record.threshold == 1.0
    assert sim.task.object.mass == 3
    bad = RunSpec("drawer-opening").with_settings(parse_settings(["executor.step_length=0.5"]))
    with pytest.raises(ConfigError, match="step_length"):
        run(bad)
    bad = RunSpec("drawer-opening").with_settings(parse_settings(["object.mass=nan"]))
    with pytest.raises(ConfigError, match=r"ObjectConfig\.mass"):
        run(bad)
    with pytest.raises(UnknownNameError):
        RunSpec(overrides=(("executor__treshold", 1.0),))
    with pytest.raises(UnknownNameError, match="executor__limits__max_steps"):
        RunSpec(overrides=(("executor__max_steps", 1),))  # a group's field needs its group


def test_cap_run_json_shows_the_settings_inputs_and_stages(tmp_path: Path) -> None:
    from constraint_aware.cli import main
    from constraint_aware.control.run_inputs import INPUT_NAMES

    path = tmp_path / "r.json"
    rc = main(
        [
            "run", "drawer-opening", "--controller", "fixed", "--offset", "0",
            "--set", "max_steps=5", "--set", "executor.limits.max_steps=2",
            "--set", "executor.robot.grasp_play=0.001", "--json", str(path),
        ]
    )  # fmt: skip
    data = json.loads(path.read_text())
    assert rc == 1 and data["outcome"] == "timeout"
    assert data["summary"]["steps"] == 2  # the executor's own field wins over the task's
    assert list(data["inputs"]) == list(INPUT_NAMES)
    k = task_config("drawer-opening").hand.translational_stiffness
    assert data["inputs"]["play_force"] == {"value": pytest.approx(k * 0.001), "source": "config"}
    assert data["inputs"]["step_force"]["source"] == "robot"
    assert data["stages"] == {}  # the fixed controller declares no stages


def test_a_3d_executor_runs_in_the_simulator_and_the_gym_env() -> None:
    """`workplane_normal=None` (3-D motion): d0 still turns about the task's normal, and the
    controllers get no rotation axis."""
    spec = RunSpec("door-opening", "policy", 10.0).with_settings(
        parse_settings(["executor.workplane_normal=none", "executor.limits.max_steps=3"])
    )
    record, _sim = run(spec)
    assert record.outcome == "timeout", record.reason
    assert record.inputs["workplane_normal"]["source"] == "missing"
    gym = pytest.importorskip("gymnasium")  # importing constraint_aware registers the envs
    env = gym.make(
        "constraint_aware/DrawerOpening-v0",
        executor={"workplane_normal": None, "limits__max_steps": 2},
    )
    env.reset(seed=0)
    env.close()


def test_errors_survive_pickling_between_processes() -> None:
    """A worker process's validation error reaches the parent intact (a process pool pickles
    it); one that cannot be rebuilt breaks the whole pool instead."""
    import pickle

    from constraint_aware.errors import ConfigError, UnknownNameError

    err = pickle.loads(pickle.dumps(ConfigError("ProbeConfig.amplitude", 0.5, "in [0.0001, 0.02]")))
    assert isinstance(err, ConfigError) and err.field == "ProbeConfig.amplitude"
    assert str(err) == "ProbeConfig.amplitude = 0.5: must be in [0.0001, 0.02]"
    name = pickle.loads(pickle.dumps(UnknownNameError("task", "drawer", ["door-opening"])))
    assert isinstance(name, UnknownNameError) and name.valid == ["door-opening"]
