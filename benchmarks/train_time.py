"""Wall time of `cap train` until the evaluation mean angle is <= a target, against a baseline.

    python benchmarks/train_time.py [--preset default] [--target 3.0] [--seeds 0 1 2]
                                    [--target-evaluation training|standard]
                                    [--no-baseline] [--baseline-seeds 0]
                                    [--baseline-threads 1] [--out PATH]

Runs the real command line in a subprocess per seed, on however many cores torch is given
(the preset's `torch_threads`). `--target-evaluation standard` applies the target to the
paper's resistance-free test set (the shipped policy's bar: 2.2 deg) instead of the periodic
evaluation in the training environment. For each seed it runs the preset and then, unless
--no-baseline, the baseline (`BASELINE_PRESET` + `BASELINE_FLAGS`: a 2x256 net, 10 epochs,
a constant learning rate, k uniform in 1000-3000 N/m), so the two share the machine's load and
their ratio means something on a shared machine. Writes JSON (default
benchmarks/results/train_time.json, with provenance) with each run, the medians over seeds,
the median of the per-seed ratios new/old, and the machine's load average before and after (a
load above the core count means the times are not the training's alone). Each run also
records the standard evaluation (no resistance, 10,000 episodes) of the policy it stopped with.
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
from typing import Any

from constraint_aware.bench.provenance import write_results

#: The baseline: the `default` preset before its smaller net (commit 1a89c01; 81.5 s to 3 deg on
#: a quiet machine): the `fast` preset (2x256, 10 epochs, constant learning rate 1e-3, 1.2 M
#: steps) in that preset's training environment (resistance, magnitude observation, k uniform
#: in 1000-3000 N/m).
BASELINE_PRESET = "fast"
BASELINE_FLAGS = (
    "--env.observation", "magnitude", "--env.resistance-free-share", "0.5",
    "--env.dry-friction", "0", "0.3", "--env.dry-friction-abs", "0", "1",
    "--env.damping", "0", "0.1", "--env.inertia", "0", "0.1", "--env.preload", "0", "0.3",
    "--env.step-force-unknown-share", "0.25",
)  # fmt: skip
#: torch threads of the baseline (its 81.5 s were measured with 2 on a quiet machine).
BASELINE_THREADS = 2


def run_once(
    preset: str, seed: int, target: float, extra: tuple[str, ...], evaluation: str = "training"
) -> dict[str, Any]:
    """One `cap train` to `target` [deg] on `evaluation`; times from the card and the process."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [
            sys.executable, "-m", "constraint_aware.cli", "train", "--preset", preset,
            "--seed", str(seed), "--target-angle", str(target), "--out", tmp,
            "--target-evaluation", evaluation,
            "--quiet", "--final-episodes", "10000", *extra,
        ]  # fmt: skip
        start = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        process_s = time.perf_counter() - start
        card = json.loads((Path(tmp) / "policy.json").read_text())
    standard = card.get("metrics_standard", card["metrics"])["policy"]
    return {
        "seed": seed,
        "target_reached_s": card["target_reached_s"],
        "process_wall_s": process_s,
        "timesteps": card["total_timesteps"],
        "steps_per_s": card["total_timesteps"] / card["wall_time_s"],
        "final_mean_angle_deg": card["metrics"]["policy"]["mean_final_angle_deg"],
        "standard_mean_angle_deg": standard["mean_final_angle_deg"],
    }


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    reached = [r["target_reached_s"] for r in runs if r["target_reached_s"] is not None]
    return {
        "runs": runs,
        "reached": f"{len(reached)}/{len(runs)}",
        "median_target_reached_s": statistics.median(reached) if reached else None,
        "median_process_wall_s": statistics.median(r["process_wall_s"] for r in runs),
        "median_steps_per_s": statistics.median(r["steps_per_s"] for r in runs),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", type=float, default=3.0, help="[deg]")
    parser.add_argument(
        "--target-evaluation",
        choices=("training", "standard"),
        default="training",
        help="where the target applies (TrainConfig.target_evaluation)",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--preset", default="default")
    parser.add_argument("--no-baseline", action="store_true", help="skip the baseline")
    parser.add_argument(
        "--baseline-seeds", type=int, nargs="*", help="seeds of the baseline (default: --seeds)"
    )
    parser.add_argument(
        "--baseline-threads",
        type=int,
        default=BASELINE_THREADS,
        help="torch threads of the baseline (on a busy machine 1: a second thread stalls)",
    )
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "train_time.json"
    )
    args = parser.parse_args()
    load_before = os.getloadavg()
    new: list[dict[str, Any]] = []
    old: list[dict[str, Any]] = []
    baseline_seeds = args.seeds if args.baseline_seeds is None else args.baseline_seeds
    baseline = (*BASELINE_FLAGS, "--torch-threads", str(args.baseline_threads))
    for seed in args.seeds:  # interleaved: new and old see the same load
        new.append(run_once(args.preset, seed, args.target, (), args.target_evaluation))
        if not args.no_baseline and seed in baseline_seeds:
            old.append(
                run_once(BASELINE_PRESET, seed, args.target, baseline, args.target_evaluation)
            )
    result: dict[str, Any] = {
        "cores": os.cpu_count(),
        "load_average_1_5_15_before": load_before,
        "load_average_1_5_15_after": os.getloadavg(),
        "preset": args.preset,
        "target_deg": args.target,
        "target_evaluation": args.target_evaluation,
        **summary(new),
    }
    if old:
        by_seed = {n["seed"]: n for n in new}
        ratios = [
            by_seed[o["seed"]]["target_reached_s"] / o["target_reached_s"]
            for o in old
            if by_seed[o["seed"]]["target_reached_s"] is not None
            and o["target_reached_s"] is not None
        ]
        result["baseline"] = {"preset": BASELINE_PRESET, "flags": list(baseline), **summary(old)}
        result["per_seed_ratio_new_over_old"] = ratios
        result["median_ratio_new_over_old"] = statistics.median(ratios) if ratios else None
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
