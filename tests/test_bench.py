"""`cap bench --quick`: every number in the report comes from results.json; figures are PNGs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

PNG = b"\x89PNG\r\n\x1a\n"


def _numbers(obj: Any) -> Iterator[float]:
    if isinstance(obj, bool):
        return
    if isinstance(obj, int | float):
        yield float(obj)
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _numbers(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _numbers(v)


def _shown_numbers(markdown: str) -> list[str]:
    text = re.sub(r"\]\([^)]*\)", "]", markdown)  # figure file names
    text = re.sub(r"`[^`]*`", "", text)  # code: file and command names
    text = re.sub(r"[A-Za-z_]+\d+[A-Za-z_\d]*", "", text)  # identifiers like fig6, p95
    return [m.replace(",", "") for m in re.findall(r"-?\d[\d,]*(?:\.\d+)?", text)]


@pytest.fixture(scope="module")
def bench_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bench")
    proc = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "bench", "--quick", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out


def test_every_number_in_the_report_is_in_results(bench_dir: Path) -> None:
    results = json.loads((bench_dir / "results.json").read_text())
    values = list(_numbers(results))
    report = (bench_dir / "report.md").read_text()
    shown = _shown_numbers(report)
    assert len(shown) > 50
    missing = []
    for token in shown:
        digits = len(token.split(".")[1]) if "." in token else 0
        x = float(token)
        if not any(round(v, digits) == x or round(abs(v), digits) == x for v in values):
            missing.append(token)
    assert not missing, f"numbers in report.md not in results.json: {missing}"


def test_every_figure_exists_and_is_a_png(bench_dir: Path) -> None:
    report = (bench_dir / "report.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", report)
    assert len(figures) >= 7
    for name in figures:
        assert (bench_dir / name).read_bytes()[:8] == PNG, name


def test_replot_redraws_without_running(bench_dir: Path) -> None:
    before = (bench_dir / "report.md").read_text()
    (bench_dir / "fig6_drawer.png").unlink()
    proc = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "bench", "--replot", str(bench_dir)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (bench_dir / "fig6_drawer.png").read_bytes()[:8] == PNG
    assert (bench_dir / "report.md").read_text() == before


def test_paper_conditions_meet_the_issue_bars(bench_dir: Path) -> None:
    """The shipped policy at the paper's conditions (issue 3's must-show, checked each run)."""
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
    tmp_path: Path, content: bytes | None
) -> None:
    if content is not None:
        (tmp_path / "results.json").write_bytes(content)
    proc = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "bench", "--replot", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert "results.json" in proc.stderr and "Traceback" not in proc.stderr


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
    assert controllers == {"default", "paper", "classical", "projection"}
    assert (
        "## Policies: paper vs default vs classical vs projection"
        in (bench_dir / "report.md").read_text()
    )
