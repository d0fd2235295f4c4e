"""The calibration (control/calibrate.py) against the simulator's truth, on both robots.

    python benchmarks/calibration.py [--seeds 5] [--out benchmarks/results/calibration.json]
    python benchmarks/calibration.py --pushes-alone [--seeds 5]
        --out benchmarks/results/calibration_pushes_alone.json
    python benchmarks/calibration.py --tool-point [--seeds 1]
        --out benchmarks/results/calibration_tool_point.json
    python benchmarks/calibration.py --free-space [--seeds 1]
        --out benchmarks/results/calibration_free_space.json

`--free-space`: the free-space calibration (`calibrate_free_space`) against the simulators'
tau, on both robots at the stiffnesses of their advertised ranges, at each task's grasp
posture with the simulator's contacts off (the hand holds nothing and meets nothing: the
simulators' own definition of tau, the 63.2 % rise time of a 1 cm step in free space at the
grasp posture); and the robot-wide use: the calibration at the drawer's grasp posture against
every task's tau (one free-space calibration per robot, as a user makes it). Must-show: tau
within 20 %; beside it the robot time it takes and sigma within 20 %.

`--tool-point`: the calibrated stiffness against the effective stiffness at the tool point,
measured with simulator privileges (`tool_point_stiffness`: the object locked, the force per
setpoint step between held levels at the calibration's force levels, the noise-free force;
settled and two periods after the step; over all four workplane directions and over the
directions the calibration found blocked), on both robots within their advertised variant
ranges (sim.embodiment.VARIANT_RANGES), every task as the fixture; the nominal gain beside
it; tau and sigma against their truths.

Each calibration runs through an adapter that forwards only the Robot protocol's required
members (no `translational_stiffness`, `tracking_time_constant`, `grasp_contact` or `hold`),
on every task of the suite as the calibration's fixture (the hand holds the task's handle),
for the hook hand and the Jaco at the stiffnesses of their advertised ranges (IN_RANGE), with
the suite's sensor noise (0.1 N per axis) drawn from `--seeds` seeds. As the user guide has
it, each grasp's calibration is given the robot's free-space calibration (one per robot,
stiffness and seed, at the drawer's grasp posture, its own noise draw): its tau, and its
readings at rest pooled into the noise; `--pushes-alone` leaves it out (tau from the pushes,
the noise from the grasp's readings alone). Each measured value is compared with the
simulator's truth:

- stiffness: the force per setpoint step at the tool point with the object locked
  (`tool_point_stiffness`, settled, the median over the blocked workplane directions); the
  nominal gain where no direction was blocked; and each direction the profile notes against
  the truth in that same direction (`per_direction`);
- tracking time constant: the robot's reported `tracking_time_constant` (the 63.2 % rise time
  of a 1 cm step in free space); beside it the linear model's c / k, the arm's damping over
  its stiffness at the grasp configuration (`SimulatedRobot.axis_time_constants` is its rise
  time; c / k comes from `_axis_dynamics`);
- force noise: the configured sigma;
- grasp play: on the hook hand's bar grasps (drawer, door) the gap its fingers leave beside
  the bar, `finger_offset - finger_thickness - handle_radius` (HandConfig, ObjectConfig).

Must-shows (tolerances from the task): stiffness within 10 %, tau within 20 %, sigma within
20 % of the truth; a full calibration under 5 s of robot time (control periods x period).
Each is reported per robot and stiffness as the share of calibrations (fixtures x seeds)
within tolerance, with every miss listed.

Diagnostics: (1) the hook hand at 10,000 N/m on its bar grasps with the wrist's rotational
stiffness raised from 5 to 50 and 500 N m/rad: the stiffness the tool point shows includes the
wrist turning under the push; (2) the Jaco's reported tau measured the simulator's own way
(a setpoint step from rest in free space) for steps of 1-20 mm: the reported value depends on
the step's size (joint friction at small steps, torque limits at large ones); (3) the force
noise over 40 seeds on one fixture: how often its readings at rest land within 20 % of sigma.
Results JSON through bench.provenance.write_results.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import statistics
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.control.calibrate import CalibrationConfig, calibrate
from constraint_aware.control.free_space import FreeSpaceConfig, calibrate_free_space
from constraint_aware.control.probe import push_directions
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.simulate import RunSpec, grasped
from constraint_aware.sim.embodiment import VARIANT_RANGES
from constraint_aware.sim.tasks import TASKS
from constraint_aware.spatial import Pose

DEFAULT_OUT = Path(__file__).parent / "results" / "calibration.json"
ROBOTS = ("hook-hand", "jaco")
SENSOR_NOISE = 0.1  # [N] the suite's (RunSpec's default)
#: relative tolerances of the must-shows
TOLERANCE = {"stiffness": 0.10, "tracking_time_constant": 0.20, "force_noise": 0.20}
MAX_ROBOT_TIME = 5.0  # [s]
FREE_SPACE_SEED = 90_000  # the free-space calibrations' noise seeds start here (apart from
# every grasp's)
BAR_TASKS = ("drawer-opening", "door-opening")
ROBOT_WIDE_POSTURE = "drawer-opening"  # the grasp posture of the robot-wide calibration


class RequiredMembers:
    """Forwards only the Robot protocol's required members to a simulated robot (and
    `grasp_contact` as "cannot tell")."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.control_period = float(inner.control_period)

    def read_wrench(self) -> Any:
        return self._inner.read_wrench()

    def read_pose(self) -> Any:
        return self._inner.read_pose()

    def commanded_pose(self) -> Any:
        return self._inner.commanded_pose()

    def grasp_contact(self) -> bool | None:
        return None  # the Robot protocol's "cannot tell": as if the member were absent

    def command_pose(self, pose: Any) -> None:
        self._inner.command_pose(pose)

    def advance(self) -> None:
        self._inner.advance()


