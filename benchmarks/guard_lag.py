"""The executor's arm-deflection guards on lagging and stiff arms: outcomes per wrist stiffness.

    python benchmarks/guard_lag.py [--stiffness 500 1000 ...] [--seeds 0 1] [--out FILE]

The hook hand with the default policy, the five tasks at the paper's offsets, at wrist
stiffnesses 500-20,000 N/m, in three settings of the robot's `tracking_time_constant` tau:
`quasi_static` (not reported: the executor assumes the arm settles within a period), and
`lag_model` with tau = c / k (the arm's damping over its stiffness: 4 sqrt(m / k) for the hook
hand's damping ratio 2 and moving mass m; 0.153 s at 500 N/m, 0.076 s at 2000 N/m), also
reported 0.5x and 1.5x (a robot that reports its lag badly). Where the simulated robot reports
tau itself, that value is used for `lag_model`. At 20,000 N/m two more rows test the step
shortening of the force prediction: without it (`predictive_force=False`), and with 4x the
step budget. Writes benchmarks/results/guard_lag.json.

The script uses only the public API, so the same command with another checkout first on
PYTHONPATH measures that code (e.g. the executor before the lag model).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter
from pathlib import Path
from typing import Any

from constraint_aware.bench.faults import hook_hand_time_constant
from constraint_aware.bench.sweep import PAPER_OFFSETS
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import task_config

RESULT = Path(__file__).parent / "results" / "guard_lag.json"
STIFFNESSES = (500.0, 1000.0, 2000.0, 4000.0, 8000.0, 20000.0)
#: settings of the reported tau: name -> share of c / k (None: not reported)
SETTINGS: dict[str, float | None] = {
    "quasi_static": None,
    "lag_model": 1.0,
    "lag_model_x0.5": 0.5,
    "lag_model_x1.5": 1.5,
}


class WithLag:
    """Forwards the Robot protocol to the simulator and reports `tracking_time_constant`."""

    def __init__(self, sim: Any, tau: float) -> None:
        self._sim = sim
        self.tracking_time_constant = tau

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)


def one_run(
    task: str, offset: float, seed: int, stiffness: float, share: float | None,
    policy: ConstraintAwarePolicy, executor: tuple[tuple[str, object], ...] = (),
) -> dict[str, Any]:  # fmt: skip
    taus: list[float] = []

    def wrap(sim: Any) -> Any:
        if share is None:
            return sim
        own = getattr(sim, "tracking_time_constant", None)
        tau = share * (float(own) if own is not None else hook_hand_time_constant(sim))
        taus.append(tau)
        return WithLag(sim, tau)

    overrides = (("hand__translational_stiffness", stiffness), *executor)
    spec = RunSpec(task, "policy", offset, seed, overrides=overrides)
    record, sim = run(spec, policy=policy, wrap=wrap)
    return {
        "task": task,
        "offset_deg": offset,
        "seed": seed,
        "stiffness_N_per_m": stiffness,
        "tau_s": taus[0] if taus else None,
        "executor": dict(executor),
        "outcome": record.outcome,
        "reason": record.reason,
        "steps": record.n_steps,
        "peak_force_N": record.peak_force,
        "progress": sim.progress(),
        "success_progress": sim.task.success_progress,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stiffness", type=float, nargs="+", default=list(STIFFNESSES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--out", type=Path, default=RESULT)
    args = parser.parse_args()
    policy = ConstraintAwarePolicy.load()
    start = time.perf_counter()
    runs: list[dict[str, Any]] = []
    cases = [(t, o) for t, offs in PAPER_OFFSETS.items() for o in offs]
    for setting in args.settings:
        for k in args.stiffness:
            for task, off in cases:
                for seed in args.seeds:
                    row = one_run(task, off, seed, k, SETTINGS[setting], policy)
                    runs.append({"setting": setting, **row})
    if 20000.0 in args.stiffness:  # the force prediction's step shortening
        share = SETTINGS["lag_model"]
        for name in ("no_prediction", "steps_x4"):
            for task, off in cases:
                executor: tuple[tuple[str, object], ...] = (
                    (("executor__predictive_force", False),)
                    if name == "no_prediction"
                    else (("executor__max_steps", 4 * task_config(task).max_steps),)
                )
                row = one_run(task, off, 0, 20000.0, share, policy, executor)
                runs.append({"setting": f"lag_model_{name}", **row})
    table: dict[str, dict[str, dict[str, int]]] = {}
    for r in runs:
        cell = table.setdefault(r["setting"], {}).setdefault(f"{r['stiffness_N_per_m']:g}", {})
        cell[r["outcome"]] = cell.get(r["outcome"], 0) + 1
    out = {
        "policy": "default",
        "cases": [list(c) for c in cases],
        "seeds": args.seeds,
        "outcomes": table,
        "n_runs": len(runs),
        "wall_time_s": time.perf_counter() - start,
        "runs": runs,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1, allow_nan=False) + "\n")
    for setting, row in table.items():
        print(setting)
        for k, cell in row.items():
            n = sum(cell.values())
            print(f"  {k:>6} N/m: success {cell.get('success', 0)}/{n}  {dict(Counter(cell))}")


if __name__ == "__main__":
    main()
