"""Many simulated runs at once: spec lists, a process pool, a progress bar, summaries."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.sim.tasks import TASKS, task_config

#: The paper's initial direction errors (sections 5.3-5.5) and the suite's ranges [deg].
PAPER_OFFSETS = {
    "drawer-opening": (30.0, -30.0),
    "plate-sliding": (-30.0,),
    "pole-pulling": (-30.0,),
    "door-opening": (15.0,),
    "handle-rotating": (15.0,),
}
SUITE_OFFSET_RANGE = {"prismatic": 30.0, "revolute": 15.0}


def suite_specs(
    n_seeds: int,
    controllers: Sequence[str],
    tasks: Iterable[str] = TASKS,
    first_seed: int = 0,
) -> list[RunSpec]:
    """Randomized suite: per task and seed, friction/mass/damping drawn (sim.tasks.randomized)
    and an offset uniform in +-30 deg (prismatic) or +-15 deg (revolute); every controller
    sees the same draws."""
    specs: list[RunSpec] = []
    for task in tasks:
        limit = SUITE_OFFSET_RANGE[task_config(task).constraint_type]
        for seed in range(first_seed, first_seed + n_seeds):
            rng = np.random.default_rng([seed, 17])
            offset = float(rng.uniform(-limit, limit))
            specs.extend(
                RunSpec(task=task, controller=c, offset_deg=offset, seed=seed, randomize=True)
                for c in controllers
            )
    return specs


def _run_one(args: tuple[RunSpec, bool]) -> dict[str, Any]:
    spec, keep_steps = args
    record, _ = run(spec)
    out: dict[str, Any] = {"spec": dataclasses.asdict(spec), "summary": record.summary()}
    if keep_steps:
        out["angles_deg"] = record.angles
        out["forces_N"] = [s.force_norm for s in record.steps]
    return out


def run_many(
    specs: Sequence[RunSpec],
    workers: int | None = None,
    keep_steps: bool = False,
    label: str = "runs",
    quiet: bool = False,
) -> list[dict[str, Any]]:
    """Run every spec (in a process pool when workers > 1); results keep the input order."""
    workers = workers or os.cpu_count() or 1
    jobs = [(s, keep_steps) for s in specs]
    results: list[dict[str, Any]] = []
    with Progress(
        TextColumn(f"[bold]{label}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        disable=quiet,
    ) as progress:
        task = progress.add_task(label, total=len(jobs))
        if workers <= 1:
            for job in jobs:
                results.append(_run_one(job))
                progress.advance(task)
        else:
            with ProcessPoolExecutor(max_workers=workers) as pool:
                for res in pool.map(_run_one, jobs, chunksize=4):
                    results.append(res)
                    progress.advance(task)
    return results


def success_table(results: Sequence[dict[str, Any]]) -> dict[str, dict[str, dict[str, Any]]]:
    """{task: {controller: {success_rate, n, peak_force_median_N, peak_force_max_N, ...}}}."""
    table: dict[str, dict[str, dict[str, Any]]] = {}
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in results:
        s = r["summary"]
        groups.setdefault((s["task"], s["controller"]), []).append(s)
    for (task, ctrl), rows in groups.items():
        peaks = np.array([x["peak_force_N"] for x in rows])
        finals = np.array([x["final_angle_deg"] for x in rows])
        table.setdefault(task, {})[ctrl] = {
            "n": len(rows),
            "success_rate": float(np.mean([x["success"] for x in rows])),
            "peak_force_median_N": float(np.median(peaks)),
            "peak_force_max_N": float(peaks.max()),
            "final_angle_median_deg": float(np.nanmedian(finals)),
            "outcomes": {o: sum(x["outcome"] == o for x in rows) for o in _outcomes(rows)},
        }
    return table


def _outcomes(rows: Sequence[dict[str, Any]]) -> list[str]:
    return sorted({x["outcome"] for x in rows})
