"""Wall time of `cap train` until the evaluation mean angle is <= a target.

    python benchmarks/train_time.py [--preset default] [--target 3.0] [--seeds 0 1 2]

Runs the real command line in a subprocess per seed, on however many cores torch is given
(the presets use 2 threads). Prints JSON with each run and the median over seeds, and the
machine's load average before and after (the machine may be shared: a load above the core
count means the time is not the training's alone). --json also writes it to a file.
"""

from __future__ import annotations

import argparse
import json
import os
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
    parser.add_argument("--preset", default="default")
    parser.add_argument("--json", help="also write the result here")
    args = parser.parse_args()
    load_before = os.getloadavg()
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
    text = json.dumps(
        {
            "cores": os.cpu_count(),
            "load_average_1_5_15_before": load_before,
            "load_average_1_5_15_after": os.getloadavg(),
            "preset": args.preset,
            "target_deg": args.target,
            "runs": runs,
            "reached": f"{len(reached)}/{len(runs)}",
            "median_target_reached_s": statistics.median(reached) if reached else None,
            "median_process_wall_s": statistics.median(r["process_wall_s"] for r in runs),
        },
        indent=2,
    )
    print(text)
    if args.json:
        Path(args.json).write_text(text + "\n")


if __name__ == "__main__":
    main()
