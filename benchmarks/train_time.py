"""Wall time of `cap train` (default preset) until the evaluation mean angle is <= a target.

    python benchmarks/train_time.py [--target 3.0] [--seeds 0 1 2]

Runs the real command line in a subprocess per seed, on however many cores torch is given
(the preset uses 2 threads). Prints JSON with each run and the median over seeds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", type=float, default=3.0, help="[deg]")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--preset", default="fast")
    args = parser.parse_args()
    runs = []
    for seed in args.seeds:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [
                sys.executable, "-m", "constraint_aware.cli", "train", "--preset", args.preset,
                "--seed", str(seed), "--target-angle", str(args.target), "--out", tmp,
                "--quiet", "--final-episodes", "10000",
            ]  # fmt: skip
            start = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True)
            process_s = time.perf_counter() - start
            card = json.loads((Path(tmp) / "policy.json").read_text())
        runs.append(
            {
                "seed": seed,
                "target_reached_s": card["target_reached_s"],
                "process_wall_s": process_s,
                "timesteps": card["total_timesteps"],
                "final_mean_angle_deg": card["metrics"]["policy"]["mean_final_angle_deg"],
            }
        )
    reached = [r["target_reached_s"] for r in runs if r["target_reached_s"] is not None]
    print(
        json.dumps(
            {
                "preset": args.preset,
                "target_deg": args.target,
                "runs": runs,
                "reached": f"{len(reached)}/{len(runs)}",
                "median_target_reached_s": statistics.median(reached) if reached else None,
                "median_process_wall_s": statistics.median(r["process_wall_s"] for r in runs),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
