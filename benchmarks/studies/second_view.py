"""Would a second look from the pre-grasp pose see the handles the head cameras cannot?

    nice -n 10 python benchmarks/studies/second_view.py [--scenes 40] [--seed 7]
        [--standoffs 0.1,0.2] [--out benchmarks/studies/results/second_view.json]

The recognizer benchmark's held-out scenes (`lfo.grasp_data.generate`'s draws for `--seed`:
the same placements, sizes, demonstrations and distractors as `benchmarks/recognizer.py`),
each kind. For each scene, the share of the handle within CONTACT_RADIUS of the true contact
point that a camera sees unoccluded (`handle_visibility(..., around=)`, ray casts against the
scene's rendered geoms; the truth is used only to score), from

- each robot's head camera, as the benchmark's crops see it;
- a camera on the demonstrated approach, `standoff` [m] back from the demonstrated point and
  looking at it (what a wrist camera would see from a pre-grasp pose the robot can compute
  without the recognizer: from the demonstration alone).

A crop counts as hidden below SEEN_SHARE (half), as in the benchmark. Reports per kind how many
scenes each view hides, and for the scenes a head camera hides, what the second view sees.
The hand itself is not in the scene: a real wrist camera also sees the fingers' edge.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

import mujoco

from constraint_aware.bench.provenance import write_results
from constraint_aware.lfo.grasp_data import SEEN_SHARE, draw_scene, handle_visibility, scene_rngs
from constraint_aware.lfo.perception import head_camera
from constraint_aware.sim.camera import CameraMount, look_at
from constraint_aware.sim.tasks import KINDS

ROBOTS = ("hook-hand", "jaco")
HERE = Path(__file__).parent


def scene_views(
    kind: str, seed: int, index: int, standoffs: list[float]
) -> dict[str, float] | None:
    """Contact visibility of scene `index` of `kind` from each head camera and each standoff;
    None when none of its draws gives a usable demonstration (as `generate` skips them)."""
    for rng in scene_rngs(seed, kind, index):  # the draws generate() makes for this scene
        scene = draw_scene(kind, rng)
        if scene is None:
            continue
        model = scene.spec.compile()
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        out = {
            f"head {robot}": handle_visibility(
                model, data, head_camera(robot, scene.skill), scene.truth
            )
            for robot in ROBOTS
        }
        origin, approach = scene.frame.origin, scene.frame.rotation[:, 2]  # the demonstrated
        for standoff in standoffs:
            mount = CameraMount(
                "second_view",
                look_at(origin - standoff * approach, origin),
                head_camera(ROBOTS[0], scene.skill).intrinsics,
            )
            out[f"approach {standoff:g} m"] = handle_visibility(model, data, mount, scene.truth)
        return out
    return None


def summarize(rows: list[dict[str, Any]], views: list[str]) -> dict[str, Any]:
    """Per kind and view: scenes hidden (visibility below SEEN_SHARE or none) and the median
    visibility; for the scenes each head camera hides, what the other views see there."""
    out: dict[str, Any] = {}
    for kind in KINDS:
        mine = [r for r in rows if r["kind"] == kind]

        def hidden(r: dict[str, Any], view: str) -> bool:
            v = r[view]
            return not (v == v and v >= SEEN_SHARE)  # NaN: no ray meets the handle

        entry: dict[str, Any] = {"scenes": len(mine)}
        for view in views:
            values = [r[view] for r in mine if r[view] == r[view]]
            entry[view] = {
                "hidden": sum(hidden(r, view) for r in mine),
                "visibility_median": statistics.median(values) if values else None,
            }
        for robot in ROBOTS:
            head = f"head {robot}"
            blind = [r for r in mine if hidden(r, head)]
            entry[f"where {head} is hidden"] = {
                view: [round(r[view], 3) for r in blind] for view in views if view != head
            }
        out[kind] = entry
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=40, help="scenes per kind (>= 1)")
    parser.add_argument("--seed", type=int, default=7, help="the recognizer benchmark's seed")
    parser.add_argument("--standoffs", default="0.1,0.2", help="[m] comma-separated, > 0")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "second_view.json")
    args = parser.parse_args()
    if args.scenes < 1:
        parser.error(f"--scenes: must be >= 1, got {args.scenes}")
    standoffs = [float(s) for s in args.standoffs.split(",")]
    if min(standoffs) <= 0.0:
        parser.error(f"--standoffs: each must be > 0 m, got {args.standoffs}")
    rows = []
    for kind in KINDS:
        for i in range(args.scenes):
            views = scene_views(kind, args.seed, i, standoffs)
            if views is not None:
                rows.append({"kind": kind, "scene": i, **views})
        print(kind, "done", flush=True)
    names = [f"head {r}" for r in ROBOTS] + [f"approach {s:g} m" for s in standoffs]
    result = {
        "scenes_per_kind": args.scenes,
        "seed": args.seed,
        "seen_share": SEEN_SHARE,
        "summary": summarize(rows, names),
        "scenes": rows,
    }
    write_results(args.out, result)
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
