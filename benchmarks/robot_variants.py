"""Which robot-spec variants work: every paper task at its paper offsets, per variant value.

    python benchmarks/robot_variants.py [--robots hook-hand,jaco] [--keys stiffness,period]
        [--seeds 3] [--out benchmarks/results/robot_variants.json]

For each robot, each variant key (`stiffness` [N/m], `period` [s]) and each value of its grid
(`GRID`, which reaches beyond every advertised range), the default policy runs every paper task
at each of its paper offsets (bench.sweep.PAPER_OFFSETS: six conditions) with `--seeds`
sensor-noise seeds. A value works when every run succeeds. The advertised ranges
(sim.embodiment.VARIANT_RANGES) must lie inside what works: `advertised_range_holds` says
whether every measured value inside each range worked. To measure beyond the advertised
ranges, this script widens them in its own process only.
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import time
from collections import Counter
from pathlib import Path
from typing import Any

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import PAPER_OFFSETS
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim import embodiment

DEFAULT_OUT = Path(__file__).parent / "results" / "robot_variants.json"
GRID: dict[str, tuple[float, ...]] = {
    "stiffness": (
        100, 150, 200, 300, 500, 600, 700, 1000, 2000, 4000, 5000, 8000, 10_000, 12_000,
        20_000, 100_000,
    ),
    "period": (0.02, 0.04, 0.05, 0.06, 0.08, 0.1, 0.2, 0.3, 0.4, 0.5),
}  # fmt: skip
#: Wide enough for every value of the grid: the measurement, not the advertised range.
PROBED_RANGE = {"stiffness": (1.0, 1e7), "period": (0.002, 5.0)}


def measure(
    robot: str, key: str, value: float, seeds: int, policy: ConstraintAwarePolicy
) -> dict[str, Any]:
    """Runs of every paper condition at `key=value` on `robot`: successes, outcomes, forces."""
    spec_text = f"{robot}:{key}={value:g}"
    rows: list[dict[str, Any]] = []
    for task, offsets in PAPER_OFFSETS.items():
        for offset in offsets:
            for seed in range(seeds):
                spec = RunSpec(task=task, offset_deg=offset, seed=seed, robot=spec_text)
                record, _ = run(spec, policy=policy)
                rows.append({"task": task, "offset_deg": offset, "seed": seed, **record.summary()})
    failed = [r for r in rows if not r["success"]]
    peaks = [r["peak_force_N"] for r in rows if r["peak_force_N"] is not None]
    return {
        "robot": robot,
        "key": key,
        "value": value,
        "success": len(rows) - len(failed),
        "runs": len(rows),
        "works": not failed,
        "outcomes": dict(Counter(r["outcome"] for r in rows)),
        "failures": [
            {k: r[k] for k in ("task", "offset_deg", "seed", "outcome", "reason")} for r in failed
        ],
        "peak_force_median_N": statistics.median(peaks) if peaks else None,
    }


def summary(
    results: list[dict[str, Any]], advertised: dict[str, dict[str, tuple[float, float]]]
) -> dict[str, Any]:
    """Per robot and key: the advertised range, the values measured in it and beyond, and
    whether every value measured inside the range worked."""
    out: dict[str, Any] = {}
    for robot, keys in advertised.items():
        for key, (low, high) in keys.items():
            cells = sorted((r for r in results if (r["robot"], r["key"]) == (robot, key)),
                           key=lambda r: r["value"])  # fmt: skip
            if not cells:
                continue
            inside = [r for r in cells if low <= r["value"] <= high]
            out[f"{robot} {key}"] = {
                "advertised_range": [low, high],
                "works": [r["value"] for r in cells if r["works"]],
                "fails": {f"{r['value']:g}": r["outcomes"] for r in cells if not r["works"]},
                "both_ends_measured": {low, high} <= {r["value"] for r in inside},
                "advertised_range_holds": bool(inside) and all(r["works"] for r in inside),
            }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="hook-hand,jaco")
    parser.add_argument("--keys", default="stiffness,period")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    robots, keys = args.robots.split(","), args.keys.split(",")
    advertised = copy.deepcopy(embodiment.VARIANT_RANGES)
    for robot in robots:  # this process only
        for key in keys:
            embodiment.VARIANT_RANGES[robot][key] = PROBED_RANGE[key]
    policy = ConstraintAwarePolicy.load("default")
    load_start = os.getloadavg()[0]
    start = time.perf_counter()
    results: list[dict[str, Any]] = []
    for robot in robots:
        for key in keys:
            for value in GRID[key]:
                cell = measure(robot, key, float(value), args.seeds, policy)
                results.append(cell)
                print(
                    f"{robot} {key}={value:g}: {cell['success']}/{cell['runs']} "
                    f"{cell['outcomes']} ({time.perf_counter() - start:.0f} s)",
                    flush=True,
                )
    write_results(
        args.out,
        {
            "seeds": args.seeds,
            "policy": "default",
            "conditions": {task: list(offsets) for task, offsets in PAPER_OFFSETS.items()},
            "summary": summary(results, advertised),
            "results": results,
            "wall_time_s": time.perf_counter() - start,
            "load_average_1min": [load_start, os.getloadavg()[0]],
        },
    )


if __name__ == "__main__":
    main()
