"""The randomized 20-seed suite on both embodiments, the Jaco also without the quasi-static guards.

    python benchmarks/jaco_suite.py [--seeds 20] [--controllers policy,classical,...]
        [--out benchmarks/results/jaco_suite.json]

Per robot, guard setting, task and controller: successes / runs, the outcomes, the median peak
|F| and mean |F| [N] (bench/sweep.py's suite: friction, mass and damping drawn per seed, offsets
uniform in +-30 deg prismatic / +-15 deg revolute; the same draws for every controller). "all
guards" is the executor as shipped (its arm-deflection guards credit the robot's reported
`tracking_time_constant` to the lag); "quasi-static guards off" disables its start-of-run
self-check and its arm-deflection stop, to separate the controllers and the arm from those
guards. One process, in order.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import time
from collections import Counter
from pathlib import Path
from typing import Any

import constraint_aware.control.guards as guards_module
from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import suite_specs
from constraint_aware.control.simulate import run
from constraint_aware.policy import ConstraintAwarePolicy

DEFAULT_OUT = Path(__file__).parent / "results" / "jaco_suite.json"
CONTROLLERS = ("policy", "classical", "projection", "fixed")
#: name -> (robots it runs on, executor overrides, the arm-force disagreement allowance)
SETTINGS: dict[str, tuple[tuple[str, ...], dict[str, object], float | None]] = {
    "all guards": (("hook-hand", "jaco"), {}, None),
    "quasi-static guards off": (("jaco",), {"self_check__steps": 0}, math.inf),
}


def cell(records: list[dict[str, Any]]) -> dict[str, Any]:
    peaks = [r["peak_force_N"] for r in records]
    means = [r["mean_force_N"] for r in records]
    return {
        "success": sum(r["success"] for r in records),
        "runs": len(records),
        "outcomes": dict(Counter(r["outcome"] for r in records)),
        "peak_force_median": statistics.median(peaks),
        "mean_force_median": statistics.median(means),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--controllers", default=",".join(CONTROLLERS))
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    controllers = args.controllers.split(",")
    policy = ConstraintAwarePolicy.load("default")
    shipped = guards_module.ARM_FORCE_DISAGREEMENT_STEPS
    out: dict[str, Any] = {
        "seeds": args.seeds,
        "policy": "default",
        "load_average_1min_at_start": os.getloadavg()[0],
        "results": {},
    }
    start = time.perf_counter()
    for setting, (robots, overrides, disagreement) in SETTINGS.items():
        guards_module.ARM_FORCE_DISAGREEMENT_STEPS = (
            shipped if disagreement is None else disagreement
        )
        for robot in robots:
            groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
            for spec in suite_specs(args.seeds, controllers):
                spec = dataclasses.replace(spec, robot=robot)
                record, _ = run(spec, policy=policy, executor_overrides=dict(overrides))
                summary = record.summary()
                groups.setdefault((spec.task, spec.controller), []).append(summary)
            out["results"][f"{robot} / {setting}"] = {
                f"{task} / {controller}": cell(rows) for (task, controller), rows in groups.items()
            }
            print(setting, robot, f"{time.perf_counter() - start:.0f} s", flush=True)
    guards_module.ARM_FORCE_DISAGREEMENT_STEPS = shipped
    out["wall_time_s"] = time.perf_counter() - start
    out["load_average_1min_at_end"] = os.getloadavg()[0]
    write_results(args.out, out)


if __name__ == "__main__":
    main()