def robot_spec(robot: str, stiffness: float) -> str:
    return f"{robot}:stiffness={stiffness:g}"


def damping_over_stiffness(sim: Any) -> float:
    """[s] c / k of the linear model, mean over the three translational axes at the grasp."""
    k, c, _m = sim._axis_dynamics(sim.data)
    return float(np.mean(c[:3] / k[:3]))


def grasp_gap(task: Any) -> float | None:
    """[m] the gap the hook hand's fingers leave beside a bar: None for other handles."""
    if task.object.handle != "bar":
        return None
    return float(task.hand.bar_gap(task.object.handle_radius))


def calibrate_one(
    robot: str,
    stiffness: float,
    task: str,
    seed: int,
    k_truth: float | None = None,
    free_space: RobotProfile | None = None,
    **overrides: Any,
) -> dict:
    spec = RunSpec(
        task,
        seed=seed,
        robot=robot_spec(robot, stiffness),
        sensor_noise=SENSOR_NOISE,
        overrides=tuple(overrides.items()),
    )
    task_cfg, sim = grasped(spec)
    config = CalibrationConfig(force_limit=min(CalibrationConfig.force_limit, task_cfg.force_limit))
    start = time.perf_counter()
    profile = calibrate(
        RequiredMembers(sim), spec.robot, task_cfg.workplane_normal, config, task, free_space
    )
    wall = time.perf_counter() - start
    truth = {
        "stiffness": k_truth if k_truth is not None else float(sim.translational_stiffness),
        "tracking_time_constant": float(sim.tracking_time_constant),
        "force_noise": SENSOR_NOISE,
        "grasp_play": grasp_gap(task_cfg) if robot == "hook-hand" else None,
    }
    row: dict[str, Any] = {
        "robot": robot,
        "stiffness_setting": stiffness,
        "task": task,
        "seed": seed,
        "overrides": {k: v for k, v in overrides.items()},
        "free_space_profile": free_space is not None,
        "periods": profile.periods,
        "robot_time_s": profile.robot_time,
        "outcome": profile.outcome,
        "convention": profile.convention,
        "damping_over_stiffness_s": damping_over_stiffness(sim),
        "wall_s": wall,
        "notes": profile.notes,
        "quantities": {},
    }
    for name, m in profile.quantities.items():
        entry: dict[str, Any] = {
            "value": m.value,
            "uncertainty": m.uncertainty,
            "unit": m.unit,
            "count": m.count,
            "reason": m.reason,
        }
        true = truth.get(name)
        if name in truth:
            entry["truth"] = true
        if m.value is not None and true:
            entry["ratio"] = m.value / true
        row["quantities"][name] = entry
    return row


def robot_wide_free_space(robot: str, stiffness: float, seed: int) -> RobotProfile:
    """The robot's free-space calibration at the drawer's grasp posture (one per robot, as
    the user guide makes it), its noise drawn from `seed`."""
    spec = RunSpec(ROBOT_WIDE_POSTURE, seed=seed, robot=robot_spec(robot, stiffness),
                   sensor_noise=SENSOR_NOISE)  # fmt: skip
    _task, sim = grasped(spec)
    return calibrate_free_space(RequiredMembers(sim.in_free_space()), spec.robot)


