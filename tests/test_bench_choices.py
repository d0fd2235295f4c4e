"""`cap bench --policy/--robot`, and a bench on a machine without an extra: the choice reaches
every section; a section that cannot run is skipped and said before anything runs."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

CHOSEN_ROBOT = "hook-hand:stiffness=3000"
#: Runs the CLI as on a machine without dm-control (the `bench` extra): an absent module is
#: None in sys.modules, so neither `import dm_control` nor find_spec finds it.
WITHOUT_DM_CONTROL = (
    "import sys; sys.modules['dm_control'] = None; "
    "from constraint_aware.cli import main; sys.exit(main(sys.argv[1:]))"
)


@pytest.fixture(scope="module")
def chosen_bench(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A quick bench with a chosen policy and robot, on a machine without the Jaco's models:
    (its directory, its stderr)."""
    out = tmp_path_factory.mktemp("bench-chosen")
    proc = subprocess.run(
        [sys.executable, "-c", WITHOUT_DM_CONTROL, "bench", "--quick", "--workers", "1",
         "--out", str(out), "--policy", "paper", "--robot", CHOSEN_ROBOT],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out, proc.stderr


@pytest.fixture(scope="module")
def chosen_bench_dir(chosen_bench: tuple[Path, str]) -> Path:
    return chosen_bench[0]


def test_a_section_without_its_extra_is_skipped_and_said_at_the_start(
    chosen_bench: tuple[Path, str],
) -> None:
    out, stderr = chosen_bench
    results = json.loads((out / "results.json").read_text())
    assert set(results["skipped"]) == {"embodiment"} and "embodiment" not in results
    line = results["skipped"]["embodiment"]
    assert "dm-control" in line and "pip install 'constraint-aware[bench]'" in line
    # the first thing said, before any run; and once in the report
    assert stderr.splitlines()[0] == f"cap bench: skipping: {line}"
    report = (out / "report.md").read_text()
    assert report.count(line) == 1 and "## Embodiments" not in report


def test_preflight_skips_only_what_cannot_run(monkeypatch: pytest.MonkeyPatch) -> None:
    from constraint_aware.bench import experiments as ex
    from constraint_aware.bench.run import preflight, section_needs

    for quick in (True, False):
        cfg = ex.BenchConfig.for_mode(quick)
        assert preflight(cfg) == {}  # the extra is installed here
        assert ("heatmap" in section_needs(cfg)) is not quick
    monkeypatch.setitem(sys.modules, "dm_control", None)
    for quick in (True, False):
        # the full bench's end-to-end section runs the Jaco too (the quick one: the hook hand)
        expected = {"embodiment"} if quick else {"embodiment", "end_to_end"}
        assert set(preflight(ex.BenchConfig.for_mode(quick))) == expected


def test_the_end_to_end_section_without_offscreen_rendering_is_skipped_with_why(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from constraint_aware.bench import experiments as ex
    from constraint_aware.bench.run import preflight
    from constraint_aware.sim import camera

    monkeypatch.setattr(camera, "depth_rendering_available", lambda: False)
    skipped = preflight(ex.BenchConfig.for_mode(True))
    assert set(skipped) == {"end_to_end"}
    assert "OpenGL" in skipped["end_to_end"] and "EGL" in skipped["end_to_end"]


def test_an_explicit_robot_without_its_models_is_refused_before_anything_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from constraint_aware.cli import main

    monkeypatch.setitem(sys.modules, "dm_control", None)
    out = tmp_path / "out"
    assert main(["bench", "--quick", "--out", str(out), "--robot", "jaco:period=0.08"]) == 2
    err = capsys.readouterr().err
    assert "--robot jaco:period=0.08" in err and "constraint-aware[bench]" in err
    assert not out.exists()


def test_bench_records_and_uses_the_chosen_policy_and_robot(
    quick_bench_dir: Path,
    chosen_bench_dir: Path,
    assert_report_numbers_in_results: Callable[[Path], None],
) -> None:
    bench_dir = quick_bench_dir
    default = json.loads((bench_dir / "results.json").read_text())
    chosen = json.loads((chosen_bench_dir / "results.json").read_text())
    pol, base = chosen["meta"]["policy"], default["meta"]["policy"]
    assert (pol["name"], pol["shipped"], base["name"]) == ("paper", True, "default")
    assert pol["card_sha256"] != base["card_sha256"]
    assert pol["weights_sha256"] != base["weights_sha256"]
    assert (chosen["meta"]["robot"], default["meta"]["robot"]) == (CHOSEN_ROBOT, "hook-hand")
    # every paper run on the chosen robot; the policy runs with the chosen policy
    for name, s in chosen["paper"].items():
        record = json.loads((chosen_bench_dir / s["record"]).read_text())
        assert record["label"]["robot"] == CHOSEN_ROBOT, name
        if s["controller"] == "policy":
            assert record["label"]["policy"] == "paper", name
    assert default["paper"]["fig6_drawer_+30_policy"]["policy"] == "default"
    assert {w["robot"] for w in chosen["worst_cases"]} == {CHOSEN_ROBOT}  # the suite's runs
    assert chosen["learning"]["policy"] == "paper"
    # the policy section still compares the named policies, on the hook hand: unchanged
    assert chosen["policy_section"] == default["policy_section"]
    report = (chosen_bench_dir / "report.md").read_text()
    assert f"card sha256 `{pol['card_sha256'][:16]}`" in report
    assert f"Robot: `{CHOSEN_ROBOT}`" in report
    assert_report_numbers_in_results(chosen_bench_dir)
