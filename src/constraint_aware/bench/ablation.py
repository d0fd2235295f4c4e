"""The default controller's ablation: each of its stages switched off, everything else on.

Rows: the full controller "policy", the paper's rule alone ("policy-raw"), the classical
controller for reference, and one row per stage of "policy" with that stage off
(`make_controller("policy", params={stage: 0.0})`). Sets: the hook hand's randomized suite,
its paper offsets over sensor-noise seeds, the Jaco's randomized suite and the resistance map
(paper offsets, friction, damping, mass, wrist stiffness, preload). A cell is one (set, task,
row): successes, median peak |F| and median of the runs' mean |F| [N].

The hook hand's sets run as the policy section does (`analysis.prepare_condition`, the dead
band derived from the sensor noise); the Jaco's as `simulate.run` does. Typed from end to end:
`ablation_jobs` lists the runs, `run_job` runs one (any process), `summarize` groups runs into
`AblationCell`s by their own keys, and the report reads an `AblationSection`.
`benchmarks/ablation.py` runs the full sets; `cap bench` a few seeds of each.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterable, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from constraint_aware import deadband
from constraint_aware.bench.analysis import (
    Condition,
    paper_offset_conditions,
    prepare_condition,
    resistance_map,
    suite_conditions,
)
from constraint_aware.bench.sweep import current_executor, default_workers, gather_in_order
from constraint_aware.control.controllers import POLICY_STAGES, make_controller
from constraint_aware.control.executor import Executor as ControlExecutor
from constraint_aware.control.simulate import RunSpec, probed_config, run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import task_config

#: The full default controller, the paper's rule alone and the classical controller.
FULL, RAW, CLASSICAL = "policy", "policy-raw", "classical"
#: [N] per axis, the simulated sensor's noise in every set (the policy section's).
SENSOR_NOISE = 0.1
#: The sets, in the order tables list them.
HOOK_SUITE = "hook-hand suite"
HOOK_PAPER = "hook-hand paper offsets"
JACO_SUITE = "jaco suite"
MAP = "resistance map"
#: The hook hand's paper offsets after a setup probe (`cap run --probe`): the only set where
#: the grasp's play is known, so the only one where the play compensation can act.
HOOK_PAPER_PROBED = "hook-hand paper offsets after a probe"
SETS = (HOOK_SUITE, HOOK_PAPER, JACO_SUITE, MAP, HOOK_PAPER_PROBED)


def without(stage: str) -> str:
    """The row label of controller "policy" with `stage` off."""
    return f"policy without {stage}"


def rows(stages: Sequence[str] = POLICY_STAGES) -> tuple[str, ...]:
    """Every row: the full controller, the paper's rule, classical, then one per stage."""
    return (FULL, RAW, CLASSICAL, *(without(s) for s in stages))


#: The stage that acts only when the grasp's play is known: after a setup probe.
PLAY_STAGE = "play_compensation"


def acts(row: str, task: str, probed: bool = False) -> bool:
    """Whether a row can differ from the full controller on `task` at all. A stage that does
    not act on the task's constraint type (`stage_inputs`: the known rotation on a prismatic
    joint), or the play compensation without a probe (no play is known), leaves the full
    controller's runs as they are, so its row is not run there."""
    _, switches = _controller(row)
    if not switches:
        return True
    stage = switches[0][0]
    if stage == PLAY_STAGE and not probed:
        return False
    return stage in _acting_stages(task_config(task).constraint_type)


@functools.cache
def _acting_stages(constraint_type: str) -> tuple[str, ...]:
    return tuple(make_controller(FULL).stage_inputs(constraint_type))


def _controller(row: str) -> tuple[str, tuple[tuple[str, float], ...]]:
    """(controller name, stage switches) of a row label."""
    if row in (FULL, RAW, CLASSICAL):
        return row, ()
    stage = row.removeprefix(without(""))
    if stage == row or stage not in POLICY_STAGES:
        raise ValueError(f"ablation row {row!r}: not one of {list(rows())}")
    return FULL, ((stage, 0.0),)


