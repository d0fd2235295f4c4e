"""`cap bench --quick` on a local Dask cluster of 1 and 2 workers (and the local pool): speedup.

    python benchmarks/sweep_dask.py [--workers 1,2] [--local]
        [--out benchmarks/results/sweep_dask.json]

Runs `run_bench(quick=True, scheduler="local", workers=n)` for each n in `--workers` (a
`distributed.LocalCluster` of n single-threaded worker processes, started by the bench), one
after the other into temporary directories, and with `--local` the same on the local process
pool (`workers=n`, no scheduler). Reports each bench's wall time (the bench's own, from
results.json, and the whole call's, cluster start included), the speedup of every run over
the first Dask one (the same machine, one after the other: the load average is recorded), and
whether every results.json is the first one's except for the wall time and the worker count
(text of the canonical JSON, so NaN compares equal to NaN; where not, the differing paths).
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.run import RESULTS, run_bench
from constraint_aware.bench.sweep import LOCAL_SCHEDULER

DEFAULT_OUT = Path(__file__).parent / "results" / "sweep_dask.json"


def canonical_results(out_dir: Path) -> tuple[dict[str, Any], float]:
    """results.json without its wall time and worker count, and that wall time [s]."""
    results = json.loads((out_dir / RESULTS).read_text())
    wall = float(results["meta"].pop("wall_time_s"))
    results["meta"].pop("workers")
    return results, wall


def differences(a: Any, b: Any, path: str = "") -> list[str]:
    """JSON paths where `a` and `b` differ (NaN equal to NaN)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{path}/{k}: only in one" for k in a.keys() ^ b.keys()]
        for k in a.keys() & b.keys():
            out += differences(a[k], b[k], f"{path}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        pairs = enumerate(zip(a, b, strict=True))
        return [d for i, (x, y) in pairs for d in differences(x, y, f"{path}[{i}]")]
    same = json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)
    return [] if same else [path]


def one_bench(tmp: Path, workers: int, scheduler: str | None) -> dict[str, Any]:
    """One quick bench; its results (canonical), wall times [s] and the load around it."""
    name = f"{scheduler or 'pool'}-{workers}"
    load = os.getloadavg()[0]
    start = time.perf_counter()
    run_bench(tmp / name, quick=True, workers=workers, scheduler=scheduler)
    call = time.perf_counter() - start
    results, wall = canonical_results(tmp / name)
    return {
        "name": name,
        "results": results,
        "bench_wall_time_s": wall,
        "call_wall_time_s": call,
        "load_average_1min_before": load,
        "load_average_1min_after": os.getloadavg()[0],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    parser.add_argument("--local", action="store_true", help="also the local process pool")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    counts = [int(n) for n in args.workers.split(",")]
    if min(counts) < 1:
        parser.error("--workers: counts must be >= 1")
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in counts:
            runs.append(one_bench(Path(tmp), n, LOCAL_SCHEDULER))
        if args.local:
            for n in counts:
                runs.append(one_bench(Path(tmp), n, None))
    first = runs[0]
    table = first["results"]["headline"]["table"]
    result = {
        "quick": True,
        "cpu_count": os.cpu_count(),
        "n_suite_runs": sum(c["n"] for row in table.values() for c in row.values()),
        "benches": [
            {
                **{k: v for k, v in r.items() if k != "results"},
                "speedup_over_first": first["bench_wall_time_s"] / r["bench_wall_time_s"],
                "differences_from_first": differences(first["results"], r["results"]),
            }
            for r in runs
        ],
    }
    result["identical_results_json_except_wall_time_and_workers"] = not any(
        b["differences_from_first"] for b in result["benches"]
    )
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
