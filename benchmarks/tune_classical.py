"""Tune the classical baseline's gains on drawer-opening only (grid search). Writes JSON.

    python benchmarks/tune_classical.py [--out benchmarks/results/classical_tuning.json]

Runs: randomized drawer-opening, seeds 0-4, initial offsets +30 and -30 deg (the paper's drawer
condition). Objective, in order: highest success rate, lowest mean |F| over the runs' steps,
lowest median final angle. The chosen gains are copied into `ClassicalGains` by hand, with
this file as their source.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import run_many
from constraint_aware.control.simulate import RunSpec

GRID = {
    "alpha_f": [0.001, 0.002, 0.004, 0.008, 0.016],  # [m/(s N)]
    "beta_f": [0.0, 0.002, 0.008],  # [m/(s^2 N)]
    "gamma_t": [50.0, 200.0, 800.0, 3200.0],  # [s/m^2]
}
SEEDS = range(5)
OFFSETS = (30.0, -30.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "classical_tuning.json"
    )
    args = parser.parse_args()
    combos = [dict(zip(GRID, values, strict=True)) for values in itertools.product(*GRID.values())]
    specs = [
        RunSpec(
            task="drawer-opening",
            controller="classical",
            offset_deg=off,
            seed=seed,
            randomize=True,
            controller_params=tuple(combo.items()),
        )
        for combo in combos
        for seed in SEEDS
        for off in OFFSETS
    ]
    start = time.perf_counter()
    results = run_many(specs, label="tuning")
    per = len(SEEDS) * len(OFFSETS)
    rows = []
    for i, combo in enumerate(combos):
        chunk = [r["summary"] for r in results[i * per : (i + 1) * per]]
        rows.append(
            {
                **combo,
                "success_rate": float(np.mean([s["success"] for s in chunk])),
                "mean_force_N": float(np.mean([s["mean_force_N"] for s in chunk])),
                "peak_force_max_N": float(np.max([s["peak_force_N"] for s in chunk])),
                "final_angle_median_deg": float(np.median([s["final_angle_deg"] for s in chunk])),
            }
        )
    rows.sort(key=lambda r: (-r["success_rate"], r["mean_force_N"], r["final_angle_median_deg"]))
    out = {
        "task": "drawer-opening",
        "seeds": list(SEEDS),
        "offsets_deg": list(OFFSETS),
        "objective": "max success rate, then min mean |F|, then min median final angle",
        "best": rows[0],
        "ranking": rows,
        "wall_s": time.perf_counter() - start,
    }
    write_results(args.out, out)
    print(json.dumps({"best": rows[0], "top5": rows[:5], "wall_s": out["wall_s"]}, indent=1))


if __name__ == "__main__":
    main()
