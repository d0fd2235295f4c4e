"""`cap`: command-line entry point. Thin: parse, call the library, print."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from constraint_aware.errors import CapError

console = Console()


# --- cap train ------------------------------------------------------------------------------
def cmd_train(args: argparse.Namespace) -> int:
    try:
        from constraint_aware.training import ppo
    except ImportError as exc:  # torch / SB3 are an extra
        raise CapError(
            f"training needs the 'train' extra: pip install -e '.[train]' ({exc})"
        ) from exc
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from constraint_aware.policy import shipped_policy_path
    from constraint_aware.training.curve import plot_learning_curve

    overrides: dict[str, Any] = {"seed": args.seed}
    if args.steps is not None:
        overrides["total_timesteps"] = args.steps
    if args.target_angle is not None:
        overrides["target_angle_deg"] = args.target_angle
    if args.time_budget is not None:
        overrides["time_budget_s"] = args.time_budget
    if args.eval_episodes is not None:
        overrides["eval_episodes"] = args.eval_episodes
    config = ppo.make_config(args.preset, **overrides)
    out = Path(args.out or f"runs/train-{config.preset}-seed{config.seed}")

    with Progress(
        TextColumn("[bold]training[/]"),
        BarColumn(),
        TextColumn("{task.completed:,}/{task.total:,} steps"),
        TextColumn("{task.fields[status]}"),
        TimeElapsedColumn(),
        console=console,
        disable=args.quiet,
    ) as progress:
        task = progress.add_task("train", total=config.total_timesteps, status="")

        def on_progress(steps: int, row: dict[str, float] | None) -> None:
            progress.update(task, completed=steps)
            if row is not None:
                angle = row["eval_mean_final_angle_deg"]
                progress.update(task, status=f"eval angle {angle:.2f} deg")

        result = ppo.train(config, out, on_progress, final_eval_episodes=args.final_episodes)
    metrics = result.policy.metrics
    refs = {k: v["mean_final_angle_deg"] for k, v in metrics.items() if k != "policy"}
    plot_learning_curve(out / "training_log.csv", out / "learning_curve.png", refs)
    if args.ship:
        target = shipped_policy_path()
        result.policy.save(target)
        (target.parent / "training_log.csv").write_text((out / "training_log.csv").read_text())
        console.print(f"shipped policy written to {target}")
    _print_metrics(metrics)
    reached = result.target_reached_s
    console.print(
        f"wall time {result.wall_time_s:.1f} s"
        + (f"; target reached at {reached:.1f} s" if reached is not None else "")
        + f"; policy, log and learning curve in {out}/"
    )
    return 0


def _print_metrics(metrics: dict[str, dict[str, Any]]) -> None:
    table = Table(title="final angle between d and u after 5 actions (standard evaluation)")
    for col in ("controller", "mean [deg]", "p95 [deg]", "mean return"):
        table.add_column(col, justify="right" if col != "controller" else "left")
    for name, m in metrics.items():
        table.add_row(
            name,
            f"{m['mean_final_angle_deg']:.2f}",
            f"{m['p95_final_angle_deg']:.2f}",
            f"{m['mean_return']:.4f}",
        )
    console.print(table)


# --- cap eval -------------------------------------------------------------------------------
def cmd_eval(args: argparse.Namespace) -> int:
    from constraint_aware.policy import ConstraintAwarePolicy
    from constraint_aware.training.config import EnvConfig
    from constraint_aware.training.evaluate import evaluate
    from constraint_aware.training.reference import reference_controllers

    policy = ConstraintAwarePolicy.load(args.policy)
    config = EnvConfig.from_dict(policy.card.get("env_config", {}))
    results = {
        name: evaluate(ctrl, config, episodes=args.episodes, seed=args.seed).to_dict()
        for name, ctrl in reference_controllers(config).items()
    }
    results["policy"] = evaluate(
        lambda obs, _f: policy.act_batch(obs), config, episodes=args.episodes, seed=args.seed
    ).to_dict()
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=2) + "\n")
    _print_metrics(results)
    return 0


# --- parser ---------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cap", description="Constraint-aware policy for compliant manipulation"
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("train", help="train the policy with PPO (needs the 'train' extra)")
    p.add_argument("--preset", default="fast", help="fast (default) or paper")
    p.add_argument("--out", help="output directory (default runs/train-PRESET-seedN)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, help="total env steps (overrides the preset)")
    p.add_argument("--target-angle", type=float, help="stop once eval mean angle <= this [deg]")
    p.add_argument("--time-budget", type=float, help="stop after this many seconds")
    p.add_argument("--eval-episodes", type=int, help="episodes per periodic evaluation")
    p.add_argument("--final-episodes", type=int, default=10_000, help="episodes for the card")
    p.add_argument("--ship", action="store_true", help="also overwrite the packaged policy")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("eval", help="evaluate a policy beside the reference controllers")
    p.add_argument("--policy", help="policy .npz (default: the shipped policy)")
    p.add_argument("--episodes", type=int, default=10_000)
    p.add_argument("--seed", type=int, default=12345)
    p.add_argument("--json", help="write the results to this JSON file")
    p.set_defaults(func=cmd_eval)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], int] = args.func
    try:
        return func(args)
    except CapError as exc:
        console.print(f"[red]error:[/] {exc}")
        return 2


if __name__ == "__main__":
    sys.exit(main())
