"""Where a result came from: the commit, the date, the machine and the library versions.

Every results file (`cap bench`'s results.json and each script under `benchmarks/`) carries
`provenance()` under the key "provenance", so a number can always be traced to the code and
the machine that produced it. Timings are only comparable within one such record; to
compare versions of the code, `run_trees` measures each source tree in the same record,
interleaved.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata
import json
import os
import platform
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

#: The distributions whose versions a result records (absent ones are recorded as None).
LIBRARIES = (
    "constraint-aware",
    "numpy",
    "scipy",
    "mujoco",
    "gymnasium",
    "dm-control",
    "stable-baselines3",
    "torch",
    "onnxruntime",
    "dask",
)


def _git(*args: str) -> str | None:
    try:
        out = subprocess.run(
            ["git", *args],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def provenance() -> dict[str, Any]:
    """The commit (None outside a git checkout; `dirty` when the tree has local changes), the
    UTC date, the machine (CPU model and count, the 1-minute load average when it was taken)
    and the versions of `LIBRARIES`. JSON-serializable."""
    commit = _git("rev-parse", "HEAD")
    status = _git("status", "--porcelain", "--untracked-files=no")
    try:
        load = round(os.getloadavg()[0], 2)
    except OSError:
        load = None
    return {
        "commit": commit,
        "dirty": None if status is None else bool(status),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": {
            "cpu": _cpu_model(),
            "cpu_count": os.cpu_count(),
            "load_1min": load,
            "system": f"{platform.system()} {platform.release()}",
            "python": platform.python_version(),
        },
        "libraries": {name: _version(name) for name in LIBRARIES},
    }


def write_results(path: str | Path, results: dict[str, Any]) -> Path:
    """Write `results` as indented JSON to `path` with `provenance()` under "provenance"
    (replacing any there), creating the parent folder. Returns the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    rest = {key: value for key, value in results.items() if key != "provenance"}
    stamped = {"provenance": provenance(), **rest}
    out.write_text(json.dumps(stamped, indent=1) + "\n", encoding="utf-8")
    return out


def parse_trees(text: str) -> dict[str, str]:
    """`NAME=SRC,NAME=SRC` (a benchmark's --trees) as {name: src directory}, in order;
    ValueError saying the expected form otherwise."""
    pairs = [item.partition("=") for item in text.split(",")]
    if any(not name or not src for name, _, src in pairs):
        raise ValueError("--trees: expected NAME=SRC,NAME=SRC")
    return {name: src for name, _, src in pairs}


def trees_from_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict[str, str]:
    """A benchmark's `--trees` and `--rounds` checked: the trees ({} when `--trees` was not
    given); a malformed `--trees` or `--rounds` below 1 exits through `parser.error`."""
    if not args.trees:
        return {}
    if args.rounds < 1:
        parser.error("--rounds must be >= 1")
    try:
        return parse_trees(args.trees)
    except ValueError as exc:
        parser.error(str(exc))


def run_trees(
    script: str | Path, arguments: Sequence[str], trees: dict[str, str], rounds: int
) -> dict[str, list[dict[str, Any]]]:
    """`script arguments --out FILE` once per source tree and round, each in a subprocess
    importing that tree (PYTHONPATH = its src directory), the trees interleaved round by round
    so that a shared machine's load falls on each alike. Returns per tree its results (the
    JSON the script wrote), in round order."""
    results: dict[str, list[dict[str, Any]]] = {name: [] for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(rounds):
            for name, src in trees.items():
                out = Path(tmp) / f"{name}-{i}.json"
                command = [sys.executable, str(script), *arguments, "--out", str(out)]
                env = {**os.environ, "PYTHONPATH": src}
                subprocess.run(command, env=env, check=True, capture_output=True)
                results[name].append(json.loads(out.read_text()))
    return results