def sweep(seeds: int, with_free_space: bool = True) -> Iterator[dict]:
    """Every robot, stiffness and fixture, each with its own noise seeds (no two cells share
    a noise draw). With `with_free_space`, each grasp's calibration is given the robot's
    free-space calibration (one per robot, stiffness and seed, its own noise draw, at the
    drawer's grasp posture, serving every fixture), as the user guide has it."""
    for r, robot in enumerate(ROBOTS):
        for s, stiffness in enumerate(IN_RANGE[robot]):
            free = [
                robot_wide_free_space(robot, stiffness, FREE_SPACE_SEED + 1000 * r + 100 * s + i)
                if with_free_space
                else None
                for i in range(seeds)
            ]
            for t, task in enumerate(TASKS):
                truth = tool_point_stiffness(robot, stiffness, task)
                for i in range(seeds):
                    seed = 1000 * r + 100 * s + 10 * t + i
                    row = calibrate_one(robot, stiffness, task, seed, free_space=free[i])
                    _stiffness_truth(row, truth)
                    q = row["quantities"]
                    print(
                        f"{robot:9s} {stiffness:7.0f} {task:16s} s{seed} {row['periods']:2d} "
                        f"periods {row['outcome']:9s} "
                        + " ".join(
                            f"{n[:5]} {q[n].get('ratio', float('nan')):.2f}" for n in TOLERANCE
                        )
                        + f" {row['convention']}",
                        flush=True,
                    )
                    yield row


def _stiffness_truth(row: dict[str, Any], truth: dict[str, Any]) -> None:
    """The row's stiffness against the tool-point truth, settled, in the directions the
    calibration measured (all blocked directions when its profile names none); the truth
    two periods after the step beside it."""
    q = row["quantities"]["stiffness"]
    measured = calibrated_directions(row["notes"])
    settled = same_directions(truth, measured, "k_command") or truth["k_command"]
    quick = same_directions(truth, measured, "k_command_quick") or truth["k_command_quick"]
    q["truth"], q["truth_two_periods"] = settled, quick
    q.pop("ratio", None)
    if q["value"] is not None and settled:
        q["ratio"] = q["value"] / settled
    if q["value"] is not None and quick:
        q["ratio_two_periods"] = q["value"] / quick
    # each direction the profile notes against the truth in that same direction
    q["by_direction"] = [
        {
            "direction": [float(x) for x in u],
            "value": k,
            "ratio": k / d["k_command"],
            "ratio_two_periods": k / d["k_command_quick"],
        }
        for u, k in measured
        for d in truth["directions"]
        if float(np.asarray(d["direction"]) @ u) > 0.99
    ]


def per_direction(rows: list[dict]) -> dict[str, Any]:
    """Per robot: how many of the blocked directions the calibrations measured are within
    10 % of the truth in the same direction (settled and two periods after the step), all
    tasks and without the pole, with the two-period ratios' range."""
    tol = TOLERANCE["stiffness"]
    out: dict[str, Any] = {}
    for robot in ROBOTS:
        for label, keep in (("all", lambda t: True), ("off_pole", lambda t: t != "pole-pulling")):
            found = [
                d
                for r in rows
                if r["robot"] == robot and keep(r["task"])
                for d in r["quantities"]["stiffness"].get("by_direction", [])
            ]
            quick = [d["ratio_two_periods"] for d in found]
            out[f"{robot} {label}"] = {
                "directions": len(found),
                "within_two_periods": sum(abs(x - 1) <= tol for x in quick),
                "within_settled": sum(abs(d["ratio"] - 1) <= tol for d in found),
                "ratio_two_periods_range": [min(quick), max(quick)] if quick else None,
            }
    return out


def summarize(rows: list[dict]) -> dict[str, Any]:
    """Per robot and stiffness, per quantity: the ratios' median and range, and how many
    calibrations were measured and within tolerance."""
    out: dict[str, Any] = {}
    for robot in ROBOTS:
        for stiffness in IN_RANGE[robot]:
            cell = [r for r in rows if r["robot"] == robot and r["stiffness_setting"] == stiffness]
            if not cell:
                continue
            entry: dict[str, Any] = {
                "calibrations": len(cell),
                "robot_time_s_max": max(r["robot_time_s"] for r in cell),
                "robot_time_s_median": statistics.median(r["robot_time_s"] for r in cell),
                "outcomes": dict(_count(r["outcome"] for r in cell)),
                "conventions": dict(_count(r["convention"] for r in cell)),
            }
            for name in (*TOLERANCE, "grasp_play"):
                ratios = [
                    r["quantities"][name]["ratio"] for r in cell if "ratio" in r["quantities"][name]
                ]
                measured = sum(r["quantities"][name]["value"] is not None for r in cell)
                q: dict[str, Any] = {"measured": measured}
                if ratios:
                    q.update(
                        ratio_median=statistics.median(ratios),
                        ratio_min=min(ratios),
                        ratio_max=max(ratios),
                    )
                if name == "stiffness":
                    quick = [
                        r["quantities"][name]["ratio_two_periods"]
                        for r in cell
                        if "ratio_two_periods" in r["quantities"][name]
                    ]
                    q["within_tolerance_two_periods"] = sum(
                        abs(x - 1.0) <= TOLERANCE[name] for x in quick
                    )
                    q["ratio_two_periods_median"] = statistics.median(quick) if quick else None
                if name in TOLERANCE:
                    q["within_tolerance"] = sum(abs(x - 1.0) <= TOLERANCE[name] for x in ratios)
                    by_task = {}
                    for task in TASKS:
                        t = [r["quantities"][name].get("ratio") for r in cell if r["task"] == task]
                        vals = [x for x in t if x is not None]
                        by_task[task] = statistics.median(vals) if vals else None
                    q["ratio_median_by_task"] = by_task
                if name == "tracking_time_constant":
                    vs_model = [
                        r["quantities"][name]["value"] / r["damping_over_stiffness_s"]
                        for r in cell
                        if r["quantities"][name]["value"] is not None
                    ]
                    if vs_model:
                        q["ratio_to_damping_over_stiffness_median"] = statistics.median(vs_model)
                entry[name] = q
            out[f"{robot}:{stiffness:g}"] = entry
    return out


