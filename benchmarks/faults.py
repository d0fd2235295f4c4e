"""Fault injection matrix: every fault on every task with the default policy. Writes JSON.

    python benchmarks/faults.py [--offsets -30 15 30] [--seeds 0 1] [--lag gains] [--out FILE]
        [--runs FILE]

Each run injects one fault of `constraint_aware.bench.faults.FAULTS` (NaN wrench or pose, pose
glitches of 2/5/50 cm, a frozen arm for good or for 10/20/30 periods, lost comms, a 200 N
spike, a 0.2 N/period bias drift, a sensor frame rotated 90 deg, a flipped sign, stale samples,
a pose lagging 3 periods) and is classified as a safe stop, a correct continuation (success)
or dangerous (the invariants in bench/faults.py). Writes the counts per fault and class to
benchmarks/results/faults.json (`--lag gains`: faults_lag.json), with provenance; `--runs FILE`
also writes every run's classification and reasons there (not committed: ~200 KB).
`--lag gains`: the robot reports its tracking_time_constant (c / k of the hook hand's arm),
so the executor's arm-deflection guards use their lag model.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from constraint_aware.bench.faults import FAULTS, fault_suite, hook_hand_time_constant
from constraint_aware.bench.provenance import write_results
from constraint_aware.sim.tasks import TASKS

RESULTS = Path(__file__).parent / "results"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--offsets", type=float, nargs="+", default=[-30.0, 15.0, 30.0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--out", type=Path, help="default: results/faults.json or faults_lag.json")
    parser.add_argument("--runs", type=Path, help="also write every run here (JSON)")
    parser.add_argument(
        "--lag",
        choices=["reported", "gains"],
        default="reported",
        help="the robot's tracking_time_constant: whatever the simulator reports (none: the "
        "executor assumes a quasi-static arm), or c/k from the hook hand's gains",
    )
    args = parser.parse_args()
    start = time.perf_counter()
    lag = hook_hand_time_constant if args.lag == "gains" else None
    suite = fault_suite(tuple(TASKS), tuple(FAULTS), args.offsets, args.seeds, lag=lag)
    out = suite.to_dict()
    out["lag"] = args.lag
    out["offsets_deg"] = args.offsets
    out["seeds"] = args.seeds
    out["n_runs"] = len(suite.runs)
    out["wall_time_s"] = time.perf_counter() - start
    runs = out.pop("runs")
    out["runs_file"] = str(args.runs) if args.runs else None
    if args.runs:
        write_results(args.runs, {"runs": runs})
    default = "faults_lag.json" if args.lag == "gains" else "faults.json"
    write_results(args.out or RESULTS / default, out)
    print(json.dumps({"counts": out["counts"], "by_fault": out["by_fault"]}, indent=1))
    dangerous = [r for r in runs if r["classification"] == "dangerous"]
    for r in dangerous:
        print("DANGEROUS:", r["task"], r["fault"], r["offset_deg"], r["seed"], r["dangers"])


if __name__ == "__main__":
    main()
