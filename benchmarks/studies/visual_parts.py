"""The objects' visual parts (door panel, drawer box, furniture) and the two embodiments.

    nice -n 10 python benchmarks/studies/visual_parts.py [--seeds 3] [--out FILE.json]

The objects' main parts and furniture have no contacts (the joint is the constraint). This
measures (1) the hook hand's least clearance to them over the five presets' runs, (2) how deep
the Jaco's geoms are inside them at its grasp of each task and over door runs with its base on
the hinge side (its placement today, azimuth +90 deg) and on the free edge's side (-90 deg),
and (3) Jaco drawer and door runs with the parts solid for the arm (sim.objects.
ARM_CONTACT_BIT) against the visual parts. The Jaco runs use the default policy and the
classical controller from 10 deg, the executor's start-of-run self-check off (it stops most
arm runs before they move on the lagging arm). Writes JSON with provenance, prints a table.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.control.controllers import make_controller
from constraint_aware.control.executor import Executor
from constraint_aware.control.simulate import RunSpec, controller_geometry, executor_config, run
from constraint_aware.geometry import rotate_about
from constraint_aware.sim import jaco
from constraint_aware.sim.embodiment import Embodiment
from constraint_aware.sim.jaco import JacoSim, arm_base
from constraint_aware.sim.objects import VISUAL_GROUP
from constraint_aware.sim.scene import OBJECT_PREFIX, intrusions, scene_spec
from constraint_aware.sim.tasks import TASKS, TaskConfig, task_config
from constraint_aware.sim.world import HOOK_PREFIX

HERE = Path(__file__).parent
DOOR_BASES = {  # Jaco base placements (sim.jaco.arm_base: reach [m], azimuth [deg], height [m])
    "hinge side (+90 deg, today)": (0.55, 90.0, -0.3),
    "free side (-90 deg)": (0.55, -90.0, -0.3),
}


def _visual_parts(model: mujoco.MjModel) -> list[int]:
    return [
        g
        for g in range(model.ngeom)
        if model.geom(g).name.startswith(OBJECT_PREFIX) and model.geom_group[g] == VISUAL_GROUP
    ]


def hook_hand_clearance(seeds: int) -> dict[str, float]:
    """[mm] least signed distance between the hook hand's geoms and the visual parts, per
    preset, over seed 0.. runs of the default policy from 30 deg."""
    out: dict[str, float] = {}
    for name in TASKS:
        least = math.inf

        def check(sim: Embodiment) -> None:
            nonlocal least
            m, d = sim.model, sim.data
            hand = [g for g in range(m.ngeom) if m.geom(g).name.startswith(HOOK_PREFIX)]
            for part in _visual_parts(m):
                for g in hand:
                    least = min(least, mujoco.mj_geomDistance(m, d, part, g, 0.2, None))

        for seed in range(seeds):
            run(RunSpec(task=name, controller="policy", offset_deg=30.0, seed=seed), on_step=check)
        out[name] = 1000 * least
    return out


@contextlib.contextmanager
def _solid_scenes() -> Iterator[None]:
    """Jaco scenes built with `scene_spec(task, solid_for_arms=True)`: sim.jaco composes its
    model on `scene_spec(task)`, so it is handed the solid builder for the while. (Setting the
    compiled model's contact bits instead does not do it: MuJoCo leaves a geom without contact
    bits out of its body's bounding-volume hierarchy at compile time, checked: `bvh_nodeid`
    holds the door panel only when it is built solid.)"""
    plain = jaco.scene_spec
    jaco.scene_spec = functools.partial(scene_spec, solid_for_arms=True)
    try:
        yield
    finally:
        jaco.scene_spec = plain


def jaco_run(
    task: TaskConfig, controller: str, seed: int, base: np.ndarray | None, solid: bool
) -> dict[str, Any]:
    """One Jaco run as `cap run --robot jaco` makes it (0.1 N sensor noise), self-check off;
    with the deepest intrusion into the visual parts over the run [mm]."""
    with _solid_scenes() if solid else contextlib.nullcontext():
        sim = JacoSim(task, base=base)
    sim.set_sensor_noise(np.random.default_rng(seed + 7919), 0.1, None)
    sim.reset()
    deepest: dict[str, float] = {}

    def note() -> None:
        for found in intrusions(sim.model, sim.data, "jaco"):
            key = f"{found.part} / {found.robot_geom}"
            deepest[key] = max(deepest.get(key, 0.0), 1000 * found.depth)

    note()
    cfg = executor_config(task).with_overrides(self_check__steps=0)
    assert cfg.workplane_normal is not None
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    d0 = rotate_about(sim.admissible_direction(), normal, math.radians(10.0))
    normal, rate = controller_geometry(cfg, sim, d0)
    ctrl = make_controller(controller, None, rate, normal, {})

    class Watched:
        """The sim, with the intrusions noted after every period."""

        def __getattr__(self, name: str) -> Any:
            return getattr(sim, name)

        def advance(self) -> None:
            sim.advance()
            note()

    record = Executor(Watched(), ctrl, cfg, monitor=sim).run(d0, {"task": task.name})
    forces = [s.force_norm for s in record.steps] or [0.0]
    top = sorted(deepest.items(), key=lambda kv: -kv[1])[:4]
    return {
        "outcome": record.outcome,
        "steps": len(record.steps),
        "progress": record.progress,
        "peak_force_N": max(forces),
        "deepest_mm": dict(top),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--out", default=str(HERE / "results" / "visual_parts.json"))
    args = parser.parse_args()
    start = time.perf_counter()
    result: dict[str, Any] = {"seeds": args.seeds}
    result["hook_hand_least_clearance_mm"] = hook_hand_clearance(args.seeds)
    grasp: dict[str, Any] = {}
    for name in TASKS:
        sim = JacoSim(task_config(name))
        sim.reset()
        grasp[name] = [
            {"part": i.part, "robot_geom": i.robot_geom, "depth_mm": 1000 * i.depth}
            for i in intrusions(sim.model, sim.data, "jaco")
        ]
    result["jaco_grasp_intrusions"] = grasp
    runs: list[dict[str, Any]] = []
    for name in ("drawer-opening", "door-opening"):
        task = task_config(name)
        bases = DOOR_BASES if name == "door-opening" else {"today": None}
        for where, placement in bases.items():
            base = arm_base(task, placement) if placement else None
            for solid in (False, True):
                for controller in ("policy", "classical"):
                    for seed in range(args.seeds):
                        row = jaco_run(task, controller, seed, base, solid)
                        row.update(task=name, base=where, solid=solid, controller=controller,
                                   seed=seed)  # fmt: skip
                        runs.append(row)
                        print(
                            f"{name:15s} {where:27s} solid={solid!s:5s} {controller:9s} "
                            f"seed {seed}: {row['outcome']:15s} {row['steps']:3d} steps "
                            f"peak {row['peak_force_N']:5.1f} N progress {row['progress']:.3f}"
                        )
    result["jaco_runs"] = runs
    result["wall_time_s"] = time.perf_counter() - start
    out = write_results(args.out, result)
    print("hook hand least clearance [mm]:", result["hook_hand_least_clearance_mm"])
    for name, found in grasp.items():
        print(f"Jaco grasp, {name}: " + (", ".join(
            f"{f['robot_geom']} {f['depth_mm']:.1f} mm in {f['part']}" for f in found[:4]
        ) or "clear"))  # fmt: skip
    print(f"wrote {out} ({result['wall_time_s']:.0f} s)")


if __name__ == "__main__":
    main()
