"""LfO end to end on randomly placed objects of every kind. Writes JSON, prints a table.

    nice -n 10 python benchmarks/placement.py [--per-kind 15] [--out FILE.json]
    nice -n 10 python benchmarks/placement.py --end-to-end [--robots hook-hand,jaco]
        [--kinds drawer,...,crank] [--per-kind 15] [--recognizer cnn] [--out FILE.json]

Per kind (drawer, plate, pole, window, door, lid, crank) `--per-kind` random placements (any
yaw, either hinge side, radii 0.06-1.0 m), each demonstrated once with 5 mm tracking noise,
inferred, and executed on the true object with the estimates in charge, by the shipped default
policy and by the classical controller (Karayiannidis et al.) on the same demonstrations. Also
the lid without its stay (its full weight on the hand), as a physics variant.

--end-to-end: the whole execution sequence from each robot's home instead (bench/endtoend.py):
demonstrations whose tracked point is up to 5 cm (plus 1 cm) from the handle, the contact
point found in the head camera's depth image, reach, approach, grasp, manipulate, release,
retreat and return home, with nothing of the simulated object at run time; beside each, the
same placement started at the grasp from the demonstration above (today's run). Per robot and
kind: successes, failures by phase, peak |F| of both and their paired difference, the same
for the true force between hand and object (independent of what the hand carried at F_d), the
recognizer's error. `--kinds` runs some kinds only (each kind's placements are the same
whichever others run).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from constraint_aware.bench.placement import FULL_PER_KIND, run_placement
from constraint_aware.bench.provenance import write_results
from constraint_aware.sim.tasks import KINDS

HERE = Path(__file__).parent


def _f(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def end_to_end(args: argparse.Namespace) -> None:
    """The --end-to-end mode (module docstring)."""
    from constraint_aware.bench.endtoend import SequenceRun, run_end_to_end, summary_table
    from constraint_aware.bench.provenance import write_results

    start = time.perf_counter()

    def progress(run: SequenceRun) -> None:
        peak = "-" if run.manipulation_peak_N is None else f"{run.manipulation_peak_N:.1f}"
        tele = "-" if run.teleported_peak_N is None else f"{run.teleported_peak_N:.1f}"
        true = _f(run.object_force_peak_N)
        true_tele = _f(run.teleported_object_force_peak_N)
        own_true = _f(run.own_teleported_object_force_peak_N)
        own = f"{_f(run.own_teleported_peak_N)} N, true {own_true}"
        print(
            f"{run.robot} {run.kind} {run.index}: {run.outcome} "
            f"({run.failed_phase or 'all phases'}), peak {peak} N, true {true} N (teleported "
            f"{run.teleported_outcome}, {tele} N, true {true_tele} N; same skill {own} N), "
            f"{run.wall_time_s:.0f} s",
            flush=True,
        )

    robots = tuple(r for r in args.robots.split(",") if r)
    kinds = tuple(k for k in args.kinds.split(",") if k)
    result = run_end_to_end(
        args.per_kind, robots, args.seed, kinds, recognizer=args.recognizer, progress=progress
    )
    data = result.to_dict()
    data["wall_time_s"] = time.perf_counter() - start
    out = write_results(args.out or HERE / "results" / "end_to_end.json", data)
    print("\n".join(summary_table(result.summary)))
    print(f"wrote {out} in {data['wall_time_s']:.0f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-kind", type=int, default=FULL_PER_KIND)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=None, help="default results/placement.json "
                        "(end to end: results/end_to_end.json)")  # fmt: skip
    parser.add_argument("--end-to-end", action="store_true", help="the sequence from home")
    parser.add_argument("--robots", default="hook-hand,jaco", help="--end-to-end: robots")
    parser.add_argument(
        "--kinds", default=",".join(KINDS), help="--end-to-end: kinds (comma-separated)"
    )
    parser.add_argument("--recognizer", default="cnn", choices=("cnn", "geometric"))
    args = parser.parse_args()
    if args.end_to_end:
        end_to_end(args)
        return
    args.out = args.out or str(HERE / "results" / "placement.json")
    start = time.perf_counter()
    result = run_placement(args.per_kind, seed=args.seed, lid_without_stay=True)
    data = result.to_dict()
    data["wall_time_s"] = time.perf_counter() - start
    out = write_results(args.out, data)
    print(
        "| kind | controller | success | refused | peak F median / max [N] | normal err p95 "
        "[deg] | direction err p95 [deg] | radius err p95 [%] | goal err p95 [cm or deg] | "
        "short of the true goal median / max [cm or deg] |"
    )
    print("|---" * 10 + "|")
    for s in result.summary:
        pf = s.peak_force_N or {}
        short = s.errors.get("shortfall") or {}

        def p95(name: str, e: dict[str, dict[str, float] | None] = s.errors) -> str:
            stats = e.get(name)
            return _f(stats["p95"] if stats else None)

        print(
            f"| {s.kind} | {s.controller} | {s.successes}/{s.n} | {s.refused} | "
            f"{_f(pf.get('median'))} / {_f(pf.get('max'))} | {p95('normal_error_deg')} | "
            f"{p95('direction_error_deg')} | {p95('radius_error_pct')} | {p95('goal_error')} | "
            f"{_f(short.get('median'))} / {_f(short.get('max'))} |"
        )
    print(json.dumps(result.overall, indent=1))
    print(f"wrote {out} in {data['wall_time_s']:.0f} s")


if __name__ == "__main__":
    main()
