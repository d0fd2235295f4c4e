"""Where the Jaco's end-to-end peak force on plates and poles comes from, one factor at a time.

    nice -n 10 python -m benchmarks.studies.jaco_grasp_state [--kinds plate,pole] [--per-kind 8]
        [--out FILE.json]

On the end-to-end benchmark's placements (bench/endtoend.py: the same draws), each kind runs
the Jaco five ways, recording the manipulation's peak |F - F_d| [N], the step it occurs at,
F_d [N] and the object's joint position after the grasp:

- `teleported`: the benchmark's pair: the hand placed at the grasp (`lfo.execute.execute`,
  the embodiment's default base) from the placement benchmark's demonstration (no offset);
- `teleported_own_demo`: the same with the end-to-end run's own demonstration (offset tracked
  point, its own tracking noise): is the paired difference the demonstration's?
- `sequence`: the whole sequence from home as the benchmark runs it (the shipped CNN);
- `true_point`: the recognizer replaced by the true contact point and approach (perception?);
- `placed`: at the end of the grasp phase the simulation is reset to the placed grasp (the
  sequence's own base and corrected skill; grasp state?);
- `rest`: at the end of the grasp phase the wrist stays commanded where it is for 2 s more
  before the executor reads F_d (is F_d read during a transient?).

After the grasp phase it also records where the hand holds the handle: the tool point's offset
from the true grasp pose in the grasp frame [mm] (z: along the approach) and the angle between
the hand's approach axis and the grasp's [deg].

Reads the simulator's state in callbacks outside the pipeline (a study, not the product).
Writes JSON with provenance, prints per-kind medians of the peak and of the paired
differences against `teleported_own_demo` and `sequence`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.studies.grasp_state import TruePoint
from constraint_aware.bench.endtoend import _demo_skill
from constraint_aware.bench.provenance import write_results
from constraint_aware.control.record import RunRecord
from constraint_aware.geometry import angle_deg
from constraint_aware.lfo.execute import execute
from constraint_aware.lfo.sequence import run_in_simulation
from constraint_aware.lfo.synthetic import HandOffset, random_placement
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.recognizer import Recognizer, make_recognizer
from constraint_aware.sim.tasks import KINDS

HERE = Path(__file__).parent
MODES = ("teleported", "teleported_own_demo", "sequence", "true_point", "placed", "rest")
REST = 2.0  # [s] the `rest` mode's extra hold


def _row(record: RunRecord | None, **extra: Any) -> dict[str, Any]:
    if record is None or not record.steps:
        return {"success": False, "peak_N": None, **extra}
    norms = [s.force_norm for s in record.steps]
    return {
        "success": record.success,
        "peak_N": record.peak_force,
        "peak_step": int(np.argmax(norms)),
        "steps": len(norms),
        "first_10_steps_peak_N": float(max(norms[:10])),
        "force_offset_N": list(record.force_offset),
        **extra,
    }


def one(kind: str, index: int, mode: str, policy: ConstraintAwarePolicy) -> dict[str, Any]:
    k = KINDS.index(kind)
    place = random_placement(kind, np.random.default_rng([0, k, index]))
    own = _demo_skill(place, np.random.default_rng([0, k, index, 2]), HandOffset())
    head = {"kind": kind, "index": index, "mode": mode}
    if mode.startswith("teleported"):
        skill = own
        if mode == "teleported":
            skill = _demo_skill(place, np.random.default_rng([0, k, index, 1]), None)
        record, _ = execute(skill, "policy", seed=index, task=place.task, policy=policy,
                            robot="jaco")  # fmt: skip
        return {**head, **_row(record)}

    recognizer: Recognizer = (
        TruePoint(place.task, own.start_position)
        if mode == "true_point"
        else make_recognizer("cnn")
    )
    moved: dict[str, Any] = {}

    def on_phase(name: str, sim: Any) -> None:
        if name != "grasp":
            return
        moved["object_after_grasp_mm"] = 1000.0 * float(type(sim).progress(sim))
        grasp, hand = sim.grasp_pose(), sim.read_pose()
        offset = grasp.orientation.inv().apply(hand.position - grasp.position)
        moved["hand_offset_mm"] = [1000.0 * float(v) for v in offset]
        moved["hand_tilt_deg"] = float(
            angle_deg(grasp.orientation.apply([0.0, 0.0, 1.0]), hand.orientation.apply([0, 0, 1.0]))
        )
        if mode == "placed":
            sim.reset()
        elif mode == "rest":  # the setpoint kept (a press stays commanded)
            for _ in range(round(REST / sim.control_period)):
                sim.advance()

    result = run_in_simulation(
        own, place.task, "jaco", policy=policy, seed=index, recognizer=recognizer,
        on_phase=on_phase,
    )  # fmt: skip
    row = _row(result.record.manipulation, **moved)
    row["success"] = result.record.success
    return {**head, **row}


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="plate,pole")
    parser.add_argument("--per-kind", type=int, default=8)
    parser.add_argument("--out", default=str(HERE / "results" / "jaco_grasp_state.json"))
    args = parser.parse_args()
    policy = ConstraintAwarePolicy.load()
    kinds = args.kinds.split(",")
    runs = []
    for kind in kinds:
        for i in range(args.per_kind):
            for mode in MODES:
                runs.append(one(kind, i, mode, policy))
                r = runs[-1]
                print(kind, i, mode, r["success"], r["peak_N"], r.get("peak_step"),
                      r.get("force_offset_N"), r.get("hand_tilt_deg"),
                      r.get("object_after_grasp_mm"), flush=True)  # fmt: skip
    summary: dict[str, dict[str, Any]] = {}
    for kind in kinds:
        by = {m: {r["index"]: r for r in runs if r["kind"] == kind and r["mode"] == m}
              for m in MODES}  # fmt: skip
        row: dict[str, Any] = {}
        for mode in MODES:
            ok = [r for r in by[mode].values() if r["success"]]
            row[mode] = {
                "successes": len(ok),
                "peak_N_median": _median([r["peak_N"] for r in ok]),
                "peak_step_median": _median([r["peak_step"] for r in ok]),
                "force_offset_z_N_median": _median([r["force_offset_N"][2] for r in ok]),
                "force_offset_horizontal_N_median": _median(
                    [float(np.hypot(*r["force_offset_N"][:2])) for r in ok]
                ),
                "hand_tilt_deg_median": _median(
                    [r["hand_tilt_deg"] for r in ok if "hand_tilt_deg" in r]
                ),
                "hand_depth_mm_median": _median(
                    [r["hand_offset_mm"][2] for r in ok if "hand_offset_mm" in r]
                ),
            }
            for ref in ("teleported", "teleported_own_demo", "sequence"):
                pairs = [
                    r["peak_N"] - by[ref][i]["peak_N"]
                    for i, r in by[mode].items()
                    if r["success"] and by[ref][i]["success"]
                ]
                row[mode][f"minus_{ref}_N_median"] = _median(pairs)
                row[mode][f"minus_{ref}_N_range"] = [min(pairs), max(pairs)] if pairs else None
        summary[kind] = row
    out = write_results(args.out, {"per_kind": args.per_kind, "runs": runs, "summary": summary})
    print(
        "| kind | mode | success | peak median [N] | peak step median | F_d z / horizontal "
        "median [N] | hand tilt / depth median [deg, mm] | minus teleported own demo median "
        "[min, max] [N] | minus sequence median [min, max] [N] |"
    )
    print("|---" * 9 + "|")

    def f(x: float | None) -> str:
        return "-" if x is None else f"{x:.2f}"

    for kind, row in summary.items():
        for mode in MODES:
            s = row[mode]
            cells = []
            for ref in ("teleported_own_demo", "sequence"):
                rng = s[f"minus_{ref}_N_range"]
                span = "" if rng is None else f" [{rng[0]:.2f}, {rng[1]:.2f}]"
                cells.append(f(s[f"minus_{ref}_N_median"]) + span)
            print(f"| {kind} | {mode} | {s['successes']}/{args.per_kind} | "
                  f"{f(s['peak_N_median'])} | {f(s['peak_step_median'])} | "
                  f"{f(s['force_offset_z_N_median'])} / "
                  f"{f(s['force_offset_horizontal_N_median'])} | "
                  f"{f(s['hand_tilt_deg_median'])} / {f(s['hand_depth_mm_median'])} | "
                  f"{cells[0]} | {cells[1]} |")  # fmt: skip
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
