"""How far healthy runs stay from each executor guard's threshold. Writes JSON, prints a table.

    python benchmarks/guard_margins.py [--robots hook-hand:stiffness=500 hook-hand jaco]
        [--seeds 0 1] [--out benchmarks/results/guard_margins.json]

The default policy on the five tasks at the paper's offsets (benchmarks/guard_lag.py's cases),
per robot spec and seed, with every guard on. A wrapper records each period's reading and
command; from them, independently of the executor's own state, per run:

- `pose_excess_mm`: the largest |hand move| - |command change| between two periods (the pose
  plausibility guard allows the command change plus guards.pose_jump_margin, 10 mm);
- `arm_excess_steps`: the largest k |deflection| - |F| in step forces k delta, the deflection
  measured - commanded less its value when moving began: `quasi_static` (no lag credit) and
  `lag_model` (control.lag's credit of tau x the hand's velocity, tau the robot's report or
  the hook hand's c / k); the arm-force guard subtracts 0.75 step forces and stops when the
  rest exceeds |F| by 0.5 step forces;
- `lead_mm`: the largest |command - measured pose| (the lead bound: force_limit / k + 2 delta);
- `along_median`, `cos_median`: the run's medians of F.d/|F| and of cos(F, deflection with the
  lag model) over the self-check's first 8 moves with an in-plane |F| of at least 2 N (the
  self-check stops above 0.1, and below 0 unless the arm confirms at 0.5 or more);
- `stale_max`: the longest run of identical wrench samples (the guard stops at 3).

Robots as `sim.embodiment` specs. One process, in order.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.faults import hook_hand_time_constant
from constraint_aware.bench.provenance import write_results
from constraint_aware.control.executor_config import ExecutorConfig
from constraint_aware.control.lag import LagModel
from constraint_aware.control.robot import reported_stiffness, reported_time_constant
from constraint_aware.control.self_check import MIN_FORCE as SELF_CHECK_FORCE
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.geometry import in_plane
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.spatial import Pose

OUT = Path(__file__).parent / "results" / "guard_margins.json"
CASES = (
    ("drawer-opening", 30.0),
    ("drawer-opening", -30.0),
    ("plate-sliding", -30.0),
    ("pole-pulling", -30.0),
    ("door-opening", 15.0),
    ("handle-rotating", 15.0),
)


class Recorder:
    """Forwards the Robot protocol to the simulator; records each reading and command."""

    def __init__(self, sim: Any) -> None:
        self._sim = sim
        self.start = sim.commanded_pose().position.copy()
        self.forces: list[np.ndarray] = []
        self.wrench_samples: list[tuple[float, ...]] = []
        self.positions: list[np.ndarray] = []
        self.commands: list[np.ndarray] = []

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)

    def read_wrench(self) -> Any:
        w = self._sim.read_wrench()
        self.forces.append(np.array(w.force, dtype=float))
        self.wrench_samples.append((*np.asarray(w.force).tolist(), *np.asarray(w.torque).tolist()))
        return w

    def read_pose(self) -> Pose:
        p = self._sim.read_pose()
        self.positions.append(np.array(p.position, dtype=float))
        return p

    def command_pose(self, pose: Pose) -> None:
        self.commands.append(np.array(pose.position, dtype=float))
        self._sim.command_pose(pose)


def margins(rec: Recorder, record: Any, k: float, tau: float, period: float) -> dict[str, Any]:
    """The module docstring's per-run figures from the recorded periods."""
    cfg = ExecutorConfig()
    first = cfg.timing.offset_samples - 1  # the last F_d sample is the first step's reading
    offset = np.asarray(record.force_offset, dtype=float)
    n = len(rec.positions)
    # the target in effect at reading j: the command sent after reading j - 1
    targets = [rec.start, *rec.commands][:n]
    normal = np.asarray(record.inputs["workplane_normal"]["value"], dtype=float)
    step_force = k * cfg.step_length
    lag = LagModel(tau)
    lag.begin(rec.positions[first], targets[first])
    quasi: list[float] = []
    lagged: list[float] = []
    along: list[float] = []
    cosines: list[float] = []
    for j in range(first, n):
        force = rec.forces[j] - offset
        lag.note_motion(rec.positions[j], period)  # as the executor: once per period
        deflection = lag.deflection(rec.positions[j], targets[j], lag_share=0.0)
        quasi.append(k * float(np.linalg.norm(deflection)) - float(np.linalg.norm(force)))
        credited = lag.lagged_deflection(rec.positions[j], targets[j])
        lagged.append(k * float(np.linalg.norm(credited)) - float(np.linalg.norm(force)))
        moves = j - first
        if 1 <= moves <= cfg.self_check.steps:
            f = in_plane(force, normal)
            size = float(np.linalg.norm(f))
            if size >= max(record.threshold, SELF_CHECK_FORCE):
                d = np.asarray(record.steps[moves].direction, dtype=float)
                along.append(float(f @ d) / size)
                full = in_plane(lag.deflection(rec.positions[j], targets[j]), normal)
                if float(np.linalg.norm(full)) > 1e-9:
                    cosines.append(float(f @ full) / (size * float(np.linalg.norm(full))))
    pose_excess = [
        float(np.linalg.norm(rec.positions[j] - rec.positions[j - 1]))
        - float(np.linalg.norm(targets[j] - targets[j - 1]))
        for j in range(first + 1, n)
    ]
    leads = [
        float(np.linalg.norm(rec.commands[j] - rec.positions[j]))
        for j in range(first, min(n, len(rec.commands)))
    ]
    stale, longest = 1, 1
    for a, b in zip(rec.wrench_samples, rec.wrench_samples[1:], strict=False):
        stale = stale + 1 if a == b else 1
        longest = max(longest, stale)
    return {
        "pose_excess_mm": 1000 * max(pose_excess, default=0.0),
        "arm_excess_steps": {
            "quasi_static": max(quasi) / step_force,
            "lag_model": max(lagged) / step_force,
        },
        "lead_mm": 1000 * max(leads, default=0.0),
        "lead_bound_mm": 1000 * (cfg.limits.force_limit / k + 2 * cfg.step_length),
        "along_median": float(np.median(along)) if along else None,
        "cos_median": float(np.median(cosines)) if cosines else None,
        "self_check_moves": len(along),
        "stale_max": longest,
    }


