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


# --- cap run / cap view ---------------------------------------------------------------------
def cmd_run(args: argparse.Namespace) -> int:
    from constraint_aware.control.plots import plot_run
    from constraint_aware.control.simulate import RunSpec, run
    from constraint_aware.policy import ConstraintAwarePolicy
    from constraint_aware.sim.tasks import task_config

    task_config(args.task)  # unknown names fail here, listing the valid ones
    spec = RunSpec(
        task=args.task,
        controller=args.controller,
        offset_deg=args.offset,
        seed=args.seed,
        randomize=args.randomize,
        torque_policy=args.torque_policy,
        sensor_noise=args.sensor_noise,
    )
    policy = ConstraintAwarePolicy.load(args.policy) if args.controller == "policy" else None
    frames: list[Any] = []
    on_step = None
    if args.video:
        from constraint_aware.sim.render import SceneRenderer

        renderer: SceneRenderer | None = None

        def on_step(sim: Any) -> None:
            nonlocal renderer
            if renderer is None:
                renderer = SceneRenderer(
                    sim.model, lookat=sim.task.object.handle_position, distance=0.9
                )
            frames.append(renderer.frame(sim.data))

    record, _sim = run(spec, policy=policy, on_step=on_step)
    summary = record.summary()
    _print_outcome(
        f"{args.task} / {record.label['controller']} / offset {args.offset:+.1f} deg",
        record,
        f"final angle {summary['final_angle_deg']:.1f} deg, slip {summary['slip_m'] * 100:.1f} cm",
    )
    if args.json:
        record.save(args.json)
    if args.plot:
        plot_run(record, args.plot)
    if args.video:
        from constraint_aware.sim.render import save_video

        save_video(frames, args.video, fps=10)
    return 0


def _print_outcome(head: str, record: Any, tail: str) -> None:
    """One line: outcome, progress toward the goal, steps, peak force, then `tail`."""
    s = record.summary()
    scale, unit = (57.29577951308232, "deg") if s["constraint_type"] == "revolute" else (100, "cm")
    console.print(
        f"{head}: [{'green' if record.success else 'red'}]{record.outcome}[/] "
        f"{s['progress'] * scale:.1f}/{s['success_progress'] * scale:.0f} {unit} in "
        f"{s['steps']} steps, peak |F| {s['peak_force_N']:.1f} N, {tail}"
        + (f" ({record.reason})" if record.reason else ""),
        soft_wrap=True,
    )


def cmd_view(args: argparse.Namespace) -> int:
    import os

    from constraint_aware.sim.tasks import task_config
    from constraint_aware.sim.world import ManipulationSim

    sim = ManipulationSim(task_config(args.task))
    sim.reset()
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise CapError("cap view needs a display; use cap run TASK --video FILE.gif headless")
    import mujoco.viewer

    mujoco.viewer.launch(sim.model, sim.data)
    return 0


# --- cap lfo --------------------------------------------------------------------------------
def cmd_lfo(args: argparse.Namespace) -> int:
    from constraint_aware.lfo.demo import GRASP_TYPES, load
    from constraint_aware.lfo.infer import infer_skill

    if args.grasp and args.grasp not in GRASP_TYPES:
        raise CapError(f"grasp {args.grasp!r}; valid names: {', '.join(GRASP_TYPES)}")
    demo = load(args.demo)
    skill = infer_skill(demo, grasp_override=args.grasp)
    out: dict[str, Any] = {"demo": str(args.demo), "skill": skill.to_dict()}
    if not args.json:
        _print_skill(skill)
    if args.execute:
        from constraint_aware.lfo.execute import execute

        record, info = execute(skill, controller=args.controller, seed=args.seed)
        out["execution"] = {**info, **record.summary()}
        if not args.json:
            _print_outcome(
                f"executed on {info['task']} with the {record.label['controller']} controller",
                record,
                "initial-direction error vs the task "
                f"{info['initial_direction_error_deg']:.1f} deg",
            )
        if args.record:
            record.save(args.record)
    if args.json:
        print(json.dumps(out, indent=1))
    if args.execute and not out["execution"]["success"]:
        return 1
    return 0


