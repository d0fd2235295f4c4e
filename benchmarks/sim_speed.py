"""Simulation speed per embodiment: MuJoCo's share of a run, real-time factors, env steps/s.

    python benchmarks/sim_speed.py [--repeats 5] [--robots hook-hand,jaco]
        [--parts overhead,realtime,env,build] [--out benchmarks/results/sim_speed.json]
    python benchmarks/sim_speed.py --trees NAME=SRC,NAME=SRC [--rounds 3] [--repeats 1]
        [--robots hook-hand,jaco] [--out ...]

Three measurements per embodiment, each a median over `--repeats` in this one run (the
machine may be shared: compare ratios from one run, never a lone absolute time; the 1-minute
load average before and after is recorded):

- `overhead`: the paper's conditions (bench/sweep.py `PAPER_OFFSETS`: the five tasks, the
  drawer at both signs) with controller "policy" (the default policy, loaded once, as a
  sweep's worker does), each a whole `control.simulate.run` (model build, grasp, episode); the
  wall time of the run over the wall time spent inside MuJoCo's `mj_step` and `mj_forward`
  during it (timed around each call). 1.0 would be MuJoCo's own
  speed; the rest is Python: the simulated robot, the executor, the controller. Per task the
  median over its conditions and repeats, per embodiment the median over the five tasks.
- `realtime`: one 30-control-step episode per task from 10 deg off, success and the force
  limit out of reach so that every episode runs all 30 steps, the executor's two quasi-static
  guards (the start-of-run self-check and the arm-deflection stop) off so the lagging arm is
  not stopped; the 30 control periods' robot time (3 s) over CPU time of this process (one
  core, the policy loaded once), twice: over the control periods alone (`Executor.run`: the
  policy, the executor and the simulated robot from the first command to the last; the
  control real-time factor) and over the whole episode (model build and grasp included).
- `env`: the Gymnasium task env (envs/task.py: `constraint_aware/<Task>-v0`), one episode per
  task and repeat, the action keeping the current direction: env steps per second of wall
  time, over `step` calls only and over whole episodes (`reset` included).
- `build`: what a run spends before its grasp, per task, in CPU time of this process:
  constructing the embodiment with the compiled-model cache emptied (the model compiled) and
  with it filled (a sweep's runs of the same task configuration), and a new `MjData` on the
  model.
- `suite` (only when asked for, and by `--trees`): a fixed set of runs, the randomized
  suite's first `SUITE_SEEDS` seeds per task with controllers policy, classical and
  projection (bench.sweep.suite_specs) and the paper's conditions with controller "policy",
  each a whole `control.simulate.run`: the CPU time of this process for the whole set, once
  cold (this process's first: the models compiled, the Jaco's grasps solved) and then warm
  (the median over `--repeats`), and each run's outcome, step count, peak and mean |F|.

With `--trees`, the `suite` measurement of several source trees (e.g. a checkout of main and
this tree's src), each in its own subprocess with `PYTHONPATH` set to the tree, interleaved
round by round (`--rounds`) so that a shared machine's load falls on every tree alike: per
tree and embodiment the median over rounds of the cold and warm CPU time, their ratios to the
first tree's, and whether every run's outcome, step count, peak and mean |F| equal the first
tree's (the largest difference of the forces).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco

import constraint_aware  # noqa: F401  (registers the Gymnasium envs)
import constraint_aware.control.executor as executor_module
import constraint_aware.control.guards as guards_module
from constraint_aware.bench.provenance import run_trees, trees_from_args, write_results
from constraint_aware.bench.sweep import PAPER_OFFSETS, suite_specs
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.envs import task_env_id
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.robot_adapter import CONTROL_PERIOD
from constraint_aware.sim.tasks import TASKS

STEPS = 30
DEFAULT_OUT = Path(__file__).parent / "results" / "sim_speed.json"
QUASI_STATIC_GUARDS_OFF: dict[str, object] = {"self_check__steps": 0}  # and the arm-force one
PARTS = ("overhead", "realtime", "env", "build")  # the default; `suite` when asked for
SUITE_SEEDS = 3
SUITE_CONTROLLERS = ("policy", "classical", "projection")


class MujocoClock:
    """Wall time [s] spent inside `mujoco.mj_step` and `mujoco.mj_forward` (`seconds`) and
    inside `Executor.step` (`executor_seconds`), timed around each call while installed (every
    module calls them as `mujoco.mj_step(...)`)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.executor_seconds = 0.0
        self._step: Callable[..., None] = mujoco.mj_step
        self._forward: Callable[..., None] = mujoco.mj_forward
        self._executor_step = executor_module.Executor.step

    def __enter__(self) -> MujocoClock:
        step, forward, executor_step = self._step, self._forward, self._executor_step

        def timed_step(m: mujoco.MjModel, d: mujoco.MjData, nstep: int = 1) -> None:
            start = time.perf_counter()
            step(m, d, nstep)
            self.seconds += time.perf_counter() - start

        def timed_forward(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            start = time.perf_counter()
            forward(m, d)
            self.seconds += time.perf_counter() - start

        def timed_executor_step(executor: Any, *args: Any) -> Any:
            start = time.perf_counter()
            try:
                return executor_step(executor, *args)
            finally:
                self.executor_seconds += time.perf_counter() - start

        mujoco.mj_step, mujoco.mj_forward = timed_step, timed_forward
        executor_module.Executor.step = timed_executor_step  # type: ignore[method-assign,assignment]
        return self

    def __exit__(self, *exc: object) -> None:
        mujoco.mj_step, mujoco.mj_forward = self._step, self._forward
        executor_module.Executor.step = self._executor_step  # type: ignore[method-assign]


def overhead(robot: str, repeats: int) -> dict[str, Any]:
    """Whole runs of the paper's conditions: wall time over MuJoCo's time (module docstring)."""
    policy = ConstraintAwarePolicy.load()
    per_task: dict[str, Any] = {}
    for task, offsets in PAPER_OFFSETS.items():
        ratios, own, walls = [], [], []
        for offset in offsets:
            spec = RunSpec(task=task, controller="policy", offset_deg=offset, robot=robot)
            run(spec, policy=policy)  # warm: this process's caches (models, the arm's grasp)
            for _ in range(repeats):
                with MujocoClock() as clock:
                    start = time.perf_counter()
                    record, _ = run(spec, policy=policy)
                    wall = time.perf_counter() - start
                ratios.append(wall / clock.seconds)
                own.append((wall - clock.executor_seconds) / clock.seconds)
                walls.append(wall)
        per_task[task] = {
            "overhead_ratio_median": statistics.median(ratios),
            "overhead_ratio_without_executor_step_median": statistics.median(own),
            "run_wall_s_median": statistics.median(walls),
            "outcome": record.outcome,
        }
    return {
        "per_task": per_task,
        **{
            key: statistics.median(v[key] for v in per_task.values())
            for key in ("overhead_ratio_median", "overhead_ratio_without_executor_step_median")
        },
    }


def episode(task: str, robot: str, policy: ConstraintAwarePolicy) -> dict[str, float]:
    """One 30-step episode: its CPU and wall time [s] and its simulated time [s]."""
    overrides = (("max_steps", STEPS), ("success_progress", 1e9), ("force_limit", 1e9))
    spec = RunSpec(task=task, offset_deg=10.0, overrides=overrides, robot=robot)
    control_cpu: list[float] = []
    executor_run = executor_module.Executor.run

    def timed_run(executor: Any, *args: Any, **kwargs: Any) -> Any:
        start = time.process_time()
        try:
            return executor_run(executor, *args, **kwargs)
        finally:
            control_cpu.append(time.process_time() - start)

    executor_module.Executor.run = timed_run  # type: ignore[method-assign,assignment]
    try:
        wall, cpu = time.perf_counter(), time.process_time()
        record, sim = run(spec, policy=policy, executor_overrides=QUASI_STATIC_GUARDS_OFF)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    finally:
        executor_module.Executor.run = executor_run  # type: ignore[method-assign]
    moves = len(record.steps) - 1  # the first record is the hold before the first move
    if moves < STEPS:
        raise RuntimeError(f"{robot} {task}: {record.outcome} after {moves} steps")
    return {
        "cpu_s": cpu,
        "control_cpu_s": sum(control_cpu),
        "wall_s": wall,
        "simulated_s": float(sim.data.time),
    }


def realtime(robot: str, repeats: int) -> dict[str, Any]:
    """The control real-time factor on one core (module docstring)."""
    policy = ConstraintAwarePolicy.load()
    guard = guards_module.ARM_FORCE_DISAGREEMENT_STEPS
    guards_module.ARM_FORCE_DISAGREEMENT_STEPS = math.inf
    try:
        per_task: dict[str, dict[str, float]] = {}
        for task in TASKS:
            episode(task, robot, policy)  # warm: model compile, IK and tracking-time caches
            runs = [episode(task, robot, policy) for _ in range(repeats)]
            cpu = statistics.median(r["cpu_s"] for r in runs)
            control_cpu = statistics.median(r["control_cpu_s"] for r in runs)
            simulated = statistics.median(r["simulated_s"] for r in runs)
            per_task[task] = {
                "cpu_s_median": cpu,
                "control_cpu_s_median": control_cpu,
                "wall_s_median": statistics.median(r["wall_s"] for r in runs),
                "simulated_s": simulated,
                "control_real_time_factor_cpu": STEPS * CONTROL_PERIOD / control_cpu,
                "episode_real_time_factor_cpu": STEPS * CONTROL_PERIOD / cpu,
                "simulated_real_time_factor_cpu": simulated / cpu,
            }
    finally:
        guards_module.ARM_FORCE_DISAGREEMENT_STEPS = guard
    factors = [v["control_real_time_factor_cpu"] for v in per_task.values()]
    episode_factors = [v["episode_real_time_factor_cpu"] for v in per_task.values()]
    return {
        "per_task": per_task,
        "control_real_time_factor_cpu_median": statistics.median(factors),
        "control_real_time_factor_cpu_min": min(factors),
        "episode_real_time_factor_cpu_median": statistics.median(episode_factors),
        "episode_cpu_s_median": statistics.median(v["cpu_s_median"] for v in per_task.values()),
    }


def env_speed(robot: str, repeats: int) -> dict[str, Any]:
    """Gymnasium task env steps per second (module docstring)."""
    per_task: dict[str, dict[str, float]] = {}
    for task in TASKS:
        env = gym.make(task_env_id(task), robot=robot, offset_deg=15.0)
        step_rates, episode_rates = [], []
        for seed in range(repeats + 1):  # the first episode warms the caches
            start = time.perf_counter()
            obs, _ = env.reset(seed=seed)
            stepping, steps, done = 0.0, 0, False
            while not done:
                t = time.perf_counter()
                obs, _, terminated, truncated, _ = env.step(obs["direction"])
                stepping += time.perf_counter() - t
                steps += 1
                done = terminated or truncated
            if seed > 0:
                step_rates.append(steps / stepping)
                episode_rates.append(steps / (time.perf_counter() - start))
        env.close()
        per_task[task] = {
            "steps_per_s_median": statistics.median(step_rates),
            "steps_per_s_with_reset_median": statistics.median(episode_rates),
        }
    return {
        "per_task": per_task,
        "steps_per_s_median": statistics.median(v["steps_per_s_median"] for v in per_task.values()),
    }


def build(robot: str, repeats: int) -> dict[str, Any]:
    """Embodiment construction with and without the model cache, and MjData (docstring)."""
    from constraint_aware.sim import jaco, world
    from constraint_aware.sim.embodiment import make_embodiment
    from constraint_aware.sim.tasks import task_config

    caches = [
        cache
        for cache in (getattr(world, "build_model", None), getattr(jaco, "_compiled", None))
        if hasattr(cache, "cache_clear")
    ]

    def seconds(fn: Callable[[], object]) -> float:
        """Median CPU time [s] of one call."""
        times = []
        for _ in range(max(repeats, 3)):
            start = time.process_time()
            fn()
            times.append(time.process_time() - start)
        return statistics.median(times)

    def cold(task: str) -> object:
        for cache in caches:
            cache.cache_clear()  # type: ignore[union-attr]
        return make_embodiment(robot, task_config(task))

    def warm(task: str) -> object:
        return make_embodiment(robot, task_config(task))

    per_task = {}
    for task in TASKS:
        model = make_embodiment(robot, task_config(task)).model  # warm everything else
        per_task[task] = {
            "construct_cold_cpu_ms": 1e3 * seconds(functools.partial(cold, task)),
            "construct_warm_cpu_ms": 1e3 * seconds(functools.partial(warm, task)),
            "mjdata_cpu_ms": 1e3 * seconds(functools.partial(mujoco.MjData, model)),
        }
    return {
        "per_task": per_task,
        "model_cache": bool(caches),
        **{
            key + "_median": statistics.median(v[key] for v in per_task.values())
            for key in ("construct_cold_cpu_ms", "construct_warm_cpu_ms", "mjdata_cpu_ms")
        },
    }


def suite(robot: str, repeats: int) -> dict[str, Any]:
    """The fixed set of runs (module docstring): CPU time [s] cold and warm, and each run's
    outcome, step count, peak and mean |F| [N]."""
    policy = ConstraintAwarePolicy.load()
    specs = [
        dataclasses.replace(spec, robot=robot)
        for spec in suite_specs(SUITE_SEEDS, SUITE_CONTROLLERS)
    ]
    specs += [
        RunSpec(task=task, controller="policy", offset_deg=offset, robot=robot)
        for task, offsets in PAPER_OFFSETS.items()
        for offset in offsets
    ]

    def all_runs() -> tuple[float, dict[str, list[Any]]]:
        records: dict[str, list[Any]] = {}
        start = time.process_time()
        for spec in specs:
            record, _ = run(spec, policy=policy)
            forces = [s.force_norm for s in record.steps if math.isfinite(s.force_norm)]
            key = f"{spec.task} {spec.controller} {spec.offset_deg:+.6f} seed {spec.seed}"
            records[key] = [
                record.outcome,
                len(record.steps),
                max(forces, default=math.nan),
                sum(forces) / len(forces) if forces else math.nan,
            ]
        return time.process_time() - start, records

    cold, records = all_runs()
    warm = [all_runs()[0] for _ in range(repeats)]
    warm_cpu = statistics.median(warm)
    return {"runs": len(specs), "cold_cpu_s": cold, "warm_cpu_s": warm_cpu, "records": records}


MEASURES: dict[str, Callable[[str, int], dict[str, Any]]] = {
    "overhead": overhead,
    "realtime": realtime,
    "env": env_speed,
    "build": build,
    "suite": suite,
}


def compare_trees(
    trees: dict[str, str], rounds: int, repeats: int, robots: list[str]
) -> dict[str, Any]:
    """The `suite` measurement of each source tree in `trees` (name -> src directory) in a
    subprocess, interleaved over `rounds` (module docstring)."""
    arguments = ["--parts", "suite", "--repeats", str(repeats), "--robots", ",".join(robots)]
    results = run_trees(__file__, arguments, trees, rounds)
    first = next(iter(trees))
    table: dict[str, Any] = {}
    for robot in robots:
        base = results[first][0][robot]["suite"]["records"]
        rows: dict[str, Any] = {}
        for name, outs in results.items():
            entries = [o[robot]["suite"] for o in outs]
            records = [e["records"] for e in entries]
            force_gap = max(
                (abs(r[k][i] - base[k][i]) for r in records for k in base for i in (2, 3)),
                default=0.0,
            )
            rows[name] = {
                "src": trees[name],
                "cold_cpu_s": statistics.median(e["cold_cpu_s"] for e in entries),
                "warm_cpu_s": statistics.median(e["warm_cpu_s"] for e in entries),
                "outcomes_and_steps_equal_to_first": all(
                    r[k][:2] == base[k][:2] for r in records for k in base
                ),
                "records_equal_to_first": all(r == base for r in records),
                "largest_force_difference_N": force_gap,
                "load_average_1min": [o["load_average_1min_at_start"] for o in outs],
            }
        for row in rows.values():
            for key in ("cold_cpu_s", "warm_cpu_s"):
                row[key.replace("_s", "_over_first")] = row[key] / rows[first][key]
        table[robot] = rows
    return {"rounds": rounds, "repeats": repeats, "runs": table}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--robots", default="hook-hand,jaco")
    parser.add_argument("--parts", default=",".join(PARTS))
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--trees", help="NAME=SRC,NAME=SRC: compare source trees (suite)")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    parts = args.parts.split(",")
    if unknown := set(parts) - set(MEASURES):
        parser.error(f"--parts: unknown {sorted(unknown)}; valid: {', '.join(MEASURES)}")
    robots = args.robots.split(",")
    if trees := trees_from_args(parser, args):
        compared = compare_trees(trees, args.rounds, args.repeats, robots)
        write_results(args.out, compared)
        print(json.dumps(compared, indent=1))
        return
    out: dict[str, Any] = {
        "load_average_1min_at_start": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "episode_steps": STEPS,
        "control_period_s": CONTROL_PERIOD,
        "controller": "policy",
        "repeats": args.repeats,
    }
    for robot in robots:
        out[robot] = {part: MEASURES[part](robot, args.repeats) for part in parts}
    out["load_average_1min_at_end"] = os.getloadavg()[0]
    write_results(args.out, out)
    for robot in robots:
        entry = out[robot]
        print(
            robot,
            {
                "overhead_ratio": entry.get("overhead", {}).get("overhead_ratio_median"),
                "without_executor_step": entry.get("overhead", {}).get(
                    "overhead_ratio_without_executor_step_median"
                ),
                "control_real_time_factor_cpu": entry.get("realtime", {}).get(
                    "control_real_time_factor_cpu_median"
                ),
                "episode_real_time_factor_cpu": entry.get("realtime", {}).get(
                    "episode_real_time_factor_cpu_median"
                ),
                "env_steps_per_s": entry.get("env", {}).get("steps_per_s_median"),
            },
        )


if __name__ == "__main__":
    main()
