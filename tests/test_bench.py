"""`cap bench --quick`: every number in the report comes from results.json; figures are PNGs."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def bench_dir(quick_bench_dir: Path) -> Path:
    return quick_bench_dir


def test_every_number_in_the_report_is_in_results(
    bench_dir: Path, assert_report_numbers_in_results: Callable[[Path], None]
) -> None:
    assert_report_numbers_in_results(bench_dir)


def test_the_report_carries_no_work_history_marks(bench_dir: Path) -> None:
    from test_docs import history_marks

    marks = history_marks((bench_dir / "report.md").read_text(encoding="utf-8"))
    assert not marks, f"work-history marks in report.md: {marks}"


def test_every_figure_exists_and_is_a_png(bench_dir: Path) -> None:
    report = (bench_dir / "report.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    assert len(figures) >= 7
    for name in figures:
        assert (bench_dir / name).read_bytes()[:8] == PNG, name


def test_replot_redraws_without_running(
    bench_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    before = (bench_dir / "report.md").read_text()
    (bench_dir / "fig6_drawer.png").unlink()
    assert main(["bench", "--replot", str(bench_dir)]) == 0, capsys.readouterr()
    assert (bench_dir / "fig6_drawer.png").read_bytes()[:8] == PNG
    assert (bench_dir / "report.md").read_text() == before


def test_paper_conditions_meet_the_bars(bench_dir: Path) -> None:
    """The shipped policy at the paper's conditions: every run succeeds, prismatic ones align
    within 5 steps (checked on every bench)."""
    paper = json.loads((bench_dir / "results.json").read_text())["paper"]
    for name, s in paper.items():
        if s["controller"] == "policy" and not name.startswith("appendix_"):
            assert s["success"], name
        if s["controller"] == "policy" and s["constraint_type"] == "prismatic":
            assert s["first_step_below_5_deg"] is not None and s["first_step_below_5_deg"] <= 5
    # the appendix: the paper's policy needs the torque policy on the handle
    assert not paper["appendix_handle_paper_policy_without_torque_policy"]["success"]


@pytest.mark.parametrize(
    "content",
    [None, b"", b'{"meta": {"quick": tru', b"\xff\xfe not utf-8", b"[" * 100_000, b'{"meta": 3}'],
    ids=["missing", "empty", "truncated", "not-utf8", "deeply-nested", "not-a-bench"],
)
def test_replot_of_a_missing_or_corrupted_results_file_is_a_clear_error(
    tmp_path: Path, content: bytes | None, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    if content is not None:
        (tmp_path / "results.json").write_bytes(content)
    assert main(["bench", "--replot", str(tmp_path)]) == 2  # an exception would propagate
    err = capsys.readouterr().err
    assert "results.json" in err and "Traceback" not in err


def test_policy_section_summaries_do_not_depend_on_run_order() -> None:
    import random

    from constraint_aware.bench.analysis import Condition, RunResult, summarize

    rng = random.Random(0)
    runs = [
        RunResult(
            Condition(axis, level, task, 15.0),
            ctrl,
            seed,
            0.4,
            rng.random() < 0.7,
            "success",
            rng.uniform(1, 30),
            rng.uniform(1, 10),
            rng.uniform(0, 5),
        )
        for axis, level in (("joint friction x", 2.0), ("joint friction x", 8.0), ("suite", 0.0))
        for task in ("door-opening", "drawer-opening")
        for ctrl in ("default", "paper", "classical")
        for seed in range(3)
    ]
    shuffled = list(runs)
    rng.shuffle(shuffled)
    assert summarize(shuffled) == summarize(runs)
    assert len(summarize(runs)) == 3 * 2 * 3


def test_policy_section_in_results_and_report(bench_dir: Path) -> None:
    from constraint_aware.bench.analysis import PolicySection
    from constraint_aware.deadband import threshold_from_noise

    results = json.loads((bench_dir / "results.json").read_text())
    section = PolicySection.from_dict(results["policy_section"])
    assert section.threshold_N == threshold_from_noise(section.sensor_noise_N)
    controllers = {c.controller for c in section.paper_offsets}
    assert controllers == {
        "default",
        "default + probe",
        "default (raw)",
        "paper",
        "classical",
        "projection",
    }
    assert (
        "## Policies: default vs default + probe vs default (raw) vs paper vs classical vs "
        "projection" in (bench_dir / "report.md").read_text()
    )


def test_results_carry_their_provenance(bench_dir: Path) -> None:
    results = json.loads((bench_dir / "results.json").read_text())
    prov = results["provenance"]
    assert prov["machine"]["cpu_count"] >= 1 and prov["date"]
    assert prov["libraries"]["mujoco"] and prov["libraries"]["constraint-aware"]
    assert results["skipped"] == {} and "embodiment" in results  # this machine has the extra


def test_policy_identity_is_the_content_not_the_file_name(tmp_path: Path) -> None:
    import shutil

    from constraint_aware.bench.run import policy_identity
    from constraint_aware.policy import ConstraintAwarePolicy, shipped_policy_path

    src = shipped_policy_path("paper")
    shutil.copy(src, tmp_path / "mine.npz")
    shutil.copy(src.with_suffix(".json"), tmp_path / "mine.json")
    shipped = policy_identity(ConstraintAwarePolicy.load("paper"), "paper")
    copy = policy_identity(ConstraintAwarePolicy.load(tmp_path / "mine.npz"), tmp_path / "mine.npz")
    assert copy["source"] == str(tmp_path / "mine.npz") and not copy["shipped"]
    assert (copy["card_sha256"], copy["weights_sha256"]) == (
        shipped["card_sha256"],
        shipped["weights_sha256"],
    )
    default = policy_identity(ConstraintAwarePolicy.load(), None)
    assert default["shipped"] and default["card_sha256"] != shipped["card_sha256"]


def test_every_bench_experiment_runs_on_the_chosen_robot() -> None:
    from constraint_aware.bench import experiments as ex

    robot = "jaco:period=0.1"
    cfg = ex.BenchConfig.for_mode(False, workers=1, robot=robot)
    assert {s.robot for s in ex.paper_specs(robot).values()} == {robot}
    assert {s.robot for s in ex.headline_specs(cfg)} == {robot}
    assert {s.robot for s in ex.heatmap_specs(cfg)} == {robot}
    cells = ex.sensitivity_cells(cfg)
    stiffness = {s.robot for s, keys in cells.items() if keys[0][0] == "wrist stiffness"}
    # the Jaco's stiffness variant runs inside its advertised range (700-4000 N/m)
    assert stiffness == {f"jaco:stiffness={k:g},period=0.1" for k in (1000, 2000, 4000)}
    assert {s.robot for s, keys in cells.items() if keys[0][0] != "wrist stiffness"} == {robot}
    assert not any(k.startswith("hand__") for s in cells for k, _ in s.overrides)
    # on the hook hand the wrist stiffness stays the hand's own override, as before
    hook = ex.sensitivity_cells(ex.BenchConfig.for_mode(False, workers=1))
    assert {s.robot for s in hook} == {"hook-hand"}


def test_run_many_gives_the_policy_to_every_worker() -> None:
    from constraint_aware.bench.sweep import run_many
    from constraint_aware.control.simulate import RunSpec
    from constraint_aware.policy import ConstraintAwarePolicy

    specs = [RunSpec("drawer-opening", c, 30.0) for c in ("policy", "classical")]
    paper = ConstraintAwarePolicy.load("paper")
    pooled = run_many(specs, workers=2, quiet=True, policy=paper)  # two processes
    assert pooled == run_many(specs, workers=1, quiet=True, policy=paper)
    assert pooled[0]["summary"]["policy"] == "paper" and "policy" not in pooled[1]["summary"]
    assert run_many(specs[:1], workers=1, quiet=True)[0]["summary"]["policy"] == "default"


def test_run_many_on_the_jaco_with_the_chosen_policy() -> None:
    """The smallest Jaco case of the bench: one policy run through the bench's runner."""
    from constraint_aware.bench import experiments as ex
    from constraint_aware.bench.sweep import run_many
    from constraint_aware.control.simulate import RunSpec
    from constraint_aware.policy import ConstraintAwarePolicy

    cfg = ex.BenchConfig.for_mode(True, workers=1, robot="jaco")
    spec = cfg.on_robot(RunSpec("plate-sliding", "policy", -30.0))
    (result,) = run_many([spec], workers=1, quiet=True, policy=ConstraintAwarePolicy.load("paper"))
    assert result["spec"]["robot"] == result["summary"]["robot"] == "jaco"
    assert result["summary"]["policy"] == "paper" and result["summary"]["steps"] >= 1


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--policy", "nope"], "unknown policy 'nope'; valid names: default, paper"),
        (["--policy", "BAD"], "not a readable .npz"),
        (["--robot", "nao"], "unknown robot 'nao'; valid names: hook-hand, jaco"),
        (["--robot", "jaco:stiffness=1"], "valid range"),
    ],
)
def test_bench_policy_and_robot_are_validated_before_anything_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    from constraint_aware.cli import main
    from constraint_aware.policy import shipped_policy_path

    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip")
    (tmp_path / "bad.json").write_text(shipped_policy_path().with_suffix(".json").read_text())
    argv = [str(bad) if a == "BAD" else a for a in args]
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--out", str(out), *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()  # nothing was run or written