def _print_skill(skill: Any) -> None:
    def vec(v: list[float] | None) -> str:
        return "-" if v is None else "(" + ", ".join(f"{x:+.3f}" for x in v) + ")"

    u = skill.uncertainty
    table = Table(title="skill parameters from the demonstration", show_header=False)
    table.add_row("constraint", skill.constraint_type)
    table.add_row(
        "workplane normal",
        vec(skill.workplane_normal)
        + (f"  +- {u['normal_std_deg']:.1f} deg" if "normal_std_deg" in u else ""),
    )
    table.add_row("initial direction", vec(skill.initial_direction))
    if skill.radius is not None:
        table.add_row(
            "radius",
            f"{skill.radius:.3f} m  +- {u['radius_std_m']:.3f} m (arc {u['arc_deg']:.0f} deg)",
        )
        table.add_row("centre", vec(skill.centre))
    table.add_row(
        "grasp",
        f"{skill.grasp}"
        + (" (fixed orientation: torque policy)" if skill.fixed_orientation else ""),
    )
    geo = skill.evidence["geometry"]
    table.add_row(
        "geometry",
        f"{geo['verdict']}: line RMS {geo['line_rms_m'] * 1000:.1f} mm"
        + (f", circle RMS {geo['circle_rms_m'] * 1000:.1f} mm" if "circle_rms_m" in geo else ""),
    )
    words = skill.evidence["words"]
    table.add_row("words", f"{words['constraint']}: {words['reason']}")
    console.print(table)
    for w in skill.warnings:
        console.print(f"[yellow]note:[/] {w}", soft_wrap=True)


# --- cap bench ------------------------------------------------------------------------------
def cmd_bench(args: argparse.Namespace) -> int:
    import time

    from constraint_aware.bench.run import replot, run_bench

    start = time.perf_counter()
    if args.replot:
        report = replot(args.replot)
    else:
        report = run_bench(args.out, quick=args.quick, workers=args.workers)
    console.print(
        f"report: {report} (results.json and figures beside it); "
        f"{time.perf_counter() - start:.0f} s",
        soft_wrap=True,
    )
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

    p = sub.add_parser("run", help="run a controller on a simulated task")
    p.add_argument(
        "task", help="drawer-opening, plate-sliding, pole-pulling, door-opening, handle-rotating"
    )
    p.add_argument("--controller", default="policy", help="policy, fixed, projection, classical")
    p.add_argument("--offset", type=float, default=30.0, help="initial direction error [deg]")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--randomize", action="store_true", help="draw friction, mass, damping")
    p.add_argument("--sensor-noise", type=float, default=0.1, help="[N] std per axis")
    tp = p.add_mutually_exclusive_group()
    tp.add_argument(
        "--torque-policy",
        dest="torque_policy",
        action="store_true",
        default=None,
        help="force the appendix's torque policy on (default: fixed-orientation grasps only)",
    )
    tp.add_argument("--no-torque-policy", dest="torque_policy", action="store_false")
    p.add_argument("--policy", help="policy .npz (default: the shipped policy)")
    p.add_argument("--json", help="save the run record here")
    p.add_argument("--plot", help="save angle and force curves here (.png)")
    p.add_argument("--video", help="render the run offscreen (.gif, or .mp4 with ffmpeg)")
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("bench", help="reproduce the paper's experiments as a report")
    p.add_argument("--quick", action="store_true", help="the paper's experiments, few seeds")
    p.add_argument("--out", default="bench-out", help="output directory (default bench-out)")
    p.add_argument("--workers", type=int, help="processes (default: every core)")
    p.add_argument("--replot", metavar="DIR", help="redraw figures and report from DIR only")
    p.set_defaults(func=cmd_bench)

    p = sub.add_parser("lfo", help="skill parameters from a demonstration (and run them)")
    p.add_argument("demo", help="demonstration .json (cap-demo/1) or a t,x,y,z .csv")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--execute", action="store_true", help="run the skill on the simulated task")
    p.add_argument("--grasp", help="override the force-exertion type")
    p.add_argument("--controller", default="policy", help="policy, classical, projection, fixed")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--record", help="save the execution's run record here (.json)")
    p.set_defaults(func=cmd_lfo)

    p = sub.add_parser("view", help="open MuJoCo's interactive viewer on a task")
    p.add_argument("task")
    p.set_defaults(func=cmd_view)
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
