"""The default controller at any dead band: `policy` against `policy-raw` from the derived dead
band up to 3 N, on both robots' randomized suites.

    python benchmarks/deadband.py [--seeds 5] [--robots hook-hand,jaco]
        [--out benchmarks/results/deadband.json]

The dead band is the executor's `threshold` (|F| below it is no force): "derived" leaves it to
the executor (from the F_d samples' spread, deadband.threshold_from_noise), the others set it
(`ExecutorConfig.threshold`). Each level runs the randomized suite of bench/sweep.py (friction,
mass and damping drawn per seed; offsets uniform in +-30 deg prismatic, +-15 deg revolute; the
same draws for both controllers) with the robots reporting everything. Per robot, level, task
and controller: successes / runs, the outcomes, the median peak |F| and the median mean |F|
[N]. Must-show: at every level `policy` has at least `policy-raw`'s successes on every task,
and a mean |F| no higher than `policy-raw`'s by more than noise (5 % or 0.2 N).
Results JSON through bench.provenance.write_results.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time
from collections import Counter
from pathlib import Path
from typing import Any

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import suite_specs
from constraint_aware.control.simulate import run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import TASKS

DEFAULT_OUT = Path(__file__).parent / "results" / "deadband.json"
ROBOTS = ("hook-hand", "jaco")
LEVELS: dict[str, float | None] = {"derived": None, "1 N": 1.0, "2 N": 2.0, "3 N": 3.0}
CONTROLLERS = ("policy", "policy-raw")
TOLERANCE = (0.05, 0.2)  # within noise: 5 % or 0.2 N, whichever is larger


def _cell(records: list[dict[str, Any]]) -> dict[str, Any]:
    return {
        "success": sum(r["success"] for r in records),
        "runs": len(records),
        "outcomes": dict(Counter(r["outcome"] for r in records)),
        "peak_force_median": statistics.median(r["peak_force_N"] for r in records),
        "mean_force_median": statistics.median(r["mean_force_N"] for r in records),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    policy = ConstraintAwarePolicy.load("default")
    start = time.perf_counter()
    cells: dict[str, Any] = {}
    verdicts: list[dict[str, Any]] = []
    for robot in args.robots.split(","):
        for level, threshold in LEVELS.items():
            rows: dict[tuple[str, str], list[dict[str, Any]]] = {}
            overrides: dict[str, object] = {} if threshold is None else {"threshold": threshold}
            for spec in suite_specs(args.seeds, CONTROLLERS):
                spec = dataclasses.replace(spec, robot=robot)
                record, _ = run(spec, policy=policy, executor_overrides=overrides)
                rows.setdefault((spec.task, spec.controller), []).append(record.summary())
            for task in TASKS:
                stats = {c: _cell(rows[(task, c)]) for c in CONTROLLERS}
                cells[f"{robot} / {level} / {task}"] = stats
                ours, raw = stats["policy"], stats["policy-raw"]
                gap = ours["mean_force_median"] - raw["mean_force_median"]
                allowed = max(TOLERANCE[0] * raw["mean_force_median"], TOLERANCE[1])
                verdicts.append(
                    {
                        "robot": robot,
                        "level": level,
                        "task": task,
                        "successes_at_least_raw": ours["success"] >= raw["success"],
                        "mean_force_not_higher": gap <= allowed,
                    }
                )
            print(robot, level, f"{time.perf_counter() - start:.0f} s", flush=True)
    write_results(
        args.out,
        {
            "seeds": args.seeds,
            "levels": {k: v for k, v in LEVELS.items()},
            "cells": cells,
            "verdicts": verdicts,
            "wall_time_s": time.perf_counter() - start,
        },
    )


if __name__ == "__main__":
    main()
