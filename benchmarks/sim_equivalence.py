"""Do two versions of the package simulate the same physics? Outcomes and forces, run by run.

    python benchmarks/sim_equivalence.py --reference PATH/TO/OTHER/src [--candidate src]
        [--seeds 20] [--robots hook-hand,jaco] [--out benchmarks/results/sim_equivalence.json]

Runs the same specs on both source trees (each in its own subprocess, `PYTHONPATH` set to
the tree, one worker process each, one after the other) and compares them:
- the randomized suites (bench/sweep.py `suite_specs`: `--seeds` seeds x 5 tasks) with the
  controllers policy and classical, and the paper's conditions (bench/experiments.py
  `paper_specs`), on every robot in `--robots`;
- every run's outcome must be identical;
- per (robot, task, controller) group, the median peak |F| and the median mean |F| must agree
  within `TOLERANCE` (1 %); the largest relative deviation of the group medians and of single
  runs are reported.

The reference is typically a checkout of main (`git archive main | tar -x -C DIR`); the
candidate defaults to this tree's src. One tree's runs can be collected alone with `--collect
FILE` (the subprocess mode) and compared later with `--reference-runs/--candidate-runs`.
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

DEFAULT_OUT = Path(__file__).parent / "results" / "sim_equivalence.json"
CONTROLLERS = ("policy", "classical")
TOLERANCE = 0.01  # relative, on each group's median peak and mean |F|


def specs(seeds: int, robots: list[str]) -> list[Any]:
    """The runs compared: suites and the paper's conditions on every robot."""
    import dataclasses

    from constraint_aware.bench.experiments import paper_specs
    from constraint_aware.bench.sweep import suite_specs

    out = []
    for robot in robots:
        out += [dataclasses.replace(s, robot=robot) for s in suite_specs(seeds, CONTROLLERS)]
        out += list(paper_specs(robot).values())
    return out


def collect(seeds: int, robots: list[str], path: Path) -> None:
    """Run every spec in this process's package; write their summaries to `path`."""
    import dataclasses

    from constraint_aware.bench.sweep import run_many

    todo = specs(seeds, robots)
    start = time.perf_counter()
    results = run_many(todo, workers=1, quiet=True)
    wall = time.perf_counter() - start
    rows = []
    for spec, r in zip(todo, results, strict=True):
        s = r["summary"]
        rows.append(
            {
                "spec": dataclasses.asdict(spec),
                "outcome": s["outcome"],
                "steps": s["steps"],
                "peak_force_N": s["peak_force_N"],
                "mean_force_N": s["mean_force_N"],
                "final_angle_deg": s["final_angle_deg"],
            }
        )
    path.write_text(json.dumps({"wall_time_s": wall, "runs": rows}) + "\n")


def run_tree(src: Path, seeds: int, robots: list[str]) -> dict[str, Any]:
    """`collect` in a subprocess whose package is the one under `src`."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "runs.json"
        env = {**os.environ, "PYTHONPATH": str(src.resolve())}
        cmd = [sys.executable, __file__, "--collect", str(out), "--seeds", str(seeds),
               "--robots", ",".join(robots)]  # fmt: skip
        subprocess.run(cmd, env=env, check=True)
        data: dict[str, Any] = json.loads(out.read_text())
    return data


def _key(row: dict[str, Any]) -> str:
    return json.dumps(row["spec"], sort_keys=True)


def _relative(a: float, b: float) -> float:
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def compare(reference: dict[str, Any], candidate: dict[str, Any]) -> dict[str, Any]:
    """Outcomes run by run, force medians group by group (see the module docstring)."""
    ref = {_key(r): r for r in reference["runs"]}
    cand = {_key(r): r for r in candidate["runs"]}
    if ref.keys() != cand.keys():
        raise SystemExit("the two trees ran different specs")
    changed = [
        {"spec": ref[k]["spec"], "reference": ref[k]["outcome"], "candidate": cand[k]["outcome"]}
        for k in ref
        if ref[k]["outcome"] != cand[k]["outcome"]
    ]
    groups: dict[tuple[str, str, str, bool], list[str]] = {}
    for k, r in ref.items():
        s = r["spec"]
        groups.setdefault((s["robot"], s["task"], s["controller"], s["randomize"]), []).append(k)
    table = []
    worst_group = 0.0
    for (robot, task, ctrl, randomized), keys in sorted(groups.items()):
        row: dict[str, Any] = {
            "robot": robot, "task": task, "controller": ctrl,
            "set": "suite" if randomized else "paper", "n": len(keys),
        }  # fmt: skip
        for field in ("peak_force_N", "mean_force_N"):
            a = statistics.median(ref[k][field] for k in keys)
            b = statistics.median(cand[k][field] for k in keys)
            row[field] = {"reference": a, "candidate": b, "relative": _relative(a, b)}
            worst_group = max(worst_group, row[field]["relative"])
        table.append(row)
    per_run = {
        field: max(_relative(ref[k][field], cand[k][field]) for k in ref)
        for field in ("peak_force_N", "mean_force_N")
    }
    steps_changed = sum(ref[k]["steps"] != cand[k]["steps"] for k in ref)
    return {
        "n_runs": len(ref),
        "outcomes_identical": not changed,
        "changed_outcomes": changed,
        "runs_with_other_step_count": steps_changed,
        "largest_group_median_deviation": worst_group,
        "group_medians_within_tolerance": worst_group <= TOLERANCE,
        "tolerance": TOLERANCE,
        "largest_single_run_deviation": per_run,
        "groups": table,
        "reference_wall_time_s": reference["wall_time_s"],
        "candidate_wall_time_s": candidate["wall_time_s"],
        "candidate_over_reference_wall_time": candidate["wall_time_s"] / reference["wall_time_s"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, help="the other tree's src directory")
    parser.add_argument("--candidate", type=Path, default=Path(__file__).parents[1] / "src")
    parser.add_argument("--reference-runs", type=Path, help="a --collect file instead")
    parser.add_argument("--candidate-runs", type=Path, help="a --collect file instead")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--robots", default="hook-hand,jaco")
    parser.add_argument("--collect", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    robots = args.robots.split(",")
    if args.collect is not None:
        collect(args.seeds, robots, args.collect)
        return
    if args.reference_runs is not None:
        reference = json.loads(args.reference_runs.read_text())
    elif args.reference is not None:
        reference = run_tree(args.reference, args.seeds, robots)
    else:
        parser.error("give --reference (a src directory) or --reference-runs")
    if args.candidate_runs is not None:
        candidate = json.loads(args.candidate_runs.read_text())
    else:
        candidate = run_tree(args.candidate, args.seeds, robots)
    result = {
        "seeds": args.seeds,
        "robots": robots,
        "controllers": list(CONTROLLERS),
        "load_average_1min_at_end": os.getloadavg()[0],
        **compare(reference, candidate),
    }
    from constraint_aware.bench.provenance import write_results

    write_results(args.out, result)
    summary = {k: v for k, v in result.items() if k != "groups"}
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
