"""Shared fixtures."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pytest
from filelock import FileLock

from constraint_aware.control.controllers import ControlInput, FixedDirection

os.environ.setdefault("MUJOCO_GL", "egl")

#: The files whose tests take longest (mypy over the tree; a quick bench each), collected
#: first: `--dist loadfile` gives each file to one worker in collection order, and a long one
#: handed out last leaves the other worker idle until it ends.
LONGEST_FIRST = ("test_lint.py", "test_bench.py", "test_bench_choices.py")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: item.path.name not in LONGEST_FIRST)  # stable: else in order


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


class _KnowsTruth(Protocol):
    def admissible_direction(self) -> np.ndarray: ...


class TrueDirection(FixedDirection):
    """Moves along the simulator's true admissible direction: a scripted pull."""

    name = "truth"

    def __init__(self, sim: _KnowsTruth) -> None:
        self.sim = sim

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        return self.sim.admissible_direction()


class RequiredOnly:
    """Forwards only the Robot protocol's required members to `inner` (no grasp_contact, hold,
    translational_stiffness or tracking_time_constant): a robot with nothing optional."""

    control_period = 0.1

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def read_wrench(self) -> Any:
        return self._inner.read_wrench()

    def read_pose(self) -> Any:
        return self._inner.read_pose()

    def commanded_pose(self) -> Any:
        return self._inner.commanded_pose()

    def command_pose(self, pose: Any) -> None:
        self._inner.command_pose(pose)

    def advance(self) -> None:
        self._inner.advance()


@pytest.fixture
def required_only() -> type[RequiredOnly]:
    """The RequiredOnly wrapper class (a robot without optional members)."""
    return RequiredOnly


@pytest.fixture
def true_direction() -> type[TrueDirection]:
    """The scripted-pull controller (a simulator's ground truth as d), for grasp tests."""
    return TrueDirection


# --- `cap bench --quick`, once per test session ---------------------------------------------
@pytest.fixture(scope="session")
def quick_bench_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The folder of `cap bench --quick` (the shipped policy, the hook hand), in one process
    (the results do not depend on the workers: tests/test_sweep.py; the suite's own workers
    have the cores): run once per test session and shared by every xdist worker (the first
    to ask runs it, the others wait for it and read it). Tests must not change its results.json."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the session's folder, shared by its workers
    out = root / "quick-bench"
    with FileLock(str(root / "quick-bench.lock")):
        if not (out / "report.md").is_file():
            proc = subprocess.run(
                [sys.executable, "-m", "constraint_aware.cli", "bench", "--quick", "--force",
                 "--workers", "1", "--out", str(out)],
                capture_output=True, text=True, timeout=900,
            )  # fmt: skip
            assert proc.returncode == 0, proc.stdout + proc.stderr
    return out


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
    text = re.sub(r"\b(?:paper|section|appendix)\s+\d+(?:\.\d+)*", "", text)  # "paper 3.3"
    # a minus sign, not the hyphen of a range such as "figs. 7-8"
    return [m.replace(",", "") for m in re.findall(r"(?:(?<!\d)-)?\d[\d,]*(?:\.\d+)?", text)]


def _report_numbers_in_results(bench_dir: Path) -> None:
    """Every number report.md shows is a value of results.json (rounded as shown)."""
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


@pytest.fixture(scope="session")
def assert_report_numbers_in_results() -> Callable[[Path], None]:
    """A check: every number in DIR/report.md is a value of DIR/results.json."""
    return _report_numbers_in_results
