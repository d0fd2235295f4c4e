"""How much faster is the full `cap bench` than at the commit its time target was set against
(e189ca9: 526 s on 2 processes, target 240 s, so 2.2x), on a machine whose speed has moved
since, and with sections the bench has gained since?

    nice -n 10 python benchmarks/studies/bench_vs_baseline.py run --baseline OLD/src --now NEW/src \
        --dir DIR
    python benchmarks/studies/bench_vs_baseline.py summarize --dir DIR [--out FILE]

`run` runs, one after the other on an otherwise idle machine, each with the default 2
processes: the baseline tree's `cap bench` (DIR/baseline), the current tree's without the sections
the baseline commit did not have (DIR/same: the end-to-end section left out through the bench's
own skip list; the stage ablation, 5 s, is kept), and the current tree's whole bench
(DIR/full). Each bench writes its own results.json with its wall time and (the current tree)
its sections' seconds; `run` also writes DIR/times.json with each process's wall and CPU time.
`summarize` reads those files and writes the comparison: wall times, their ratios to the baseline
bench's, and the 526 s the baseline bench took when the target was set scaled by that ratio.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

DEFAULT_OUT = Path(__file__).parent / "results" / "bench_vs_baseline.json"
BASELINE_WALL_S = 526.0  # the baseline bench's wall time when the target was set
TARGET_WALL_S = 240.0
#: The current tree's `cap bench`, minus the sections the baseline commit did not have.
#: (Guarded: the bench's worker processes must not run it again.)
WITHOUT_NEW_SECTIONS = (
    "import sys\n"
    "if __name__ == '__main__':\n"
    "    from constraint_aware.bench import run as bench_run\n"
    "    preflight = bench_run.preflight\n"
    "    bench_run.preflight = lambda cfg: {**preflight(cfg), 'end_to_end': "
    "'left out: absent at the baseline commit'}\n"
    "    from constraint_aware.cli import main\n"
    "    sys.exit(main(sys.argv[1:]))\n"
)
BENCHES = ("baseline", "same", "full")


def _timed(command: list[str], src: str, log: Path) -> dict[str, float]:
    """Run `command` importing the tree `src`; its wall time and its CPU time (user + system,
    the process and its children) [s]."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    with log.open("w") as out:
        subprocess.run(
            command, env={**os.environ, "PYTHONPATH": src}, stdout=out, stderr=out, check=True
        )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall_s": wall, "cpu_s": cpu}


def run(baseline: str, now: str, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    cli = [sys.executable, "-m", "constraint_aware.cli"]
    without = [sys.executable, "-c", WITHOUT_NEW_SECTIONS]
    commands = {
        name: ([*start, "bench", "--force", "--out", str(folder / name)], src)
        for name, start, src in (
            ("baseline", cli, baseline),
            ("same", without, now),
            ("full", cli, now),
        )
    }
    times = {
        name: _timed(command, src, folder / f"{name}.log")
        for name, (command, src) in commands.items()
    }
    (folder / "times.json").write_text(json.dumps(times, indent=1) + "\n")


def summarize(folder: Path) -> dict[str, Any]:
    reports = {name: json.loads((folder / name / "results.json").read_text()) for name in BENCHES}
    times_file = folder / "times.json"
    times = json.loads(times_file.read_text()) if times_file.is_file() else {}
    baseline = reports["baseline"]["meta"]["wall_time_s"]
    out: dict[str, Any] = {
        "baseline_wall_s_when_set": BASELINE_WALL_S,
        "target_wall_s": TARGET_WALL_S,
    }
    for name in BENCHES:
        meta = reports[name]["meta"]
        wall = meta["wall_time_s"]
        out[name] = {
            "wall_time_s": wall,
            "baseline_over_this": baseline / wall,
            "at_the_baseline_machine_speed_s": BASELINE_WALL_S * wall / baseline,
            "section_seconds": meta.get("section_seconds"),
            "skipped": reports[name].get("skipped", {}),
            "process": times.get(name),
        }
    out["target_ratio"] = BASELINE_WALL_S / TARGET_WALL_S
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run")
    p_run.add_argument("--baseline", required=True, help="src of a checkout of e189ca9")
    p_run.add_argument("--now", required=True, help="src of the tree to measure")
    p_run.add_argument("--dir", type=Path, required=True)
    p_sum = sub.add_parser("summarize")
    p_sum.add_argument("--dir", type=Path, required=True)
    p_sum.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.command == "run":
        run(args.baseline, args.now, args.dir)
        return
    from constraint_aware.bench.provenance import write_results

    write_results(args.out, summarize(args.dir))
    print(args.out)


if __name__ == "__main__":
    main()
