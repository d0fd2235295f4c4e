"""The hand's travel and the force across d: undoing its attenuation, measured.

    python -m benchmarks.studies.travel_study [--seeds 20] [--noise-seeds 10] [--map-seeds 2]
        [--out FILE]

Why. After each command the executor re-anchors the target across the new d at the measured
pose (`command_from="measured"`), so the arm's stretch right after a command lies along d:
(lead + delta) d, with the lead the part of the old stretch kept along d. The hand then
travels x along the path u before the next reading. The reading's force across d is
therefore k x sin(e) (e: the angle from d to u), whatever the lead, while the quasi-static
model the policy was trained on reads k delta sin(e) for an unresisted step. At the first
reading from rest the hand has travelled about a third of the step (the arm's lag and the
object's start), so that reading understates the error. The executor knows x: the hand's own
poses.

Variants, each the `policy` controller with its start reading taken as read (`BASE`: the
travel scaling off, and the carry removal when the controller has it) and then its reading or
step force changed, against that base, the full `policy` and the classical controller (the
forces study's conditions: hook hand, sensor noise 0.1 N, the dead band derived from it):
- `step force from stretch`: step_force = k x |the commanded stretch in the workplane|;
- `step force from travel`: step_force = k x max(x, delta / 10);
- `across / travel`: the force across d multiplied by delta / clip(x, delta / 10, delta) on
  readings whose force across d is above the dead band (one inside it is noise, not
  amplified);
- `across / travel, first located`: the same on the first such reading only;
- `across / travel, weighted`: the same, its gain (delta / x - 1) times |F_across| / |F|;
- `hold after the first move`: no scaling; instead the controller commands no move (step
  length 0, d kept) on the first reading after the first move from rest, so that the reading
  it first corrects on is the settled one the policy was trained on;
- `across / travel, gated`: `across / travel` only on readings whose force along d the hand's
  travel explains, k x > -F.d (until then the object still holds the hand and the force
  across d is its resistance seen at an angle);
- `across / travel, gated, first reading`: the same on the reading after the first move only.

The full `policy` has the last of these with the arm's lag credited, delta / (x (1 + tau /
dt)) (`SteadyConfig.travel_scaling`). Cells: the 20-seed randomized suite and the paper's
offsets over sensor-noise seeds (every task), and the resistance map (the policy section's
cells, 2 seeds each). Writes the per-cell summary to `--out` and prints the tables
(docs/design/default-controller.md has what was adopted and why).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware import deadband
from constraint_aware.bench.analysis import (
    Condition,
    paper_offset_conditions,
    prepare_condition,
    resistance_map,
    suite_conditions,
)
from constraint_aware.control.controllers import (
    POLICY_STAGES,
    ControlInput,
    DirectionController,
    make_controller,
)
from constraint_aware.control.executor import Executor
from constraint_aware.control.simulate import RunSpec
from constraint_aware.control.steady import MIN_TRAVEL_SHARE, across_force
from constraint_aware.geometry import FloatArray
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.spatial import Pose

RESULT = Path(__file__).parent / "results" / "travel_study.json"
SENSOR_NOISE = 0.1  # [N] as the forces study
# MIN_TRAVEL_SHARE (control.steady): here the least travel the scalings divide by, as a share of
# the step (a hand that has hardly moved would otherwise give an unbounded factor)
#: the base every variant changes: `policy` with the start's reading as read
BASE = "policy: start as read"
BASE_OFF: dict[str, float] = {
    s: 0.0 for s in ("travel_scaling", "carry_removal") if s in POLICY_STAGES
}
REFERENCES = (BASE, "policy", "classical")
VARIANTS = (
    "step force from stretch",
    "step force from travel",
    "across / travel",
    "across / travel, first located",
    "across / travel, weighted",
    "hold after the first move",
    "across / travel, gated",
    "across / travel, gated, first reading",
)


class TravelMeter:
    """Forwards the Robot protocol to the simulator and measures, in the workplane, the hand's
    travel between the first pose readings of consecutive control periods and the stretch
    each command sets (target minus the last pose read)."""

    def __init__(self, sim: Any, normal: FloatArray) -> None:
        self._sim = sim
        self._normal = normal
        self._last: FloatArray | None = None
        self._advanced = True
        self.travel: float | None = None  # [m]
        self.stretch: float | None = None  # [m]

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)

    def _in_plane(self, v: FloatArray) -> float:
        return float(np.linalg.norm(v - float(v @ self._normal) * self._normal))

    def advance(self) -> None:
        self._sim.advance()
        self._advanced = True

    def read_pose(self) -> Pose:
        pose = self._sim.read_pose()
        if self._advanced:
            if self._last is not None:
                self.travel = self._in_plane(pose.position - self._last)
            self._last = pose.position.copy()
            self._advanced = False
        return pose

    def command_pose(self, pose: Pose) -> None:
        if self._last is not None:
            self.stretch = self._in_plane(pose.position - self._last)
        self._sim.command_pose(pose)


class TravelScaled:
    """The `policy` controller with its reading or step force changed from the meter's
    travel and stretch (module docstring). step: delta [m]; stiffness: k [N/m]."""

    def __init__(
        self, inner: DirectionController, meter: TravelMeter, stiffness: float, step: float,
        variant: str,
    ) -> None:  # fmt: skip
        self.inner, self.meter, self.k, self.delta = inner, meter, stiffness, step
        self.variant = variant
        self.name = inner.name
        self._scaled_once = False
        self._readings = 0

    def reset(self, direction: FloatArray) -> None:
        self._scaled_once = False
        self._readings = 0
        self.inner.reset(direction)

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return self.inner.hand_rotation()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return self.inner.next_direction(self._changed(inp))

    def _changed(self, inp: ControlInput) -> ControlInput:
        self._readings += 1  # reading 1 is at rest, reading 2 after the first move
        travel, stretch = self.meter.travel, self.meter.stretch
        if travel is None or inp.step_force is None or inp.workplane_normal is None:
            return inp
        floor = MIN_TRAVEL_SHARE * self.delta
        if self.variant == "step force from stretch":
            return inp if stretch is None else dataclasses.replace(
                inp, step_force=self.k * max(stretch, floor)
            )  # fmt: skip
        if self.variant == "step force from travel":
            return dataclasses.replace(inp, step_force=self.k * max(travel, floor))
        located = across_force(inp)  # the steady controller's own split (known workplane)
        assert located is not None
        across, across_dir = located
        force = np.asarray(inp.force, dtype=float)
        if abs(across) <= inp.threshold:
            return inp
        if self.variant == "across / travel, first located":
            if self._scaled_once:
                return inp
            self._scaled_once = True
        if ", gated" in self.variant and self.k * travel + float(force @ inp.direction) <= 0:
            return inp  # the object still holds the hand
        if self.variant.endswith("first reading") and self._readings != 2:
            return inp
        gain = self.delta / min(self.delta, max(travel, floor)) - 1.0
        if self.variant == "across / travel, weighted":
            gain *= abs(across) / float(np.linalg.norm(force))
        return dataclasses.replace(inp, force=force + gain * across * across_dir)


class HoldFirst:
    """The `policy` controller, holding still for one period after the first move from rest:
    the first reading after it is not passed on, d is kept and the step length is 0."""

    def __init__(self, inner: DirectionController) -> None:
        self.inner = inner
        self.name = inner.name
        self._calls = 0
        self._hold = False

    def reset(self, direction: FloatArray) -> None:
        self._calls, self._hold = 0, False
        self.inner.reset(direction)

    def step_length(self, nominal: float) -> float:
        return 0.0 if self._hold else self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return None if self._hold else self.inner.hand_rotation()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        self._calls += 1  # call 1 is the reading at rest, before the first move
        self._hold = self._calls == 2
        return inp.direction if self._hold else self.inner.next_direction(inp)


@functools.cache
def _policy() -> ConstraintAwarePolicy:
    """The default policy, loaded once per worker process."""
    return ConstraintAwarePolicy.load()


def one_run(cond: Condition, seed: int, variant: str) -> dict[str, Any]:
    policy = _policy()
    spec = RunSpec(
        cond.task, "policy", cond.offset_deg, seed=seed, randomize=cond.randomize,
        sensor_noise=SENSOR_NOISE, overrides=cond.overrides,
    )  # fmt: skip
    prep = prepare_condition(cond, spec, deadband.threshold_from_noise(SENSOR_NOISE))
    sim, cfg = prep.sim, prep.config
    assert cfg.workplane_normal is not None
    meter = TravelMeter(sim, np.asarray(cfg.workplane_normal, dtype=float))
    ctrl: DirectionController
    # `policy` with the start's reading as read, under every variant
    base = make_controller("policy", policy, prep.rotation_rate, prep.normal, BASE_OFF)
    if variant == BASE:
        ctrl = base
    elif variant in REFERENCES:
        ctrl = make_controller(variant, policy, prep.rotation_rate, prep.normal)
    elif variant == "hold after the first move":
        ctrl = HoldFirst(base)
    else:
        ctrl = TravelScaled(base, meter, sim.translational_stiffness, cfg.step_length, variant)
    record = Executor(meter, ctrl, cfg, monitor=sim).run(prep.d0, {"task": cond.task})
    return {  # the condition's overrides follow from its axis and level (bench.analysis)
        "axis": cond.axis,
        "level": cond.level,
        "task": cond.task,
        "offset_deg": cond.offset_deg,
        "seed": seed,
        "variant": variant,
        "outcome": record.outcome,
        "success": record.success,
        "peak_force_N": record.peak_force,
        "mean_force_N": record.mean_force,
    }


def _star(args: tuple[Condition, int, str]) -> dict[str, Any]:
    return one_run(*args)


def _cell_key(row: dict[str, Any]) -> tuple[str, float, str, float, str]:
    axis = row["axis"]
    level = 0.0 if axis == "suite" else row["level"]  # the suite's cell is the task
    offset = 0.0 if axis == "suite" else row["offset_deg"]
    return axis, level, row["task"], offset, row["variant"]


def summarize(runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (axis, level, task, offset, variant): successes, median peak, mean of mean |F|."""
    cells: dict[tuple[str, float, str, float, str], list[dict[str, Any]]] = {}
    for r in runs:
        cells.setdefault(_cell_key(r), []).append(r)
    out = []
    for (axis, level, task, offset, variant), rows in sorted(cells.items()):
        out.append({
            "axis": axis, "level": level, "task": task, "offset_deg": offset,
            "variant": variant, "n": len(rows), "successes": sum(r["success"] for r in rows),
            "median_peak_force_N": float(np.median([r["peak_force_N"] for r in rows])),
            "mean_force_N": float(np.mean([r["mean_force_N"] for r in rows])),
        })  # fmt: skip
    return out


