"""The bench's experiments. Each writes result files (records, snapshots) and returns numbers.

Nothing here plots: `bench/figures.py` reads what these write.
"""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.sweep import PAPER_OFFSETS, run_many, success_table, suite_specs
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.errors import UnknownNameError
from constraint_aware.policy import ConstraintAwarePolicy, is_shipped, shipped_log_path
from constraint_aware.sim.embodiment import (
    DEFAULT_ROBOT,
    ROBOT_PARAMS,
    VARIANT_RANGES,
    parse_robot,
)
from constraint_aware.sim.tasks import TASKS

CONTROLLERS = ("policy", "classical", "projection", "fixed")


@dataclass(frozen=True)
class BenchConfig:
    """How much to run. `quick` covers the paper's experiments only, with few seeds."""

    quick: bool = False
    workers: int | None = None  # process pool size (None: every core)
    suite_seeds: int = 20  # randomized runs per task and controller (headline table)
    heatmap_offsets: tuple[float, ...] = tuple(float(x) for x in range(-75, 76, 15))
    heatmap_seeds: int = 3
    sensitivity_seeds: int = 3
    render: bool = True  # snapshots of the paper's drawer scenes
    robot: str = DEFAULT_ROBOT  # embodiment of the paper's experiments, the suite, the offset
    # map and the sensitivity: a robot spec (sim.embodiment), e.g. "jaco:stiffness=2000"

    def __post_init__(self) -> None:
        parse_robot(self.robot)  # an unknown embodiment or variant names the valid ones

    @classmethod
    def for_mode(
        cls, quick: bool, workers: int | None = None, robot: str = DEFAULT_ROBOT
    ) -> BenchConfig:
        if quick:
            return cls(quick=True, workers=workers, suite_seeds=3, robot=robot)
        return cls(workers=workers, robot=robot)

    def on_robot(self, spec: RunSpec) -> RunSpec:
        """`spec` on this bench's robot."""
        return spec if spec.robot == self.robot else dataclasses.replace(spec, robot=self.robot)


def robot_variant(robot: str, **params: float) -> str:
    """The robot spec `robot` with variant parameters set (`ROBOT_PARAMS` keys), as text:
    robot_variant("jaco:period=0.2", stiffness=800) == "jaco:stiffness=800,period=0.2"."""
    spec = parse_robot(robot)
    for key in params:
        if key not in ROBOT_PARAMS:
            raise UnknownNameError("robot parameter", key, list(ROBOT_PARAMS))
    values = {k: params.get(k, getattr(spec, k)) for k in ROBOT_PARAMS}
    items = [f"{k}={v:g}" for k, v in values.items() if v is not None]
    text = spec.name + (":" + ",".join(items) if items else "")
    parse_robot(text)  # the new values' ranges
    return text


def training_log_path(source: str | Path | None, policy: ConstraintAwarePolicy) -> Path | None:
    """The training log of the policy loaded from `source`: the one shipped beside a named
    policy, or `training_log.csv` beside a policy file (where `cap train` writes it); None
    when there is none."""
    if source is None or is_shipped(source):
        return shipped_log_path(str(source or policy.name))
    log = Path(source).parent / "training_log.csv"
    return log if log.is_file() else None


# --- 1. learning curve --------------------------------------------------------------------
def learning(
    out: Path, policy: ConstraintAwarePolicy | None = None, source: str | Path | None = None
) -> dict[str, Any]:
    """The bench policy's training log and card metrics (nothing is run). `policy` was loaded
    from `source` (a shipped name or a file; None: the shipped default)."""
    policy = policy or ConstraintAwarePolicy.load(source)
    log_src = training_log_path(source, policy)
    log_dst = out / "training_log.csv"
    log_dst.write_text(log_src.read_text() if log_src is not None else "")
    with log_dst.open() as fh:
        rows = list(csv.DictReader(fh))
    metrics = policy.metrics
    card = policy.card
    return {
        "log_file": log_dst.name,
        "log_points": len(rows),
        "total_timesteps": card.get("total_timesteps"),
        "best_timesteps": card.get("best_timesteps"),
        "wall_time_s": card.get("wall_time_s"),
        "preset": card.get("train_config", {}).get("preset"),
        "final_angle_deg": {k: v["mean_final_angle_deg"] for k, v in metrics.items()},
        "p95_final_angle_deg": {k: v["p95_final_angle_deg"] for k, v in metrics.items()},
        "episodes": metrics.get("policy", {}).get("episodes"),
        "policy": policy.name,
        "has_log": log_src is not None,
        "observation_study": card.get("observation_study"),
    }