def test_bench_replot_takes_no_policy_or_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    for flags in (["--policy", "paper"], ["--robot", "jaco"]):
        assert main(["bench", "--replot", str(tmp_path), *flags]) == 2
        assert (
            "--replot redraws a finished bench: no --policy or --robot" in capsys.readouterr().err
        )


def test_learning_section_of_a_policy_file_with_and_without_its_log(tmp_path: Path) -> None:
    import shutil

    from constraint_aware.bench import experiments as ex
    from constraint_aware.bench.figures import fig_learning
    from constraint_aware.policy import ConstraintAwarePolicy, shipped_log_path, shipped_policy_path

    src = shipped_policy_path("paper")
    (tmp_path / "p").mkdir()
    for suffix in (".npz", ".json"):
        shutil.copy(src.with_suffix(suffix), tmp_path / "p" / f"mine{suffix}")
    path = tmp_path / "p" / "mine.npz"
    out = tmp_path / "out"
    out.mkdir()
    le = ex.learning(out, ConstraintAwarePolicy.load(path), path)
    assert (le["has_log"], le["log_points"], le["policy"]) == (False, 0, "paper")
    results = {"learning": le}
    assert (out / fig_learning(out, results)).read_bytes()[:8] == PNG  # an empty curve
    shutil.copy(shipped_log_path("paper"), tmp_path / "p" / "training_log.csv")
    le = ex.learning(out, ConstraintAwarePolicy.load(path), path)
    assert le["has_log"] and le["log_points"] > 0
    assert (out / "training_log.csv").read_text() == shipped_log_path("paper").read_text()


