"""bench/ablation.py: the default controller's stage-off rows, typed results and their report."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from constraint_aware.bench.ablation import (
    CLASSICAL,
    FULL,
    HOOK_PAPER,
    HOOK_PAPER_PROBED,
    JACO_SUITE,
    MAP,
    RAW,
    SETS,
    AblationCell,
    AblationJob,
    AblationRun,
    AblationSection,
    ablation_jobs,
    acts,
    bench_jobs,
    beyond_noise,
    changes,
    rows,
    run_job,
    summarize,
    without,
)
from constraint_aware.bench.analysis import Condition
from constraint_aware.bench.figures import fig_ablation
from constraint_aware.bench.report import ablation_lines
from constraint_aware.control.controllers import POLICY_STAGES


def _run(row: str, task: str, seed: int, peak: float, mean: float, ok: bool = True) -> AblationRun:
    return AblationRun(HOOK_PAPER, row, task, "paper offsets", 0.0, 15.0, seed, ok,
                       "success" if ok else "force_limit", peak, mean)  # fmt: skip


def test_rows_are_the_full_controller_the_references_and_one_per_stage() -> None:
    labels = rows()
    assert labels[:3] == (FULL, RAW, CLASSICAL)
    assert labels[3:] == tuple(without(s) for s in POLICY_STAGES)


def test_jobs_cover_each_set_and_the_probed_set_only_its_rows() -> None:
    jobs = ablation_jobs([FULL, RAW], 1, 2, 1, 1, probed_rows=[FULL])
    by_set = {s: [j for j in jobs if j.set == s] for s in SETS}
    assert len(by_set[HOOK_PAPER]) == 6 * 2 * 2  # six paper offsets x 2 noise seeds x 2 rows
    assert {j.robot for j in by_set[JACO_SUITE]} == {"jaco"}
    assert {j.row for j in by_set[HOOK_PAPER_PROBED]} == {FULL}
    assert all(j.probe for j in by_set[HOOK_PAPER_PROBED])
    assert not any(j.probe for s in SETS[:4] for j in by_set[s])
    quick = ablation_jobs([FULL], 0, 1, 0, 0, quick=True, sets=(HOOK_PAPER,))
    assert len(quick) == 2


def test_a_row_is_run_only_where_its_stage_can_act() -> None:
    """The known rotation acts on revolute joints only, the play compensation only when the
    play is known (after a probe): elsewhere the row would repeat the full controller's runs."""
    rotation, play = without("rotation_feedforward"), without("play_compensation")
    assert acts(rotation, "door-opening") and not acts(rotation, "drawer-opening")
    assert not acts(play, "drawer-opening") and acts(play, "drawer-opening", probed=True)
    assert acts(FULL, "drawer-opening") and acts(without("travel_scaling"), "door-opening")


def test_the_bench_runs_a_few_of_every_set_and_quick_a_handful() -> None:
    labels = [r for r in rows() if r != CLASSICAL]
    jobs = bench_jobs(labels)
    assert {j.set for j in jobs} == set(SETS[:4])
    assert {j.seed for j in jobs} == {0}
    assert len(jobs) < 120
    quick = bench_jobs(labels, quick=True)
    assert {j.set for j in quick} == {HOOK_PAPER} and len(quick) <= 16


def test_summaries_do_not_depend_on_the_order_of_the_runs() -> None:
    runs = [
        _run(FULL, "door-opening", 0, 4.6, 1.5),
        _run(FULL, "door-opening", 1, 4.8, 1.6),
        _run(without("confidence_ramp"), "door-opening", 0, 4.6, 1.5),
        _run(without("confidence_ramp"), "door-opening", 1, 5.8, 1.4, ok=False),
    ]
    forward, backward = summarize(runs), summarize(reversed(runs))
    assert {c.row: c for c in forward} == {c.row: c for c in backward}
    full = next(c for c in forward if c.row == FULL)
    assert (full.n, full.successes) == (2, 2)
    assert full.median_peak_force_N == pytest.approx(4.7)
    assert full.median_mean_force_N == pytest.approx(1.55)


def test_noise_is_five_percent_or_two_tenths_of_a_newton_whichever_is_larger() -> None:
    assert not beyond_noise(1.19, 1.0)  # 0.19 N < 0.2 N
    assert beyond_noise(1.21, 1.0)
    assert not beyond_noise(10.49, 10.0)  # 0.49 N < 5 % of 10 N
    assert beyond_noise(10.51, 10.0)
    assert beyond_noise(float("nan"), 1.0) and not beyond_noise(float("nan"), float("nan"))


def test_changes_list_every_stage_cell_beyond_noise_and_any_change_in_successes() -> None:
    def cell(row: str, successes: int, peak: float, mean: float) -> AblationCell:
        return AblationCell(HOOK_PAPER, "door-opening", row, 10, successes, peak, mean, mean)

    cells = [
        cell(FULL, 10, 4.7, 1.5),
        cell(without("confidence_ramp"), 10, 4.8, 1.6),  # within noise
        cell(without("overshoot_damping"), 9, 4.7, 1.5),  # one run lost
        cell(without("travel_scaling"), 10, 5.7, 1.5),  # peak up 1 N
    ]
    found = {(c.stage, c.successes, c.peak_N, c.mean_N) for c in changes(cells, POLICY_STAGES)}
    assert found == {("overshoot_damping", -1, None, None), ("travel_scaling", 0, 1.0, None)}


def test_the_section_survives_json_and_the_report_and_figure_read_only_it(
    tmp_path: Path,
) -> None:
    cells = summarize(
        [
            _run(FULL, "door-opening", 0, 4.6, 1.5),
            _run(without("travel_scaling"), "door-opening", 0, 5.6, 1.5),
            _run(RAW, "door-opening", 0, 5.4, 2.6),
        ]
    )
    sec = AblationSection(POLICY_STAGES, rows(), {HOOK_PAPER: "noise seed 0"}, 0.1, cells)
    data = json.loads(json.dumps(sec.to_dict()))
    assert AblationSection.from_dict(data) == sec
    name = fig_ablation(tmp_path, {"ablation": data})
    assert (tmp_path / name).stat().st_size > 1000
    lines = ablation_lines(AblationSection.from_dict(data), {"ablation": name})
    text = "\n".join(lines)
    assert "| policy without travel_scaling | **1/1, 5.60, 1.50** |" in text  # beyond noise
    assert "| policy | 1/1, 4.60, 1.50 |" in text
    assert "benchmarks/results/ablation_every_stage.json" in text


def test_a_job_runs_the_row_it_names() -> None:
    """The drawer at +30 deg (noise seed 0): without the travel scaling the start's peak is
    about 1 N higher (11.0 against 10.1 N); an unknown row is refused."""
    cond = Condition("paper offsets", 30.0, "drawer-opening", 30.0)
    full = run_job(AblationJob(HOOK_PAPER, FULL, cond, 0))
    off = run_job(AblationJob(HOOK_PAPER, without("travel_scaling"), cond, 0))
    assert full.success and off.success
    assert off.peak_force_N > full.peak_force_N + 0.5
    assert dataclasses.replace(full, peak_force_N=0.0).row == FULL
    with pytest.raises(ValueError, match="ablation row"):
        run_job(AblationJob(MAP, "policy without the network", cond, 0))
