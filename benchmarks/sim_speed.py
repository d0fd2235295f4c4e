"""Simulation speed: 30-step episodes (3 s of robot time) vs real time, one core. Prints JSON.

    python benchmarks/sim_speed.py [--repeats 5] [--robots hook-hand,jaco]

Per embodiment and task: the median wall time of a 30-control-step episode with the policy
(success is pushed out of reach so every episode runs all 30 steps; the wall time includes the
grasp, the robot time counts only the 30 periods) and its real-time factor; then the median
wall time of running all five tasks once to their normal end with one controller. Both
embodiments are measured in the same run, so their ratio holds on a loaded machine too.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time

from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.sim.tasks import TASKS
from constraint_aware.sim.world import CONTROL_PERIOD

OFFSETS = {"prismatic": -30.0, "revolute": 15.0}


def episode_seconds(task: str, steps: int, repeats: int, robot: str = "hook-hand") -> float:
    overrides = (("max_steps", steps), ("success_progress", 1e9), ("force_limit", 1e9))
    spec = RunSpec(task=task, offset_deg=10.0, overrides=overrides, robot=robot)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run(spec)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--controller", default="policy")
    parser.add_argument("--robots", default="hook-hand,jaco")
    args = parser.parse_args()
    steps = 30
    out: dict[str, object] = {
        # other processes on the machine slow every figure alike: compare embodiments by ratio
        "load_average_1min_at_start": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "episode_steps": steps,
        "controller": args.controller,
        "repeats": args.repeats,
    }
    for robot in args.robots.split(","):
        per_task = {}
        for task in TASKS:
            wall = episode_seconds(task, steps, args.repeats, robot)
            per_task[task] = {
                "episode_wall_s": wall,
                "real_time_factor": steps * CONTROL_PERIOD / wall,
            }
        suite_times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            for task in TASKS:
                run(RunSpec(task=task, controller=args.controller, offset_deg=15.0, robot=robot))
            suite_times.append(time.perf_counter() - start)
        out[robot] = {
            "per_task": per_task,
            "min_real_time_factor": min(v["real_time_factor"] for v in per_task.values()),
            "all_five_tasks_wall_s_median": statistics.median(suite_times),
        }
    out["load_average_1min_at_end"] = os.getloadavg()[0]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