# --- 2-5. the paper's experiments -----------------------------------------------------------
PAPER_RUNS: dict[str, RunSpec] = {
    # figure 6: drawer-opening with +-30 deg errors
    "fig6_drawer_+30_policy": RunSpec("drawer-opening", "policy", 30.0),
    "fig6_drawer_-30_policy": RunSpec("drawer-opening", "policy", -30.0),
    # figures 7-8: classical vs constraint-aware at -30 deg
    **{
        f"fig78_{task.split('-')[0]}_{ctrl}": RunSpec(task, ctrl, -30.0)
        for task in ("drawer-opening", "plate-sliding", "pole-pulling")
        for ctrl in ("classical", "policy")
    },
    # figure 9: revolute tasks at +15 deg
    **{
        f"fig9_{task.split('-')[0]}_{ctrl}": RunSpec(task, ctrl, 15.0)
        for task in ("door-opening", "handle-rotating")
        for ctrl in ("classical", "policy")
    },
    # appendix: the handle with and without the torque policy
    "appendix_handle_policy_without_torque_policy": RunSpec(
        "handle-rotating", "policy", 15.0, torque_policy=False
    ),
    # the appendix's claim is about the paper's policy as published (its rule alone): run it
    "appendix_handle_paper_policy_without_torque_policy": RunSpec(
        "handle-rotating", "policy-raw", 15.0, torque_policy=False
    ),
}
#: Runs of the paper's policy (`load("paper")`); every other policy run uses the bench's.
PAPER_POLICY_RUNS = frozenset({"appendix_handle_paper_policy_without_torque_policy"})
FIG6 = ("fig6_drawer_+30_policy", "fig6_drawer_-30_policy")
FIG11 = "fig6_drawer_-30_policy"  # |F| over time (paper fig. 11 is drawer-opening)
FIG12 = "fig9_door_policy"  # the door's trajectory with d and F arrows


def paper_specs(robot: str = DEFAULT_ROBOT) -> dict[str, RunSpec]:
    """`PAPER_RUNS` on `robot` (a robot spec)."""
    return {name: dataclasses.replace(spec, robot=robot) for name, spec in PAPER_RUNS.items()}


def paper_experiments(
    out: Path,
    render: bool = True,
    policy: ConstraintAwarePolicy | None = None,
    robot: str = DEFAULT_ROBOT,
) -> dict[str, Any]:
    """Run the paper's conditions once each on `robot` with `policy` (None: the shipped
    default; `PAPER_POLICY_RUNS` keep the paper's); save every record and the drawer snapshots."""
    records_dir = out / "records"
    results: dict[str, Any] = {}
    for name, spec in paper_specs(robot).items():
        chosen = ConstraintAwarePolicy.load("paper") if name in PAPER_POLICY_RUNS else policy
        record, sim = run(spec, policy=chosen)
        record.save(records_dir / f"{name}.json")
        summary = record.summary()
        angles = np.array(record.angles)
        below = np.flatnonzero(angles < 5.0)
        summary["first_step_below_5_deg"] = int(below[0]) if below.size else None
        summary["record"] = f"records/{name}.json"
        if render and name in FIG6:
            from constraint_aware.sim.render import SceneRenderer, save_png

            renderer = SceneRenderer(
                sim.model, lookat=sim.task.object.handle_position, distance=1.0
            )
            save_png(renderer.frame(sim.data), out / f"snapshot_{name}.png")
            renderer.close()
            summary["snapshot"] = f"snapshot_{name}.png"
        results[name] = summary
    return results


# --- headline: the randomized suite ---------------------------------------------------------
def headline_specs(cfg: BenchConfig) -> list[RunSpec]:
    """The randomized suite (bench.sweep.suite_specs) on the bench's robot."""
    return [cfg.on_robot(s) for s in suite_specs(cfg.suite_seeds, CONTROLLERS)]


