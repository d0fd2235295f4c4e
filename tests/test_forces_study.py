"""bench/forces.py: the force study's typed results (one short simulated run per variant)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from constraint_aware.bench.analysis import Condition
from constraint_aware.bench.forces import (
    PROBE_ACROSS_N,
    PROBE_ALONG_N,
    VARIANTS,
    RunDiagnosis,
    probe_turns,
    run_variant,
    summarize,
    summary_from_dict,
    table_lines,
)
from constraint_aware.policy import ConstraintAwarePolicy

DRAWER = Condition("test", 1.0, "drawer-opening", 30.0)


@pytest.fixture(scope="module")
def runs() -> list[RunDiagnosis]:
    return [run_variant(DRAWER, v, 0) for v in ("default", "classical", "steady")]


def test_a_diagnosis_splits_the_run_and_agrees_with_its_summary(runs: list[RunDiagnosis]) -> None:
    for r in runs:
        assert r.success, r.outcome
        assert r.peak_force_N >= r.mean_force_N > 0
        assert 0 <= r.peak_step <= r.n_steps + 1
        assert r.path_turn_deg == 0.0  # prismatic: the path does not turn
        assert math.isfinite(r.steady_mean_force_N) and math.isfinite(r.steady_lag_deg)


def test_summaries_do_not_depend_on_the_order_of_the_runs(runs: list[RunDiagnosis]) -> None:
    forward = summarize(runs)
    backward = summarize(list(reversed(runs)))
    assert forward == backward
    assert [c.variant for c in forward] == ["default", "classical", "steady"]  # VARIANTS order
    again = [summary_from_dict(dataclasses.asdict(c)) for c in forward]
    assert again == forward
    lines = table_lines(again, ["default", "steady"])
    assert lines[0].startswith("| axis | level | task | default | steady |")
    assert "1/1" in lines[2]


def test_every_variant_label_builds_a_controller() -> None:
    policy = ConstraintAwarePolicy.load()
    for label, build in VARIANTS.items():
        ctrl = build(policy, 0.2, np.array([0.0, 0.0, 1.0]))
        assert hasattr(ctrl, "next_direction"), label


def test_the_probe_covers_its_grid_and_reports_the_implied_error() -> None:
    probe = probe_turns(ConstraintAwarePolicy.load())
    assert len(probe) == len(PROBE_ALONG_N) * len(PROBE_ACROSS_N)
    for p in probe:
        assert math.isfinite(p.turn_deg)
        assert p.implied_error_deg == pytest.approx(math.degrees(math.asin(p.across_N / 20.0)))
