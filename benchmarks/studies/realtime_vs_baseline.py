"""How much faster does a simulated episode run than at the commit the speed targets were set
against (e189ca9), measured the way that commit measured it, in one run?

    nice -n 10 python benchmarks/studies/realtime_vs_baseline.py \
        --trees baseline=OLD/src,now=NEW/src [--rounds 3] [--repeats 3] [--out FILE]

OLD is a checkout of e189ca9 (`git worktree add --detach /tmp/baseline e189ca9`), NEW one of the
code to measure. The targets (60x real time on the hook hand, 30x on the Jaco) were set when
that commit's benchmarks/sim_speed.py read 20-24x and 11-12x; the machine's speed has moved
since (the same commit reads 14x and 7x on a busy hour), so only a ratio measured in one run
says whether the code got there: 60 / 22 = 2.7x on the hook hand and 30 / 11.5 = 2.6x on the
Jaco.

The measurement is that commit's, unchanged: per robot and task, one warm-up episode and then
`--repeats` whole 30-step episodes with controller `policy` (model build, grasp and episode;
success and the force limit out of reach; the start-of-run self-check and the arm-deflection
stop off), each timed as CPU time of its process; the control real-time factor is the 3 s of
control periods over that CPU time. Each tree runs in its own subprocess (`PYTHONPATH` = its
src), the trees interleaved round by round so that a shared machine's load falls on both.
Reported per tree and robot: the median over rounds of the median over tasks, per task the
median over rounds, and every ratio to the first tree.

Also the executor's cost per control period, whose target (median 300 us, 99th percentile
1 ms) was set against a median of 790 us and a 99th percentile of 1.3 ms, so 2.6x and 1.3x:
the paper's conditions on the hook hand (the five tasks, the drawer at both signs) with the
default controller, run as `control.simulate.run` runs them, each `Executor.step` call timed
(CPU time of its process; the task monitor's queries to the simulator included, in both trees
alike); per tree the median over rounds of the steps' median and 99th percentile, and their
ratios to the first tree's.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

STEPS = 30
ROBOTS = ("hook-hand", "jaco")
DEFAULT_OUT = Path(__file__).parent / "results" / "realtime_vs_baseline.json"


def _guards_off() -> dict[str, object]:
    """The measured commit's guards off, under the executor settings' names of the tree on
    the path (renamed since) and its arm-deflection constant (moved since)."""
    nested = importlib.util.find_spec("constraint_aware.control.executor_config") is not None
    for name in ("constraint_aware.control.guards", "constraint_aware.control.executor"):
        if importlib.util.find_spec(name) is None:
            continue
        module = importlib.import_module(name)
        if hasattr(module, "ARM_FORCE_DISAGREEMENT_STEPS"):
            module.ARM_FORCE_DISAGREEMENT_STEPS = math.inf  # type: ignore[attr-defined]
            break
    return {"self_check__steps" if nested else "self_check_steps": 0}


def measure(repeats: int) -> dict[str, Any]:
    """Every robot's and task's control real-time factor in this process's tree."""
    from constraint_aware.control.simulate import RunSpec, run
    from constraint_aware.sim.robot_adapter import CONTROL_PERIOD
    from constraint_aware.sim.tasks import TASKS

    off = _guards_off()
    out: dict[str, Any] = {}
    for robot in ROBOTS:
        per_task = {}
        for task in TASKS:
            overrides = (("max_steps", STEPS), ("success_progress", 1e9), ("force_limit", 1e9))
            spec = RunSpec(task=task, offset_deg=10.0, overrides=overrides, robot=robot)
            times = []
            for i in range(repeats + 1):  # the first warms the caches
                cpu = time.process_time()
                record, _ = run(spec, executor_overrides=off)
                if i:
                    times.append(time.process_time() - cpu)
                if len(record.steps) - 1 < STEPS:
                    raise RuntimeError(f"{robot} {task}: {record.outcome} before {STEPS} steps")
            per_task[task] = STEPS * CONTROL_PERIOD / statistics.median(times)
        out[robot] = per_task
    steps = step_times(repeats)
    out["executor_step"] = {
        "steps": len(steps),
        "cpu_us_median": statistics.median(steps),
        "cpu_us_p99": float(np.percentile(steps, 99)),  # as benchmarks/executor_speed.py
    }
    return out