def headline(
    cfg: BenchConfig, policy: ConstraintAwarePolicy | None = None
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    runs = run_many(
        headline_specs(cfg), cfg.workers, label="suite (5 tasks x 4 controllers)", policy=policy
    )
    return success_table(runs), runs


# --- beyond: offsets, sensitivity ------------------------------------------------------------
def heatmap_specs(cfg: BenchConfig) -> list[RunSpec]:
    """Every task, controller, offset and seed of the offset map, on the bench's robot."""
    return [
        RunSpec(task, ctrl, off, seed=seed, robot=cfg.robot)
        for task in TASKS
        for ctrl in CONTROLLERS
        for off in cfg.heatmap_offsets
        for seed in range(cfg.heatmap_seeds)
    ]


def offset_heatmap(
    cfg: BenchConfig, policy: ConstraintAwarePolicy | None = None
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    runs = run_many(heatmap_specs(cfg), cfg.workers, label="offset map", policy=policy)
    grid: dict[str, dict[str, list[float]]] = {}
    peak: dict[str, dict[str, list[float]]] = {}
    for task in TASKS:
        for ctrl in CONTROLLERS:
            cells, peaks = [], []
            for off in cfg.heatmap_offsets:
                rows = [
                    r["summary"]
                    for r in runs
                    if r["spec"]["task"] == task
                    and r["spec"]["controller"] == ctrl
                    and r["spec"]["offset_deg"] == off
                ]
                cells.append(float(np.mean([x["success"] for x in rows])))
                peaks.append(float(np.median([x["peak_force_N"] for x in rows])))
            grid.setdefault(task, {})[ctrl] = cells
            peak.setdefault(task, {})[ctrl] = peaks
    return {
        "offsets_deg": list(cfg.heatmap_offsets),
        "seeds": cfg.heatmap_seeds,
        "success_rate": grid,
        "peak_force_median_N": peak,
    }, runs


@dataclass(frozen=True)
class Factor:
    name: str  # shown in the report
    unit: str
    levels: tuple[float, ...]
    tasks: tuple[str, ...]

    def levels_on(self, robot: str) -> tuple[float, ...]:
        """The levels run on `robot`: the wrist stiffness of a robot other than the default is
        its `stiffness` variant, run only inside that robot's advertised range."""
        if self.name != "wrist stiffness" or robot == DEFAULT_ROBOT:
            return self.levels
        low, high = VARIANT_RANGES[parse_robot(robot).name]["stiffness"]
        return tuple(level for level in self.levels if low <= level <= high)

    def spec(
        self, task: str, ctrl: str, level: float, seed: int, robot: str = DEFAULT_ROBOT
    ) -> RunSpec:
        offset = PAPER_OFFSETS[task][0]
        base = RunSpec(task, ctrl, offset, seed=seed, robot=robot)
        if self.name == "joint friction x":
            return dataclasses.replace(base, overrides=(("object__frictionloss", level),))
        if self.name == "object mass x":
            return dataclasses.replace(base, overrides=(("object__mass", level),))
        if self.name == "hinge radius":
            return dataclasses.replace(base, overrides=(("object__radius", level),))
        if self.name == "sensor noise":
            return dataclasses.replace(base, sensor_noise=level)
        if self.name == "sensor bias":
            b = level / np.sqrt(3.0)
            return dataclasses.replace(base, sensor_bias=(b, b, b))
        if self.name == "wrist stiffness" and robot == DEFAULT_ROBOT:
            return dataclasses.replace(base, overrides=(("hand__translational_stiffness", level),))
        if self.name == "wrist stiffness":  # the arm's own Cartesian stiffness (its variant)
            return dataclasses.replace(base, robot=robot_variant(robot, stiffness=level))
        raise KeyError(self.name)


PRISMATIC = ("drawer-opening", "plate-sliding", "pole-pulling")
ALL_TASKS = tuple(TASKS)
FACTORS = (
    Factor("joint friction x", "x preset", (0.25, 0.5, 1.0, 2.0, 4.0, 8.0), ALL_TASKS),
    Factor("object mass x", "x preset", (0.5, 1.0, 2.0, 4.0), ALL_TASKS),
    Factor("hinge radius", "m", (0.08, 0.12, 0.2, 0.35, 0.5, 0.8), ("door-opening",)),
    Factor("sensor noise", "N", (0.0, 0.1, 0.3, 0.6, 1.0), ALL_TASKS),
    Factor("sensor bias", "N", (0.0, 0.25, 0.5, 1.0, 2.0), ALL_TASKS),
    Factor("wrist stiffness", "N/m", (1000.0, 2000.0, 4000.0, 8000.0), ALL_TASKS),
)


def _scaled(factor: Factor, task: str, level: float) -> float:
    """Relative factors multiply the task's preset value."""
    from constraint_aware.sim.tasks import task_config

    obj = task_config(task).object
    if factor.name == "joint friction x":
        return obj.frictionloss * level
    if factor.name == "object mass x":
        return obj.mass * level
    return level


def sensitivity_cells(cfg: BenchConfig) -> dict[RunSpec, list[tuple[str, str, str, float]]]:
    """Each run of the sensitivity (on the bench's robot) and the cells it serves: (factor,
    task, controller, level)."""
    cells: dict[RunSpec, list[tuple[str, str, str, float]]] = {}
    for f in FACTORS:
        for task in f.tasks:
            for ctrl in CONTROLLERS:
                for level in f.levels_on(cfg.robot):
                    for seed in range(cfg.sensitivity_seeds):
                        s = f.spec(task, ctrl, _scaled(f, task, level), seed, cfg.robot)
                        cells.setdefault(s, []).append((f.name, task, ctrl, level))
    return cells


def sensitivity(
    cfg: BenchConfig, policy: ConstraintAwarePolicy | None = None
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Each factor's levels on its tasks. Results are matched to their cells by the run's own
    spec (a spec may serve several cells, e.g. the preset), never by the order of the runs."""
    cells = sensitivity_cells(cfg)
    runs = run_many(list(cells), cfg.workers, label="sensitivity", policy=policy)
    rows: dict[tuple[str, str, str, float], list[dict[str, Any]]] = {}
    for r in runs:
        for key in cells[RunSpec(**r["spec"])]:
            rows.setdefault(key, []).append(r["summary"])
    out: dict[str, Any] = {}
    for f in FACTORS:
        levels = f.levels_on(cfg.robot)
        entry: dict[str, Any] = {"unit": f.unit, "levels": list(levels), "tasks": {}}
        for task in f.tasks:
            for ctrl in CONTROLLERS:
                succ, peaks, finals = [], [], []
                for level in levels:
                    cell = rows[(f.name, task, ctrl, level)]
                    succ.append(float(np.mean([x["success"] for x in cell])))
                    peaks.append(float(np.median([x["peak_force_N"] for x in cell])))
                    finals.append(float(np.nanmedian([x["final_angle_deg"] for x in cell])))
                entry["tasks"].setdefault(task, {})[ctrl] = {
                    "success_rate": succ,
                    "peak_force_median_N": peaks,
                    "final_angle_median_deg": finals,
                }
        out[f.name] = entry
    return out, runs


def worst_cases(
    runs: Sequence[dict[str, Any]], controller: str = "policy", n: int = 10
) -> list[dict[str, Any]]:
    """The controller's failures first (least progress), then its highest peak forces."""
    mine = [r for r in runs if r["spec"]["controller"] == controller]
    mine.sort(key=lambda r: (r["summary"]["success"], -r["summary"]["peak_force_N"]))
    rows = []
    for r in mine[:n]:
        s, spec = r["summary"], r["spec"]
        rows.append(
            {
                "task": s["task"],
                "offset_deg": s["offset_deg"],
                "seed": s["seed"],
                "robot": spec["robot"],
                "outcome": s["outcome"],
                "reason": s["reason"],
                "peak_force_N": s["peak_force_N"],
                "progress": s["progress"],
                "randomized": spec["randomize"],
                "overrides": [list(o) for o in spec["overrides"]],
                "sensor_noise_N": spec["sensor_noise"],
                "sensor_bias_N": list(spec["sensor_bias"]),
            }
        )
    return rows


def peak_force_samples(runs: Sequence[dict[str, Any]]) -> dict[str, dict[str, list[float]]]:
    out: dict[str, dict[str, list[float]]] = {}
    for r in runs:
        s = r["summary"]
        out.setdefault(s["task"], {}).setdefault(s["controller"], []).append(s["peak_force_N"])
    return out
