"""Any robot, measured: a robot reporting only the Robot protocol's required members, given a
robot profile from `cap calibrate`, against the same robot reporting everything; and dead or
frozen force sensors on both.

    python benchmarks/stripped_robot.py [--seeds 20] [--sections stripped,dead_sensor]
        [--free-space TASK|none] [--out benchmarks/results/stripped_robot.json]

Profiles: one calibration (control.calibrate.calibrate, default settings, pushing in the
task's workplane as `cap calibrate` does) per robot and task, on the task's preset object (not
randomized), seed 0, through an adapter exposing only the required members: the profile a
user would make once per robot and grasp. With `--fixture
ROBOT=TASK`, one calibration of ROBOT holding TASK's object serves every task (a user who
calibrates once per robot, on an object where every quantity can be measured).
`--free-space TASK` (default drawer-opening; "none": off): first one free-space calibration
per robot (control.free_space.calibrate_free_space, through the same adapter) at TASK's grasp
posture with the simulator's contacts off (the hand holding nothing), given to every task's
calibration as `free_space_profile`: its tracking time constant replaces the pushes' estimate,
and its lag error (from setpoint ramps at the executor's step per period) times the task's
stiffness gives the deflection error per speed where the task's pushes leave it unmeasured (a
user's order: free space once, then each grasp).

Section "stripped" (on the randomized suite of bench/sweep.py, controller `policy`, the same
draws for each condition):
- "full reports": the simulated robot as it is (translational_stiffness,
  tracking_time_constant, grasp_contact, hold), no profile, and on the hook hand's bar grasps
  (drawer, door) the grasp play its geometry defines (`HandConfig.bar_gap`, 1.5 mm) as
  ExecutorConfig.robot.grasp_play: the Robot protocol has no member for the play, so a
  robot that knows everything says it in its configuration (the Jaco's fingers close on the
  bar: no play the simulator defines);
- "stripped + profile": only the required members (read_wrench, read_pose, commanded_pose,
  command_pose, advance, control_period), with the profile;
- "stripped, no profile": only the required members, no profile (what the profile buys);
- "stripped + profile, reported k and tau" (a diagnostic, outside the must-show): the
  profile with its stiffness and tracking time constant replaced by the robot's reports,
  which shows what is left of a difference once both conditions use the same k and tau.
Per robot, task and condition: successes / runs, the median peak |F| and the median mean |F|
[N], the outcomes, and the sources of the run inputs. Must-show: "stripped + profile" has the
same successes as "full reports" and median peak and mean |F| within noise (5 % or 0.2 N).

Section "dead_sensor": each task at offset +-15 deg (prismatic +-30 deg) with seed 0, the
sensor failing after ONSET moves: "noise_at_tare" (fresh Gaussian noise of the simulated
sigma around the mean reading over the F_d hold: a dead sensor's tare), "noise_at_last"
(the same noise around the last reading before the failure: an amplifier stuck at its last
level), "jitter" (the last reading held with 1e-9 N of
jitter), "frozen" (the last reading held exactly); the failed sensor's noise drawn from its
own generator per run (seeded with the run's index); with the profile, with and without the
robot's translational_stiffness report; and without a profile for contrast. The true force is
the simulator's noise-free wrench minus its mean over the F_d hold; each run records its peak
over the run and after the failure. Must-show: no true |F| above the force limit after any
period, and no `success` on a dead sensor.
Results JSON through bench.provenance.write_results.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.sweep import suite_specs
from constraint_aware.control.calibrate import calibrate
from constraint_aware.control.executor_config import ExecutorConfig
from constraint_aware.control.free_space import calibrate_free_space
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.robot import Robot
from constraint_aware.control.simulate import RunSpec, grasped, run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import TASKS, task_config
from constraint_aware.spatial import Pose, Wrench

DEFAULT_OUT = Path(__file__).parent / "results" / "stripped_robot.json"
ROBOTS = ("hook-hand", "jaco")
CONDITIONS = (
    "full reports",
    "stripped + profile",
    "stripped, no profile",
    "stripped + profile, reported k and tau",
)
FAULTS = ("noise_at_tare", "noise_at_last", "jitter", "frozen")
ONSET = 5  # moves before the sensor fails
SENSOR_NOISE = 0.1  # [N] the suite's
TOLERANCE = (0.05, 0.2)  # within noise: 5 % or 0.2 N, whichever is larger


class RequiredOnly:
    """Forwards only the Robot protocol's required members to `inner`."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.control_period = float(inner.control_period)

    def read_wrench(self) -> Wrench:
        return self._inner.read_wrench()

    def read_pose(self) -> Pose:
        return self._inner.read_pose()

    def commanded_pose(self) -> Pose:
        return self._inner.commanded_pose()

    def grasp_contact(self) -> bool | None:
        return None  # the Robot protocol's "cannot tell": as if the member were absent

    def command_pose(self, pose: Pose) -> None:
        self._inner.command_pose(pose)

    def advance(self) -> None:
        self._inner.advance()


