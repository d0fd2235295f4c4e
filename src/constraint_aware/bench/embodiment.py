"""The embodiment axis: the same controllers, unchanged, on the hook hand and on the Jaco arm.

The paper's third claim: the policy sees only the normalized force, so it needs no retuning
when the robot changes, while the classical controller's gains (m/(s N)) depend on the force
scale. Here the classical gains stay as tuned on embodiment 1's drawer, the policy is the
shipped one, and nothing is tuned per embodiment. Three experiments:

- transfer: the 20-seed randomized suite (bench/sweep.py's `suite_specs`) on each embodiment;
- paper: the paper's conditions (bench/experiments.py's `PAPER_RUNS`) on each embodiment, with
  the executor's default dead band and with a 0.4 N one;
- variants: the paper's conditions with the arm's Cartesian stiffness (500-20,000 N/m) and the
  control period (50-200 ms) varied, on each embodiment (policy and classical).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from constraint_aware.bench.sweep import PAPER_OFFSETS, run_many, suite_specs
from constraint_aware.control.simulate import EXECUTOR_PREFIX, RunSpec
from constraint_aware.errors import UnknownNameError
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import EMBODIMENTS
from constraint_aware.sim.robot_adapter import TIMESTEP, period_substeps
from constraint_aware.sim.tasks import TASKS

CONTROLLERS = ("policy", "classical", "projection", "fixed")
ROBOTS = ("hook-hand", "jaco")
#: Variant levels inside every embodiment's advertised range (sim.embodiment.VARIANT_RANGES;
#: benchmarks/robot_variants.py measures the ranges and beyond)
STIFFNESS_LEVELS = (700.0, 1000.0, 2000.0, 4000.0)  # [N/m]
PERIOD_LEVELS = (0.06, 0.1, 0.2)  # [s] nominal control periods
LOW_THRESHOLD = 0.4  # [N] the dead band measured beside the executor's default


@dataclass(frozen=True)
class Cell:
    """One (task, robot, controller[, variant]) group of runs."""

    task: str
    robot: str
    controller: str
    n: int
    successes: int
    peak_force_median_N: float
    mean_force_median_N: float
    outcomes: dict[str, int]
    variant: str = ""  # "" or "stiffness" / "period" / "threshold"
    level: float | None = None  # the variant's value [N/m], [s] or [N]

    @property
    def success_rate(self) -> float:
        return self.successes / self.n if self.n else float("nan")


@dataclass
class EmbodimentResults:
    """Typed results of `embodiment_experiments`; `to_dict` for results.json."""

    robots: tuple[str, ...]
    controllers: tuple[str, ...]
    seeds: int
    transfer: list[Cell] = field(default_factory=list)
    paper: list[Cell] = field(default_factory=list)
    variants: list[Cell] = field(default_factory=list)
    simulated_period_s: dict[str, float] = field(default_factory=dict)  # nominal -> actual
    wall_time_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        def cells(rows: list[Cell]) -> list[dict[str, Any]]:
            return [{**dataclasses.asdict(c), "success_rate": c.success_rate} for c in rows]

        return {
            "robots": list(self.robots),
            "controllers": list(self.controllers),
            "seeds": self.seeds,
            "transfer": cells(self.transfer),
            "paper": cells(self.paper),
            "variants": cells(self.variants),
            "simulated_period_s": self.simulated_period_s,
            "wall_time_s": self.wall_time_s,
        }


def simulated_period(nominal: float) -> float:
    """[s] the time one `advance` simulates for a nominal period (sim/robot_adapter.py)."""
    return period_substeps(nominal) * TIMESTEP


def _cell(
    specs_records: Sequence[tuple[RunSpec, dict[str, Any]]],
    variant: str = "",
    level: float | None = None,
) -> Cell:
    spec = specs_records[0][0]
    rows = [s for _, s in specs_records]
    outcomes: dict[str, int] = {}
    for s in rows:
        outcomes[s["outcome"]] = outcomes.get(s["outcome"], 0) + 1
    return Cell(
        task=spec.task,
        robot=spec.robot.partition(":")[0],
        controller=spec.controller,
        n=len(rows),
        successes=sum(bool(s["success"]) for s in rows),
        peak_force_median_N=float(np.median([s["peak_force_N"] for s in rows])),
        mean_force_median_N=float(np.median([s["mean_force_N"] for s in rows])),
        outcomes=outcomes,
        variant=variant,
        level=level,
    )


def _run_all(
    specs: Sequence[RunSpec],
    executor_overrides: dict[str, object] | None = None,
    policy: ConstraintAwarePolicy | None = None,
) -> list[tuple[RunSpec, dict[str, Any]]]:
    """Every spec (with `executor_overrides`) on the sweep's executor (bench/sweep.py), in
    order: (spec, its record's summary)."""
    extra = tuple((EXECUTOR_PREFIX + k, v) for k, v in (executor_overrides or {}).items())
    runs = [dataclasses.replace(s, overrides=(*s.overrides, *extra)) for s in specs]
    results = run_many(runs, label="embodiment", policy=policy)
    return [(spec, r["summary"]) for spec, r in zip(specs, results, strict=True)]


def _grouped(
    runs: Sequence[tuple[RunSpec, dict[str, Any]]], variant: str = "", level: float | None = None
) -> list[Cell]:
    groups: dict[tuple[str, str, str], list[tuple[RunSpec, dict[str, Any]]]] = {}
    for spec, summary in runs:
        groups.setdefault((spec.task, spec.robot, spec.controller), []).append((spec, summary))
    return [_cell(rows, variant, level) for rows in groups.values()]


def paper_specs(robot: str, controllers: Sequence[str] = CONTROLLERS) -> list[RunSpec]:
    """Each task at its paper offset(s) (bench/sweep.py's PAPER_OFFSETS), seed 0."""
    return [
        RunSpec(task, c, offset, robot=robot)
        for task in TASKS
        for offset in PAPER_OFFSETS[task]
        for c in controllers
    ]


def for_bench(
    quick: bool, seeds: int, policy: ConstraintAwarePolicy | None = None
) -> EmbodimentResults:
    """`cap bench`'s share: quick = the paper's conditions on the arm with the policy and the
    classical controller (12 runs); full = everything with `seeds` suite seeds. `policy`: the
    bench's policy (None: the shipped default)."""
    if quick:
        return embodiment_experiments(
            seeds=0,
            robots=("jaco",),
            controllers=("policy", "classical"),
            variants=False,
            low_threshold=False,
            policy=policy,
        )
    return embodiment_experiments(seeds=seeds, policy=policy)


def embodiment_experiments(
    seeds: int = 20,
    robots: Sequence[str] = ROBOTS,
    controllers: Sequence[str] = CONTROLLERS,
    variants: bool = True,
    tasks: Sequence[str] = tuple(TASKS),
    low_threshold: bool = True,
    variant_controllers: Sequence[str] = ("policy", "classical"),
    paper: bool = True,
    policy: ConstraintAwarePolicy | None = None,
) -> EmbodimentResults:
    """The transfer suite (`seeds` per task; 0 skips it), (paper) the paper's conditions at the
    executor's default dead band (and at `LOW_THRESHOLD` if `low_threshold`), and (variants)
    the stiffness and period variants with `variant_controllers`, on every robot; the policy
    controller runs `policy` (None: the shipped default)."""
    start = time.perf_counter()
    for robot in robots:
        if robot not in EMBODIMENTS:
            raise UnknownNameError("robot", robot, list(EMBODIMENTS))
    res = EmbodimentResults(tuple(robots), tuple(controllers), seeds)
    for robot in robots:
        if seeds > 0:
            specs = [
                dataclasses.replace(s, robot=robot) for s in suite_specs(seeds, controllers, tasks)
            ]
            res.transfer += _grouped(_run_all(specs, policy=policy))
        conditions = [s for s in paper_specs(robot, controllers) if s.task in tasks]
        if paper:
            res.paper += _grouped(_run_all(conditions, policy=policy), "threshold", None)
        if paper and low_threshold:
            res.paper += _grouped(
                _run_all(conditions, {"threshold": LOW_THRESHOLD}, policy),
                "threshold",
                LOW_THRESHOLD,
            )
        if not variants:
            continue
        base = [s for s in conditions if s.controller in variant_controllers]
        for k in STIFFNESS_LEVELS:
            specs = [dataclasses.replace(s, robot=f"{robot}:stiffness={k:g}") for s in base]
            res.variants += _grouped(_run_all(specs, policy=policy), "stiffness", k)
        for p in PERIOD_LEVELS:
            specs = [dataclasses.replace(s, robot=f"{robot}:period={p:g}") for s in base]
            res.variants += _grouped(_run_all(specs, policy=policy), "period", p)
    res.simulated_period_s = {f"{p:g}": simulated_period(p) for p in PERIOD_LEVELS}
    res.wall_time_s = time.perf_counter() - start
    return res