def must_shows(rows: list[dict]) -> dict[str, Any]:
    """Each must-show: held or not, with every miss (and every unmeasured value) listed."""
    shows: dict[str, Any] = {}
    for name, tol in TOLERANCE.items():
        misses, unmeasured = [], []
        for r in rows:
            q = r["quantities"][name]
            label = f"{r['robot']}:{r['stiffness_setting']:g} {r['task']} seed {r['seed']}"
            if q["value"] is None:
                unmeasured.append(f"{label}: {q['reason']}")
            elif abs(q["ratio"] - 1.0) > tol:
                misses.append(f"{label}: {q['ratio']:.2f} x truth")
        measured = len(rows) - len(unmeasured)
        shows[name] = {
            "tolerance": tol,
            "measured": measured,
            "within": measured - len(misses),
            "held": not misses,
            "misses": misses,
            "unmeasured": unmeasured,
        }
    slow = [
        f"{r['robot']}:{r['stiffness_setting']:g} {r['task']} seed {r['seed']}: "
        f"{r['robot_time_s']:.1f} s"
        for r in rows
        if r["robot_time_s"] >= MAX_ROBOT_TIME
    ]
    shows["robot_time"] = {
        "limit_s": MAX_ROBOT_TIME,
        "max_s": max(r["robot_time_s"] for r in rows),
        "held": not slow,
        "misses": slow,
    }
    return shows


def wrist_rotation() -> list[dict]:
    """The hook hand at 10,000 N/m on its bar grasps, the wrist's rotational stiffness
    raised: the stiffness measured at the tool point."""
    out = []
    for task in BAR_TASKS:
        for rotational in (5.0, 50.0, 500.0):
            row = calibrate_one(
                "hook-hand", 10000.0, task, 0, hand__rotational_stiffness=rotational
            )
            out.append(
                {
                    "task": task,
                    "rotational_stiffness_N_m_per_rad": rotational,
                    "stiffness_measured": row["quantities"]["stiffness"]["value"],
                    "stiffness_ratio": row["quantities"]["stiffness"].get("ratio"),
                }
            )
    return out


def jaco_step_sizes() -> list[dict]:
    """The Jaco's reported tau measured the simulator's way, with other step sizes: the
    simulator's module constant for the step is set and its cache cleared (diagnostic only)."""
    import constraint_aware.sim.jaco as jaco

    step0 = getattr(jaco, "TRACKING_STEP", None)
    cache = getattr(jaco, "_TAU_CACHE", None)
    if step0 is None or cache is None:
        return [{"skipped": "sim.jaco has no TRACKING_STEP / _TAU_CACHE"}]
    out = []
    try:
        for stiffness in (700.0, 1000.0, 4000.0):
            _task, sim = grasped(RunSpec("drawer-opening", robot=robot_spec("jaco", stiffness)))
            row: dict[str, Any] = {
                "stiffness": stiffness,
                "damping_over_stiffness_s": damping_over_stiffness(sim),
            }
            for step in (0.001, 0.003, 0.01, 0.02):
                jaco.TRACKING_STEP = step
                cache.clear()
                row[f"rise_time_s_step_{step * 1000:g}mm"] = sim._free_space_time_constant()
            out.append(row)
    finally:
        jaco.TRACKING_STEP = step0
        cache.clear()
    return out


