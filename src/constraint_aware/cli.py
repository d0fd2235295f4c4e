"""`cap`: command-line entry point. Thin: parse, call the library, print.

Conventions (every subcommand):
- exit codes: 0 success, 1 the task failed (a run or an executed skill did not succeed, or the
  run raised), 2 usage or input error (argparse, `CapError`, an unwritable output), 130 Ctrl-C;
- results on stdout, errors on stderr, user text never interpreted as rich markup;
- `--json PATH` writes strict JSON (NaN and infinities become null); `-` means stdout, and the
  human-readable lines then go to stderr;
- output paths are checked (suffix, writer available) before anything is simulated;
- flags for configuration dataclasses are generated from their fields (cli_flags.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import importlib.util
import json
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

from constraint_aware import __version__
from constraint_aware.cli_flags import FlagSpec, add_dataclass_flags, collect
from constraint_aware.errors import CapError, InvalidInputError

console = Console()
err_console = Console(stderr=True)

EXIT_OK = 0
EXIT_FAILED = 1  # the task failed
EXIT_USAGE = 2  # usage or input error
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention

EPILOG = (
    "exit codes: 0 success; 1 the task failed (a run or an executed skill did not succeed); "
    "2 usage or input error; 130 interrupted (Ctrl-C). "
    "--json PATH writes strict JSON ('-' = stdout)."
)
JSON_SUFFIXES = (".json",)


class _Formatter(argparse.ArgumentDefaultsHelpFormatter):
    """Defaults shown for hand-written flags (generated flags carry their own)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "default" in text or action.default in (None, False, argparse.SUPPRESS):
            return text
        return super()._get_help_string(action)


# --- output helpers ---------------------------------------------------------------------------
def print_error(message: str) -> None:
    """`error: ...` on stderr; the message is plain text (brackets stay brackets)."""
    err_console.print(Text.assemble(("error: ", "bold red"), message), soft_wrap=True)


def report_partial(exc: BaseException, attr: str, path: str | None, what: str) -> int:
    """Inside `except`: write the result attached to `exc` as `attr` (a record or a probe
    result) to `path` as JSON, then re-raise a Ctrl-C (or an exception with nothing attached),
    or report the exception: exit 1."""
    partial = getattr(exc, attr, None)
    if partial is None:
        raise exc
    if path:
        write_json(partial.to_dict(), path)
    if not isinstance(exc, Exception) or isinstance(exc, CapError):  # Ctrl-C; input: exit 2
        raise exc
    print_error(f"{what} raised {type(exc).__name__}: {exc}")
    return EXIT_FAILED


def human(args: argparse.Namespace) -> Console:
    """Where human-readable lines go: stderr when the JSON result goes to stdout."""
    return err_console if getattr(args, "json", None) == "-" else console


def strict(value: Any) -> Any:
    """A JSON-ready copy: NaN/inf -> None, tuples and numpy values -> lists and numbers."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): strict(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [strict(v) for v in value]
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return strict(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(data: Any, path: str) -> None:
    """Strict JSON to `path` ('-': stdout). Write failures become a CapError (exit 2)."""
    text = json.dumps(strict(data), indent=1, allow_nan=False) + "\n"
    if path == "-":
        sys.stdout.write(text)
        sys.stdout.flush()
        return
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
    except OSError as exc:
        raise CapError(f"cannot write {path}: {exc.strerror or exc}") from exc


def check_output(
    path: str | None, flag: str, suffixes: Sequence[str], stdout: bool = False
) -> None:
    """Fail before any work if `path` has a suffix no writer handles or cannot be a file."""
    if path is None or (stdout and path == "-"):
        return
    out = Path(path)
    if out.suffix.lower() not in suffixes:
        raise InvalidInputError(
            f"{flag} {path!r}: suffix {out.suffix or '(none)'!r}; valid: {', '.join(suffixes)}"
            + (" or - for stdout" if stdout else "")
        )
    if out.is_dir():
        raise InvalidInputError(f"{flag} {path!r} is a directory")
    parent = next((p for p in out.absolute().parents if p.exists()), None)
    if parent is not None and not parent.is_dir():
        raise InvalidInputError(f"{flag} {path!r}: {parent} is not a directory")


def _installed(module: str) -> bool:
    """Whether `module` can be imported, looked up without importing it."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # blocked in sys.modules (None), or a broken parent
        return False


def require_extra(module: str, extra: str, what: str) -> None:
    """Fail before any work when an optional extra's package is missing."""
    try:
        importlib.import_module(module)
    except ImportError as exc:
        raise CapError(
            f"{what} needs the '{extra}' extra: pip install 'constraint-aware[{extra}]' ({exc})"
        ) from exc


def plot_suffixes() -> tuple[str, ...]:
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted("." + k for k in FigureCanvasBase.get_supported_filetypes()))


def _add_json(p: argparse.ArgumentParser | argparse._ArgumentGroup, what: str) -> None:
    p.add_argument("--json", metavar="PATH", help=f"write {what} as JSON here ('-' = stdout)")


