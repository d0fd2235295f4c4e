"""The setup-time sensor probe (control/probe.py) on both embodiments: its verdicts under
convention faults, and what its measured stiffness does to the policy's runs.

    python benchmarks/probe.py [--seeds 20] [--workers 2] [--out benchmarks/results/probe.json]
        [--runs FILE]

Part 1, verdicts: every task, seeds 0-4 with the suite's randomized objects, on the hook hand
and the Jaco, healthy and with three faults: the wrench sign flipped, the sensor frame turned
90 deg about the workplane normal (bench/faults.py), and the robot reporting half its
stiffness; with each healthy probe's measured play. Part 2, runs: controller `policy` on the
randomized suite (bench/sweep.py, `--seeds` per task) and at the paper's offsets (sensor-noise
seeds 0-9), each run once as shipped (the step force from the robot's reported stiffness) and
once after the probe (`RunSpec.probe`: the stiffness and the grasp's play the probe measured),
with the classical controller beside them. Same seeds throughout; per cell the median peak |F|,
the median run mean |F| [N], and the run-by-run difference (probe minus shipped). Part 3,
diagnostics behind the README's explanations (seed 0): the Jaco probed with its joints'
friction feed-forward off (`OscConfig.friction_compensation = 0`); the hook hand's pole grasp
held still for 12 s, no probe (the reading and the pole's travel per second); and probing the
object and then running from that same grasp, without a re-grasp (drawer and pole suites, hook
hand), which is why `RunSpec.probe` probes a twin; and the force a grasp meets against the
push's size, 1.5-8 mm (play in the grasp, a force bias in the arm). Runs are independent,
spread over `--workers` processes. The JSON (with provenance) holds the verdicts, the cells and
the diagnostics; `--runs FILE` also writes part 2's runs one by one (not committed: ~300 KB).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.faults import FaultyRobot, Reporting
from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import PAPER_OFFSETS, suite_specs
from constraint_aware.control.simulate import RunSpec, probe, run
from constraint_aware.sim.tasks import TASKS

DEFAULT_OUT = Path(__file__).parent / "results" / "probe.json"
ROBOTS = ("hook-hand", "jaco")
FAULTS = ("none", "flipped_sign", "rotated_90", "stiffness_half")
VERDICT_SEEDS = range(5)
PAPER_SEEDS = range(10)


def half_stiffness(sim: Any) -> Reporting:
    """The simulated robot, reporting half its translational stiffness."""
    return Reporting(sim, translational_stiffness=0.5 * sim.translational_stiffness)


def verdict(job: tuple[str, str, str, int]) -> dict[str, Any]:
    robot, task, fault, seed = job
    wrap: Any = None
    if fault == "stiffness_half":
        wrap = half_stiffness
    elif fault != "none":

        def wrap(sim: Any) -> FaultyRobot:
            return FaultyRobot(sim, fault, 0)

    result, _ = probe(RunSpec(task, seed=seed, randomize=True, robot=robot), wrap=wrap)
    return {
        "robot": robot,
        "task": task,
        "fault": fault,
        "seed": seed,
        "verdict": result.verdict,
        "reason": result.reason,
        "median_cos": result.median_cos,
        "arm_stiffness": result.arm_stiffness,
        "reported_stiffness": result.reported_stiffness,
        "judged": sum(p.judged for p in result.pushes),
        "give_m": result.give,
        "play_m": result.play,
    }


def one_run(spec: RunSpec) -> dict[str, Any]:
    record, _ = run(spec)
    s = record.summary()
    return {
        "robot": spec.robot,
        "task": spec.task,
        "seed": spec.seed,
        "offset_deg": spec.offset_deg,
        "randomize": spec.randomize,
        "controller": spec.controller,
        "probe": spec.probe,
        "probe_verdict": record.label.get("probe"),
        "success": record.success,
        "outcome": record.outcome,
        "peak_force_N": s["peak_force_N"],
        "mean_force_N": s["mean_force_N"],
    }


def jaco_without_friction_feedforward(task: str) -> dict[str, Any]:
    """The probe on the Jaco with OscConfig.friction_compensation = 0 (seed 0)."""
    from constraint_aware.control.probe import probe_sensor
    from constraint_aware.control.simulate import build_task
    from constraint_aware.sim.jaco import JacoSim, OscConfig

    spec = RunSpec(task, seed=0, robot="jaco")
    config = build_task(spec)
    sim = JacoSim(config, dataclasses.replace(OscConfig(), friction_compensation=0.0))
    sim.reset()
    result = probe_sensor(sim, config.workplane_normal)
    return {"task": task, "verdict": result.verdict, "arm_stiffness": result.arm_stiffness}


def pole_held_still(periods: int = 120) -> list[dict[str, float]]:
    """The hook hand's pole grasp held at its setpoint, no probe: |F - F(0)| [N] and the pole's
    travel [mm] once per second."""
    from constraint_aware.control.simulate import grasped

    _task, sim = grasped(RunSpec("pole-pulling", seed=0))
    f0, p0 = sim.read_wrench().force, sim.progress()
    out = []
    for period in range(1, periods + 1):
        sim.advance()
        if period % 10 == 0:
            change = float(np.linalg.norm(sim.read_wrench().force - f0))
            travel = (sim.progress() - p0) * 1000
            out.append({"time_s": period * sim.control_period, "force_change_N": change,
                        "pole_travel_mm": travel})  # fmt: skip
    return out


def probed_first(sim: Any) -> Reporting:
    """The simulated robot after a probe of the object itself (no re-grasp), reporting the
    stiffness that probe measured (its own report when the probe measured none)."""
    from constraint_aware.control.probe import STIFFNESS_VERDICTS, probe_sensor

    result = probe_sensor(sim, sim.task.workplane_normal)
    measured = result.arm_stiffness if result.verdict in STIFFNESS_VERDICTS else None
    return Reporting(sim, translational_stiffness=measured or sim.translational_stiffness)


def same_grasp_run(spec: RunSpec) -> dict[str, Any]:
    """`policy` after probing the object itself, from that grasp (no twin, no re-grasp)."""
    record, _ = run(spec, wrap=probed_first)
    s = record.summary()
    return {"task": spec.task, "seed": spec.seed, "success": record.success,
            "peak_force_N": s["peak_force_N"], "mean_force_N": s["mean_force_N"]}  # fmt: skip


#: Part 3: push sizes [m] for the force each grasp meets against the push's size (seed 0).
AMPLITUDES = (0.0015, 0.002, 0.003, 0.004, 0.006, 0.008)
AMPLITUDE_CASES = (
    ("hook-hand", "drawer-opening"),
    ("hook-hand", "door-opening"),
    ("hook-hand", "handle-rotating"),
    ("jaco", "drawer-opening"),
    ("jaco", "door-opening"),
)


def force_by_amplitude(job: tuple[str, str, float]) -> dict[str, Any]:
    """The largest force a push met along itself, -dF . u [N], at one push size: a grasp with
    play meets none below the play; an arm with a force bias meets it at any size."""
    from constraint_aware.control.probe import ProbeConfig

    robot, task, amplitude = job
    config = ProbeConfig(amplitude=amplitude, force_limit=40.0, play_amplitude=None)
    result, _ = probe(RunSpec(task, seed=0, robot=robot), config)
    met = [-float(np.dot(p.force_change, p.direction)) for p in result.pushes]
    return {"robot": robot, "task": task, "amplitude_m": amplitude, "verdict": result.verdict,
            "largest_push_force_N": max(met, default=None)}  # fmt: skip


def run_specs(n_seeds: int) -> list[tuple[str, RunSpec]]:
    """(cell kind, spec) for part 2."""
    out: list[tuple[str, RunSpec]] = []
    for robot in ROBOTS:
        for spec in suite_specs(n_seeds, ("policy", "classical")):
            out.extend(_variants("suite", dataclasses.replace(spec, robot=robot)))
        for task in TASKS:
            for off in PAPER_OFFSETS[task]:
                for seed in PAPER_SEEDS:
                    for controller in ("policy", "classical"):
                        spec = RunSpec(task, controller, off, seed, robot=robot)
                        out.extend(_variants(f"paper {off:+.0f}", spec))
    return out


def _variants(kind: str, spec: RunSpec) -> list[tuple[str, RunSpec]]:
    if spec.controller != "policy":
        return [(kind, spec)]
    return [(kind, spec), (kind, dataclasses.replace(spec, probe=True))]


def summarize(runs: list[dict[str, Any]], kinds: list[str]) -> list[dict[str, Any]]:
    cells: dict[tuple[str, str, str], dict[str, list[dict[str, Any]]]] = {}
    for kind, r in zip(kinds, runs, strict=True):
        name = (
            "classical"
            if r["controller"] == "classical"
            else ("policy + probe" if r["probe"] else "policy")
        )
        cells.setdefault((r["robot"], r["task"], kind), {}).setdefault(name, []).append(r)
    rows = []
    for (robot, task, kind), by in sorted(cells.items()):
        row: dict[str, Any] = {"robot": robot, "task": task, "cell": kind}
        for name, rs in by.items():
            row[name] = {
                "success": sum(r["success"] for r in rs),
                "runs": len(rs),
                "peak_force_median": statistics.median(r["peak_force_N"] for r in rs),
                "mean_force_median": statistics.median(r["mean_force_N"] for r in rs),
            }
        shipped = {(r["seed"], r["offset_deg"]): r for r in by.get("policy", [])}
        probed = {(r["seed"], r["offset_deg"]): r for r in by.get("policy + probe", [])}
        pairs = [(probed[k], shipped[k]) for k in sorted(shipped) if k in probed]
        if pairs:
            row["probe_minus_shipped"] = {
                "peak_force_median": statistics.median(
                    a["peak_force_N"] - b["peak_force_N"] for a, b in pairs
                ),
                "mean_force_median": statistics.median(
                    a["mean_force_N"] - b["mean_force_N"] for a, b in pairs
                ),
                "probe_lower_mean": sum(a["mean_force_N"] < b["mean_force_N"] for a, b in pairs),
                "pairs": len(pairs),
            }
        rows.append(row)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="suite seeds per task (part 2)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument("--runs", type=Path, help="also write part 2's runs here (JSON)")
    args = parser.parse_args()
    start = time.perf_counter()
    jobs = [(r, t, f, s) for r in ROBOTS for t in TASKS for f in FAULTS for s in VERDICT_SEEDS]
    specs = run_specs(args.seeds)
    same_grasp_specs = [
        s for s in suite_specs(args.seeds, ("policy",), ("drawer-opening", "pole-pulling"))
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        verdicts = list(pool.map(verdict, jobs, chunksize=4))
        runs = list(pool.map(one_run, [s for _, s in specs], chunksize=4))
        same_grasp = list(pool.map(same_grasp_run, same_grasp_specs, chunksize=4))
        no_feedforward = list(pool.map(jaco_without_friction_feedforward, TASKS))
        amplitude_jobs = [(r, t, a) for r, t in AMPLITUDE_CASES for a in AMPLITUDES]
        by_amplitude = list(pool.map(force_by_amplitude, amplitude_jobs))
    held = pole_held_still()
    same_grasp_cells = {
        task: {
            "success": sum(r["success"] for r in rs),
            "runs": len(rs),
            "peak_force_median": statistics.median(r["peak_force_N"] for r in rs),
            "mean_force_median": statistics.median(r["mean_force_N"] for r in rs),
        }
        for task in ("drawer-opening", "pole-pulling")
        for rs in [[r for r in same_grasp if r["task"] == task]]
    }
    counts = {
        f"{r} / {f}": dict(
            Counter(v["verdict"] for v in verdicts if (v["robot"], v["fault"]) == (r, f))
        )
        for r in ROBOTS
        for f in FAULTS
    }
    stiffness: dict[str, dict[str, float | None]] = {}
    for robot in ROBOTS:
        for task in TASKS:
            ks = [
                v["arm_stiffness"]
                for v in verdicts
                if (v["robot"], v["task"], v["fault"]) == (robot, task, "none")
                and v["arm_stiffness"] is not None
            ]
            stiffness.setdefault(robot, {})[task] = statistics.median(ks) if ks else None
    play: dict[str, dict[str, list[float]]] = {}  # [mm] min and max over the healthy seeds
    for robot in ROBOTS:
        for task in TASKS:
            ps = [
                1000 * v["play_m"]
                for v in verdicts
                if (v["robot"], v["task"], v["fault"]) == (robot, task, "none")
                and v["play_m"] is not None
            ]
            play.setdefault(robot, {})[task] = [min(ps), max(ps)] if ps else []
    out = {
        "seeds": args.seeds,
        "workers": args.workers,
        "load_average_1min_at_start": os.getloadavg()[0],
        "verdict_counts": counts,
        "measured_stiffness_median": stiffness,
        "measured_play_range_mm": play,
        "cells": summarize(runs, [k for k, _ in specs]),
        "diagnostics": {
            "jaco_without_friction_feedforward": no_feedforward,
            "hook_hand_pole_held_still": held,
            "probe_then_run_same_grasp_hook_hand_suite": same_grasp_cells,
            "force_by_push_size": by_amplitude,
        },
        "verdicts": verdicts,
        "runs_file": str(args.runs) if args.runs else None,
        "wall_time_s": time.perf_counter() - start,
    }
    if args.runs:
        write_results(args.runs, {"runs": runs})
    write_results(args.out, out)
    print(json.dumps(counts, indent=1))
    print(json.dumps(stiffness, indent=1))
    print(json.dumps(play, indent=1))
    for row in out["cells"]:
        parts = [f"{row['robot']:9s} {row['task']:16s} {row['cell']:10s}"]
        for name in ("policy", "policy + probe", "classical"):
            c = row.get(name)
            if c:
                parts.append(
                    f"{name} {c['success']}/{c['runs']} {c['peak_force_median']:.2f} / "
                    f"{c['mean_force_median']:.3f}"
                )
        print(" | ".join(parts))
    print(json.dumps(out["diagnostics"], indent=1))
    print(f"{out['wall_time_s']:.0f} s -> {args.out}")


if __name__ == "__main__":
    main()