def one_run(robot: str, task: str, offset: float, seed: int, policy: Any) -> dict[str, Any]:
    recorders: list[Recorder] = []

    def wrap(sim: Any) -> Recorder:
        recorders.append(Recorder(sim))
        return recorders[-1]

    spec = RunSpec(task, "policy", offset, seed, robot=robot)
    record, sim = run(spec, policy=policy, wrap=wrap)
    k, _ = reported_stiffness(sim)
    tau, _ = reported_time_constant(sim)
    if tau is None:
        tau = hook_hand_time_constant(sim)  # type: ignore[arg-type]
    assert k is not None
    out = {"robot": robot, "task": task, "offset_deg": offset, "seed": seed}
    out |= {"outcome": record.outcome, "stiffness_N_per_m": k, "tau_s": tau}
    return out | margins(recorders[0], record, k, tau, float(sim.control_period))


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    def top(key: str, sub: str | None = None) -> float:
        return max(r[key][sub] if sub else r[key] for r in runs)

    along = [r["along_median"] for r in runs if r["along_median"] is not None]
    cos = [r["cos_median"] for r in runs if r["cos_median"] is not None]
    return {
        "runs": len(runs),
        "outcomes": {o: sum(r["outcome"] == o for r in runs) for o in {r["outcome"] for r in runs}},
        "pose_excess_mm_max": top("pose_excess_mm"),
        "arm_excess_steps_max": {
            "quasi_static": top("arm_excess_steps", "quasi_static"),
            "lag_model": top("arm_excess_steps", "lag_model"),
        },
        "lead_mm_max": top("lead_mm"),
        "lead_bound_mm": runs[0]["lead_bound_mm"],
        "along_median_range": [min(along), max(along)] if along else None,
        "cos_median_range": [min(cos), max(cos)] if cos else None,
        "stale_max": top("stale_max"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--robots", nargs="+", default=["hook-hand:stiffness=500", "hook-hand", "jaco"]
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    policy = ConstraintAwarePolicy.load("default")
    runs = []
    for robot in args.robots:
        for task, offset in CASES:
            for seed in args.seeds:
                runs.append(one_run(robot, task, offset, seed, policy))
                r = runs[-1]
                arm = r["arm_excess_steps"]
                print(
                    f"{robot:24s} {task:16s} {offset:+4.0f} s{seed} {r['outcome']:14s} "
                    f"pose {r['pose_excess_mm']:5.2f} mm, arm {arm['quasi_static']:+.2f}/"
                    f"{arm['lag_model']:+.2f} steps, lead {r['lead_mm']:5.1f} mm, "
                    f"along {r['along_median']}, cos {r['cos_median']}",
                    flush=True,
                )
    results = {
        "cases": [list(c) for c in CASES],
        "seeds": args.seeds,
        "by_robot": {rb: summary([r for r in runs if r["robot"] == rb]) for rb in args.robots},
        "runs": runs,
    }
    write_results(args.out, results)
    print(json.dumps(results["by_robot"], indent=1))


if __name__ == "__main__":
    main()
