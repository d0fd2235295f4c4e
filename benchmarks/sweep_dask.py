"""`cap bench --quick` on a local Dask cluster against the local pool: same results.json?

    python benchmarks/sweep_dask.py [--workers 1] [--out benchmarks/results/sweep_dask.json]

Runs `run_bench(quick=True)` twice into temporary directories: once on the local process
pool, once with `scheduler=` the address of a `distributed.LocalCluster` (worker processes,
one thread each). Compares the two results.json files with the wall time removed (text of the
canonical JSON, so NaN compares equal to NaN) and reports where they differ, and both wall
times with their ratio (one run each, the same machine, one after the other).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

from distributed import LocalCluster

from constraint_aware.bench.run import RESULTS, run_bench


def canonical_results(out_dir: Path) -> tuple[dict[str, Any], float]:
    """results.json without its wall time, and that wall time [s]."""
    results = json.loads((out_dir / RESULTS).read_text())
    wall = float(results["meta"].pop("wall_time_s"))
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=1, help="local processes = Dask workers")
    parser.add_argument("--out", default="benchmarks/results/sweep_dask.json")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        local_dir, dask_dir = Path(tmp) / "local", Path(tmp) / "dask"
        run_bench(local_dir, quick=True, workers=args.workers)
        start = time.perf_counter()
        with LocalCluster(
            n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster:
            cluster_start_s = time.perf_counter() - start
            run_bench(dask_dir, quick=True, scheduler=cluster.scheduler_address)
        local, local_wall = canonical_results(local_dir)
        remote, dask_wall = canonical_results(dask_dir)
    diff = differences(local, remote)
    table = local["headline"]["table"]
    result = {
        "quick": True,
        "workers": args.workers,
        "identical_results_json_except_wall_time": not diff,
        "differences": diff,
        "n_suite_runs": sum(c["n"] for row in table.values() for c in row.values()),
        "local_wall_time_s": local_wall,
        "dask_wall_time_s": dask_wall,
        "dask_over_local_wall_time": dask_wall / local_wall,
        "cluster_start_s": cluster_start_s,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
