"""The state the hook hand's own grasp of a bar leaves, against the hand placed at the grasp.

    nice -n 10 python benchmarks/studies/grasp_state.py [--kinds drawer,door,lid] [--per-kind 5]
        [--out FILE.json]

On the end-to-end benchmark's placements (bench/endtoend.py: the same draws, offset
demonstrations), each hooked-bar kind runs the whole sequence from home five ways, recording
the manipulation's peak |F - F_d| [N], the vertical component of F_d [N] (the hand's weight
and whatever of the object it carries) and the object's joint position after the grasp:

- `sequence`: as `cap lfo --execute` runs it (the shipped CNN's contact point; the hook's play
  taken up after closing, SequenceConfig.take_up);
- `no_take_up`: the same with `take_up_travel` 0 (closing sweeps the bar against the palm,
  the play lies between the bar and the fingers that pull it);
- `true_point`: the recognizer replaced by the true contact point and approach (is it
  perception?);
- `object_back`: at the end of the grasp phase the object's joint is put back to 0;
- `placed`: at the end of the grasp phase the simulation is reset to the placed grasp (as
  `--start at-grasp` starts), then the same executor runs.

Reads the simulator's state in callbacks outside the pipeline (a study, not the product).
Writes JSON with provenance, prints a table.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from constraint_aware.bench.endtoend import _demo_skill
from constraint_aware.bench.provenance import write_results
from constraint_aware.lfo.grasp_data import contact_label
from constraint_aware.lfo.sequence import SequenceConfig, run_in_simulation
from constraint_aware.lfo.synthetic import HandOffset, random_placement
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.recognizer import Recognition, Recognizer, make_recognizer
from constraint_aware.sim.tasks import KINDS

HERE = Path(__file__).parent
MODES = ("sequence", "no_take_up", "true_point", "object_back", "placed")


def _object_back(sim: Any) -> None:
    joint = (
        sim.model.joint(sim._obj_joint).id if isinstance(sim._obj_joint, str) else sim._obj_joint
    )
    sim.data.qpos[sim.model.jnt_qposadr[joint]] = 0.0
    sim.data.qvel[:] = 0.0
    mujoco.mj_forward(sim.model, sim.data)


class TruePoint:
    """A recognizer that answers the placed object's true contact point and approach (for
    the hand point `near` (3,) [m]), whatever the camera saw: the perception factor removed."""

    name = "true-point"

    def __init__(self, task: Any, near: Any) -> None:
        self.task, self.near = task, np.asarray(near, dtype=float)

    def recognize(self, height: Any, frame: Any, shape: str) -> Recognition:
        point, approach = contact_label(self.task, shape, self.near)
        return Recognition(point, approach, self.name)


def one(kind: str, index: int, mode: str, policy: ConstraintAwarePolicy) -> dict[str, Any]:
    k = KINDS.index(kind)
    place = random_placement(kind, np.random.default_rng([0, k, index]))
    skill = _demo_skill(place, np.random.default_rng([0, k, index, 2]), HandOffset())
    moved: dict[str, float] = {}

    recognizer: Recognizer = (
        TruePoint(place.task, skill.start_position)
        if mode == "true_point"
        else make_recognizer("cnn")
    )

    def on_phase(name: str, sim: Any) -> None:
        if name != "grasp":
            return
        # [mm] of a drawer's travel, [mrad] of a hinge's angle
        moved["object_after_grasp"] = 1000.0 * float(type(sim).progress(sim))
        if mode == "object_back":
            _object_back(sim)
        elif mode == "placed":
            sim.reset()

    hook: Callable[[str, Any], None] = on_phase
    config = SequenceConfig(take_up_travel=0.0) if mode == "no_take_up" else None
    result = run_in_simulation(
        skill, place.task, "hook-hand", policy=policy, seed=index, recognizer=recognizer,
        on_phase=hook, config=config,
    )  # fmt: skip
    m = result.record.manipulation
    return {
        "kind": kind,
        "index": index,
        "mode": mode,
        "success": result.record.success,
        "peak_N": None if m is None else m.peak_force,
        "force_offset_z_N": None if m is None else m.force_offset[2],
        **moved,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="drawer,door,lid")
    parser.add_argument("--per-kind", type=int, default=5)
    parser.add_argument("--out", default=str(HERE / "results" / "grasp_state.json"))
    args = parser.parse_args()
    policy = ConstraintAwarePolicy.load()
    runs = [
        one(kind, i, mode, policy)
        for kind in args.kinds.split(",")
        for i in range(args.per_kind)
        for mode in MODES
    ]
    summary: dict[str, dict[str, float]] = {}
    for kind in args.kinds.split(","):
        row = {}
        for mode in MODES:
            mine = [r for r in runs if r["kind"] == kind and r["mode"] == mode]
            row[mode] = float(np.median([r["peak_N"] for r in mine if r["peak_N"] is not None]))
            row[f"{mode}_force_offset_z"] = float(
                np.median(
                    [r["force_offset_z_N"] for r in mine if r["force_offset_z_N"] is not None]
                )
            )
        mine = [r for r in runs if r["kind"] == kind]
        for mode in ("no_take_up", "sequence"):
            moved = [r["object_after_grasp"] for r in mine if r["mode"] == mode]
            row[f"{mode}_object_after_grasp"] = float(np.median(moved))
        summary[kind] = row
    out = write_results(args.out, {"per_kind": args.per_kind, "runs": runs, "summary": summary})
    print("peak |F - F_d| median [N] (F_d's vertical component median [N])")
    print("| kind | " + " | ".join(MODES) + " | object after the grasp without / with take-up "
          "[mm or mrad] |")  # fmt: skip
    print("|---" * (len(MODES) + 2) + "|")
    for kind, row in summary.items():
        cells = " | ".join(f"{row[m]:.2f} ({row[m + '_force_offset_z']:.1f})" for m in MODES)
        print(
            f"| {kind} | {cells} | {row['no_take_up_object_after_grasp']:.2f} / "
            f"{row['sequence_object_after_grasp']:.2f} |"
        )
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
