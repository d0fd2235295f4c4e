"""The executor's arm-deflection guards on lagging and stiff arms: outcomes per wrist stiffness.

    python benchmarks/guard_lag.py [--stiffness 500 1000 ...] [--seeds 0 1] [--out FILE]

The hook hand with the default policy, the five tasks at the paper's offsets, at wrist
stiffnesses 500-20,000 N/m, in four settings of the robot's `tracking_time_constant` tau:
`quasi_static` (not reported: the executor assumes the arm settles within a period), and
`lag_model` with tau = c / k (the arm's damping over its stiffness: 4 sqrt(m / k) for the hook
hand's damping ratio 2 and moving mass m; 0.153 s at 500 N/m, 0.076 s at 2000 N/m), also
reported 0.5x and 1.5x (a robot that reports its lag badly). Where the simulated robot reports
tau itself, that value is used for `lag_model`. At 20,000 N/m two more rows test the step
shortening of the force prediction: without it (`predictive_force=False`), and with 4x the
step budget. And drawer-opening on the Jaco arm (`--robot jaco`, 30 deg, seed 0) with tau
reported as given (`--jaco-tau`; 0: not reported), the self-check on and off, and the arm's
measured lag behind its moving target (lag / speed). Writes benchmarks/results/guard_lag.json.

The script uses only the public API, so the same command with another checkout first on
PYTHONPATH measures that code (e.g. the executor before the lag model).
"""

from __future__ import annotations

import argparse
import math
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench.faults import Reporting, hook_hand_time_constant
from constraint_aware.bench.provenance import write_results
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


class WithLag(Reporting):
    """Forwards the Robot protocol to the simulator and reports `tracking_time_constant`."""

    def __init__(self, sim: Any, tau: float) -> None:
        super().__init__(sim, tracking_time_constant=tau)


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


class LagProbe(WithLag):
    """WithLag that also records, per period, the hand's lag behind its target along its
    measured motion: lag time = -(measured - commanded) . v / |v|^2 [s] (first order: tau)."""

    def __init__(self, sim: Any, tau: float | None) -> None:
        super().__init__(sim, tau if tau is not None else math.nan)
        if tau is None:
            del self.tracking_time_constant  # not reported
        self._last: Any = None
        self.lag_times: list[float] = []

    def advance(self) -> None:
        self._sim.advance()
        position = self._sim.read_pose().position
        if self._last is not None:
            v = (position - self._last) / self._sim.control_period
            speed = float(np.linalg.norm(v))
            if speed > 0.05:  # [m/s] half the nominal 1 cm per 100 ms: in motion
                lag = position - self._sim.commanded_pose().position
                self.lag_times.append(-float(lag @ v) / speed**2)
        self._last = position


def jaco_run(policy: ConstraintAwarePolicy, tau: float, self_check: bool) -> dict[str, Any]:
    """drawer-opening on the Jaco arm at 30 deg, seed 0, with tau reported (0: not reported)
    and the self-check on or off; with the arm's measured lag time."""
    probes: list[LagProbe] = []

    def wrap(sim: Any) -> Any:
        probes.append(LagProbe(sim, tau if tau > 0 else None))
        return probes[-1]

    executor = () if self_check else (("executor__self_check__steps", 0),)
    spec = RunSpec("drawer-opening", "policy", 30.0, 0, robot="jaco", overrides=executor)
    record, sim = run(spec, policy=policy, wrap=wrap)
    lag = probes[0].lag_times
    return {
        "tau_s": tau,
        "self_check": self_check,
        "outcome": record.outcome,
        "reason": record.reason,
        "steps": record.n_steps,
        "peak_force_N": record.peak_force,
        "progress": sim.progress(),
        "median_lag_time_s": float(np.median(lag)) if lag else None,
    }


def jaco_runs(taus: list[float], policy_names: list[str]) -> list[dict[str, Any]]:
    """`jaco_run` for each policy, tau, and with the self-check on and off."""
    rows = []
    for name in policy_names:
        policy = ConstraintAwarePolicy.load(name)
        for tau in taus:
            for check in (True, False):
                rows.append({"policy": name, **jaco_run(policy, tau, check)})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stiffness", type=float, nargs="+", default=list(STIFFNESSES))
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument("--out", type=Path, default=RESULT)
    parser.add_argument(
        "--jaco-tau", type=float, nargs="*", default=[0.0, 0.14, 0.48],
        help="[s] taus reported on the Jaco drawer run (0: not reported); none given: no Jaco runs",
    )  # fmt: skip
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
                    (("executor__guards__predictive_force", False),)
                    if name == "no_prediction"
                    else (("executor__limits__max_steps", 4 * task_config(task).max_steps),)
                )
                row = one_run(task, off, 0, 20000.0, share, policy, executor)
                runs.append({"setting": f"lag_model_{name}", **row})
    jaco = jaco_runs(args.jaco_tau, ["default", "paper"]) if args.jaco_tau else []
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
        "jaco_drawer_30deg": jaco,
    }
    write_results(args.out, out)
    for setting, row in table.items():
        print(setting)
        for k, cell in row.items():
            n = sum(cell.values())
            print(f"  {k:>6} N/m: success {cell.get('success', 0)}/{n}  {dict(Counter(cell))}")
    for r in jaco:
        lag = r["median_lag_time_s"]
        print(f"jaco drawer 30 deg {r['policy']} tau {r['tau_s']} self-check {r['self_check']}:")
        print(f"    {r['outcome']} after {r['steps']} steps; measured lag time {lag}")


if __name__ == "__main__":
    main()