def noise_seeds(count: int = 40, with_free_space: bool = True) -> dict[str, Any]:
    """sigma over `count` seeds on the hook hand's drawer (each with its own free-space
    calibration when `with_free_space`): the share within 20 %, beside the share a Gaussian
    estimate with the calibration's degrees of freedom would give."""
    rows = []
    for i in range(count):
        free = robot_wide_free_space("hook-hand", 2000.0, 60_000 + i) if with_free_space else None
        rows.append(
            calibrate_one("hook-hand", 2000.0, "drawer-opening", 50_000 + i, free_space=free)
        )
    noise = [r["quantities"]["force_noise"] for r in rows]
    ratios = [q["ratio"] for q in noise]
    relative = statistics.median(q["uncertainty"] / q["value"] for q in noise)
    expected = math.erf(0.2 / relative / math.sqrt(2.0))
    return {
        "seeds": count,
        "readings_median": statistics.median(q["count"] for q in noise),
        "ratios": ratios,
        "within_20_percent": sum(abs(r - 1.0) <= 0.2 for r in ratios),
        "relative_standard_error_median": relative,
        "expected_share_within_20_percent": expected,
    }


def _count(items: Iterator[str]) -> dict[str, int]:
    out: dict[str, int] = {}
    for item in items:
        out[item] = out.get(item, 0) + 1
    return out


#: The tool-point truth's stiffnesses: within each robot's advertised variant range.
CANDIDATES = (200.0, 500.0, 700.0, 1000.0, 2000.0, 4000.0, 5000.0, 10000.0)
IN_RANGE = {
    robot: tuple(k for k in CANDIDATES if low <= k <= high)
    for robot in ROBOTS
    for low, high in [VARIANT_RANGES[robot]["stiffness"]]
}
#: The object locked for the truth: its joint confined to +-10 um, and dry friction far above
#: any push.
LOCKED = (("object__joint_range", (-1e-5, 1e-5)), ("object__frictionloss", 1000.0))
SETTLE_PERIODS = 15  # control periods held at each static level (the hook hand settles in
# two; the Jaco's force still creeps after twelve: both holds are reported)
SEARCH_PERIODS = 3  # control periods held at each step of the contact search
CONTACT_STEP = 0.00025  # [m] the setpoint's smallest step while looking for contact
CONTACT_TRAVEL = 0.035  # [m] no contact_force within this: the direction is not blocked
QUICK_PERIODS = 2  # the calibration holds each level this many periods (the stair's and one)


def tool_point_stiffness(robot: str, stiffness: float, task: str) -> dict[str, Any]:
    """The effective tool-point stiffness with simulator privileges, at the calibration's force
    levels: the object locked, the noise-free wrist force read (`true_wrench`), static pushes
    from rest in the four workplane directions. In each direction the setpoint steps out by
    CONTACT_STEP (each held SEARCH_PERIODS periods) until |dF| from rest (read again before
    each direction) reaches the
    calibration's contact_force (none within CONTACT_TRAVEL: not blocked, the hook's open
    side); that setpoint, held SETTLE_PERIODS periods, is level A; level B is one step beyond
    it sized from the last search step's slope to add push_force - contact_force, held
    SETTLE_PERIODS periods. Per blocked direction: k_command = |F_B - F_A| / |setpoint_B -
    setpoint_A| in the workplane (the force per blocked setpoint step, what the controller's
    k x step means), settled; k_command_quick the same with B read QUICK_PERIODS periods after
    its step (what one calibration stair and its hold see); k_stretch = |F_B - F_A| /
    |stretch_B - stretch_A| (stretch = setpoint - measured tool point, the arm's spring
    alone). Returns their medians over the blocked directions, the per-direction values and
    their spread."""
    spec = RunSpec(task, seed=0, robot=robot_spec(robot, stiffness), sensor_noise=0.0,
                   overrides=LOCKED)  # fmt: skip
    task_cfg, sim = grasped(spec)
    home = sim.commanded_pose()
    cfg = CalibrationConfig()
    normal = np.asarray(task_cfg.workplane_normal, dtype=float)

    def hold_at(position: Any, periods: int) -> list[tuple[Any, Any]]:
        out = []
        for _ in range(periods):
            sim.command_pose(Pose(position, home.orientation))
            sim.advance()
            out.append((np.asarray(sim.true_wrench().force), np.asarray(sim.read_pose().position)))
        return out

    def plane(v: Any) -> float:
        return float(np.linalg.norm(v - (v @ normal) * normal))

    directions: list[dict[str, Any]] = []
    for u in push_directions(4, normal):
        # the rest force read again before each direction: a grasp that stays wedged after a
        # push (the hook on the pole) keeps a force the next push must not count
        rest = hold_at(home.position, SETTLE_PERIODS)[-1][0]
        depth, df = 0.0, 0.0
        while depth < CONTACT_TRAVEL:
            # a quarter of the way to contact_force at the nominal gain, at least CONTACT_STEP
            step = max(CONTACT_STEP, (cfg.contact_force - df) / (4.0 * stiffness))
            depth += step
            last = df
            f, _x = hold_at(home.position + depth * u, SEARCH_PERIODS)[-1]
            df = float(np.linalg.norm(f - rest))
            if df >= cfg.contact_force:
                break
        else:
            hold_at(home.position, SETTLE_PERIODS)
            continue  # not blocked (the hook's open side)
        slope = max((df - last) / step, 1.0)
        sa = home.position + depth * u
        fa, xa = hold_at(sa, SETTLE_PERIODS)[-1]
        sb = sa + min((cfg.push_force - cfg.contact_force) / slope, 0.01) * u
        b = hold_at(sb, SETTLE_PERIODS)
        (fq, _xq), (fb, xb) = b[QUICK_PERIODS - 1], b[-1]
        hold_at(home.position, SETTLE_PERIODS)
        ds = plane(sb - sa)
        directions.append({
            "direction": [round(float(x), 3) for x in u],
            "k_command": plane(fb - fa) / ds,
            "k_command_quick": plane(fq - fa) / ds,
            "k_stretch": plane(fb - fa) / max(plane((sb - xb) - (sa - xa)), 1e-9),
            "force_a": float(np.linalg.norm(fa - rest)),
            "force_b": float(np.linalg.norm(fb - rest)),
        })  # fmt: skip

    def median(key: str) -> float | None:
        values = [d[key] for d in directions]
        return statistics.median(values) if values else None

    k_cmd = [d["k_command"] for d in directions]
    return {
        "blocked_directions": len(directions),
        "k_command": median("k_command"),
        "k_command_range": [min(k_cmd), max(k_cmd)] if k_cmd else None,
        "k_command_quick": median("k_command_quick"),
        "k_stretch": median("k_stretch"),
        "directions": directions,
    }


