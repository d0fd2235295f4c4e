"""Observation study: train the three observations, measure them, pick the default's.

    nice -n 10 python benchmarks/studies/observation_study.py train [--steps 600000]
        [--obs paper ...]
    nice -n 10 python benchmarks/studies/observation_study.py measure [--closed-loop]

`train` writes runs/study/OBS/policy.npz (fast preset, resistance env, equal env steps);
`measure` evaluates them (analytic standard and resistance evaluation, the pure-resistance
probe and, with --closed-loop, the MuJoCo resistance cases vs the classical controller) and
writes benchmarks/studies/results/observation_study.json (with provenance).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from constraint_aware.bench.provenance import write_results
from constraint_aware.policy import OBSERVATIONS, ConstraintAwarePolicy
from constraint_aware.training.config import resistance_config
from constraint_aware.training.study import analytic_study

RUNS = Path("runs/study")
OUT = Path(__file__).parent / "results" / "observation_study.json"


def train_all(observations: list[str], steps: int, seed: int, threads: int, tag: str = "") -> None:
    from constraint_aware.training.ppo import train
    from constraint_aware.training.train_config import make_config

    for obs in observations:
        env = resistance_config(obs)  # magnitude: with STEP_FORCE_UNKNOWN_SHARE
        config = make_config(
            "fast", env=env, seed=seed, total_timesteps=steps, torch_threads=threads
        )
        start = time.perf_counter()
        result = train(config, RUNS / f"{obs}{tag}")
        print(
            obs,
            f"{time.perf_counter() - start:.0f} s",
            result.policy.metrics["policy"]["mean_final_angle_deg"],
        )


def measure(observations: list[str], closed_loop: bool) -> None:
    out: dict[str, object] = {}
    policies = {"paper": ConstraintAwarePolicy.load("paper")}
    for obs in observations:
        policies[f"study-{obs}"] = ConstraintAwarePolicy.load(RUNS / obs / "policy.npz")
    policies["default"] = ConstraintAwarePolicy.load("default")
    for name, policy in policies.items():
        study = analytic_study(policy)
        out[name] = {
            "analytic": dataclasses.asdict(study),
            "train_wall_time_s": policy.card.get("wall_time_s"),
            "train_timesteps": policy.card.get("total_timesteps"),
            "best_timesteps": policy.card.get("best_timesteps"),
        }
        print(
            name,
            study.standard_mean_deg,
            study.resistance_mean_deg,
            study.probe.worst_deg,
            study.probe.max_turn_with_step_force_deg,
        )
    if closed_loop:
        from constraint_aware import deadband
        from constraint_aware.bench.analysis import closed_loop_cases, run_all, summarize

        thr = deadband.threshold_from_noise(0.1)  # the simulated sensor's noise: 0.1 N
        runs = run_all(  # each policy alone: the observations compared, not the wrapper
            closed_loop_cases(), [0, 1], ("classical",), policies=policies, threshold=thr,
            policy_controller="policy-raw",
        )  # fmt: skip
        cells = summarize(runs)
        out["closed_loop_threshold_N"] = thr
        out["closed_loop"] = [dataclasses.asdict(c) for c in cells]
        for c in cells:
            print(
                f"{c.axis} {c.level:g} {c.task} {c.controller}: {c.successes}/{c.n} "
                f"peak {c.median_peak_force_N:.1f} mean {c.mean_force_N:.1f}"
            )
    write_results(OUT, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=("train", "measure"))
    parser.add_argument("--obs", nargs="+", default=list(OBSERVATIONS))
    parser.add_argument("--steps", type=int, default=600_000, help="env steps per training run")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (shared machine)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--closed-loop", action="store_true")
    parser.add_argument("--tag", default="", help="suffix of the run folder")
    args = parser.parse_args()
    if args.what == "train":
        train_all(args.obs, args.steps, args.seed, args.threads, args.tag)
    else:
        measure(args.obs, args.closed_loop)


if __name__ == "__main__":
    main()