class DeadSensor:
    """The simulated robot with its force sensor failing after ONSET moves (module
    docstring); reports its stiffness only when `report_stiffness`; tracks the true force."""

    def __init__(
        self, sim: Any, fault: str, report_stiffness: bool, hold_periods: int, seed: int = 99
    ) -> None:
        self.sim = sim
        self.fault = fault
        self.report_stiffness = report_stiffness
        self.hold_periods = hold_periods
        self.control_period = float(sim.control_period)
        self.periods = 0
        self.holds = 0
        self.true_forces: list[np.ndarray] = []
        self.last: Wrench | None = None
        self.rest: list[Wrench] = []  # the readings over the F_d hold
        self.rng = np.random.default_rng(seed)  # the failed sensor's noise
        self.onset: int | None = None  # the period the sensor failed at

    def __getattr__(self, name: str) -> Any:
        if name == "translational_stiffness" and not self.__dict__["report_stiffness"]:
            raise AttributeError(name)
        if name in ("translational_stiffness", "tracking_time_constant", "grasp_contact"):
            return getattr(self.__dict__["sim"], name)
        raise AttributeError(name)

    def read_wrench(self) -> Wrench:
        failed = self.periods - self.hold_periods >= ONSET and self.last is not None
        if not failed:
            self.last = self.sim.read_wrench()
            if self.periods <= self.hold_periods:
                self.rest.append(self.last)
            return self.last
        assert self.last is not None
        if self.onset is None:
            self.onset = self.periods
        if self.fault == "noise_at_tare":
            tare = np.mean([w.force for w in self.rest], axis=0)
            torque = np.mean([w.torque for w in self.rest], axis=0)
            return Wrench(tare + SENSOR_NOISE * self.rng.normal(size=3), torque)
        if self.fault == "noise_at_last":
            return Wrench(
                self.last.force + SENSOR_NOISE * self.rng.normal(size=3), self.last.torque
            )
        jitter = 1e-9 * math.sin(self.periods) if self.fault == "jitter" else 0.0
        return Wrench(self.last.force + jitter, self.last.torque + jitter)

    def read_pose(self) -> Pose:
        return self.sim.read_pose()

    def commanded_pose(self) -> Pose:
        return self.sim.commanded_pose()

    def command_pose(self, pose: Pose) -> None:
        self.sim.command_pose(pose)

    def advance(self) -> None:
        self.sim.advance()
        self.periods += 1
        self.true_forces.append(np.asarray(self.sim.true_wrench().force, dtype=float))

    def hold(self) -> None:
        self.holds += 1
        self.sim.command_pose(self.sim.read_pose())


def free_space_profiles(robots: tuple[str, ...], posture: str) -> dict[str, RobotProfile]:
    """One free-space calibration per robot at `posture`'s grasp (module docstring)."""
    out = {}
    for robot in robots:
        _task, sim = grasped(RunSpec(task=posture, robot=robot, seed=0))
        out[robot] = calibrate_free_space(
            RequiredOnly(sim.in_free_space()),
            f"{robot} / free space",
            setup=f"free space ({posture})",
        )
    return out


def profiles(
    robots: tuple[str, ...],
    fixtures: dict[str, str],
    free: dict[str, RobotProfile] | None = None,
) -> dict[tuple[str, str], RobotProfile]:
    """One calibration per robot and task (module docstring); or, for a robot in `fixtures`,
    one calibration on that task used for every task; each given the robot's free-space
    profile from `free` when there is one."""
    out = {}
    for robot in robots:
        for task in TASKS:
            fixture = fixtures.get(robot, task)
            if (robot, fixture) not in out:
                task_cfg, sim = grasped(RunSpec(task=fixture, robot=robot, seed=0))
                out[(robot, fixture)] = calibrate(
                    RequiredOnly(sim),
                    f"{robot} / {fixture}",
                    task_cfg.workplane_normal,
                    free_space_profile=(free or {}).get(robot),
                )
            out[(robot, task)] = out[(robot, fixture)]
    return out