def _table(summary: list[dict[str, Any]], keep: Callable[[dict[str, Any]], bool]) -> list[str]:
    labels = [*REFERENCES, *VARIANTS]
    rows: dict[tuple[str, str, float], dict[str, dict[str, Any]]] = {}
    for s in summary:
        if keep(s):
            rows.setdefault((s["axis"], s["task"], s["offset_deg"]), {})[s["variant"]] = s
    lines = ["| cell | " + " | ".join(labels) + " |", "|---" * (len(labels) + 1) + "|"]
    for (axis, task, offset), by in sorted(rows.items()):
        name = f"{task} {axis}" + ("" if axis == "suite" else f" {offset:+g} deg")
        cells = []
        for v in labels:
            c = by.get(v)
            text = ""
            if c is not None:
                text = f"{c['successes']}/{c['n']}, "
                text += f"{c['median_peak_force_N']:.2f} / {c['mean_force_N']:.3f}"
            cells.append(text)
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def map_totals(summary: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per variant over the resistance map's cells: successes, runs, the sum of the median
    peaks and of the mean |F|."""
    totals: dict[str, dict[str, float]] = {}
    for s in summary:
        if s["axis"] in ("suite", "paper offsets"):
            continue
        t = totals.setdefault(s["variant"], {"successes": 0, "runs": 0, "peaks_N": 0.0,
                                             "means_N": 0.0})  # fmt: skip
        t["successes"] += s["successes"]
        t["runs"] += s["n"]
        t["peaks_N"] += s["median_peak_force_N"]
        t["means_N"] += s["mean_force_N"]
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20, help="suite seeds per task")
    parser.add_argument("--noise-seeds", type=int, default=10, help="paper offsets, noise seeds")
    parser.add_argument("--map-seeds", type=int, default=2, help="seeds per resistance cell")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    parser.add_argument("--out", type=Path, default=RESULT)
    args = parser.parse_args()
    start = time.perf_counter()
    conds: list[tuple[Condition, int]] = [
        *suite_conditions(args.seeds),
        *((c, s) for c in paper_offset_conditions() for s in range(args.noise_seeds)),
        *((c, s) for c in resistance_map() for s in range(args.map_seeds)),
    ]
    jobs = [(c, s, v) for c, s in conds for v in (*REFERENCES, *VARIANTS)]
    with ProcessPoolExecutor(args.workers) as pool:
        runs = list(pool.map(_star, jobs, chunksize=16))
    summary = summarize(runs)
    totals = map_totals(summary)
    data = {
        "policy": _policy().name,
        "sensor_noise_N": SENSOR_NOISE,
        "min_travel_share": MIN_TRAVEL_SHARE,
        "wall_time_s": time.perf_counter() - start,
        "workers": args.workers,
        "summary": summary,
        "map_totals": totals,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1, allow_nan=True) + "\n")
    print("cells: successes, median peak |F| / mean |F| [N]")
    print("\n".join(_table(summary, lambda s: s["axis"] in ("suite", "paper offsets"))))
    print("\nresistance map totals (sum over cells of the median peak and of the mean |F|):")
    for v, t in totals.items():
        print(f"  {v}: {t['successes']:.0f}/{t['runs']:.0f} succeed, peaks {t['peaks_N']:.1f} N,"
              f" means {t['means_N']:.2f} N")  # fmt: skip
    print(f"wrote {args.out} ({data['wall_time_s']:.0f} s)")


if __name__ == "__main__":
    main()
