"""`cap bench --quick` on a local Dask cluster of 1 and 2 workers (and the local pool): speedup.

    python benchmarks/sweep_dask.py [--workers 1,2] [--rounds 3] [--local]
        [--out benchmarks/results/sweep_dask.json]

For each n in `--workers`: a `distributed.LocalCluster` of n single-threaded worker
processes without a dashboard (as `cap bench --scheduler local --workers n` starts) and
`run_bench(quick=True, scheduler=<its address>)`, one after the other, each bench in a fresh
Python process (as a `cap bench` run is), into temporary directories; with `--local` the same
on the local process pool (`workers=n`, no scheduler). The whole set is repeated `--rounds`
times, every other round in reverse order, because this machine's speed drifts by tens of
percent within minutes: a speedup is a ratio of two benches of one round, and the figure is
the median over rounds. Reports each bench's wall time (from results.json), the CPU time of
this process and of each Dask worker during the bench, the speedup of every bench over its
round's first kind measured two ways: by wall time (the load average is recorded, and on a
loaded machine the share of the CPUs, not their number, sets it) and by the CPU critical path
(this process's CPU time plus the busiest worker's: the wall time on otherwise idle cores,
each worker on its own); and whether every results.json is the first one's except for the
wall times and the worker count (text of the canonical JSON, so NaN compares equal to NaN;
where not, the differing paths). On the local cluster the rendering sections are the
workers' tasks (their CPU is in the workers'); on the local pool they run in a side process,
whose CPU is in the children's.

With `--scaling`, also the machine's own ceiling for the sweeps: the full bench's suite runs
(`experiments.headline_specs`, 400 runs) on a process pool of 1 and then 2 workers, nothing
else of the bench: wall time, the runs' summed CPU time, and the speedup. A speedup below 2 with the
summed CPU time grown by the same factor means each run is slower while both cores work (the
cores share caches and memory bandwidth), which no scheduling recovers.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import resource
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from distributed import Client, LocalCluster

from constraint_aware.bench.experiments import BenchConfig, headline_specs
from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.run import RESULTS, run_bench
from constraint_aware.bench.sweep import _run_one
from constraint_aware.sim.embodiment import DEFAULT_ROBOT

DEFAULT_OUT = Path(__file__).parent / "results" / "sweep_dask.json"


def canonical_results(out_dir: Path) -> tuple[dict[str, Any], float]:
    """results.json without its wall times (the bench's and its sections'), worker count and
    provenance (date and load average), and the bench's wall time [s]."""
    results = json.loads((out_dir / RESULTS).read_text())
    wall = float(results["meta"].pop("wall_time_s"))
    results["meta"].pop("workers")
    results["meta"].pop("section_seconds", None)
    results.pop("provenance", None)

    def drop_wall_times(node: Any) -> None:
        if isinstance(node, dict):
            node.pop("wall_time_s", None)
            node.pop("wall_time_s_median", None)
            for value in node.values():
                drop_wall_times(value)
        elif isinstance(node, list):
            for value in node:
                drop_wall_times(value)

    drop_wall_times(results)
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