def known_play(robot: str, task: str) -> float | None:
    """[m] the grasp play the simulated robot's geometry defines: the hook hand's gap beside
    a bar; None elsewhere."""
    cfg = task_config(task)
    if robot != "hook-hand" or cfg.object.handle != "bar":
        return None
    return cfg.hand.bar_gap(cfg.object.handle_radius)


def with_reports(profile: RobotProfile, sim: Any) -> RobotProfile:
    """`profile` with its stiffness and tracking time constant replaced by `sim`'s reports."""
    quantities = dict(profile.quantities)
    for name, reported in (
        ("stiffness", sim.translational_stiffness),
        ("tracking_time_constant", sim.tracking_time_constant),
    ):
        quantities[name] = dataclasses.replace(quantities[name], value=float(reported))
    return dataclasses.replace(profile, quantities=quantities)


def _within_noise(a: float, b: float) -> bool:
    return abs(a - b) <= max(TOLERANCE[0] * max(abs(a), abs(b)), TOLERANCE[1])


def stripped(
    seeds: int, robots: tuple[str, ...], profs: dict[tuple[str, str], RobotProfile]
) -> dict[str, Any]:
    policy = ConstraintAwarePolicy.load("default")
    rows: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for robot in robots:
        reported = {
            task: with_reports(profs[(robot, task)], grasped(RunSpec(task=task, robot=robot))[1])
            for task in TASKS
        }
        for spec in suite_specs(seeds, ["policy"]):
            spec = dataclasses.replace(spec, robot=robot)
            for condition in CONDITIONS:
                wrap: Callable[[Any], Robot] | None = None
                given: RobotProfile | None = None
                one = spec
                if condition == "full reports":
                    play = known_play(robot, spec.task)
                    if play is not None:
                        one = dataclasses.replace(
                            spec,
                            overrides=(*spec.overrides, ("executor__robot__grasp_play", play)),
                        )
                else:
                    wrap = RequiredOnly
                if condition == "stripped + profile":
                    given = profs[(robot, spec.task)]
                elif condition == "stripped + profile, reported k and tau":
                    given = reported[spec.task]
                record, _ = run(one, policy=policy, wrap=wrap, profile=given)
                summary = record.summary()
                summary["sources"] = {k: v["source"] for k, v in record.inputs.items()}
                rows.setdefault((robot, spec.task, condition), []).append(summary)
    cells: dict[str, Any] = {}
    verdicts: list[dict[str, Any]] = []
    for robot in robots:
        for task in TASKS:
            group = {c: rows[(robot, task, c)] for c in CONDITIONS}
            stats = {c: _cell(records) for c, records in group.items()}
            cells[f"{robot} / {task}"] = stats
            full, prof = stats["full reports"], stats["stripped + profile"]
            verdicts.append(
                {
                    "robot": robot,
                    "task": task,
                    "same_successes": full["success"] == prof["success"],
                    "peak_within_noise": _within_noise(
                        full["peak_force_median"], prof["peak_force_median"]
                    ),
                    "mean_within_noise": _within_noise(
                        full["mean_force_median"], prof["mean_force_median"]
                    ),
                }
            )
    return {"cells": cells, "verdicts": verdicts}


def _cell(records: list[dict[str, Any]]) -> dict[str, Any]:
    sources: Counter[str] = Counter()
    for r in records:
        sources.update(f"{k}:{v}" for k, v in r["sources"].items())
    return {
        "success": sum(r["success"] for r in records),
        "runs": len(records),
        "outcomes": dict(Counter(r["outcome"] for r in records)),
        "peak_force_median": statistics.median(r["peak_force_N"] for r in records),
        "mean_force_median": statistics.median(r["mean_force_N"] for r in records),
        "input_sources": dict(sources),
    }


