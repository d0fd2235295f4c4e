"""Which doors the Jaco can open from one base: the door's radius and opening angle against
the base placements that reach the whole demonstrated arc.

    nice -n 10 python benchmarks/studies/jaco_door_reach.py [--radii 0.4,0.6,...,1.0]
        [--angles 60,75,90] [--senses 1,-1] [--out FILE.json]

A door with its handle at 0.9 m, hinged either side, each radius [m] and opening angle
[deg]; for each, `sim.reach.reaches_from` (the pre-grasp and the grasp at 0, 50 and 100 % of
the opening, 0.15 rad inside the joint limits, clear of the door; a home clear of it) from

- `candidates`: the sequence's own search (`sim.jaco.BASE_PLACEMENT` and
  `sim.reach.BASE_CANDIDATES`, 11 placements);
- `wide`: a denser grid of placements (horizontal distance 0.35-0.65 m from the handle's
  half-way position, every 45 deg of azimuth, heights -0.3 and -0.1 m: 64), after a
  distance filter (every grasp along the arc within `REACH` of the shoulder).

Writes JSON with provenance, prints a line per door: the number of placements that reach.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.lfo.scene import STEP_LENGTH
from constraint_aware.sim.jaco import BASE_PLACEMENT, arm_base
from constraint_aware.sim.reach import (
    BASE_CANDIDATES,
    _grasp,
    motion_poses,
    reaches_from,
)
from constraint_aware.sim.tasks import TaskConfig, object_for, task_from_object

HERE = Path(__file__).parent
HANDLE = np.array([0.6, 0.0, 0.9])  # [m]
SHOULDER = 0.2755  # [m] the Jaco's shoulder above its base (Kinova's D1)
REACH = 0.95  # [m] shoulder to tool point, fully stretched, rounded up
WIDE = tuple(
    (r, a, h) for r in (0.35, 0.45, 0.55, 0.65) for a in range(0, 360, 45) for h in (-0.3, -0.1)
)
HOME = (-0.10, 0.50)  # SequenceConfig's jaco_home_forward, jaco_home_up


def door(radius: float, angle_deg: float, sense: float) -> TaskConfig:
    """A door facing -x with its handle at `HANDLE`, hinged `radius` [m] to the side."""
    radial = np.array([0.0, sense, 0.0])
    obj = object_for(
        "door",
        position=tuple(float(v) for v in HANDLE - radius * radial),
        axis=(0.0, 0.0, sense),
        radial=tuple(float(v) for v in radial),
        radius=radius,
    )
    return task_from_object(
        "door", obj, success_progress=math.radians(angle_deg), step_length=STEP_LENGTH
    )


def _within_reach(task: TaskConfig, base: np.ndarray, motion: list[Any]) -> bool:
    shoulder = base + np.array([0.0, 0.0, SHOULDER])
    return all(float(np.linalg.norm(p.position - shoulder)) <= REACH for p in motion)


def one(radius: float, angle: float, sense: float) -> dict[str, Any]:
    task = door(radius, angle, sense)
    grasp = _grasp(task)
    motion = motion_poses(task, grasp, (0.0, 0.5, 1.0))
    kind = ("revolute", "bar")
    out: dict[str, Any] = {"radius_m": radius, "angle_deg": angle, "sense": sense}
    for name, grid in (("candidates", [BASE_PLACEMENT[kind], *BASE_CANDIDATES]), ("wide", WIDE)):
        bases = [(p, arm_base(task, p)) for p in grid]
        near = [(p, b) for p, b in bases if _within_reach(task, b, motion)]
        ok = [p for p, b in near if reaches_from(task, b, 0.10, HOME, grasp)]
        out[name] = {"tried": len(grid), "within_reach": len(near), "reach": len(ok),
                     "placements": ok}  # fmt: skip
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--radii", default="0.4,0.6,0.7,0.8,0.9,1.0")
    parser.add_argument("--angles", default="60,75,90")
    parser.add_argument("--senses", default="1,-1", help="hinge axis +z, -z")
    parser.add_argument("--out", default=str(HERE / "results" / "jaco_door_reach.json"))
    args = parser.parse_args()
    runs = []
    for radius in (float(r) for r in args.radii.split(",")):
        for angle in (float(a) for a in args.angles.split(",")):
            for sense in (float(v) for v in args.senses.split(",")):
                run = one(radius, angle, sense)
                runs.append(run)
                print(
                    f"R {radius:.2f} m, {angle:.0f} deg, axis {sense:+.0f}z: "
                    f"{run['candidates']['reach']}/{run['candidates']['tried']} candidates, "
                    f"{run['wide']['reach']}/{run['wide']['tried']} of the wide grid "
                    f"({run['wide']['within_reach']} within reach)",
                    flush=True,
                )
    out = write_results(args.out, {"handle_m": HANDLE.tolist(), "runs": runs})
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