def _add_policy(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    from constraint_aware import policy

    names: tuple[str, ...] = tuple(getattr(policy, "POLICY_NAMES", ()))
    p.add_argument(
        "--policy",
        metavar="NAME|FILE",
        help="a shipped policy's name"
        + (f" ({', '.join(names)})" if names else "")
        + " or a policy .npz (default: the shipped default policy)",
    )


def _add_profile_flags(p: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """--profile FILE and --strict-inputs (both default None: "not given")."""
    p.add_argument(
        "--profile",
        metavar="FILE",
        help="a robot profile .json from `cap calibrate`: its measured stiffness, time "
        "constant, grasp play and dead band become the run's inputs (the record names each "
        "input's source); it must be for the robot's control period",
    )
    p.add_argument(
        "--strict-inputs",
        action="store_true",
        default=None,
        help="refuse to run (exit 2) when an input a controller stage needs is missing, "
        "instead of warning and running with that stage off",
    )


def _load_profile(path: str | None) -> Any:
    """The robot profile at `path` (ProfileFileError naming the file and field), or None."""
    if not path:
        return None
    from constraint_aware.control.profile import RobotProfile

    return RobotProfile.load(path)


def _add_robot(
    p: argparse.ArgumentParser | argparse._ArgumentGroup, what: str, default: str | None = None
) -> None:
    """--robot; `default` None: the default robot ("": none, to see whether it was given)."""
    from constraint_aware.sim.embodiment import DEFAULT_ROBOT, EMBODIMENTS, variant_ranges

    p.add_argument(
        "--robot",
        default=DEFAULT_ROBOT if default is None else default,
        metavar="NAME[:KEY=VALUE,...]",
        help=f"the embodiment {what} (default: {DEFAULT_ROBOT}): {', '.join(EMBODIMENTS)}, "
        f"optionally with variants ({variant_ranges()}), e.g. jaco:stiffness=2000,period=0.2",
    )


# --- cap train --------------------------------------------------------------------------------
_TRAIN_ALIASES = {
    "total_timesteps": ("--steps",),
    "target_angle_deg": ("--target-angle",),
    "time_budget_s": ("--time-budget",),
}


def _train_parser(p: argparse.ArgumentParser) -> None:
    # torch / SB3 are an extra: looked up, not imported (the arguments are parsed and checked
    # without the seconds torch takes to import)
    absent = [name for name in ("torch", "stable_baselines3") if not _installed(name)]
    if absent:  # before any argument is parsed: `cap train --steps 10` says it too
        raise CapError(
            "training needs the 'train' extra: pip install 'constraint-aware[train]' "
            f"({', '.join(absent)} not installed)"
        )
    from constraint_aware.training import train_config
    from constraint_aware.training.config import EnvConfig

    presets = train_config.PRESETS
    train = p.add_argument_group("training (TrainConfig; defaults per --preset)")
    train.add_argument("--preset", default="fast", choices=sorted(presets), help="base config")

    def per_preset(name: str) -> str:
        values = {k: getattr(v, name) for k, v in presets.items()}
        if len({repr(v) for v in values.values()}) == 1:
            return _shown(next(iter(values.values())))
        return ", ".join(f"{k}: {_shown(v)}" for k, v in values.items())

    train_fields = [f.name for f in dataclasses.fields(train_config.TrainConfig) if f.name != "env"]
    specs = add_dataclass_flags(
        train,
        train_config.TrainConfig,
        skip=("preset", "env"),
        defaults={name: per_preset(name) for name in train_fields},
        aliases=_TRAIN_ALIASES,
        choices={"target_evaluation": train_config.TARGET_EVALUATIONS},
    )
    env = p.add_argument_group("training environment (EnvConfig)")
    env_specs = add_dataclass_flags(env, EnvConfig, prefix="env.")
    run = p.add_argument_group("outputs")
    run.add_argument("--out", help="output directory (default runs/train-PRESET-seedN)")
    run.add_argument("--final-episodes", type=int, default=10_000, help="episodes for the card")
    run.add_argument("--ship", action="store_true", help="also overwrite the packaged policy")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_json(run, "the final metrics")
    p.set_defaults(func=cmd_train, train_specs=specs, env_specs=env_specs)


def _shown(value: Any) -> str:
    return " ".join(map(str, value)) if isinstance(value, tuple) else str(value)


def cmd_train(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from constraint_aware.policy import shipped_policy_path
    from constraint_aware.training.train_config import make_config

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    train_specs: list[FlagSpec] = args.train_specs
    env_specs: list[FlagSpec] = args.env_specs
    config = make_config(args.preset, **collect(args, train_specs))
    env_overrides = collect(args, env_specs)
    if env_overrides:
        config = dataclasses.replace(config, env=dataclasses.replace(config.env, **env_overrides))
    # the configuration is checked: now the seconds of importing torch and SB3
    from constraint_aware.training import ppo
    from constraint_aware.training.curve import plot_learning_curve

    out = Path(args.out or f"runs/train-{config.preset}-seed{config.seed}")
    out_console = human(args)

    with Progress(
        TextColumn("[bold]training[/]"),
        BarColumn(),
        TextColumn("{task.completed:,}/{task.total:,} steps"),
        TextColumn("{task.fields[status]}"),
        TimeElapsedColumn(),
        console=out_console,
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
        out_console.print(Text(f"shipped policy written to {target}"))
    _print_metrics(metrics, out_console, "training environment (the --env.* flags)")
    reached = result.target_reached_s
    out_console.print(
        Text(
            f"wall time {result.wall_time_s:.1f} s"
            + (f"; target reached at {reached:.1f} s" if reached is not None else "")
            + f"; policy, log and learning curve in {out}/"
        )
    )
    if args.json:
        write_json(
            {
                "out": out,
                "config": config.to_dict(),
                "metrics": metrics,
                "wall_time_s": result.wall_time_s,
                "target_reached_s": reached,
            },
            args.json,
        )
    return EXIT_OK


def _print_metrics(metrics: dict[str, dict[str, Any]], out: Console, where: str) -> None:
    """The evaluation table: per controller, the final angle between d and u and the return;
    `where` names the environment the episodes came from (a heading line above the table)."""
    out.print(Text(f"{where}: final angle between d and u after the episode", style="bold"))
    table = Table()
    for col in ("controller", "mean [deg]", "p95 [deg]", "mean return"):
        table.add_column(Text(col), justify="right" if col != "controller" else "left")
    for name, m in metrics.items():
        table.add_row(
            Text(name),
            f"{m['mean_final_angle_deg']:.2f}",
            f"{m['p95_final_angle_deg']:.2f}",
            f"{m['mean_return']:.4f}",
        )
    out.print(table)


# --- cap eval ---------------------------------------------------------------------------------
#: cap eval's largest --episodes: every episode's angles are kept (about 100 bytes each).
MAX_EVAL_EPISODES = 10_000_000


def _eval_parser(p: argparse.ArgumentParser) -> None:
    _add_policy(p)
    p.add_argument(
        "--episodes",
        type=int,
        default=10_000,
        help=f"episodes per controller and environment (1 to {MAX_EVAL_EPISODES:,})",
    )
    p.add_argument("--seed", type=int, default=12345, help="seeds the episodes (>= 0)")
    _add_json(p, "the results")
    p.set_defaults(func=cmd_eval)


def cmd_eval(args: argparse.Namespace) -> int:
    """The policy beside the reference controllers in the environment it was trained in (its
    card's env_config) and, when that has resistance, in the standard evaluation's
    resistance-free environment; the card's own standard evaluation is shown under its name."""
    from constraint_aware.policy import ConstraintAwarePolicy
    from constraint_aware.training.config import EnvConfig
    from constraint_aware.training.evaluate import evaluate, standard_config
    from constraint_aware.training.reference import reference_controllers

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    if not 1 <= args.episodes <= MAX_EVAL_EPISODES:
        raise InvalidInputError(f"--episodes {args.episodes}: valid 1 to {MAX_EVAL_EPISODES:,}")
    if args.seed < 0:
        raise InvalidInputError(f"--seed {args.seed}: must be >= 0")
    policy = ConstraintAwarePolicy.load(args.policy)
    try:
        trained = EnvConfig.from_dict(policy.card.get("env_config", {}))
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"the policy card's env_config: {exc}") from exc
    standard = standard_config(policy.observation)

    def run(config: EnvConfig) -> dict[str, Any]:
        results = {
            name: evaluate(ctrl, config, episodes=args.episodes, seed=args.seed).to_dict()
            for name, ctrl in reference_controllers(config).items()
        }
        results["policy"] = evaluate(
            lambda obs, _f: policy.act_batch(obs), config, episodes=args.episodes, seed=args.seed
        ).to_dict()
        return results

    out = human(args)
    same = trained == standard
    training = run(trained)
    _print_metrics(
        training,
        out,
        "standard evaluation (the paper's environment, also the policy's training one)"
        if same
        else "training environment (the policy card's env_config)",
    )
    results: dict[str, Any] = {"training_environment": training}
    if same:
        results["standard_evaluation"] = training
    else:
        results["standard_evaluation"] = run(standard)
        _print_metrics(
            results["standard_evaluation"],
            out,
            "standard evaluation (the paper's environment: no resistance along the joint)",
        )
    card = policy.card.get("standard_evaluation")
    if card is None and same:  # trained in the standard environment: its metrics are that
        metrics = policy.card.get("metrics", {})
        card = metrics.get("policy") if isinstance(metrics, dict) else None
        if isinstance(card, dict):
            card = {**card, "source": "the card's metrics: its training environment's"}
    if isinstance(card, dict) and isinstance(card.get("mean_final_angle_deg"), int | float):
        results["card_standard_evaluation"] = card
        p95 = card.get("p95_final_angle_deg")
        out.print(
            Text(
                f"the card's standard evaluation: mean {card['mean_final_angle_deg']:.2f} deg"
                + (f", p95 {p95:.2f} deg" if isinstance(p95, int | float) else "")
                + (f" ({card['source']})" if isinstance(card.get("source"), str) else "")
            ),
            soft_wrap=True,
        )
    if args.json:
        write_json(results, args.json)
    return EXIT_OK


# --- cap run / cap view -----------------------------------------------------------------------
def _task_names() -> list[str]:
    from constraint_aware.sim.tasks import TASKS

    return list(TASKS)


def _run_parser(p: argparse.ArgumentParser) -> None:
    from constraint_aware.control.controllers import CONTROLLERS
    from constraint_aware.control.simulate import RunSpec

    p.add_argument("task", choices=_task_names(), help="the simulated task")
    specs = add_dataclass_flags(
        p,
        RunSpec,
        skip=("task", "overrides", "controller_params"),
        choices={"controller": CONTROLLERS},
        aliases={"offset_deg": ("--offset",)},
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="repeatable; any task or executor field: FIELD (TaskConfig, e.g. force_limit=40), "
        "object.FIELD, hand.FIELD, executor.FIELD or executor.GROUP.FIELD (ExecutorConfig, "
        "e.g. executor.threshold=1, executor.limits.force_limit=40, "
        "executor.guards.predictive_force=false); an unknown key lists the valid ones",
    )
    _add_profile_flags(p)
    _add_policy(p)
    out = p.add_argument_group("outputs (checked before the run starts)")
    out.add_argument(
        "--json", metavar="PATH", help="the run record as JSON ('-' = stdout); written on failure"
    )
    out.add_argument("--plot", metavar="PATH", help="angle and force curves (.png, .pdf, .svg...)")
    out.add_argument(
        "--video",
        metavar="PATH",
        help="render the run offscreen: .gif (Pillow) or .mp4 (the 'video' extra)",
    )
    out.add_argument(
        "--mcap",
        metavar="PATH",
        help="the run record as .mcap for Foxglove: tool poses, wrench and direction arrows "
        "(the 'mcap' extra); written on failure",
    )
    p.set_defaults(func=cmd_run, run_specs=specs)


def _check_run_outputs(args: argparse.Namespace) -> None:
    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    if args.plot:  # matplotlib is imported only when a plot is asked for
        check_output(args.plot, "--plot", plot_suffixes())
    if args.video:
        from constraint_aware.sim.render import check_video_path

        check_video_path(args.video)
    check_output(args.mcap, "--mcap", (".mcap",))
    if args.mcap:
        require_extra("mcap.writer", "mcap", "--mcap")


def cmd_run(args: argparse.Namespace) -> int:
    from constraint_aware.control.controllers import POLICY_CONTROLLERS
    from constraint_aware.control.settings import parse_settings
    from constraint_aware.control.simulate import RunSpec, run
    from constraint_aware.policy import ConstraintAwarePolicy

    _check_run_outputs(args)
    spec = RunSpec(task=args.task, **collect(args, args.run_specs))
    if args.set:
        spec = spec.with_settings(parse_settings(args.set))
    uses_policy = spec.controller in POLICY_CONTROLLERS
    profile = _load_profile(args.profile)
    strict: dict[str, object] | None = {"strict_inputs": True} if args.strict_inputs else None
    policy = ConstraintAwarePolicy.load(args.policy) if uses_policy else None
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

    try:
        record, _sim = run(
            spec, policy=policy, on_step=on_step, executor_overrides=strict, profile=profile
        )
    except BaseException as exc:  # write what we have, then report (Ctrl-C: 130)
        partial = getattr(exc, "run_record", None)
        if partial is None:
            raise
        _write_run_outputs(args, partial, frames)
        if not isinstance(exc, Exception) or isinstance(exc, CapError):  # input error: exit 2
            raise
        print_error(f"the run raised {type(exc).__name__}: {exc}")
        return EXIT_FAILED
    summary = record.summary()
    _print_outcome(
        human(args),
        f"{args.task} / {record.label['controller']} / offset {spec.offset_deg:+.1f} deg",
        record,
        f"final angle {summary['final_angle_deg']:.1f} deg, slip {summary['slip_m'] * 100:.1f} cm",
    )
    _write_run_outputs(args, record, frames)
    return EXIT_OK if record.success else EXIT_FAILED


def _write_run_outputs(args: argparse.Namespace, record: Any, frames: list[Any]) -> None:
    """The record (JSON), its plot and the video: each one the run produced enough for."""
    if args.json:
        write_json(record.to_dict(), args.json)
    try:
        if args.mcap:
            from constraint_aware.control.mcap_export import write_mcap

            write_mcap(record, args.mcap)
        if args.plot and record.steps:
            from constraint_aware.control.plots import plot_run

            plot_run(record, args.plot)
        if args.video and frames:
            from constraint_aware.sim.render import save_video

            save_video(frames, args.video, fps=10)
    except OSError as exc:
        target = exc.filename or "an output"
        raise CapError(f"cannot write {target}: {exc.strerror or exc}") from exc


def _print_outcome(out: Console, head: str, record: Any, tail: str) -> None:
    """One line: outcome, progress toward the goal, steps, peak force, then `tail`."""
    s = record.summary()
    scale, unit = (57.29577951308232, "deg") if s["constraint_type"] == "revolute" else (100, "cm")
    out.print(
        Text.assemble(
            f"{head}: ",
            (record.outcome, "green" if record.success else "red"),
            f" {s['progress'] * scale:.1f}/{s['success_progress'] * scale:.0f} {unit} in "
            f"{s['steps']} steps, peak |F| {s['peak_force_N']:.1f} N, {tail}"
            + (f" ({record.reason})" if record.reason else ""),
        ),
        soft_wrap=True,
    )


def _view_parser(p: argparse.ArgumentParser) -> None:
    p.add_argument("task", choices=_task_names(), help="the simulated task")
    p.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    from constraint_aware.sim.tasks import task_config
    from constraint_aware.sim.world import ManipulationSim

    sim = ManipulationSim(task_config(args.task))
    sim.reset()
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise CapError("cap view needs a display; use cap run TASK --video FILE.gif headless")
    import mujoco.viewer

    mujoco.viewer.launch(sim.model, sim.data)
    return EXIT_OK


# --- cap lfo ----------------------------------------------------------------------------------
def _lfo_parser(p: argparse.ArgumentParser) -> None:
    from constraint_aware.control.controllers import CONTROLLERS
    from constraint_aware.lfo.demo import GRASP_TYPES
    from constraint_aware.recognizer import METHODS

    p.add_argument("demo", help="demonstration .json (cap-demo/1) or a t,x,y,z .csv")
    p.add_argument(
        "--trajectory",
        metavar="CSV",
        help="a t,x,y,z[,qw,qx,qy,qz] CSV replacing the demonstration's own trajectory (a "
        "demonstration's trajectory_csv may only name a file in its own folder)",
    )
    _add_json(p, "the skill (and the execution's summary)")
    p.add_argument("--execute", action="store_true", help="run the skill on the simulated task")
    p.add_argument("--grasp", choices=GRASP_TYPES, help="override the force-exertion type")
    run = p.add_argument_group("execution (with --execute only)")
    run.add_argument(
        "--controller",
        choices=CONTROLLERS,
        help=f"the direction controller (default: {LFO_CONTROLLER})",
    )
    run.add_argument("--seed", type=int, help="the simulated sensor's noise seed (default: 0)")
    _add_robot(run, "that executes the skill", default="")
    _add_profile_flags(run)
    _add_policy(run)
    run.add_argument("--record", metavar="PATH", help="the execution's run record (.json)")
    run.add_argument(
        "--start",
        choices=LFO_STARTS,
        help="home (default): see the object, reach, grasp, manipulate, release and return "
        "home; at-grasp: the hand placed on the simulated handle (experiments)",
    )
    run.add_argument(
        "--recognizer",
        choices=METHODS,
        help=f"the contact-points recognizer with --start home (default: {LFO_RECOGNIZER})",
    )
    run.add_argument(
        "--video",
        metavar="PATH",
        help="render the execution offscreen: .gif (Pillow) or .mp4 (the 'video' extra)",
    )
    p.set_defaults(func=cmd_lfo)


#: cap lfo's execution flags: (flag, attribute); each one given without --execute is an error.
LFO_EXECUTION_FLAGS = (
    ("--controller", "controller"),
    ("--seed", "seed"),
    ("--robot", "robot"),
    ("--policy", "policy"),
    ("--record", "record"),
    ("--profile", "profile"),
    ("--strict-inputs", "strict_inputs"),
    ("--start", "start"),
    ("--recognizer", "recognizer"),
    ("--video", "video"),
)
LFO_CONTROLLER = "policy"
LFO_STARTS = ("home", "at-grasp")
LFO_START = "home"
LFO_RECOGNIZER = "cnn"


def cmd_lfo(args: argparse.Namespace) -> int:
    from constraint_aware.lfo.demo import load
    from constraint_aware.lfo.infer import infer_skill
    from constraint_aware.sim.embodiment import DEFAULT_ROBOT

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    check_output(args.record, "--record", JSON_SUFFIXES, stdout=True)
    given = [flag for flag, attr in LFO_EXECUTION_FLAGS if getattr(args, attr) not in (None, "")]
    if given and not args.execute:  # never silently ignored
        raise InvalidInputError(
            f"{', '.join(given)} without --execute: {'it sets' if len(given) == 1 else 'they set'}"
            " the execution; add --execute to run the skill"
        )
    if args.json == "-" and args.record == "-":
        raise InvalidInputError("--json - and --record -: only one of them can go to stdout")
    args.controller = args.controller or LFO_CONTROLLER
    args.seed = 0 if args.seed is None else args.seed
    args.robot = args.robot or DEFAULT_ROBOT
    args.start = args.start or LFO_START
    if args.recognizer is not None and args.start != "home":
        raise InvalidInputError(
            f"--recognizer with --start {args.start}: only the sequence from home sees the object"
        )
    if args.video is not None and args.start != "home":
        raise InvalidInputError(
            f"--video with --start {args.start}: the video shows the sequence from home"
        )
    args.recognizer = args.recognizer or LFO_RECOGNIZER
    if args.video:
        from constraint_aware.sim.render import check_video_path

        check_video_path(args.video)
    out_console = err_console if "-" in (args.json, args.record) else console
    policy = None
    if args.execute:
        from constraint_aware.sim.embodiment import parse_robot

        if args.seed < 0:
            raise InvalidInputError(f"--seed {args.seed}: must be >= 0")
        parse_robot(args.robot)  # before any work
    profile = _load_profile(args.profile)  # before any work
    from constraint_aware.control.controllers import POLICY_CONTROLLERS

    if args.execute and args.controller in POLICY_CONTROLLERS:
        from constraint_aware.policy import ConstraintAwarePolicy

        policy = ConstraintAwarePolicy.load(args.policy)  # before any work
    demo = load(args.demo, trajectory=args.trajectory)
    skill = infer_skill(demo, grasp_override=args.grasp)
    out: dict[str, Any] = {"demo": str(args.demo), "skill": skill.to_dict()}
    _print_skill(skill, out_console)
    if args.execute and args.start == "home":
        return _lfo_sequence(args, skill, policy, profile, out, out_console)
    if args.execute:
        from constraint_aware.lfo.execute import execute

        try:
            record, info = execute(
                skill,
                controller=args.controller,
                seed=args.seed,
                policy=policy,
                robot=args.robot,
                profile=profile,
                strict_inputs=bool(args.strict_inputs),
            )
        except BaseException as exc:  # write the attached record, as cap run does
            return report_partial(exc, "run_record", args.record, "the execution")
        out["execution"] = {**info, **record.summary()}
        _print_outcome(
            out_console,
            f"executed on {info['task']} by {info['robot']} with the "
            f"{record.label['controller']} controller",
            record,
            f"initial-direction error vs the task {info['initial_direction_error_deg']:.1f} deg",
        )
        _print_notes(info["notes"], out_console)  # what was assumed building the object
        if args.record:
            write_json(record.to_dict(), args.record)
    if args.json:
        write_json(out, args.json)
    if args.execute and not out["execution"]["success"]:
        return EXIT_FAILED
    return EXIT_OK


def _lfo_sequence(
    args: argparse.Namespace,
    skill: Any,
    policy: Any,
    profile: Any,
    out: dict[str, Any],
    out_console: Console,
) -> int:
    """`cap lfo --execute` from home: the whole sequence on the object the demonstration
    shows, its record (--record), video (--video) and summary (--json)."""
    from constraint_aware.lfo.execute import execute_from_home

    frames: list[Any] = []
    on_period = _video_recorder(frames) if args.video else None
    try:
        result, info = execute_from_home(
            skill, controller=args.controller, seed=args.seed, policy=policy, robot=args.robot,
            recognizer=args.recognizer, on_period=on_period,
            profile=profile, strict_inputs=bool(args.strict_inputs),
        )  # fmt: skip
    except BaseException as exc:  # write what there is, then report
        partial = getattr(exc, "sequence_record", None)
        if partial is not None and args.record:
            write_json(partial.to_dict(), args.record)
        _save_frames(args, frames)
        if not isinstance(exc, Exception):
            raise
        if isinstance(exc, CapError):
            raise
        print_error(f"the execution raised {type(exc).__name__}: {exc}")
        return EXIT_FAILED
    record = result.record
    out["execution"] = {**info, "sequence": record.to_dict()}
    for phase in record.phases:
        colour = {"ok": "green", "not_run": "dim"}.get(phase.outcome, "red")
        out_console.print(
            Text.assemble(
                f"{phase.name:<11}", (phase.outcome, colour),
                f"  {phase.periods} periods, peak |F| {phase.peak_force:.1f} N"
                + (f" ({phase.reason})" if phase.reason else ""),
            ),
            soft_wrap=True,
        )  # fmt: skip
    verdict = "done" if record.success else f"stopped in {record.failed_phase}"
    out_console.print(
        Text.assemble(
            f"executed on {info['task']} by {info['robot']} from home: ",
            (verdict, "green" if record.success else "red"),
        )
    )
    _print_notes(info["notes"], out_console)
    if args.record:
        write_json(record.to_dict(), args.record)
    _save_frames(args, frames)
    if args.json:
        write_json(out, args.json)
    return EXIT_OK if record.success else EXIT_FAILED


def _video_recorder(frames: list[Any]) -> Callable[[Any], None]:
    """An on_period(sim) that renders one frame per control period into `frames`."""
    from constraint_aware.sim.render import SceneRenderer

    renderer: list[SceneRenderer] = []

    def on_period(sim: Any) -> None:
        if not renderer:
            renderer.append(
                SceneRenderer(
                    sim.model, width=480, height=360, lookat=sim.model.stat.center, distance=1.8
                )
            )
        frames.append(renderer[0].frame(sim.data))

    return on_period


def _save_frames(args: argparse.Namespace, frames: list[Any]) -> None:
    if args.video and frames:
        from constraint_aware.sim.render import save_video

        try:
            save_video(frames, args.video, fps=10)
        except OSError as exc:
            raise CapError(f"cannot write {args.video}: {exc.strerror or exc}") from exc


def _print_skill(skill: Any, out: Console) -> None:
    def vec(v: list[float] | None) -> str:
        return "-" if v is None else "(" + ", ".join(f"{x:+.3f}" for x in v) + ")"

    u = skill.uncertainty
    table = Table(title="skill parameters from the demonstration", show_header=False)
    rows: list[tuple[str, str]] = [
        ("constraint", skill.constraint_type),
        (
            "workplane normal",
            vec(skill.workplane_normal)
            + (f"  +- {u['normal_std_deg']:.1f} deg" if "normal_std_deg" in u else ""),
        ),
        ("initial direction", vec(skill.initial_direction)),
    ]
    if skill.radius is not None:
        rows.append(
            (
                "radius",
                f"{skill.radius:.3f} m  +- {u['radius_std_m']:.3f} m (arc {u['arc_deg']:.0f} deg)",
            )
        )
        rows.append(("centre", vec(skill.centre)))
    rows.append(
        (
            "grasp",
            f"{skill.grasp}"
            + (" (fixed orientation: torque policy)" if skill.fixed_orientation else ""),
        )
    )
    geo = skill.evidence["geometry"]
    rows.append(
        (
            "geometry",
            f"{geo['verdict']}: line RMS {geo['line_rms_m'] * 1000:.1f} mm"
            + (
                f", circle RMS {geo['circle_rms_m'] * 1000:.1f} mm" if "circle_rms_m" in geo else ""
            ),
        )
    )
    words = skill.evidence["words"]
    rows.append(("words", f"{words['constraint']}: {words['reason']}"))
    for key, value in rows:
        table.add_row(Text(key), Text(value))  # demo text is data, never markup
    out.print(table)
    _print_notes(skill.warnings, out)


def _print_notes(notes: Sequence[str], out: Console) -> None:
    """`note: ...` lines: the assumptions and disagreements (words vs geometry) that --json
    holds as `skill.warnings` and `execution.notes`, in plain text."""
    for note in notes:
        out.print(Text.assemble(("note: ", "yellow"), note), soft_wrap=True)


# --- cap train-grasp --------------------------------------------------------------------------
def _train_grasp_parser(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenes", type=int, default=200, help="training scenes per object kind")
    p.add_argument(
        "--validation-scenes", type=int, default=30, help="validation scenes per object kind"
    )
    p.add_argument("--crops", type=int, default=4, help="crops per camera view (demo offsets)")
    p.add_argument(
        "--looks", type=int, default=4, help="second-look crops per robot and scene (>= 0)"
    )
    p.add_argument("--epochs", type=int, default=20, help="training epochs")
    p.add_argument("--seed", type=int, default=0, help="seeds the scenes and the training")
    p.add_argument("--data", metavar="NPZ", help="reuse a training set (grasp_train.npz)")
    p.add_argument("--out", help="output directory (default runs/train-grasp-seedN)")
    p.add_argument("--ship", action="store_true", help="also overwrite the packaged weights")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_json(p, "the scores per method and kind")
    p.set_defaults(func=cmd_train_grasp)


def cmd_train_grasp(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    counts = {
        "--scenes": args.scenes,
        "--validation-scenes": args.validation_scenes,
        "--crops": args.crops,
        "--epochs": args.epochs,
    }
    for flag, value in counts.items():
        if value < 1:
            raise InvalidInputError(f"{flag} {value}: must be >= 1")
    if args.looks < 0:
        raise InvalidInputError(f"--looks {args.looks}: must be >= 0")
    if args.seed < 0:
        raise InvalidInputError(f"--seed {args.seed}: must be >= 0")
    if args.data and not Path(args.data).is_file():
        raise InvalidInputError(f"--data {args.data!r}: no such file")
    # torch loads with these, after the input is checked
    require_extra("torch", "train", "cap train-grasp")
    from constraint_aware.lfo.grasp_training import train_grasp
    from constraint_aware.recognizer import shipped_recognizer_path
    from constraint_aware.training.grasp import GraspTrainConfig

    config = GraspTrainConfig(epochs=args.epochs, seed=args.seed)
    out = Path(args.out or f"runs/train-grasp-seed{args.seed}")
    out_console = human(args)
    with Progress(
        TextColumn("[bold]{task.description}[/]"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TextColumn("{task.fields[status]}"),
        TimeElapsedColumn(),
        console=out_console,
        disable=args.quiet,
    ) as progress:
        bars: dict[str, Any] = {}

        def on_scene(stage: str, done: int, total: int) -> None:
            if stage not in bars:
                bars[stage] = progress.add_task(f"{stage} scenes", total=total, status="")
            progress.update(bars[stage], completed=done)

        epochs = progress.add_task("training epochs", total=args.epochs, status="")

        def on_epoch(epoch: int, row: dict[str, float]) -> None:
            status = f"median {row['val_median_mm']:.1f} mm, p95 {row['val_p95_mm']:.1f} mm"
            progress.update(epochs, completed=epoch, status=status)

        result = train_grasp(
            out, args.scenes, args.validation_scenes, args.crops, args.seed, config,
            args.data, on_scene, on_epoch, looks_per_view=args.looks,
        )  # fmt: skip
    table = Table(title="contact-point recognizers on the validation scenes")
    for col in ("method", "kind", "median [mm]", "p95 [mm]", "approach p95 [deg]"):
        table.add_column(col, justify="left" if col in ("method", "kind") else "right")

    def cell(x: float | None) -> str:
        return "no answer" if x is None else f"{x:.1f}"

    for method, rows in result.scores.items():
        for kind, r in rows.items():
            table.add_row(
                method, kind, cell(r["median_mm"]), cell(r["p95_mm"]),
                cell(r["approach_p95_deg"]),
            )  # fmt: skip
    out_console.print(table)
    if args.ship:
        result.recognizer.save(shipped_recognizer_path())
        out_console.print(Text(f"shipped recognizer written to {shipped_recognizer_path()}"))
    times = result.times
    out_console.print(
        Text(
            f"data {times['data_s']:.0f} s, training {times['training_s']:.0f} s; "
            f"recognizer in {result.path}"
        )
    )
    if args.json:
        write_json({"out": out, "scores": result.scores, "times": result.times}, args.json)
    return EXIT_OK


# --- cap bench --------------------------------------------------------------------------------
def _bench_parser(p: argparse.ArgumentParser) -> None:
    p.add_argument("--quick", action="store_true", help="the paper's experiments, few seeds")
    p.add_argument("--out", default="bench-out", help="output directory")
    p.add_argument("--workers", type=int, help="processes (default: the usable cores)")
    p.add_argument("--replot", metavar="DIR", help="redraw figures and report from DIR only")
    p.add_argument(
        "--force", action="store_true", help="write into --out even if it holds other files"
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the sweeps on a Dask cluster (the 'cluster' extra): a scheduler address "
        "(tcp://host:8786), or 'local' for a local cluster of --workers processes",
    )
    _add_policy(p)
    _add_robot(p, "of the paper's experiments, the suite and the maps")
    _add_json(p, "results.json's content")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    import time

    from constraint_aware.bench.run import RESULTS, replot, run_bench
    from constraint_aware.sim.embodiment import DEFAULT_ROBOT

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    if args.workers is not None and args.workers < 1:
        raise InvalidInputError(f"--workers {args.workers}: must be >= 1")
    if args.scheduler is not None:
        require_extra("distributed", "cluster", "--scheduler")
    start = time.perf_counter()
    if args.replot:
        if args.policy is not None or args.robot != DEFAULT_ROBOT:
            raise InvalidInputError("--replot redraws a finished bench: no --policy or --robot")
        report = replot(args.replot)
    else:
        report = run_bench(
            args.out,
            quick=args.quick,
            workers=args.workers,
            force=args.force,
            scheduler=args.scheduler,
            policy=args.policy,
            robot=args.robot,
        )
    human(args).print(
        Text(
            f"report: {report} (results.json and figures beside it); "
            f"{time.perf_counter() - start:.0f} s"
        ),
        soft_wrap=True,
    )
    if args.json:
        write_json(json.loads((Path(report).parent / RESULTS).read_text()), args.json)
    return EXIT_OK


# --- cap export-onnx --------------------------------------------------------------------------
def _export_onnx_parser(p: argparse.ArgumentParser) -> None:
    _add_policy(p)
    p.add_argument("out", metavar="OUT.onnx", help="the ONNX model to write")
    p.add_argument(
        "--parity",
        type=int,
        default=10_000,
        metavar="N",
        help="check ONNX Runtime against the numpy policy on N random observations (0: skip; "
        "at most 1,000,000)",
    )
    _add_json(p, "the model's path, metadata and parity")
    p.set_defaults(func=cmd_export_onnx)


def cmd_export_onnx(args: argparse.Namespace) -> int:
    from constraint_aware.policy import ConstraintAwarePolicy

    check_output(args.out, "OUT", (".onnx",))
    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    from constraint_aware.export.onnx import MAX_PARITY_OBSERVATIONS

    if not 0 <= args.parity <= MAX_PARITY_OBSERVATIONS:
        raise InvalidInputError(
            f"--parity {args.parity:,}: valid 0 (skip) to {MAX_PARITY_OBSERVATIONS:,} observations"
        )
    require_extra("onnx", "onnx", "cap export-onnx")
    if args.parity:
        require_extra("onnxruntime", "onnx", "the parity check (--parity 0 skips it)")
    from constraint_aware.export.onnx import export_onnx, onnx_parity, read_onnx_metadata

    policy = ConstraintAwarePolicy.load(args.policy)
    try:
        path = export_onnx(policy, args.out)
    except OSError as exc:
        raise CapError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
    result: dict[str, Any] = {"out": str(path), "metadata": read_onnx_metadata(path)}
    line = f"wrote {path}"
    if args.parity:
        err = onnx_parity(policy, path, n_observations=args.parity)
        result["parity"] = {"n_observations": args.parity, "max_abs_error": err}
        line += f"; max |numpy - onnxruntime| over {args.parity:,} observations: {err:.2e}"
    human(args).print(Text(line), soft_wrap=True)
    if args.json:
        write_json(result, args.json)
    return EXIT_OK


# --- cap check-sensor -------------------------------------------------------------------------
#: The bench's faults that act on every period from the start (or from its 5th): the ones
#: meaningful for a probe, which makes no executor moves.
PROBE_FAULTS = ("flipped_sign", "rotated_90", "frozen", "bias_drift", "stale_wrench")


def _check_sensor_parser(p: argparse.ArgumentParser) -> None:
    from constraint_aware.bench.faults import FAULTS
    from constraint_aware.control.probe import ProbeConfig

    p.add_argument("task", choices=_task_names(), help="the simulated task, grasped")
    _add_robot(p, "to probe")
    p.add_argument("--seed", type=int, default=0, help="the sensor noise's seed")
    p.add_argument(
        "--fault",
        default="none",
        choices=("none", *PROBE_FAULTS),
        help="a fault to inject between the probe and the robot (bench/faults.py: "
        + "; ".join(f"{f}: {FAULTS[f]}" for f in PROBE_FAULTS)
        + "; the bench's other faults are timed by the executor's moves and are not offered)",
    )
    specs = add_dataclass_flags(p.add_argument_group("probe"), ProbeConfig)
    p.add_argument("--json", metavar="PATH", help="the probe's result as JSON ('-' = stdout)")
    p.add_argument(
        "--plot", metavar="PATH", help="each push's force change and stiffness (.png, .svg...)"
    )
    p.set_defaults(func=cmd_check_sensor, probe_specs=specs)


def cmd_check_sensor(args: argparse.Namespace) -> int:
    from constraint_aware.bench.faults import FaultyRobot
    from constraint_aware.control.probe import PROBE_VERDICTS, STIFFNESS_VERDICTS, ProbeConfig
    from constraint_aware.control.simulate import RunSpec, probe

    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    if args.plot:  # matplotlib is imported only when a plot is asked for
        check_output(args.plot, "--plot", plot_suffixes())
    spec = RunSpec(task=args.task, seed=args.seed, robot=args.robot)
    chosen = collect(args, args.probe_specs)
    config = ProbeConfig(**chosen) if chosen else None
    wrap = None
    if args.fault != "none":
        fault = args.fault

        def wrap(sim: Any) -> Any:
            return FaultyRobot(sim, fault, 0)

    try:
        result, _sim = probe(spec, config, wrap)
    except BaseException as exc:  # write what the probe has, then report (Ctrl-C: 130)
        return report_partial(exc, "probe_result", args.json, "the probe")
    out = human(args)
    used = config or ProbeConfig()
    title = f"{args.task} / {args.robot}: pushes of {used.amplitude * 1000:g} mm"
    if used.play_amplitude is not None:
        title += f" (deep, for the play: {used.play_amplitude * 1000:g} mm)"
    table = Table(title=Text(title))
    columns = ("direction", "|dF| [N]", "cos(dF, stretch)", "arm [N/m]", "push [N/m]", "give [mm]")
    for column in columns:
        table.add_column(column, justify="right")
    for push in [*result.pushes, *result.play_pushes]:
        df = math.hypot(*push.force_change)
        deep = push.amplitude > used.amplitude  # a play push
        table.add_row(
            " ".join(f"{x:+.2f}" for x in push.direction) + (" (deep)" if deep else ""),
            f"{df:.2f}",
            "-" if push.cos is None else f"{push.cos:+.2f}",
            "-" if push.arm_stiffness is None else f"{push.arm_stiffness:.0f}",
            f"{push.push_stiffness:.0f}",
            "-" if push.give is None else f"{push.give * 1000:.2f}",
        )
    out.print(table)
    ok = result.verdict in STIFFNESS_VERDICTS  # the convention holds
    out.print(
        Text.assemble(
            "verdict: ",
            (result.verdict, "green" if result.verdict == "consistent" else "red"),
            f" ({result.reason}). {PROBE_VERDICTS[result.verdict]}",
        ),
        soft_wrap=True,
    )
    if result.play is not None:
        out.print(
            Text(
                f"grasp play {result.play * 1000:.2f} mm (the deep pushes' give against force, "
                f"extrapolated to zero force); median give {(result.give or 0) * 1000:.2f} mm"
            ),
            soft_wrap=True,
        )
    for note in result.notes:
        out.print(Text(f"note: {note}"), soft_wrap=True)
    if args.json:
        write_json(result.to_dict(), args.json)
    if args.plot:
        from constraint_aware.control.plots import plot_probe

        plot_probe(result, args.plot)
    return EXIT_OK if ok else EXIT_FAILED


# --- cap calibrate ----------------------------------------------------------------------------
#: CalibrationConfig's fields a free-space calibration takes too (FreeSpaceConfig's).
_FREE_SPACE_SHARED = (
    "rest_periods", "force_limit", "contact_force", "max_stiffness", "max_periods",
)  # fmt: skip


def _calibrate_parser(p: argparse.ArgumentParser) -> None:
    from constraint_aware.control.calibrate import CalibrationConfig
    from constraint_aware.control.free_space import FreeSpaceConfig

    p.add_argument("task", choices=_task_names(), help="the simulated task whose handle is held")
    _add_robot(p, "to calibrate")
    p.add_argument("--seed", type=int, default=0, help="the sensor noise's seed")
    p.add_argument(
        "--noise", type=float, default=0.1, metavar="N", help="the simulated sensor noise [N]"
    )
    p.add_argument("--name", help="the robot's name in the profile (default: the robot spec)")
    p.add_argument("--out", metavar="PATH", help="write the robot profile here (.json)")
    p.add_argument(
        "--free-space",
        action="store_true",
        help="calibrate in free space instead (tau, noise; the simulated hand at the task's "
        "grasp posture with contacts off, holding nothing): once per robot",
    )
    p.add_argument(
        "--with",
        dest="with_profile",
        metavar="FILE",
        help="the robot's free-space profile (from --free-space): its tracking time constant "
        "replaces the pushes' estimate, and its lag error gives the deflection error per speed "
        "where the pushes leave it unmeasured",
    )
    specs = add_dataclass_flags(p.add_argument_group("calibration"), CalibrationConfig)
    free_specs = add_dataclass_flags(
        p.add_argument_group("free-space calibration (--free-space)"),
        FreeSpaceConfig,
        skip=_FREE_SPACE_SHARED,
    )
    p.add_argument("--json", metavar="PATH", help="the profile as JSON ('-' = stdout)")
    p.set_defaults(func=cmd_calibrate, calibration_specs=specs, free_space_specs=free_specs)


def cmd_calibrate(args: argparse.Namespace) -> int:
    from constraint_aware.control.calibrate import CalibrationConfig, calibrate
    from constraint_aware.control.free_space import FreeSpaceConfig, calibrate_free_space
    from constraint_aware.control.profile import QUANTITIES
    from constraint_aware.control.simulate import RunSpec, grasped

    check_output(args.out, "--out", JSON_SUFFIXES)
    check_output(args.json, "--json", JSON_SUFFIXES, stdout=True)
    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise InvalidInputError(f"--noise {args.noise}: must be finite and >= 0 [N]")
    spec = RunSpec(task=args.task, seed=args.seed, robot=args.robot, sensor_noise=args.noise)
    chosen = collect(args, args.calibration_specs)
    free_chosen = collect(args, args.free_space_specs)
    if args.free_space and args.with_profile:
        raise InvalidInputError("--with: a free-space calibration takes no other profile")
    pushes_only = sorted(set(chosen) - set(_FREE_SPACE_SHARED))
    if args.free_space and pushes_only:
        flag = "--" + pushes_only[0].replace("_", "-")
        raise InvalidInputError(f"{flag}: a push setting, not used with --free-space")
    if not args.free_space and free_chosen:
        flag = "--" + sorted(free_chosen)[0].replace("_", "-")
        raise InvalidInputError(f"{flag}: a free-space setting, used only with --free-space")
    free_profile = _load_profile(args.with_profile)
    task, sim = grasped(spec)
    # the calibration's force limit stays below the object's own
    chosen.setdefault("force_limit", min(CalibrationConfig.force_limit, task.force_limit))
    name = args.name if args.name is not None else args.robot
    try:
        if args.free_space:
            config_free = FreeSpaceConfig(**chosen, **free_chosen)
            sim.in_free_space()
            profile = calibrate_free_space(sim, name, config_free, f"free space ({args.task})")
        else:
            profile = calibrate(
                sim, name, task.workplane_normal, CalibrationConfig(**chosen), setup=args.task,
                free_space_profile=free_profile,
            )  # fmt: skip
    except BaseException as exc:  # write what was measured, then report (Ctrl-C: 130)
        return report_partial(exc, "robot_profile", args.json, "the calibration")
    out = human(args)
    table = Table(
        title=Text(
            f"{name} {'in free space at' if args.free_space else 'holding'} {args.task}: "
            f"{profile.outcome}, {profile.periods} periods "
            f"({profile.robot_time:.1f} s of robot time)"
        )
    )
    for column in ("quantity", "value", "+-", "unit", "samples", "why not measured / from"):
        # the names whole on a narrow terminal: the explanations wrap instead
        width = max(map(len, profile.quantities)) if column == "quantity" else None
        table.add_column(column, justify="left" if column[0] in "qwu" else "right", min_width=width)
    for key, m in profile.quantities.items():
        shown = "-" if m.value is None else f"{m.value:.4g}"
        error = "-" if m.uncertainty is None else f"{m.uncertainty:.2g}"
        table.add_row(key, shown, error, m.unit, str(m.count), m.reason or m.source)
    out.print(table)
    out.print(Text("how each was measured: the profile's 'method' fields"), soft_wrap=True)
    out.print(Text(f"sensor convention: {profile.convention or 'not judged'}"), soft_wrap=True)
    for note in profile.notes:
        out.print(Text(f"note: {note}"), soft_wrap=True)
    if args.out:
        try:
            profile.save(args.out)
        except OSError as exc:
            raise CapError(f"cannot write {args.out}: {exc.strerror or exc}") from exc
        out.print(Text(f"wrote {args.out}"), soft_wrap=True)
    if args.json:
        write_json(profile.to_dict(), args.json)
    assert set(profile.quantities) == set(QUANTITIES)
    wrong = profile.convention in ("flipped_sign", "inconsistent")
    return EXIT_OK if profile.outcome == "complete" and not wrong else EXIT_FAILED


# --- parser -----------------------------------------------------------------------------------
COMMANDS: dict[str, tuple[str, Callable[[argparse.ArgumentParser], None]]] = {
    "bench": ("reproduce the paper's experiments as a report", _bench_parser),
    "run": ("run a controller on a simulated task", _run_parser),
    "lfo": ("skill parameters from a demonstration (and run them)", _lfo_parser),
    "train": ("train the policy with PPO (needs the 'train' extra)", _train_parser),
    "train-grasp": (
        "train the contact-points recognizer on rendered scenes (needs the 'train' extra)",
        _train_grasp_parser,
    ),
    "eval": ("evaluate a policy beside the reference controllers", _eval_parser),
    "view": ("open MuJoCo's interactive viewer on a task", _view_parser),
    "check-sensor": (
        "push the grasped object in known directions: check the wrench sign, frame and "
        "stiffness (exit 0 when the convention holds)",
        _check_sensor_parser,
    ),
    "export-onnx": ("the policy as an ONNX model for C++ controllers", _export_onnx_parser),
    "calibrate": (
        "measure a robot's force noise, stiffness, tracking time constant, grasp play and "
        "sensor convention through the Robot protocol, into a robot profile",
        _calibrate_parser,
    ),
}


def _selected_command(argv: Sequence[str]) -> str | None:
    """The subcommand named on the command line (top-level options take no values)."""
    return next((a for a in argv if not a.startswith("-")), None)


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The `cap` parser; only the subcommand named in `argv` gets its (possibly heavy) flags.

    Generating a subcommand's flags imports its configuration classes (training: torch), so
    `cap --help` and the other subcommands stay fast.
    """
    selected = _selected_command(argv)
    parser = argparse.ArgumentParser(
        prog="cap",
        description="Constraint-aware policy for compliant manipulation (Saito et al.)",
        epilog=EPILOG,
        formatter_class=_Formatter,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (help_text, build) in COMMANDS.items():
        p = sub.add_parser(
            name, help=help_text, description=help_text, epilog=EPILOG, formatter_class=_Formatter
        )
        if name == selected:
            build(p)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser(args_list)
        args = parser.parse_args(args_list)
        func: Callable[[argparse.Namespace], int] = args.func
        return func(args)
    except CapError as exc:
        print_error(str(exc))
        return EXIT_USAGE
    except KeyboardInterrupt:
        print_error("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `cap ... --json - | head`: the reader left; no traceback
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
