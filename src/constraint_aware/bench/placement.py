"""The placement benchmark: LfO end to end on randomly placed objects of every kind.

Each run: an object of one kind at a random pose (lfo.synthetic.random_placement: any yaw,
either hinge side, radii 0.06-1.0 m, horizontal and vertical hinges and slides), a synthetic
demonstration of it (5 mm tracking noise, tremor, glitches, varying speed), the skill inferred
from that demonstration alone, then executed on the true object with the estimates in charge
(workplane, initial direction, radius, grasp, goal). Recorded: the outcome, peak |F|, and each
estimate's error against the truth.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from constraint_aware.bench.sweep import map_in_order
from constraint_aware.errors import CapError
from constraint_aware.geometry import angle_deg
from constraint_aware.lfo.execute import execute
from constraint_aware.lfo.infer import SkillParameters, infer_skill
from constraint_aware.lfo.scene import kind_for
from constraint_aware.lfo.synthetic import (
    Placement,
    TrackingNoise,
    demo_of_object,
    random_placement,
)
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import KINDS

NOISE = 0.005  # [m] tracking noise of the demonstrations
RADIUS_RANGE = (0.06, 1.0)  # [m] hinge radii of the placements (lfo.synthetic.random_placement)
FULL_PER_KIND = 15  # placements per kind of benchmarks/placement.py
NO_STAY = "lid (no stay)"  # the lid without its stay: a physics variant, not a kind


@dataclass(frozen=True)
class PlacementRun:
    """One demonstration executed on its object. Errors: deg, %, m; None where undefined."""

    kind: str
    controller: str
    index: int
    outcome: str  # a RunRecord outcome, or "refused" (an error before moving)
    success: bool
    peak_force_N: float | None
    steps: int | None
    reason: str
    constraint_correct: bool | None
    kind_correct: bool | None  # the object built from the demonstration has the true kind
    normal_error_deg: float | None  # workplane normal vs the truth (prismatic: as an axis)
    direction_error_deg: float | None  # initial direction vs the true opening direction
    radius_error_pct: float | None
    goal_error: float | None  # [cm] travel or [deg] angle, estimate - truth
    start_error_m: float | None  # the handle's start position
    hinge_error_m: float | None  # revolute: distance of the fitted centre from the hinge line
    true_goal: float = math.nan  # [m] or [rad] the demonstrated travel or angle (truth)
    progress: float = math.nan  # [m] or [rad] where the object ended (truth)
    shortfall: float | None = None  # [cm] or [deg] true goal - final progress (> 0: short)


@dataclass(frozen=True)
class PlacementSummary:
    kind: str
    controller: str
    n: int
    successes: int
    success_rate: float
    refused: int
    peak_force_N: dict[str, float] | None  # median, p95, max over executed runs
    errors: dict[str, dict[str, float] | None]  # name -> median, p95, max
    outcomes: dict[str, int]


@dataclass
class PlacementResult:
    per_kind: int
    noise_m: float
    seed: int
    controllers: list[str]
    kinds: list[str]
    runs: list[PlacementRun] = field(default_factory=list)
    summary: list[PlacementSummary] = field(default_factory=list)
    overall: dict[str, dict[str, float]] = field(default_factory=dict)  # controller -> stats

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    a = np.abs(np.asarray(values, dtype=float))
    return {
        "median": float(np.median(a)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
    }


def _errors(skill: SkillParameters, place: Placement) -> dict[str, Any]:
    o = place.task.object
    truth_normal = np.asarray(place.task.workplane_normal)
    est_normal = np.asarray(skill.workplane_normal)
    revolute = o.joint_type == "revolute"
    normal_err = float(angle_deg(est_normal, truth_normal))
    if not revolute:
        normal_err = min(normal_err, 180.0 - normal_err)
    out: dict[str, Any] = {
        "constraint_correct": skill.constraint_type == o.joint_type,
        "normal_error_deg": normal_err,
        "direction_error_deg": float(
            angle_deg(np.asarray(skill.initial_direction), o.opening_direction)
        ),
        "radius_error_pct": None,
        "goal_error": None,
        "start_error_m": None,
        "hinge_error_m": None,
    }
    if skill.start_position is not None:
        out["start_error_m"] = float(
            np.linalg.norm(np.asarray(skill.start_position) - o.handle_position)
        )
    if skill.goal is not None and skill.constraint_type == o.joint_type:
        scale = math.degrees(1.0) if revolute else 100.0
        out["goal_error"] = (skill.goal - place.goal) * scale
    if revolute and skill.radius is not None and skill.centre is not None:
        out["radius_error_pct"] = (skill.radius - o.radius) / o.radius * 100.0
        axis = np.asarray(o.axis)
        rel = np.asarray(skill.centre) - np.asarray(o.position)
        out["hinge_error_m"] = float(np.linalg.norm(rel - float(rel @ axis) * axis))
    return out


def _one_run_job(
    args: tuple[Placement, str, int, str, list[int], ConstraintAwarePolicy | None],
) -> PlacementRun:
    """`one_run` on one job of `run_placement`, its demonstration drawn from the job's seed
    (a sweep's worker calls it)."""
    place, kind, index, controller, demo_seed, policy = args
    return one_run(place, kind, index, controller, np.random.default_rng(demo_seed), policy)


def one_run(
    place: Placement,
    kind: str,
    index: int,
    controller: str,
    rng: np.random.Generator,
    policy: ConstraintAwarePolicy | None,
) -> PlacementRun:
    demo = demo_of_object(place.task, place.goal, rng, TrackingNoise(noise=NOISE))
    errors: dict[str, Any] = {}
    kind_ok = None
    try:
        skill = infer_skill(demo)
        errors = _errors(skill, place)
        if skill.constraint_type in ("prismatic", "revolute"):
            kind_ok = kind_for(skill)[0] == place.kind
        record, _ = execute(skill, controller, seed=index, task=place.task, policy=policy)
    except CapError as exc:
        return PlacementRun(
            kind, controller, index, "refused", False, None, None, str(exc),
            errors.get("constraint_correct"), kind_ok,
            errors.get("normal_error_deg"), errors.get("direction_error_deg"),
            errors.get("radius_error_pct"), errors.get("goal_error"),
            errors.get("start_error_m"), errors.get("hinge_error_m"),
        )  # fmt: skip
    scale = math.degrees(1.0) if place.task.constraint_type == "revolute" else 100.0
    return PlacementRun(
        kind, controller, index, record.outcome, record.success, record.peak_force,
        record.n_steps, record.reason, kind_correct=kind_ok, true_goal=place.goal,
        progress=record.progress, shortfall=(place.goal - record.progress) * scale, **errors,
    )  # fmt: skip


def summarize(runs: list[PlacementRun], kind: str, controller: str) -> PlacementSummary:
    mine = [r for r in runs if r.kind == kind and r.controller == controller]
    done = [r for r in mine if r.peak_force_N is not None]
    outcomes: dict[str, int] = {}
    for r in mine:
        outcomes[r.outcome] = outcomes.get(r.outcome, 0) + 1
    names = ("normal_error_deg", "direction_error_deg", "radius_error_pct", "goal_error",
             "start_error_m", "hinge_error_m")  # fmt: skip
    errors = {n: _stats([getattr(r, n) for r in mine if getattr(r, n) is not None]) for n in names}
    # signed: how far short of the true goal the object stopped (negative: beyond it)
    short = [r.shortfall for r in mine if r.shortfall is not None]
    errors["shortfall"] = (
        {"median": float(np.median(short)), "max": float(np.max(short))} if short else None
    )
    successes = sum(r.success for r in mine)
    return PlacementSummary(
        kind, controller, len(mine), successes, successes / max(len(mine), 1),
        sum(r.outcome == "refused" for r in mine),
        _stats([r.peak_force_N for r in done if r.peak_force_N is not None]), errors, outcomes,
    )  # fmt: skip


def run_placement(
    per_kind: int,
    controllers: tuple[str, ...] = ("policy", "classical"),
    seed: int = 0,
    kinds: tuple[str, ...] = KINDS,
    lid_without_stay: bool = False,
    policy: ConstraintAwarePolicy | None = None,
) -> PlacementResult:
    """`per_kind` placements of each kind, each demonstrated once and executed by every
    controller (the same demonstration for all), on the sweep's executor (bench/sweep.py)."""
    policy = policy or ConstraintAwarePolicy.load()
    names = list(kinds) + ([NO_STAY] if lid_without_stay else [])
    result = PlacementResult(per_kind, NOISE, seed, list(controllers), names)
    jobs = []
    for k, name in enumerate(names):
        kind = "lid" if name == NO_STAY else name
        for i in range(per_kind):
            place_rng = np.random.default_rng([seed, k, i])
            place = random_placement(kind, place_rng)
            if name == NO_STAY:
                obj = dataclasses.replace(place.task.object, counterbalance=0.0)
                place = dataclasses.replace(place, task=dataclasses.replace(place.task, object=obj))
            demo_seed = [seed, k, i, 1]
            jobs += [(place, name, i, controller, demo_seed, policy) for controller in controllers]
    result.runs.extend(map_in_order(_one_run_job, jobs, label="placement"))
    for name in names:
        for controller in controllers:
            result.summary.append(summarize(result.runs, name, controller))
    for controller in controllers:
        mine = [r for r in result.runs if r.controller == controller and r.kind != NO_STAY]
        rates = [s.success_rate for s in result.summary
                 if s.controller == controller and s.kind != NO_STAY]  # fmt: skip
        result.overall[controller] = {
            "n": float(len(mine)),
            "success_rate": sum(r.success for r in mine) / max(len(mine), 1),
            "worst_kind_success_rate": min(rates) if rates else math.nan,
        }
    return result


#: `cap bench`'s reduced set: placements per kind (full, quick) and the controllers.
BENCH_PER_KIND = {False: 4, True: 1}


def bench_section(quick: bool, policy: ConstraintAwarePolicy | None = None) -> dict[str, Any]:
    """The placement experiment as `cap bench` runs it (benchmarks/placement.py runs more),
    with the bench's policy (None: the shipped default)."""
    controllers = ("policy",) if quick else ("policy", "classical")
    out = run_placement(BENCH_PER_KIND[quick], controllers, policy=policy).to_dict()
    # what the report's prose states, so that every number shown is in results.json
    out["noise_mm"] = NOISE * 1000.0
    out["radius_range_m"] = list(RADIUS_RANGE)
    out["full_benchmark_per_kind"] = FULL_PER_KIND
    out["error_percentile"] = 95
    for o in out["overall"].values():
        o["success_pct"] = 100.0 * o["success_rate"]
        o["worst_kind_success_pct"] = 100.0 * o["worst_kind_success_rate"]
    return out


def report_lines(section: dict[str, Any]) -> list[str]:
    """The report's placement section, read from results.json's "placement"."""

    def f(x: float | None, digits: int = 1) -> str:
        return "-" if x is None else f"{x:.{digits}f}"

    def p95(s: dict[str, Any], name: str) -> str:
        stats = s["errors"].get(name)
        return f(stats["p95"] if stats else None)

    lo, hi = section["radius_range_m"]
    lines = [
        "## Beyond the paper: LfO on randomly placed objects\n",
        f"{section['per_kind']} random placements per kind (any yaw, either hinge side, radii "
        f"{lo:g} to {hi:g} m), each demonstrated once with {section['noise_mm']:g} mm tracking "
        "noise and executed on the true object with the demonstration's estimates in charge "
        "(workplane, initial direction, radius, grasp, goal); the robot stops at the "
        "demonstrated goal measured on its own poses. Errors are the "
        f"{section['error_percentile']}th percentiles of |estimate - truth| "
        f"(`python benchmarks/placement.py` runs {section['full_benchmark_per_kind']} per "
        "kind).\n",
        "| kind | controller | success | peak F median / max [N] | normal [deg] | "
        "direction [deg] | radius [%] | goal [cm or deg] | short of the goal, median / max "
        "[cm or deg] |",
        "|---" * 9 + "|",
    ]
    for s in section["summary"]:
        pf = s["peak_force_N"] or {}
        short = s["errors"].get("shortfall") or {}
        lines.append(
            f"| {s['kind']} | {s['controller']} | {s['successes']}/{s['n']} | "
            f"{f(pf.get('median'))} / {f(pf.get('max'))} | {p95(s, 'normal_error_deg')} | "
            f"{p95(s, 'direction_error_deg')} | {p95(s, 'radius_error_pct')} | "
            f"{p95(s, 'goal_error')} | {f(short.get('median'))} / {f(short.get('max'))} |"
        )
    lines.append("")
    for controller, o in section["overall"].items():
        lines.append(
            f"- {controller}: {o['success_pct']:.0f} % of {o['n']:.0f} runs succeed; "
            f"worst kind {o['worst_kind_success_pct']:.0f} %."
        )
    lines.append("")
    return lines