@dataclass(frozen=True)
class AblationJob:
    """One run: a row on one condition and seed of a set (robot "jaco" for the Jaco's)."""

    set: str
    row: str
    condition: Condition
    seed: int
    robot: str = "hook-hand"
    probe: bool = False


@dataclass(frozen=True)
class AblationRun:
    """One run's outcome. Forces [N]."""

    set: str
    row: str
    task: str
    axis: str
    level: float
    offset_deg: float
    seed: int
    success: bool
    outcome: str
    peak_force_N: float
    mean_force_N: float


@dataclass(frozen=True)
class AblationCell:
    """One (set, task, row): counts and medians over its runs. Forces [N]."""

    set: str
    task: str
    row: str
    n: int
    successes: int
    median_peak_force_N: float
    median_mean_force_N: float  # median over runs of each run's mean |F|
    mean_mean_force_N: float  # mean over runs of each run's mean |F|


def ablation_jobs(
    row_labels: Sequence[str],
    suite_seeds: int,
    noise_seeds: int,
    jaco_seeds: int,
    map_seeds: int,
    probed_rows: Sequence[str] = (),
    quick: bool = False,
    sets: Sequence[str] = SETS,
) -> list[AblationJob]:
    """Every run of the ablation, set by set. suite_seeds / jaco_seeds: randomized suite
    seeds per task (bench.sweep.suite_specs draws); noise_seeds: sensor-noise seeds per paper
    offset; map_seeds: seeds per resistance-map condition; quick: the paper offsets' and the
    map's quick conditions (`analysis.paper_offset_conditions`, `resistance_map`);
    probed_rows: the rows run on the probed paper offsets (none: no such set)."""
    jobs: list[AblationJob] = []

    def add(name: str, conds: Iterable[tuple[Condition, int]], labels: Sequence[str]) -> None:
        if name not in sets:
            return
        robot = "jaco" if name == JACO_SUITE else "hook-hand"
        probe = name == HOOK_PAPER_PROBED
        jobs.extend(
            AblationJob(name, r, c, s, robot, probe)
            for c, s in conds
            for r in labels
            if acts(r, c.task, probe)
        )

    paper = [(c, s) for c in paper_offset_conditions(quick) for s in range(noise_seeds)]
    add(HOOK_SUITE, suite_conditions(suite_seeds), row_labels)
    add(HOOK_PAPER, paper, row_labels)
    add(JACO_SUITE, suite_conditions(jaco_seeds), row_labels)
    add(MAP, [(c, s) for c in resistance_map(quick) for s in range(map_seeds)], row_labels)
    if probed_rows:
        add(HOOK_PAPER_PROBED, paper, probed_rows)
    return jobs


def run_job(job: AblationJob, policy: ConstraintAwarePolicy | None = None) -> AblationRun:
    """Run one job (`policy`: the one driving "policy" and "policy-raw"; None: the default)."""
    policy = policy or ConstraintAwarePolicy.load()
    name, switches = _controller(job.row)
    cond = job.condition
    spec = RunSpec(
        cond.task, name, cond.offset_deg, seed=job.seed, randomize=cond.randomize,
        sensor_noise=SENSOR_NOISE, overrides=cond.overrides, controller_params=switches,
        robot=job.robot,
    )  # fmt: skip
    if job.robot != "hook-hand":
        record, _ = run(spec, policy=policy)
    else:
        threshold = deadband.threshold_from_noise(SENSOR_NOISE)
        prep = prepare_condition(cond, spec, threshold)
        config = probed_config(spec, prep.config) if job.probe else prep.config
        ctrl = make_controller(name, policy, prep.rotation_rate, prep.normal, dict(switches))
        executor = ControlExecutor(prep.sim, ctrl, config, monitor=prep.sim)
        record = executor.run(prep.d0, {"task": cond.task})
    return AblationRun(
        set=job.set,
        row=job.row,
        task=cond.task,
        axis=cond.axis,
        level=cond.level,
        offset_deg=cond.offset_deg,
        seed=job.seed,
        success=record.success,
        outcome=record.outcome,
        peak_force_N=float(record.peak_force),
        mean_force_N=float(record.mean_force),
    )


