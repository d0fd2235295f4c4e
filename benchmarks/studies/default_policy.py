"""The shipped default policy: train it, measure it, write its card.

    nice -n 10 python benchmarks/studies/default_policy.py train [--seed 0] [--threads 1]
    python benchmarks/studies/default_policy.py ship [--run runs/default-seed0]
        [--compare LABEL=PATH ...]
    nice -n 10 python benchmarks/studies/default_policy.py closed-loop [--compare LABEL=PATH ...]
    nice -n 10 python benchmarks/studies/default_policy.py forces [--compare LABEL=PATH ...]

`train` runs the `default` preset (training.train_config.PRESETS) into runs/default-seedN/.
`ship` measures that run's policy with training.study.analytic_study (standard evaluation,
evaluation with resistance, pure-resistance probe) and over wrist-stiffness bands, writes
data/default.npz + .json (the training card plus those measurements, the observation study
carried over) and data/training_log.csv, and benchmarks/studies/results/default_policy.json. With
--compare, other policies (e.g. the previous default) are measured the same way for the JSON.
`closed-loop` runs the observation study's 13 MuJoCo resistance cases (seeds 0, 1) for the
shipped default, the --compare policies and classical, and fills the default's card row.
`forces` compares their forces on the randomized suite's door and drawer (first --seeds
seeds) and on every task at the paper's offsets. Each step rewrites the JSON with provenance.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
from pathlib import Path
from typing import Any

from constraint_aware.bench.provenance import write_results
from constraint_aware.policy import ConstraintAwarePolicy, shipped_log_path, shipped_policy_path
from constraint_aware.training.config import EnvConfig, resistance_config
from constraint_aware.training.evaluate import evaluate
from constraint_aware.training.study import analytic_study

OUT = Path(__file__).parent / "results" / "default_policy.json"

#: [N/m] wrist stiffness bands of the per-band evaluation (the hook hand is 2000 N/m; the
#: embodiment variants span 500-20,000 N/m).
STIFFNESS_BANDS = ((500.0, 1000.0), (1000.0, 3000.0), (3000.0, 8000.0), (8000.0, 20_000.0))

DESCRIPTION = (
    "Constraint-aware policy, default: (F/|F|, d, |F|/(k*delta), step force known) "
    "-> direction update, trained with the object's own resistance along the joint (dry "
    "friction, damping, inertia, released preload) and wrist stiffness k log-uniform in "
    "500-20,000 N/m; without the robot's step force k*delta the ratio and the flag are zero "
    "(trained for that in 25 % of the episodes)"
)


def measure(policy: ConstraintAwarePolicy) -> dict[str, Any]:
    """Analytic study (10,000 episodes each) plus standard and resistance means per k band."""
    study = analytic_study(policy)

    def ctrl(obs: Any, _f: Any) -> Any:
        return policy.act_batch(obs)

    bands = []
    for band in STIFFNESS_BANDS:
        std = EnvConfig(observation=policy.observation, stiffness=band)
        res = resistance_config(policy.observation, step_force_unknown_share=0.0, stiffness=band)
        bands.append(
            {
                "stiffness_N_per_m": list(band),
                "standard_mean_deg": evaluate(ctrl, std).mean_final_angle_deg,
                "resistance_mean_deg": evaluate(ctrl, res).mean_final_angle_deg,
            }
        )
    return {"analytic_study": dataclasses.asdict(study), "stiffness_bands": bands}


def relabel_study(old: dict[str, Any], study: dict[str, Any]) -> dict[str, Any]:
    """The observation study of the previous card, its default row renamed (the previous
    default: the magnitude observation, annealed preset), plus a row for this policy
    (closed-loop columns from `closed-loop`)."""
    rows = []
    for row in old["rows"]:
        row = dict(row)
        if row["observation"].endswith("= default"):
            row["observation"] = "+ |F|/(k delta) (magnitude), annealed preset (previous default)"
        rows.append(row)
    new_row = {
        "observation": "+ |F|/(k delta) and a known flag (magnitude_flag), annealed preset "
        "= default",
        "standard_mean_deg": study["standard_mean_deg"],
        "resistance_mean_deg": study["resistance_mean_deg"],
        "probe_worst_deg": max(study["probe"]["max_turn_deg"]),
        "closed_loop_successes": None,
        "closed_loop_runs": None,
        "closed_loop_median_peak_N": None,
        "closed_loop_mean_force_N": None,
    }
    rows.insert(next(i for i, r in enumerate(rows) if "reference" in r["observation"]), new_row)
    reason = old["reason"] + (
        " The magnitude alone coded an unknown step force as 0, next to the ratio of a small "
        "force (a few percent of k delta), and the policy hardly used the ratio: it turned d "
        "by 11 deg for F = 0.78 N against d and 0.31 N across at k delta = 20 N, where the "
        "training physics implies 0.9 deg. With a separate known flag it turns 1.5 deg there; "
        "the standard evaluation falls from 1.72 to ~1.0 deg and the MuJoCo suite's door peak "
        "|F| of the policy alone from 12 to ~7 N (benchmarks/studies/results/default_policy.json)."
    )
    return {**old, "chosen": "magnitude_flag", "rows": rows, "reason": reason}


def train_run(seed: int, threads: int) -> None:
    from constraint_aware.training.ppo import train
    from constraint_aware.training.train_config import make_config

    config = make_config("default", seed=seed, torch_threads=threads)
    result = train(config, Path(f"runs/default-seed{seed}"))
    print(f"{result.wall_time_s:.0f} s, best at {result.policy.card['best_timesteps']} steps")


def ship(run: Path, compare: list[str]) -> None:
    trained = ConstraintAwarePolicy.load(run / "policy.npz")
    measured = measure(trained)
    study = measured["analytic_study"]
    previous = ConstraintAwarePolicy.load("default").card
    card = dict(trained.card)
    card["name"] = "default"
    card["description"] = DESCRIPTION
    card["standard_evaluation"] = {
        "mean_final_angle_deg": study["standard_mean_deg"],
        "p95_final_angle_deg": study["standard_p95_deg"],
        "bar_deg": 2.2,
        "source": "training.study.analytic_study (10,000 episodes, seed 12345, no resistance)",
    }
    card["resistance_evaluation"] = {
        "mean_final_angle_deg": study["resistance_mean_deg"],
        "p95_final_angle_deg": study["resistance_p95_deg"],
    }
    card["pure_resistance_probe"] = {
        **study["probe"],
        "worst_deg": max(study["probe"]["max_turn_deg"]),
        "bar_deg": 3.0,
    }
    card["stiffness_bands"] = measured["stiffness_bands"]
    if "observation_study" in previous:
        card["observation_study"] = relabel_study(previous["observation_study"], study)
    target = shipped_policy_path("default")
    trained.with_card(card).save(target)
    shutil.copyfile(run / "training_log.csv", shipped_log_path("default"))
    out: dict[str, Any] = {"default": {"run": str(run), **measured}}
    for item in compare:  # LABEL=PATH
        label, _, path = item.partition("=")
        out[label] = {"path": path, **measure(ConstraintAwarePolicy.load(path or label))}
    if OUT.is_file():  # the closed loop and forces of the same weights stay
        kept = json.loads(OUT.read_text())
        if kept.get("default", {}).get("run") == str(run):
            out.update({k: kept[k] for k in ("closed_loop", "forces") if k in kept})
    write_results(OUT, out)
    studies = {k: v["analytic_study"] for k, v in out.items() if "analytic_study" in v}
    print(json.dumps({k: v["standard_mean_deg"] for k, v in studies.items()}))


def closed_loop(compare: list[str]) -> None:
    """The observation study's closed loop (13 MuJoCo resistance cases x seeds 0, 1 at the
    derived 0.4 N band) for the shipped default, `compare` (LABEL=PATH) and classical, in one
    run; the default's row of the card's observation study gets these numbers."""
    import statistics

    from constraint_aware import deadband
    from constraint_aware.bench.analysis import closed_loop_cases, run_all

    policies = {"default": ConstraintAwarePolicy.load("default")}
    for item in compare:
        label, _, path = item.partition("=")
        policies[label] = ConstraintAwarePolicy.load(path)
    thr = deadband.threshold_from_noise(0.1)  # the simulated sensor's noise: 0.1 N
    runs = run_all(  # each policy alone (policy-raw), as the card's other rows were measured
        closed_loop_cases(), [0, 1], ("classical",), policies=policies, threshold=thr,
        policy_controller="policy-raw",
    )  # fmt: skip
    rows: dict[str, Any] = {}
    for label in ["classical", *policies]:
        mine = [r for r in runs if r.controller == label]
        rows[label] = {
            "closed_loop_successes": sum(r.success for r in mine),
            "closed_loop_runs": len(mine),
            "closed_loop_median_peak_N": statistics.median(r.peak_force_N for r in mine),
            "closed_loop_mean_force_N": statistics.fmean(r.mean_force_N for r in mine),
        }
        print(label, rows[label])
    out = json.loads(OUT.read_text())
    out["closed_loop"] = {
        "threshold_N": thr,
        "summary": rows,
        "runs": [dataclasses.asdict(r) for r in runs],
    }
    write_results(OUT, out)
    policy = policies["default"]
    card = dict(policy.card)
    study = card.get("observation_study")
    if study:
        for row in study["rows"]:
            if row["observation"].endswith("= default"):
                row.update(rows["default"])
        policy.with_card(card).save(shipped_policy_path("default"))


def forces(compare: list[str], seeds: int) -> None:
    """The randomized suite's first `seeds` seeds on the door and the drawer, and every task at
    the paper's offsets: success, median peak and mean |F| of the shipped default, `compare`
    (LABEL=PATH) and classical, in one run (derived 0.4 N dead band, 0.1 N sensor noise)."""
    import statistics

    from constraint_aware import deadband
    from constraint_aware.bench.analysis import (
        paper_offset_conditions,
        run_condition,
        suite_conditions,
    )

    policies = {"default": ConstraintAwarePolicy.load("default")}
    for item in compare:
        label, _, path = item.partition("=")
        policies[label] = ConstraintAwarePolicy.load(path)
    thr = deadband.threshold_from_noise(0.1)
    cases = [
        (c, s) for c, s in suite_conditions(seeds) if c.task in ("door-opening", "drawer-opening")
    ]
    cases += [(c, 0) for c in paper_offset_conditions()]
    runs = []
    for cond, seed in cases:
        runs.append(run_condition(cond, "classical", seed, thr))
        for label, policy in policies.items():
            runs.append(run_condition(cond, label, seed, thr, policy=policy))
    cells: dict[str, Any] = {}
    for r in runs:
        key = f"{r.condition.axis}|{r.condition.task}|{r.controller}"
        cells.setdefault(key, []).append(r)
    summary = {
        key: {
            "successes": sum(r.success for r in rs),
            "runs": len(rs),
            "median_peak_N": statistics.median(r.peak_force_N for r in rs),
            "mean_force_N": statistics.fmean(r.mean_force_N for r in rs),
        }
        for key, rs in sorted(cells.items())
    }
    for key, value in summary.items():
        print(key, value)
    out = json.loads(OUT.read_text())
    out["forces"] = {
        "threshold_N": thr,
        "suite_seeds": seeds,
        "summary": summary,
        "runs": [dataclasses.asdict(r) for r in runs],
    }
    write_results(OUT, out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--threads", type=int, default=1)
    s = sub.add_parser("ship")
    s.add_argument("--run", default="runs/default-seed0")
    s.add_argument("--compare", nargs="*", default=[])
    c = sub.add_parser("closed-loop")
    c.add_argument("--compare", nargs="*", default=[])
    f = sub.add_parser("forces")
    f.add_argument("--compare", nargs="*", default=[])
    f.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    if args.cmd == "forces":
        forces(args.compare, args.seeds)
    elif args.cmd == "train":
        train_run(args.seed, args.threads)
    elif args.cmd == "ship":
        ship(Path(args.run), args.compare)
    else:
        closed_loop(args.compare)


if __name__ == "__main__":
    main()
