"""LfO end to end on randomly placed objects of every kind. Writes JSON, prints a table.

    nice -n 10 python benchmarks/placement.py [--per-kind 15] [--out FILE.json]

Per kind (drawer, plate, pole, window, door, lid, crank) `--per-kind` random placements (any
yaw, either hinge side, radii 0.06-1.0 m), each demonstrated once with 5 mm tracking noise,
inferred, and executed on the true object with the estimates in charge, by the shipped default
policy and by the classical controller (Karayiannidis et al.) on the same demonstrations. Also
the lid without its stay (its full weight on the hand), as a physics variant.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from constraint_aware.bench.placement import FULL_PER_KIND, run_placement
from constraint_aware.bench.provenance import write_results

HERE = Path(__file__).parent


def _f(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-kind", type=int, default=FULL_PER_KIND)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=str(HERE / "results" / "placement.json"))
    args = parser.parse_args()
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