def calibrated_directions(notes: list[str]) -> list[tuple[Any, float]]:
    """The calibration's per-direction stiffness from its profile note: [(direction (3,),
    k [N/m])]."""
    for note in notes:
        if note.startswith("stiffness by blocked direction"):
            found = re.findall(r"\(([^)]*)\) (\d+)", note)
            return [(np.array([float(x) for x in d.split(",")]), float(k)) for d, k in found]
    return []


def same_directions(truth: dict[str, Any], measured: list[tuple[Any, float]], key: str) -> Any:
    """[N/m] the truth's `key` averaged over the directions the calibration measured (the
    directions it found blocked on the free fixture), or None."""
    values = [
        d[key]
        for u, _k in measured
        for d in truth["directions"]
        if float(np.asarray(d["direction"]) @ u) > 0.99
    ]
    return float(np.mean(values)) if values else None


def tool_point(seeds: int) -> dict[str, Any]:
    """The calibration's stiffness against the tool-point truth (settled and after
    QUICK_PERIODS, over all blocked directions and over the directions the calibration
    measured) and against the nominal (reported) gain; tau and sigma against theirs; per robot
    and in-range stiffness, on every task as the fixture."""
    rows = []
    for robot in ROBOTS:
        for stiffness in IN_RANGE[robot]:
            for task in TASKS:
                truth = tool_point_stiffness(robot, stiffness, task)
                for seed in range(seeds):
                    row = calibrate_one(robot, stiffness, task, seed)
                    k = row["quantities"]["stiffness"]["value"]
                    measured = calibrated_directions(row["notes"])
                    refs = {
                        "settled": truth["k_command"],
                        "quick": truth["k_command_quick"],
                        "settled_same_directions": same_directions(truth, measured, "k_command"),
                        "quick_same_directions": same_directions(
                            truth, measured, "k_command_quick"
                        ),
                        "nominal": stiffness,
                    }
                    rows.append({
                        "robot": robot, "stiffness_setting": stiffness, "task": task,
                        "seed": seed, "truth": truth, "calibrated": k,
                        "calibrated_directions": [(u.tolist(), v) for u, v in measured],
                        "ratio": {
                            n: k / t if k is not None and t else None for n, t in refs.items()
                        },
                        "tau": row["quantities"]["tracking_time_constant"],
                        "force_noise": row["quantities"]["force_noise"],
                        "robot_time_s": row["robot_time_s"],
                    })  # fmt: skip
                    r = rows[-1]["ratio"]
                    print(
                        f"{robot:9s} {stiffness:6.0f} {task:16s} calibrated "
                        f"{k if k is not None else float('nan'):8.0f} / truth settled "
                        f"{r['settled'] or float('nan'):.2f} quick {r['quick'] or float('nan'):.2f}"
                        f" same dirs {r['settled_same_directions'] or float('nan'):.2f} / "
                        f"{r['quick_same_directions'] or float('nan'):.2f}",
                        flush=True,
                    )
    summary: dict[str, Any] = {}
    for robot in ROBOTS:
        for stiffness in IN_RANGE[robot]:
            cell = [r for r in rows if r["robot"] == robot and r["stiffness_setting"] == stiffness]
            entry: dict[str, Any] = {
                "calibrations": len(cell),
                "measured": sum(r["calibrated"] is not None for r in cell),
                "robot_time_s_max": max(r["robot_time_s"] for r in cell),
            }
            for ref in cell[0]["ratio"]:
                ratios = [r["ratio"][ref] for r in cell if r["ratio"][ref] is not None]
                entry[f"k_vs_{ref}"] = {
                    "within_10pct": sum(abs(x - 1) <= TOLERANCE["stiffness"] for x in ratios),
                    "ratio_median": statistics.median(ratios) if ratios else None,
                    "ratio_range": [min(ratios), max(ratios)] if ratios else None,
                }
            spread = [
                r["truth"]["k_command_range"][1] / r["truth"]["k_command_range"][0]
                for r in cell
                if r["truth"]["k_command_range"]
            ]
            entry["truth_direction_spread_max_over_min_median"] = (
                statistics.median(spread) if spread else None
            )
            for name, key in (("tau", "tracking_time_constant"), ("force_noise", "force_noise")):
                ratios = [r[name]["ratio"] for r in cell if r[name].get("ratio") is not None]
                entry[name] = {
                    "measured": len(ratios),
                    "within_tolerance": sum(abs(x - 1) <= TOLERANCE[key] for x in ratios),
                    "ratio_median": statistics.median(ratios) if ratios else None,
                }
            summary[f"{robot}:{stiffness:g}"] = entry
    return {"stiffnesses": IN_RANGE, "summary": summary, "rows": rows}


