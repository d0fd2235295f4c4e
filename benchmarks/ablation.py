"""The default controller's ablation: each stage of controller "policy" off, everything else on.

    nice -n 10 python benchmarks/ablation.py [--suite-seeds 20] [--noise-seeds 10]
        [--jaco-seeds 20] [--map-seeds 2] [--rows ROW,...] [--out benchmarks/results/ablation.json]

Rows (bench/ablation.py): the full controller "policy", "policy-raw" (the paper's rule alone),
"classical", and "policy without STAGE" for every stage `make_controller("policy", params=...)`
can switch off. Sets: the hook hand's randomized suite (20 seeds x 5 tasks), its paper offsets
over 10 sensor-noise seeds, the Jaco's randomized suite (20 seeds x 5 tasks), the resistance
map (2 seeds per condition), and the hook hand's paper offsets after a setup probe (the full
controller and the play compensation off: the play is known only after a probe). Per cell
(set, task, row): successes, median peak |F|, median and mean of the runs' mean |F| [N].

Writes the cells and the cells that differ from the full controller's beyond noise (5 % or
0.2 N, whichever is larger; any change in successes) to `--out` with provenance, and every
run to `--runs-out` (not committed: over 200 KB). One process, set by set; the results file
is rewritten after each set. `--append` adds to the runs already in `--runs-out` (a run of
the same set, row, condition and seed is not run again) and summarizes them all.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path
from typing import Any

from constraint_aware.bench.ablation import (
    FULL,
    PLAY_STAGE,
    SETS,
    AblationJob,
    AblationRun,
    ablation_jobs,
    changes,
    rows,
    run_job,
    summarize,
    without,
)
from constraint_aware.bench.provenance import write_results
from constraint_aware.control.controllers import POLICY_STAGES
from constraint_aware.policy import ConstraintAwarePolicy

RESULTS = Path(__file__).parent / "results"


def _job_key(job: AblationJob) -> tuple[str, str, str, str, float, float, int]:
    c = job.condition
    return job.set, job.row, c.task, c.axis, c.level, c.offset_deg, job.seed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite-seeds", type=int, default=20, help="hook-hand suite seeds")
    parser.add_argument("--noise-seeds", type=int, default=10, help="per paper offset")
    parser.add_argument("--jaco-seeds", type=int, default=20, help="Jaco suite seeds")
    parser.add_argument("--map-seeds", type=int, default=2, help="per resistance-map condition")
    parser.add_argument("--rows", default=",".join(rows()), help="comma-separated row labels")
    parser.add_argument("--sets", default=",".join(SETS), help="comma-separated set names")
    parser.add_argument("--out", type=Path, default=RESULTS / "ablation.json")
    parser.add_argument("--runs-out", type=Path, default=RESULTS / "ablation_runs.json")
    parser.add_argument("--append", action="store_true", help="add to --runs-out's runs")
    args = parser.parse_args()
    labels = args.rows.split(",")
    probed = [r for r in (FULL, without(PLAY_STAGE)) if r in labels]
    policy = ConstraintAwarePolicy.load()
    runs: list[AblationRun] = []
    if args.append and args.runs_out.is_file():
        runs = [AblationRun(**r) for r in json.loads(args.runs_out.read_text())]
    done = {(r.set, r.row, r.task, r.axis, r.level, r.offset_deg, r.seed) for r in runs}
    # (a run's key, as `_job_key` gives it for a job)
    start = time.perf_counter()
    for name in args.sets.split(","):
        jobs = ablation_jobs(
            labels, args.suite_seeds, args.noise_seeds, args.jaco_seeds, args.map_seeds,
            probed_rows=probed, sets=(name,),
        )  # fmt: skip
        jobs = [j for j in jobs if _job_key(j) not in done]
        runs.extend(run_job(j, policy) for j in jobs)
        cells = summarize(runs)
        labels_run = list(dict.fromkeys(r.row for r in runs))
        stages = [s for s in POLICY_STAGES if without(s) in labels_run]
        data: dict[str, Any] = {
            "policy": policy.name,
            "seeds": {
                "hook-hand suite": args.suite_seeds,
                "paper offsets noise": args.noise_seeds,
                "jaco suite": args.jaco_seeds,
                "map": args.map_seeds,
            },
            "rows": labels_run,
            "stages": stages,
            "wall_time_s": time.perf_counter() - start,
            "cells": [dataclasses.asdict(c) for c in cells],
            "changes": [dataclasses.asdict(c) for c in changes(cells, stages)],
        }
        write_results(args.out, data)
        args.runs_out.write_text(json.dumps([dataclasses.asdict(r) for r in runs]) + "\n")
        print(f"{name}: {len(jobs)} runs, {time.perf_counter() - start:.0f} s", flush=True)


if __name__ == "__main__":
    main()
