"""Do two versions of the package simulate the same physics? Outcomes and forces, run by run.

    python benchmarks/sim_equivalence.py --reference PATH/TO/OTHER/src [--candidate src]
        [--seeds 20] [--robots hook-hand,jaco] [--controllers policy,classical]
        [--out benchmarks/results/sim_equivalence.json]

Runs the same specs on both source trees (each in its own subprocess, `PYTHONPATH` set to
the tree, one worker process each, one after the other) and compares them:
- the randomized suites (bench/sweep.py `suite_specs`: `--seeds` seeds x 5 tasks) with the
  `--controllers` (default policy and classical), and the paper's conditions (bench/experiments.py
  `paper_specs`), on every robot in `--robots`;
- every run's outcome must be identical;
- per (robot, task, controller) group, the median peak |F| and the median mean |F| must agree
  within `TOLERANCE` (1 %); the largest relative deviation of the group medians and of single
  runs are reported;
- a run that differs by more than `TOLERANCE` is run again in both trees, perturbed in ways
  no measurement could tell apart (physically the same run): the initial direction turned by
  k 1e-9 deg, and the object's mass k units in the last place larger (k = 1..`PERTURBATIONS`
  each); where the reference's own values spread by more than the tolerance, the quantity is
  chaotic at the last bit (a squeezed pole's grip chatters; a Jaco drawer run moves by 12 %
  when one grasp joint angle moves by one unit in the last place) and no change that is not
  bit-exact can hold it; the report lists each such run with both trees' spreads, and a group
  over the tolerance passes only when every run that moves it differs only in such
  quantities.

`--bench A/results.json B/results.json` compares two `cap bench` results instead: every
outcome field (outcome, outcomes, success, successes, success_rate, n) must be equal and every
median force (keys with "median" ending in "_N") within `TOLERANCE`; it lists what is not.

The reference is typically a checkout of main (`git archive main | tar -x -C DIR`); the
candidate defaults to this tree's src. Runs collected earlier (the subprocess's `--collect
FILE`) can stand in for either tree's with `--reference-runs/--candidate-runs`; the re-runs
still need the trees.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

DEFAULT_OUT = Path(__file__).parent / "results" / "sim_equivalence.json"
CONTROLLERS = ("policy", "classical")
TOLERANCE = 0.01  # relative, on each group's median peak and mean |F|
PERTURBATIONS = 4  # of each kind, for a run that differs (module docstring)
FIELDS = ("peak_force_N", "mean_force_N")


def specs(seeds: int, robots: list[str], controllers: tuple[str, ...] = CONTROLLERS) -> list[Any]:
    """The runs compared: suites and the paper's conditions on every robot."""
    import dataclasses

    from constraint_aware.bench.experiments import paper_specs
    from constraint_aware.bench.sweep import suite_specs

    out = []
    for robot in robots:
        out += [dataclasses.replace(s, robot=robot) for s in suite_specs(seeds, controllers)]
        out += list(paper_specs(robot).values())
    return out


def _spec(data: dict[str, Any]) -> Any:
    """A RunSpec from its `dataclasses.asdict` (JSON lists back to tuples)."""
    from constraint_aware.control.simulate import RunSpec

    def tuples(v: Any) -> Any:
        return tuple(tuples(x) for x in v) if isinstance(v, list) else v

    return RunSpec(**{k: tuples(v) for k, v in data.items()})


def collect(todo: list[Any], path: Path) -> None:
    """Run every spec in this process's package; write their summaries to `path`."""
    import dataclasses

    from constraint_aware.bench.sweep import run_many

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


def run_tree(src: Path, todo: list[dict[str, Any]]) -> dict[str, Any]:
    """`collect` of the specs `todo` (asdict) in a subprocess whose package is under `src`."""
    with tempfile.TemporaryDirectory() as tmp:
        specs, out = Path(tmp) / "specs.json", Path(tmp) / "runs.json"
        specs.write_text(json.dumps(todo))
        env = {**os.environ, "PYTHONPATH": str(src.resolve())}
        cmd = [sys.executable, __file__, "--collect", str(out), "--specs", str(specs)]
        subprocess.run(cmd, env=env, check=True)
        data: dict[str, Any] = json.loads(out.read_text())
    return data


def perturbed(spec: dict[str, Any]) -> list[dict[str, Any]]:
    """The run with its initial direction turned by k 1e-9 deg, then with the object's mass
    k units in the last place larger, k = 1..PERTURBATIONS (the subprocess resolves the mass:
    see `_resolve_mass`)."""
    turned = [
        {**spec, "offset_deg": spec["offset_deg"] + k * 1e-9} for k in range(1, PERTURBATIONS + 1)
    ]
    heavier = [
        {**spec, "overrides": [*spec["overrides"], ["object__mass", f"ulps:{k}"]]}
        for k in range(1, PERTURBATIONS + 1)
    ]
    return turned + heavier