def one_bench(tmp: Path, workers: int, dask: bool) -> dict[str, Any]:
    """One quick bench; its results (canonical), wall and CPU times [s], the load around it."""
    name = f"{'dask' if dask else 'pool'}-{workers}"
    entry: dict[str, Any] = {"name": name, "load_average_1min_before": os.getloadavg()[0]}
    if dask:
        with (
            LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            client.wait_for_workers(workers)
            before = client.run(time.process_time)
            cpu = time.process_time()
            children = resource.getrusage(resource.RUSAGE_CHILDREN)
            run_bench(tmp / name, quick=True, scheduler=cluster.scheduler_address)
            entry["main_cpu_s"] = time.process_time() - cpu
            done = resource.getrusage(resource.RUSAGE_CHILDREN)  # a side process, if any
            entry["side_process_cpu_s"] = (
                done.ru_utime + done.ru_stime - children.ru_utime - children.ru_stime
            )
            after = client.run(time.process_time)
        entry["worker_cpu_s"] = sorted(after[w] - before[w] for w in after)
    else:
        cpu = time.process_time()
        children = resource.getrusage(resource.RUSAGE_CHILDREN)
        run_bench(tmp / name, quick=True, workers=workers)  # pool and side process: children
        entry["main_cpu_s"] = time.process_time() - cpu
        done = resource.getrusage(resource.RUSAGE_CHILDREN)
        entry["workers_total_cpu_s"] = (
            done.ru_utime + done.ru_stime - children.ru_utime - children.ru_stime
        )
    entry["results"], entry["bench_wall_time_s"] = canonical_results(tmp / name)
    entry["load_average_1min_after"] = os.getloadavg()[0]
    if dask:
        entry["cpu_critical_path_s"] = entry["main_cpu_s"] + max(entry["worker_cpu_s"])
    return entry


def _quiet() -> None:
    logging.disable(logging.WARNING)  # the runs' missing-input lines, once per run


def _timed_run(spec: Any) -> float:
    """One run's CPU time [s] in the worker that ran it (as the bench runs it)."""
    start = time.process_time()
    _run_one((spec, False, None))
    return time.process_time() - start


def sweep_scaling(counts: list[int]) -> list[dict[str, Any]]:
    """The full bench's suite runs alone on a process pool of each worker count."""
    specs = headline_specs(BenchConfig.for_mode(False, None, DEFAULT_ROBOT))
    out = []
    for n in counts:
        with ProcessPoolExecutor(max_workers=n, initializer=_quiet) as pool:
            list(pool.map(_timed_run, specs[: 2 * n]))  # warm: the workers' model caches
            start = time.perf_counter()
            cpu = list(pool.map(_timed_run, specs))
            wall = time.perf_counter() - start
        out.append({"workers": n, "runs": len(specs), "wall_s": wall, "runs_cpu_s_total": sum(cpu)})
    for entry in out:
        entry["speedup_over_first"] = out[0]["wall_s"] / entry["wall_s"]
        entry["runs_cpu_over_first"] = entry["runs_cpu_s_total"] / out[0]["runs_cpu_s_total"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", default="1,2", help="worker counts, comma-separated")
    parser.add_argument("--local", action="store_true", help="also the local process pool")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--rounds", type=int, default=3, help="repeats, interleaved (>= 1)")
    parser.add_argument("--scaling", action="store_true", help="also the sweeps alone")
    parser.add_argument("--single", help=argparse.SUPPRESS)  # the subprocess: "dask-2", ...
    args = parser.parse_args()
    if args.single is not None:
        kind, n = args.single.split("-")
        entry = one_bench(args.out.parent, int(n), dask=kind == "dask")
        args.out.write_text(json.dumps(entry))
        return
    counts = [int(n) for n in args.workers.split(",")]
    if min(counts) < 1:
        parser.error("--workers: counts must be >= 1")
    if args.rounds < 1:
        parser.error(f"--rounds: must be >= 1, got {args.rounds}")
    names = [f"dask-{n}" for n in counts] + ([f"pool-{n}" for n in counts] if args.local else [])
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.rounds):
            for name in names if i % 2 == 0 else names[::-1]:
                out = Path(tmp) / f"{name}-{i}.json"
                cmd = [sys.executable, __file__, "--single", name, "--out", str(out)]
                subprocess.run(cmd, check=True)
                runs.append({"round": i, **json.loads(out.read_text())})
    first = runs[0]
    table = first["results"]["headline"]["table"]

    def base(r: dict[str, Any]) -> dict[str, Any]:
        """The bench of the first kind in `r`'s round."""
        return next(b for b in runs if b["round"] == r["round"] and b["name"] == names[0])

    benches = [
        {
            **{k: v for k, v in r.items() if k != "results"},
            "speedup_over_first": base(r)["bench_wall_time_s"] / r["bench_wall_time_s"],
            "cpu_critical_path_speedup_over_first": (
                base(r)["cpu_critical_path_s"] / r["cpu_critical_path_s"]
                if "cpu_critical_path_s" in r
                else None
            ),
            "differences_from_first": differences(first["results"], r["results"]),
        }
        for r in runs
    ]
    result = {
        "quick": True,
        "cpu_count": os.cpu_count(),
        "n_suite_runs": sum(c["n"] for row in table.values() for c in row.values()),
        "rounds": args.rounds,
        "speedup_median_over_rounds": {
            name: float(np.median([b["speedup_over_first"] for b in benches if b["name"] == name]))
            for name in names
        },
        "benches": benches,
    }
    result["identical_results_json_except_wall_time_and_workers"] = not any(
        b["differences_from_first"] for b in result["benches"]
    )
    if args.scaling:
        result["sweep_alone"] = sweep_scaling(counts)
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
