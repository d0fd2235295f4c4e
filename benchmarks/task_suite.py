"""The randomized task suite: success rate and peak force per task and controller. Writes JSON.

    python benchmarks/task_suite.py [--seeds 20] [--controllers policy fixed projection]
        [--workers N] [--out benchmarks/results/task_suite.json]

Per task and seed: friction, mass and damping drawn as in `sim.tasks.randomized`, an initial
offset uniform in +-30 deg (prismatic) or +-15 deg (revolute); all controllers see the same
draws. Uses every core.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import run_many, success_table, suite_specs
from constraint_aware.control.controllers import CONTROLLERS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--controllers", nargs="+", default=["policy", "fixed", "projection"])
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "task_suite.json"
    )
    args = parser.parse_args()
    for c in args.controllers:
        if c not in CONTROLLERS:
            parser.error(f"unknown controller {c!r}; valid: {', '.join(CONTROLLERS)}")
    start = time.perf_counter()
    results = run_many(suite_specs(args.seeds, args.controllers), args.workers, label="suite")
    out = {
        "seeds": args.seeds,
        "wall_s": time.perf_counter() - start,
        "table": success_table(results),
    }
    write_results(args.out, out)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
