"""How close the Jaco's hand comes to a crank's hinge post on the way to the knob: at the
grasp and at points back along the approach, for each of the knob's two grasps (the knob is
a box: a half turn about the approach holds it the same way) and each finger shape.

    nice -n 10 python benchmarks/studies/jaco_crank_clearance.py [--per-kind 15]
        [--out FILE.json]

The end-to-end benchmark's crank placements (bench/endtoend.py), each as the robot believes
it (the object built from the offset demonstration: what the station and the planner check)
and as it is (the simulated object). For each: the knob's radius, the distance from the
hinge axis to the tool axis less the post's radius (the room the hand has toward the post),
and the least distance [cm] of any hand geom from the post (`scene_hinge`) with the tool at
the grasp and 5 and 10 cm back along the approach, the hand turned 0 or 180 deg about the
approach, its fingers at the knob's pre-shape or closed. The planner keeps 2 cm
(`sim.reach.PlannerConfig.clearance`). The hand's distance does not depend on the arm's
posture: the tool pose fixes the hand.

Writes JSON with provenance, prints a line per placement.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.bench.endtoend import FULL_PER_KIND, _demo_skill
from constraint_aware.bench.provenance import write_results
from constraint_aware.lfo.scene import scene_from_skill
from constraint_aware.lfo.synthetic import HandOffset, random_placement
from constraint_aware.sim.jaco import BASE_PLACEMENT, JACO_GRASPS, arm_base
from constraint_aware.sim.reach import (
    BASE_CANDIDATES,
    JACO_PRESHAPE,
    JacoPlanner,
    _grasp,
    facing,
)
from constraint_aware.sim.scene import OBJECT_PREFIX
from constraint_aware.sim.tasks import KINDS, TaskConfig
from constraint_aware.spatial import Pose

HERE = Path(__file__).parent
POST = OBJECT_PREFIX + "scene_hinge"
POST_RADIUS = 0.012  # [m] sim.objects._hinge_post
BACK = (0.0, 0.05, 0.10)  # [m] back from the grasp along the approach
ROLLS = (0.0, 180.0)  # [deg] about the approach
FINGERS = {"pre-shape": JACO_PRESHAPE["knob"], "closed": JACO_GRASPS["knob"].finger_target}


def _hand_at(planners: list[JacoPlanner], pose: Pose) -> tuple[JacoPlanner, np.ndarray] | None:
    """The first of `planners` (one per base) whose arm puts the tool at `pose`, with its arm
    angles (6,) [rad]; None when none does. The hand's geometry depends on the tool pose
    alone, not on the base or the arm's posture."""
    for planner in planners:
        seeds = planner._seeds(pose, facing(planner.base, pose.position))
        for seed in seeds:
            q = planner._ik_from(seed, pose)
            if q is not None:
                return planner, q
    return None


def hand_to_post(task: TaskConfig) -> dict[str, Any]:
    """The hand's least distance [cm] from the hinge post of `task`'s crank (module
    docstring), with the closest hand part."""
    obj = task.object
    axis = np.asarray(obj.axis, dtype=float)
    rel = np.asarray(obj.handle_position, dtype=float) - np.asarray(obj.position, dtype=float)
    rel -= float(rel @ axis) * axis
    planners = []
    for placement in (BASE_PLACEMENT[("revolute", "knob")], *BASE_CANDIDATES):
        planner = JacoPlanner(arm_base(task, placement))
        planner.set_object(task)
        planners.append(planner)
    grasp = _grasp(task)
    approach = grasp.orientation.apply([0.0, 0.0, 1.0])
    rows: list[dict[str, Any]] = []
    for roll in ROLLS:
        turned = Pose(grasp.position, grasp.orientation * Rotation.from_euler("z", roll, True))
        for back in BACK:
            found = _hand_at(planners, turned.moved(-back * approach))
            if found is None:
                rows.append({"roll_deg": roll, "back_m": back, "reached": False})
                continue
            planner, q = found
            m, d = planner.model, planner._scratch
            post = m.geom(POST).id
            hand = [g for g in planner._robot_geoms if "/hand/" in m.body(m.geom_bodyid[g]).name]
            for shape, angle in FINGERS.items():
                planner.fingers = angle
                d.qpos[:] = planner._full(q)
                mujoco.mj_kinematics(m, d)
                near = min((mujoco.mj_geomDistance(m, d, g, post, 0.5, None), g) for g in hand)
                rows.append(
                    {
                        "roll_deg": roll,
                        "back_m": back,
                        "fingers": shape,
                        "reached": True,
                        "distance_cm": 100.0 * float(near[0]),
                        "closest": m.body(m.geom_bodyid[near[1]]).name,
                    }
                )
    return {
        "radius_m": float(np.linalg.norm(rel)),
        "room_cm": 100.0 * (float(np.linalg.norm(rel)) - POST_RADIUS),
        "approach": [float(v) for v in approach],
        "rows": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--per-kind", type=int, default=FULL_PER_KIND)
    parser.add_argument("--out", default=str(HERE / "results" / "jaco_crank_clearance.json"))
    args = parser.parse_args()
    k = KINDS.index("crank")
    out: list[dict[str, Any]] = []
    for i in range(args.per_kind):
        place = random_placement("crank", np.random.default_rng([0, k, i]))
        skill = _demo_skill(place, np.random.default_rng([0, k, i, 2]), HandOffset())
        entry: dict[str, Any] = {"index": i}
        for label, task in (("believed", scene_from_skill(skill).task), ("true", place.task)):
            entry[label] = hand_to_post(task)
        out.append(entry)

        def at(label: str, back: float, shape: str, e: dict[str, Any] = entry) -> str:
            cells = []
            for roll in ROLLS:
                found = [
                    r["distance_cm"]
                    for r in e[label]["rows"]
                    if r["reached"]
                    and r["roll_deg"] == roll
                    and r["back_m"] == back
                    and r["fingers"] == shape
                ]
                cells.append("-" if not found else f"{found[0]:.1f}")
            return "/".join(cells)

        t = entry["true"]
        print(
            f"crank {i}: radius {t['radius_m']:.3f} m (believed "
            f"{entry['believed']['radius_m']:.3f}), room {t['room_cm']:.1f} cm; hand to post "
            f"[cm], roll 0/180 deg, true: pre-grasp 10 cm {at('true', 0.10, 'pre-shape')}, "
            f"5 cm {at('true', 0.05, 'pre-shape')}, grasp {at('true', 0.0, 'pre-shape')} "
            f"(closed {at('true', 0.0, 'closed')}); believed pre-grasp 10 cm "
            f"{at('believed', 0.10, 'pre-shape')}",
            flush=True,
        )
    data = {"per_kind": args.per_kind, "planner_clearance_m": 0.02, "placements": out,
            "rolls_deg": list(ROLLS), "back_m": list(BACK)}  # fmt: skip
    print(f"wrote {write_results(args.out, data)}")


if __name__ == "__main__":
    main()