def step_times(repeats: int) -> list[float]:
    """[us] the CPU time of every `Executor.step` call over `repeats` passes of the paper's
    conditions (a first pass warms the caches)."""
    from constraint_aware.bench.sweep import PAPER_OFFSETS  # in both trees
    from constraint_aware.control.executor import Executor
    from constraint_aware.control.simulate import RunSpec, run

    times: list[float] = []
    step = Executor.step

    def timed(self: Any, *args: Any) -> Any:
        start = time.process_time_ns()
        try:
            return step(self, *args)
        finally:
            times.append((time.process_time_ns() - start) / 1000)

    Executor.step = timed  # type: ignore[method-assign,assignment]
    try:
        for i in range(repeats + 1):
            if i == 1:
                times.clear()
            for task, offsets in PAPER_OFFSETS.items():
                for offset in offsets:
                    run(RunSpec(task=task, offset_deg=offset))
    finally:
        Executor.step = step  # type: ignore[method-assign]
    return times


def compare(trees: dict[str, str], rounds: int, repeats: int) -> dict[str, Any]:
    from constraint_aware.bench.provenance import run_trees

    runs = run_trees(__file__, ["--measure", "--repeats", str(repeats)], trees, rounds)
    first = next(iter(trees))
    table: dict[str, Any] = {}
    for robot in ROBOTS:
        rows: dict[str, Any] = {}
        for name, outs in runs.items():
            medians = [statistics.median(o[robot].values()) for o in outs]
            tasks = outs[0][robot]
            rows[name] = {
                "src": trees[name],
                "control_real_time_factor_cpu_median": statistics.median(medians),
                "per_round": medians,
                "per_task": {t: statistics.median(o[robot][t] for o in outs) for t in tasks},
            }
        base = rows[first]
        for row in rows.values():
            row["ratio_to_first"] = (
                row["control_real_time_factor_cpu_median"]
                / base["control_real_time_factor_cpu_median"]
            )
            row["ratio_to_first_per_round"] = [
                a / b for a, b in zip(row["per_round"], base["per_round"], strict=True)
            ]
            row["ratio_to_first_per_task"] = {
                t: v / base["per_task"][t] for t, v in row["per_task"].items()
            }
        table[robot] = rows
    step_rows: dict[str, Any] = {}
    for name, outs in runs.items():
        step_rows[name] = {
            key: statistics.median(o["executor_step"][key] for o in outs)
            for key in ("cpu_us_median", "cpu_us_p99")
        }
        step_rows[name]["steps"] = outs[0]["executor_step"]["steps"]
    for row in step_rows.values():
        for key in ("cpu_us_median", "cpu_us_p99"):
            row[f"{key}_first_over_this"] = step_rows[first][key] / row[key]
    return {
        "rounds": rounds,
        "repeats": repeats,
        "episode_steps": STEPS,
        "robots": table,
        "executor_step": step_rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trees", help="NAME=SRC,NAME=SRC: the baseline commit's src first")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    if args.measure:  # a subprocess of `compare`, inside one tree: plain JSON
        args.out.write_text(json.dumps(measure(args.repeats)))
        return
    from constraint_aware.bench.provenance import trees_from_args, write_results

    trees = trees_from_args(parser, args)
    if len(trees) < 2:
        parser.error("--trees: two or more, the baseline commit's first")
    write_results(args.out, compare(trees, args.rounds, args.repeats))
    print(args.out)


if __name__ == "__main__":
    main()