def dead_sensor(
    robots: tuple[str, ...], profs: dict[tuple[str, str], RobotProfile]
) -> dict[str, Any]:
    policy = ConstraintAwarePolicy.load("default")
    hold_periods = ExecutorConfig().timing.offset_samples - 1
    runs: list[dict[str, Any]] = []
    for robot in robots:
        for task in TASKS:
            revolute = task_config(task).constraint_type == "revolute"
            for offset in (-15.0, 15.0) if revolute else (-30.0, 30.0):
                for fault in FAULTS:
                    for with_profile in (True, False):
                        for report in (True, False):
                            made: list[DeadSensor] = []

                            def wrap(
                                sim: Any,
                                fault: str = fault,
                                report: bool = report,
                                made: list[DeadSensor] = made,
                            ) -> Any:
                                made.append(
                                    DeadSensor(sim, fault, report, hold_periods, seed=len(runs))
                                )
                                return made[-1]

                            spec = RunSpec(task=task, robot=robot, offset_deg=offset, seed=0)
                            prof = profs[(robot, task)] if with_profile else None
                            record, sim = run(spec, policy=policy, wrap=wrap, profile=prof)
                            robot_ = made[0]
                            true = np.array(robot_.true_forces)
                            hold = true[: max(hold_periods, 1)].mean(axis=0)
                            magnitude = np.linalg.norm(true - hold, axis=1)
                            peak = float(np.max(magnitude))
                            after = magnitude[robot_.onset :] if robot_.onset is not None else []
                            peak_after = float(np.max(after)) if len(after) else None
                            limit = float(sim.task.force_limit)
                            runs.append(
                                {
                                    "robot": robot,
                                    "task": task,
                                    "offset_deg": offset,
                                    "fault": fault,
                                    "profile": with_profile,
                                    "stiffness_report": report,
                                    "outcome": record.outcome,
                                    "reason": record.reason,
                                    "peak_true_force_N": peak,
                                    "peak_true_force_after_onset_N": peak_after,
                                    "force_limit_N": limit,
                                    "true_force_above_limit": peak > limit,
                                    "success_on_dead_sensor": record.success,
                                    "holds": robot_.holds,
                                }
                            )
    summary: dict[str, Any] = {}
    for r in runs:
        key = (
            f"{r['robot']} / {r['fault']} / "
            f"{'profile' if r['profile'] else 'no profile'} / "
            f"{'stiffness report' if r['stiffness_report'] else 'no stiffness report'}"
        )
        row = summary.setdefault(
            key, {"runs": 0, "outcomes": Counter(), "above_limit": 0, "success": 0, "peak": 0.0}
        )
        row["runs"] += 1
        row["outcomes"][r["outcome"]] += 1
        row["above_limit"] += r["true_force_above_limit"]
        row["success"] += r["success_on_dead_sensor"]
        row["peak"] = max(row["peak"], r["peak_true_force_N"])
        if r["success_on_dead_sensor"] and r["peak_true_force_after_onset_N"] is not None:
            row["success_peak_after_onset"] = max(
                row.get("success_peak_after_onset", 0.0), r["peak_true_force_after_onset_N"]
            )
    for row in summary.values():
        row["outcomes"] = dict(row["outcomes"])
    return {"onset_moves": ONSET, "summary": summary, "runs": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    # the randomized suite's seeds per task (bench.sweep: 20 in `cap bench`)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--robots", default=",".join(ROBOTS))
    parser.add_argument("--sections", default="stripped,dead_sensor")
    parser.add_argument(
        "--fixture",
        action="append",
        default=[],
        metavar="ROBOT=TASK",
        help="calibrate ROBOT once, holding TASK's object, and use that profile on every task",
    )
    parser.add_argument(
        "--free-space",
        default="drawer-opening",
        metavar="TASK",
        help="calibrate each robot once in free space at TASK's grasp posture and give that "
        "profile to every calibration ('none': off)",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args()
    if args.free_space != "none" and args.free_space not in TASKS:
        parser.error(f"--free-space {args.free_space!r}: one of {', '.join(TASKS)} or none")
    robots = tuple(args.robots.split(","))
    sections = args.sections.split(",")
    fixtures = dict(item.split("=", 1) for item in args.fixture)
    start = time.perf_counter()
    free = free_space_profiles(robots, args.free_space) if args.free_space != "none" else {}
    profs = profiles(robots, fixtures, free)
    out: dict[str, Any] = {
        "seeds": args.seeds,
        "robots": list(robots),
        "fixtures": fixtures,
        "free_space_posture": None if args.free_space == "none" else args.free_space,
        "free_space_profiles": {r: p.to_dict() for r, p in free.items()},
        "profiles": {f"{r} / {t}": p.to_dict() for (r, t), p in profs.items()},
    }
    if "stripped" in sections:
        out["stripped"] = stripped(args.seeds, robots, profs)
        print("stripped", f"{time.perf_counter() - start:.0f} s", flush=True)
    if "dead_sensor" in sections:
        out["dead_sensor"] = dead_sensor(robots, profs)
        print("dead_sensor", f"{time.perf_counter() - start:.0f} s", flush=True)
    out["wall_time_s"] = time.perf_counter() - start
    write_results(args.out, out)


if __name__ == "__main__":
    main()