def free_space_sweep(seeds: int) -> dict[str, Any]:
    """The free-space calibration against tau on both robots, every in-range stiffness and
    task posture (module docstring)."""
    rows: list[dict[str, Any]] = []
    for r, robot in enumerate(ROBOTS):
        for s, stiffness in enumerate(IN_RANGE[robot]):
            for t, task in enumerate(TASKS):
                for i in range(seeds):
                    seed = 1000 * r + 100 * s + 10 * t + i
                    spec = RunSpec(task, seed=seed, robot=robot_spec(robot, stiffness),
                                   sensor_noise=SENSOR_NOISE)  # fmt: skip
                    _task, sim = grasped(spec)
                    truth = float(sim.tracking_time_constant)
                    start = time.perf_counter()
                    profile = calibrate_free_space(RequiredMembers(sim.in_free_space()), spec.robot)
                    wall = time.perf_counter() - start
                    tau = profile.quantities["tracking_time_constant"]
                    sigma = profile.value("force_noise")
                    rows.append({
                        "robot": robot, "stiffness_setting": stiffness, "task": task,
                        "seed": seed, "outcome": profile.outcome, "periods": profile.periods,
                        "robot_time_s": profile.robot_time, "wall_s": wall,
                        "tau": tau.value, "tau_uncertainty": tau.uncertainty,
                        "tau_reason": tau.reason, "tau_truth": truth,
                        "tau_ratio": None if tau.value is None else tau.value / truth,
                        "damping_over_stiffness_s": damping_over_stiffness(sim),
                        "force_noise": sigma,
                        "force_noise_ratio": None if sigma is None else sigma / SENSOR_NOISE,
                        "lag_error_s": profile.value("lag_error"),
                        "notes": profile.notes,
                    })  # fmt: skip
                    print(
                        f"{robot:9s} {stiffness:6.0f} {task:16s} s{seed} {profile.outcome} "
                        f"{profile.periods} periods tau {tau.value or float('nan'):.3f} truth "
                        f"{truth:.3f} ratio {rows[-1]['tau_ratio'] or float('nan'):.2f}",
                        flush=True,
                    )
    tol = TOLERANCE["tracking_time_constant"]
    summary: dict[str, Any] = {}
    robot_wide: dict[str, Any] = {}
    for robot in ROBOTS:
        for stiffness in IN_RANGE[robot]:
            cell = [r for r in rows if r["robot"] == robot and r["stiffness_setting"] == stiffness]
            ratios = [r["tau_ratio"] for r in cell if r["tau_ratio"] is not None]
            noise = [r["force_noise_ratio"] for r in cell if r["force_noise_ratio"] is not None]
            lags = [r["lag_error_s"] for r in cell if r["lag_error_s"] is not None]
            summary[f"{robot}:{stiffness:g}"] = {
                "calibrations": len(cell),
                "tau_measured": len(ratios),
                "tau_within_20pct": sum(abs(x - 1) <= tol for x in ratios),
                "tau_ratio_median": statistics.median(ratios) if ratios else None,
                "tau_ratio_range": [min(ratios), max(ratios)] if ratios else None,
                "force_noise_within_20pct": sum(abs(x - 1) <= 0.2 for x in noise),
                "robot_time_s_max": max(r["robot_time_s"] for r in cell),
                "robot_time_s_min": min(r["robot_time_s"] for r in cell),
                "lag_error_measured": len(lags),
                "lag_error_s_median": statistics.median(lags) if lags else None,
                "lag_error_s_range": [min(lags), max(lags)] if lags else None,
                "outcomes": dict(_count(r["outcome"] for r in cell)),
            }
            # one calibration per robot (the drawer's posture, first seed) for every task
            wide = next(r for r in cell if r["task"] == ROBOT_WIDE_POSTURE)
            truths = {r["task"]: r["tau_truth"] for r in cell}
            robot_wide[f"{robot}:{stiffness:g}"] = {
                "tau": wide["tau"],
                "ratio_by_task": {
                    task: None if wide["tau"] is None else wide["tau"] / truth
                    for task, truth in truths.items()
                },
            }
    misses = [
        f"{r['robot']}:{r['stiffness_setting']:g} {r['task']} seed {r['seed']}: "
        + (f"{r['tau_ratio']:.2f} x truth" if r["tau_ratio"] is not None else r["tau_reason"])
        for r in rows
        if r["tau_ratio"] is None or abs(r["tau_ratio"] - 1) > tol
    ]
    wide_misses = [
        f"{key} {task}: {ratio:.2f} x truth" if ratio is not None else f"{key} {task}: unmeasured"
        for key, entry in robot_wide.items()
        for task, ratio in entry["ratio_by_task"].items()
        if ratio is None or abs(ratio - 1) > tol
    ]
    return {
        "config": {
            "seeds": seeds,
            "stiffnesses_N_per_m": IN_RANGE,
            "tasks": list(TASKS),
            "sensor_noise_N": SENSOR_NOISE,
            "free_space": vars(FreeSpaceConfig()),
            "robot_wide_posture": ROBOT_WIDE_POSTURE,
        },
        "must_shows": {
            "tau_within_20pct": {
                "calibrations": len(rows),
                "within": len(rows) - len(misses),
                "held": not misses,
                "misses": misses,
            },
            "robot_wide_tau_within_20pct": {
                "pairs": sum(len(e["ratio_by_task"]) for e in robot_wide.values()),
                "held": not wide_misses,
                "misses": wide_misses,
            },
            "robot_time_s_max": max(r["robot_time_s"] for r in rows),
        },
        "summary": summary,
        "robot_wide": robot_wide,
        "calibrations": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--seeds", type=int, default=5, help="sensor-noise seeds per cell")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    parser.add_argument(
        "--tool-point",
        action="store_true",
        help="only the stiffness against the tool-point truth, in each robot's variant range",
    )
    parser.add_argument(
        "--free-space",
        action="store_true",
        help="only the free-space calibration's tau against the simulators' (module docstring)",
    )
    parser.add_argument(
        "--pushes-alone",
        action="store_true",
        help="calibrate each grasp without the robot's free-space calibration (tau from the "
        "pushes, the noise from the grasp's own readings at rest)",
    )
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error("--seeds must be >= 1")
    start = time.perf_counter()
    if args.free_space:
        out = free_space_sweep(args.seeds)
        out["wall_time_s"] = time.perf_counter() - start
        write_results(args.out, out)
        print(f"wrote {args.out}")
        print(json.dumps(out["must_shows"], indent=1))
        return
    if args.tool_point:
        out = tool_point(args.seeds)
        out["wall_time_s"] = time.perf_counter() - start
        write_results(args.out, out)
        print(f"wrote {args.out}")
        return
    with_free_space = not args.pushes_alone
    rows = list(sweep(args.seeds, with_free_space))
    results: dict[str, Any] = {
        "config": {
            "seeds": args.seeds,
            "robots": ROBOTS,
            "stiffnesses_N_per_m": IN_RANGE,
            "tasks": list(TASKS),
            "sensor_noise_N": SENSOR_NOISE,
            "calibration": vars(CalibrationConfig()),
            "free_space_profile": (
                f"one per robot, stiffness and seed at the {ROBOT_WIDE_POSTURE} grasp posture"
                if with_free_space
                else None
            ),
            "free_space": vars(FreeSpaceConfig()) if with_free_space else None,
        },
        "must_shows": must_shows(rows),
        "summary": summarize(rows),
        "per_direction": per_direction(rows),
        "diagnostics": {
            "wrist_rotation": wrist_rotation(),
            "jaco_step_sizes": jaco_step_sizes(),
            "noise_seeds": noise_seeds(with_free_space=with_free_space),
        },
        "calibrations": rows,
        "wall_time_s": time.perf_counter() - start,
    }
    write_results(args.out, results)
    print(f"wrote {args.out}")
    for name, show in results["must_shows"].items():
        print(name, "held" if show["held"] else f"NOT held ({len(show['misses'])} misses)")


if __name__ == "__main__":
    main()