def _resolve_mass(spec: Any) -> Any:
    """A spec whose mass override reads "ulps:k": the task's own (randomized) object mass k
    units in the last place larger."""
    import dataclasses

    from constraint_aware.control.simulate import build_task

    marked = [v for k, v in spec.overrides if k == "object__mass" and isinstance(v, str)]
    if not marked:
        return spec
    rest = tuple((k, v) for k, v in spec.overrides if k != "object__mass")
    mass = build_task(dataclasses.replace(spec, overrides=rest)).object.mass
    for _ in range(int(marked[0].split(":")[1])):
        mass = math.nextafter(mass, math.inf)
    return dataclasses.replace(spec, overrides=(*rest, ("object__mass", mass)))


def _key(row: dict[str, Any]) -> str:
    return json.dumps(row["spec"], sort_keys=True)


def _relative(a: float, b: float) -> float:
    if a == b:
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def compare(
    reference: dict[str, Any],
    candidate: dict[str, Any],
    rerun: Callable[[str, list[dict[str, Any]]], dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """Outcomes run by run, force medians group by group (see the module docstring); runs
    over the tolerance re-run perturbed through `rerun(tree, specs)` ("reference" or
    "candidate"), if given."""
    ref = {_key(r): r for r in reference["runs"]}
    cand = {_key(r): r for r in candidate["runs"]}
    if ref.keys() != cand.keys():
        raise SystemExit("the two trees ran different specs")
    changed = [
        {"spec": ref[k]["spec"], "reference": ref[k]["outcome"], "candidate": cand[k]["outcome"]}
        for k in ref
        if ref[k]["outcome"] != cand[k]["outcome"]
    ]
    deviation = {k: max(_relative(ref[k][f], cand[k][f]) for f in FIELDS) for k in ref}
    chaotic = _chaotic_runs(ref, cand, [k for k in ref if deviation[k] > TOLERANCE], rerun)
    groups: dict[tuple[str, str, str, bool], list[str]] = {}
    for k, r in ref.items():
        s = r["spec"]
        groups.setdefault((s["robot"], s["task"], s["controller"], s["randomize"]), []).append(k)
    table = []
    for (robot, task, ctrl, randomized), keys in sorted(groups.items()):
        row: dict[str, Any] = {
            "robot": robot, "task": task, "controller": ctrl,
            "set": "suite" if randomized else "paper", "n": len(keys),
        }  # fmt: skip
        for field in FIELDS:
            a = statistics.median(ref[k][field] for k in keys)
            b = statistics.median(cand[k][field] for k in keys)
            row[field] = {"reference": a, "candidate": b, "relative": _relative(a, b)}
        worst = max(row[f]["relative"] for f in FIELDS)
        movers = [k for k in keys if deviation[k] > TOLERANCE]
        row["within_tolerance"] = worst <= TOLERANCE
        row["passes"] = worst <= TOLERANCE or all(
            chaotic.get(k, {}).get("explained") for k in movers
        )
        table.append(row)
    steady = [g for g in table if g["within_tolerance"]]
    return {
        "n_runs": len(ref),
        "outcomes_identical": not changed,
        "changed_outcomes": changed,
        "runs_with_other_step_count": sum(ref[k]["steps"] != cand[k]["steps"] for k in ref),
        "largest_group_median_deviation": max(max(g[f]["relative"] for f in FIELDS) for g in table),
        "largest_group_median_deviation_of_groups_within_tolerance": max(
            (max(g[f]["relative"] for f in FIELDS) for g in steady), default=0.0
        ),
        "groups_over_tolerance": [
            {k: g[k] for k in ("robot", "task", "controller", "set", "n", "passes", *FIELDS)}
            for g in table
            if not g["within_tolerance"]
        ],
        "every_group_passes": all(g["passes"] for g in table),
        "tolerance": TOLERANCE,
        "largest_single_run_deviation": {
            f: max(_relative(ref[k][f], cand[k][f]) for k in ref) for f in FIELDS
        },
        "runs_over_tolerance": list(chaotic.values()),
        "groups": table,
        "reference_wall_time_s": reference["wall_time_s"],
        "candidate_wall_time_s": candidate["wall_time_s"],
        "candidate_over_reference_wall_time": candidate["wall_time_s"] / reference["wall_time_s"],
    }


def _chaotic_runs(
    ref: dict[str, Any],
    cand: dict[str, Any],
    keys: list[str],
    rerun: Callable[[str, list[dict[str, Any]]], dict[str, Any]] | None,
) -> dict[str, dict[str, Any]]:
    """Per run over the tolerance: both trees' values from the perturbed re-runs, whether the
    reference's own values spread by more than the tolerance (chaotic at the last bit), and
    whether every quantity that differs is such a one (explained)."""
    if not keys or rerun is None:
        return {}
    todo = [p for k in keys for p in perturbed(ref[k]["spec"])]
    again = {tree: rerun(tree, todo)["runs"] for tree in ("reference", "candidate")}
    out = {}
    for i, k in enumerate(keys):
        rows = slice(i * 2 * PERTURBATIONS, (i + 1) * 2 * PERTURBATIONS)
        entry: dict[str, Any] = {"spec": ref[k]["spec"]}
        explained = True
        for field in FIELDS:
            spreads = {
                tree: [r[field] for r in again[tree][rows]] + [run[k][field]]
                for tree, run in (("reference", ref), ("candidate", cand))
            }
            low, high = min(spreads["reference"]), max(spreads["reference"])
            chaotic = _relative(low, high) > TOLERANCE
            entry[field] = {
                "reference": ref[k][field],
                "candidate": cand[k][field],
                "reference_spread": [low, high],
                "candidate_spread": [min(spreads["candidate"]), max(spreads["candidate"])],
                "chaotic": chaotic,
            }
            explained = explained and (
                _relative(ref[k][field], cand[k][field]) <= TOLERANCE or chaotic
            )
        entry["explained"] = explained
        out[k] = entry
    return out


OUTCOME_KEYS = ("outcome", "outcomes", "success", "successes", "success_rate", "n")


def compare_bench(a: Any, b: Any, path: str = "", median: bool = False) -> dict[str, list[Any]]:
    """Two `cap bench` results.json trees: outcome fields that differ and median forces (every
    number under a key with "median" ending in "_N") that differ by more than the tolerance
    (paths and values)."""
    out: dict[str, list[Any]] = {"outcomes": [], "median_forces": [], "structure": []}
    if isinstance(a, dict) and isinstance(b, dict):
        for key in a.keys() | b.keys():
            here = f"{path}/{key}"
            if key not in a or key not in b:
                out["structure"].append(here)
            elif key in OUTCOME_KEYS and a[key] != b[key]:
                out["outcomes"].append([here, a[key], b[key]])
            else:
                forces = median or ("median" in key and key.endswith("_N"))
                for k, v in compare_bench(a[key], b[key], here, forces).items():
                    out[k] += v
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out["structure"].append(path)
        for i, (x, y) in enumerate(zip(a, b, strict=False)):
            for k, v in compare_bench(x, y, f"{path}[{i}]", median).items():
                out[k] += v
    elif median and isinstance(a, float | int) and isinstance(b, float | int):
        out["median_forces"] += [[path, a, b]] if _relative(float(a), float(b)) > TOLERANCE else []
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reference", type=Path, help="the other tree's src directory")
    parser.add_argument("--candidate", type=Path, default=Path(__file__).parents[1] / "src")
    parser.add_argument("--reference-runs", type=Path, help="a --collect file instead")
    parser.add_argument("--candidate-runs", type=Path, help="a --collect file instead")
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--robots", default="hook-hand,jaco")
    parser.add_argument(
        "--controllers", default=",".join(CONTROLLERS), help="the suites' controllers"
    )
    parser.add_argument("--collect", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--specs", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--bench", type=Path, nargs=2, help="two cap bench results.json files")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    if args.bench is not None:
        a, b = (json.loads(p.read_text()) for p in args.bench)
        print(json.dumps(compare_bench(a, b), indent=1))
        return
    robots = args.robots.split(",")
    controllers = tuple(args.controllers.split(","))
    if args.collect is not None:  # the subprocess: this tree's package
        if args.specs is not None:
            todo = [_resolve_mass(_spec(s)) for s in json.loads(args.specs.read_text())]
        else:
            todo = specs(args.seeds, robots, controllers)
        collect(todo, args.collect)
        return
    import dataclasses

    everything = [dataclasses.asdict(s) for s in specs(args.seeds, robots, controllers)]
    trees = {"reference": args.reference, "candidate": args.candidate}
    runs = {"reference": args.reference_runs, "candidate": args.candidate_runs}
    loaded = {}
    for tree in trees:
        if runs[tree] is not None:
            loaded[tree] = json.loads(runs[tree].read_text())
        elif trees[tree] is not None:
            loaded[tree] = run_tree(trees[tree], everything)
        else:
            parser.error(f"give --{tree} (a src directory) or --{tree}-runs")

    def rerun(tree: str, todo: list[dict[str, Any]]) -> dict[str, Any]:
        if trees[tree] is None:
            raise SystemExit(f"runs over the tolerance: re-running them needs --{tree}")
        return run_tree(trees[tree], todo)

    result = {
        "seeds": args.seeds,
        "robots": robots,
        "controllers": list(controllers),
        "perturbations": {"initial_direction_deg": 1e-9, "mass_ulps": 1, "each": PERTURBATIONS},
        **compare(loaded["reference"], loaded["candidate"], rerun),
        "load_average_1min_at_end": os.getloadavg()[0],
    }
    from constraint_aware.bench.provenance import write_results

    write_results(args.out, result)
    summary = {k: v for k, v in result.items() if k != "groups"}
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
