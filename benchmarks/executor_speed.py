"""The executor's cost per control period: one `Executor.step` with the default controller.

    python benchmarks/executor_speed.py [--repeats 5] [--robot hook-hand] [--top 25]
        [--out benchmarks/results/executor_speed.json]
    python benchmarks/executor_speed.py --trees NAME=SRC,NAME=SRC [--rounds 3] [--repeats 1]
        [--out ...]

Each of the paper's conditions (bench/sweep.py `PAPER_OFFSETS`: the five tasks, the drawer at
both signs) is run `--repeats` times with controller "policy" (the shipped default policy),
step by step as `Executor.run` does. Only `Executor.step(wrench, pose)` is timed: the
simulator advances and the wrench and pose are read outside the timed call, and the task
monitor the executor consults is a snapshot taken after each period (`SnapshotMonitor`: the
same values, read from memory), so the figure is the executor's own (guards, controller,
policy, record). Reported over every step of every run: the median and the 99th percentile of
the wall time and of this process's CPU time, beside the median CPU time of the network's own
forward pass (`ConstraintAwarePolicy.act_batch` on one observation; `act` adds input
validation) and their ratio; the 1-minute load average; and where the time goes: a cProfile of
one more pass over the conditions (not timed), the `--top` functions by own time with their
share of the steps' total.

With `--trees`, the same measurement of several source trees (e.g. a checkout of main and
this tree's src), each in its own subprocess with `PYTHONPATH` set to the tree, interleaved
round by round (`--rounds`) so that a shared machine's load falls on every tree alike; per
tree the median over rounds of the step's median and 99th percentile CPU time and of the
forward pass, and the ratio of each tree's step median to the first tree's.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import os
import pstats
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.provenance import run_trees, trees_from_args, write_results
from constraint_aware.bench.sweep import PAPER_OFFSETS
from constraint_aware.control.controllers import make_controller
from constraint_aware.control.executor import Executor
from constraint_aware.control.record import RunRecord
from constraint_aware.control.simulate import (
    RunSpec,
    controller_geometry,
    executor_config,
    grasped,
)
from constraint_aware.geometry import FloatArray, rotate_about
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import Embodiment

DEFAULT_OUT = Path(__file__).parent / "results" / "executor_speed.json"


class SnapshotMonitor:
    """The task monitor's answers for the simulator's current state, computed by `refresh`
    (outside the timed step) and handed out from memory."""

    def __init__(self, sim: Embodiment) -> None:
        self.sim = sim
        self.refresh()

    def refresh(self) -> None:
        sim = self.sim
        self._direction = sim.admissible_direction()
        self._progress = sim.progress()
        self._succeeded = sim.succeeded()
        self._failure = sim.grasp_failure()
        self._slip = sim.slip()
        self._handle = sim.handle_position()

    def admissible_direction(self) -> FloatArray:
        return self._direction.copy()

    def progress(self) -> float:
        return self._progress

    def succeeded(self) -> bool:
        return self._succeeded

    def grasp_failure(self) -> str | None:
        return self._failure

    def slip(self) -> tuple[float, float]:
        return self._slip

    def handle_position(self) -> FloatArray:
        return self._handle.copy()


def timed_run(
    spec: RunSpec, policy: ConstraintAwarePolicy, profile: cProfile.Profile | None = None
) -> tuple[RunRecord, list[int], list[int]]:
    """One run as `control.simulate.run` sets it up; the wall and CPU time [ns] of each
    `Executor.step`, or none: the steps profiled into `profile` if given."""
    task, sim = grasped(spec)
    cfg = executor_config(task)
    assert cfg.workplane_normal is not None
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    d0 = rotate_about(sim.admissible_direction(), normal, math.radians(spec.offset_deg))
    normal, rate = controller_geometry(cfg, sim, d0)
    controller = make_controller(spec.controller, policy, rate, normal, {})
    monitor = SnapshotMonitor(sim)
    executor = Executor(sim, controller, cfg, monitor=monitor)
    executor.start(d0, {"task": spec.task})
    walls, cpus = [], []
    while True:
        wrench, pose = sim.read_wrench(), sim.read_pose()
        if profile is not None:  # profiled runs are not timed
            out = profile.runcall(executor.step, wrench, pose)
        else:
            wall, cpu = time.perf_counter_ns(), time.process_time_ns()
            out = executor.step(wrench, pose)
            cpu, wall = time.process_time_ns() - cpu, time.perf_counter_ns() - wall
            walls.append(wall)
            cpus.append(cpu)
        if isinstance(out, RunRecord):
            return out, walls, cpus
        sim.command_pose(out)
        sim.advance()
        monitor.refresh()


def forward_pass_us(policy: ConstraintAwarePolicy, calls: int = 2000) -> dict[str, float]:
    """Median CPU time [us] of the network's forward pass on one observation, and of `act`
    (which validates its inputs first), over 7 batches of `calls`."""
    n_in = len(policy.observation_layout)
    obs = np.zeros((1, n_in))
    obs[0, 0], obs[0, 3] = 1.0, 1.0
    extra = [0.0] * (n_in - 6)

    def batch(fn: Any) -> float:
        times = []
        for _ in range(7):
            start = time.process_time_ns()
            for _ in range(calls):
                fn()
            times.append((time.process_time_ns() - start) / calls / 1e3)
        return statistics.median(times)

    return {
        "act_batch_us_median": batch(lambda: policy.act_batch(obs)),
        "act_us_median": batch(lambda: policy.act(obs[0, :3], obs[0, 3:6], *extra)),
    }


def profile_table(profile: cProfile.Profile, top: int) -> list[dict[str, Any]]:
    """The `top` functions by own time: calls, own and cumulative time [ms], own share."""
    stats = pstats.Stats(profile)
    entries = stats.stats  # type: ignore[attr-defined]
    total = sum(v[2] for v in entries.values())
    rows = sorted(entries.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    return [
        {
            "function": f"{Path(file).name}:{line}({name})",
            "calls": int(v[1]),
            "own_ms": 1e3 * v[2],
            "cumulative_ms": 1e3 * v[3],
            "own_share": v[2] / total,
        }
        for (file, line, name), v in rows
    ]


def compare_trees(trees: dict[str, str], rounds: int, repeats: int, robot: str) -> dict[str, Any]:
    """The measurement of each source tree in `trees` (name -> src directory) in a subprocess,
    interleaved over `rounds` (module docstring)."""
    arguments = ["--repeats", str(repeats), "--robot", robot]
    runs = run_trees(__file__, arguments, trees, rounds)
    keys = ("step_cpu_us_median", "step_cpu_us_p99", "act_batch_us_median")
    first = next(iter(trees))
    table: dict[str, Any] = {
        name: {
            "src": trees[name],
            **{k: statistics.median(r[k] for r in rows) for k in keys},
            "load_average_1min": [r["load_average_1min_at_start"] for r in rows],
        }
        for name, rows in runs.items()
    }
    for row in table.values():
        row["step_median_over_first"] = (
            row["step_cpu_us_median"] / table[first]["step_cpu_us_median"]
        )
    return {"robot": robot, "rounds": rounds, "repeats": repeats, "trees": table}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--robot", default="hook-hand")
    parser.add_argument("--top", type=int, default=25)
    parser.add_argument("--trees", help="NAME=SRC,NAME=SRC: compare source trees")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    if trees := trees_from_args(parser, args):
        compared = compare_trees(trees, args.rounds, args.repeats, args.robot)
        write_results(args.out, compared)
        print(json.dumps(compared, indent=1))
        return
    load_start = os.getloadavg()[0]
    policy = ConstraintAwarePolicy.load()
    specs = [
        RunSpec(task=task, controller="policy", offset_deg=offset, robot=args.robot)
        for task, offsets in PAPER_OFFSETS.items()
        for offset in offsets
    ]
    profile = cProfile.Profile()
    for spec in specs:  # also warms the model caches and the policy
        timed_run(spec, policy, profile)
    walls: list[int] = []
    cpus: list[int] = []
    per_condition: dict[str, Any] = {}
    for _ in range(args.repeats):
        for spec in specs:
            record, wall, cpu = timed_run(spec, policy)
            walls += wall
            cpus += cpu
            key = f"{spec.task} {spec.offset_deg:+g}"
            entry = per_condition.setdefault(key, {"outcome": record.outcome, "cpu_us": []})
            entry["cpu_us"] += [c / 1e3 for c in cpu]
    for entry in per_condition.values():
        entry["steps_per_run"] = len(entry["cpu_us"]) // args.repeats
        entry["cpu_us_median"] = statistics.median(entry.pop("cpu_us"))
    forward = forward_pass_us(policy)
    wall_us, cpu_us = np.array(walls) / 1e3, np.array(cpus) / 1e3
    step_median = float(np.median(cpu_us))
    result = {
        "robot": args.robot,
        "controller": "policy",
        "policy": policy.name,
        "repeats": args.repeats,
        "n_steps": len(walls),
        "step_wall_us_median": float(np.median(wall_us)),
        "step_wall_us_p99": float(np.percentile(wall_us, 99)),
        "step_cpu_us_median": step_median,
        "step_cpu_us_p99": float(np.percentile(cpu_us, 99)),
        **forward,
        "step_over_forward_pass": step_median / forward["act_batch_us_median"],
        "per_condition": per_condition,
        "profile_top_own_time": profile_table(profile, args.top),
        "load_average_1min_at_start": load_start,
        "load_average_1min_at_end": os.getloadavg()[0],
    }
    write_results(args.out, result)
    brief = {k: v for k, v in result.items() if k not in ("per_condition", "profile_top_own_time")}
    print(brief)
    for row in result["profile_top_own_time"]:
        print(f"{row['own_share']:6.1%} {row['calls']:7d} {row['function']}")


if __name__ == "__main__":
    main()