def test_a_sweep_prints_each_run_input_warning_once(caplog: pytest.LogCaptureFixture) -> None:
    import logging

    from constraint_aware.bench.run import _each_warning_once

    logger = logging.getLogger("constraint_aware")
    with caplog.at_level(logging.WARNING, logger="constraint_aware"), _each_warning_once():
        for _ in range(5):
            logger.warning("play_force missing: stage play_compensation off")
        logger.warning("rotation_rate missing: stage rotational_part off")
    logger.warning("play_force missing: stage play_compensation off")  # after the sweep: again
    messages = [r.getMessage() for r in caplog.records]
    assert messages.count("play_force missing: stage play_compensation off") == 2
    assert messages.count("rotation_rate missing: stage rotational_part off") == 1


def test_parse_trees_keeps_the_order_and_names_the_expected_form() -> None:
    from constraint_aware.bench.provenance import parse_trees

    assert list(parse_trees("main=/a/src,new=/b/src").items()) == [
        ("main", "/a/src"),
        ("new", "/b/src"),
    ]
    for bad in ("main", "main=/a/src,=/b/src", "main="):
        with pytest.raises(ValueError, match="NAME=SRC,NAME=SRC"):
            parse_trees(bad)


def test_a_benchmarks_tree_arguments_are_checked_through_its_parser(
    capsys: pytest.CaptureFixture[str],
) -> None:
    import argparse

    from constraint_aware.bench.provenance import trees_from_args

    parser = argparse.ArgumentParser()
    parser.add_argument("--trees")
    parser.add_argument("--rounds", type=int, default=3)
    assert trees_from_args(parser, parser.parse_args([])) == {}
    assert trees_from_args(parser, parser.parse_args(["--trees", "a=/a,b=/b"])) == {
        "a": "/a",
        "b": "/b",
    }
    for argv, said in ((["--trees", "a=/a", "--rounds", "0"], "--rounds must be >= 1"),
                       (["--trees", "a"], "NAME=SRC,NAME=SRC")):  # fmt: skip
        with pytest.raises(SystemExit):
            trees_from_args(parser, parser.parse_args(argv))
        assert said in capsys.readouterr().err