@functools.cache
def _default_policy() -> ConstraintAwarePolicy:
    """The shipped default policy, loaded once per worker process."""
    return ConstraintAwarePolicy.load()


def _run_job_default(job: AblationJob) -> AblationRun:
    return run_job(job, _default_policy())


def run_jobs(jobs: Sequence[AblationJob], workers: int | None = None) -> list[AblationRun]:
    """Every job, in the jobs' order: on the executor set by `sweep.use_executor`, else in a
    local pool of `workers` processes (default: the available CPUs; 1: in this process)."""
    executor: Executor | None = current_executor()
    if executor is not None:
        return gather_in_order(executor, _run_job_default, jobs)
    n = workers or default_workers(len(jobs))
    if n <= 1:
        return [_run_job_default(j) for j in jobs]
    with ProcessPoolExecutor(max_workers=min(n, len(jobs))) as pool:
        return gather_in_order(pool, _run_job_default, jobs)


def summarize(runs: Iterable[AblationRun]) -> list[AblationCell]:
    """One cell per (set, task, row), in SETS order, then task, then the row's first
    appearance; inside a cell the runs are sorted, so no sum depends on the run order."""
    groups: dict[tuple[str, str, str], list[AblationRun]] = {}
    order: dict[str, int] = {}
    for r in runs:
        groups.setdefault((r.set, r.task, r.row), []).append(r)
        order.setdefault(r.row, len(order))
    set_order = {name: i for i, name in enumerate(SETS)}
    out = []
    for key in sorted(groups, key=lambda k: (set_order.get(k[0], 99), k[0], k[1], order[k[2]])):
        cell = sorted(groups[key], key=lambda r: (r.axis, r.level, r.offset_deg, r.seed))
        means = [r.mean_force_N for r in cell]
        out.append(
            AblationCell(
                set=key[0],
                task=key[1],
                row=key[2],
                n=len(cell),
                successes=sum(r.success for r in cell),
                median_peak_force_N=float(np.median([r.peak_force_N for r in cell])),
                median_mean_force_N=float(np.median(means)),
                mean_mean_force_N=float(np.mean(means)),
            )
        )
    return out


#: A difference within max(this share, NOISE_FLOOR_N) of the full controller's value is a tie.
NOISE_SHARE = 0.05
NOISE_FLOOR_N = 0.2


def beyond_noise(value: float, reference: float) -> bool:
    """Whether two forces [N] differ by more than noise: 5 % of the reference or 0.2 N,
    whichever is larger (non-finite values differ unless both are non-finite)."""
    if not (math.isfinite(value) and math.isfinite(reference)):
        return math.isfinite(value) != math.isfinite(reference)
    return abs(value - reference) > max(NOISE_SHARE * abs(reference), NOISE_FLOOR_N)


@dataclass(frozen=True)
class Change:
    """A stage-off cell against the full controller's on the same set and task: the change
    in successes and, when beyond noise, in median peak and median mean |F| [N] (+: higher
    without the stage, i.e. the stage lowers it)."""

    set: str
    task: str
    stage: str
    successes: int
    peak_N: float | None
    mean_N: float | None


def changes(cells: Iterable[AblationCell], stages: Sequence[str]) -> list[Change]:
    """Every stage-off cell that differs from the full controller's beyond noise (any change
    in successes counts)."""
    cells = list(cells)
    full = {(c.set, c.task): c for c in cells if c.row == FULL}
    out = []
    for stage in stages:
        for c in cells:
            ref = full.get((c.set, c.task))
            if c.row != without(stage) or ref is None:
                continue
            peak = c.median_peak_force_N - ref.median_peak_force_N
            mean = c.median_mean_force_N - ref.median_mean_force_N
            peak_beyond = beyond_noise(c.median_peak_force_N, ref.median_peak_force_N)
            mean_beyond = beyond_noise(c.median_mean_force_N, ref.median_mean_force_N)
            if c.successes != ref.successes or peak_beyond or mean_beyond:
                out.append(
                    Change(
                        c.set,
                        c.task,
                        stage,
                        c.successes - ref.successes,
                        peak if peak_beyond else None,
                        mean if mean_beyond else None,
                    )
                )
    return out


