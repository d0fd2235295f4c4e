"""The embodiment axis: controllers unchanged on the hook hand and the Jaco arm. Writes JSON.

    python benchmarks/embodiment.py [--seeds 20] [--no-variants] [--no-paper] [--robots R1,R2]

The 20-seed randomized suite, the paper's conditions (executor default dead band and 0.4 N),
and the stiffness / control-period variants (bench/embodiment.py); one process.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from constraint_aware.bench.embodiment import embodiment_experiments
from constraint_aware.bench.provenance import write_results

OUT = Path(__file__).parent / "results" / "embodiment.json"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--robots", default="hook-hand,jaco")
    parser.add_argument("--no-variants", action="store_true")
    parser.add_argument("--no-paper", action="store_true")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    res = embodiment_experiments(
        seeds=args.seeds,
        robots=args.robots.split(","),
        variants=not args.no_variants,
        paper=not args.no_paper,
    )
    write_results(args.out, res.to_dict())
    print(json.dumps({"wall_time_s": res.wall_time_s, "out": str(args.out)}))


if __name__ == "__main__":
    main()