@dataclass(frozen=True)
class AblationSection:
    """Everything the report's ablation section shows. seeds: per set, what its runs cover;
    benchmark_seeds: what benchmarks/ablation.py runs instead ("suite": suite seeds per task
    on each robot, "noise": noise seeds per paper offset, "map": seeds per map condition);
    noise_percent [%] and noise_floor_N [N]: the tie rule (`beyond_noise`)."""

    stages: tuple[str, ...]
    rows: tuple[str, ...]
    seeds: dict[str, str]
    sensor_noise_N: float
    cells: list[AblationCell]
    benchmark_seeds: dict[str, int] = dataclasses.field(
        default_factory=lambda: {"suite": 20, "noise": 10, "map": 2}
    )
    noise_percent: float = 100.0 * NOISE_SHARE
    noise_floor_N: float = NOISE_FLOOR_N

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> AblationSection:
        return cls(
            stages=tuple(data["stages"]),
            rows=tuple(data["rows"]),
            seeds=dict(data["seeds"]),
            sensor_noise_N=float(data["sensor_noise_N"]),
            cells=[AblationCell(**c) for c in data["cells"]],
            benchmark_seeds=dict(data["benchmark_seeds"]),
            noise_percent=float(data["noise_percent"]),
            noise_floor_N=float(data["noise_floor_N"]),
        )


#: `cap bench`'s share of the sets (benchmarks/ablation.py runs 20 suite seeds per task on
#: each robot, 10 noise seeds per paper offset and 2 seeds per resistance-map condition): seed 0
#: of every hook-hand set, the Jaco's suite seed 0 on its door and drawer, and two
#: resistance-map cells, the door at 8x joint friction and the drawer at 8 kg.
BENCH_JACO_TASKS = ("drawer-opening", "door-opening")
BENCH_MAP_CELLS = (
    ("joint friction x", 8.0, "door-opening"),
    ("drawer mass kg", 8.0, "drawer-opening"),
)


def bench_jobs(row_labels: Sequence[str], quick: bool = False) -> list[AblationJob]:
    """The bench's runs: `BENCH_JACO_TASKS`, `BENCH_MAP_CELLS` and seed 0 of the hook hand's
    suite and paper offsets (quick: the drawer at +30 deg and the door at +15 deg only)."""
    if quick:
        return ablation_jobs(row_labels, 0, 1, 0, 0, quick=True, sets=(HOOK_PAPER,))
    jobs = ablation_jobs(row_labels, 1, 1, 1, 1, sets=SETS[:4])
    return [
        j
        for j in jobs
        if (j.set != JACO_SUITE or j.condition.task in BENCH_JACO_TASKS)
        and (
            j.set != MAP
            or (j.condition.axis, j.condition.level, j.condition.task) in BENCH_MAP_CELLS
        )
    ]


def ablation_section(quick: bool = False, workers: int | None = None) -> AblationSection:
    """The bench's ablation (`bench_jobs`): the full controller, the paper's rule alone and
    each stage off."""
    labels = tuple(r for r in rows() if r != CLASSICAL)
    if quick:
        seeds = {HOOK_PAPER: "the drawer at +30 deg and the door at +15 deg, noise seed 0"}
    else:
        seeds = {
            HOOK_SUITE: "seed 0 per task",
            HOOK_PAPER: "noise seed 0",
            JACO_SUITE: "seed 0, drawer and door",
            MAP: "seed 0; the door at 8x joint friction, the drawer at 8 kg",
        }
    runs = run_jobs(bench_jobs(labels, quick), workers)
    return AblationSection(POLICY_STAGES, labels, seeds, SENSOR_NOISE, summarize(runs))
