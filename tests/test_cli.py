"""`cap` subcommands: smoke tests (subprocess, tiny budgets) and the CLI's conventions
(arguments refused before any work: `main` in this process, `cap_here`)."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from constraint_aware.cli import build_parser, main


def cap(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def cap_here(capsys: pytest.CaptureFixture[str], *args: str) -> subprocess.CompletedProcess[str]:
    """`cap ARGS` in this process, for arguments refused before any work (no interpreter to
    start): its exit code, stdout and stderr as the console script gives them."""
    capsys.readouterr()
    try:
        code = main(list(args))
    except SystemExit as exc:  # argparse: usage errors and --help
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return subprocess.CompletedProcess(list(args), code, out.out, out.err)


def options_of(*argv: str) -> set[str]:
    parser = build_parser(list(argv))
    sub = next(a for a in parser._actions if a.dest == "command")
    chosen = sub.choices[argv[0]]  # type: ignore[index]
    return {s for a in chosen._actions for s in a.option_strings}


# --- conventions ------------------------------------------------------------------------------
def test_help_lists_subcommands_and_exit_codes() -> None:
    out = cap("--help")
    assert out.returncode == 0
    for name in ("train", "eval", "run", "view", "bench", "lfo"):
        assert name in out.stdout
    assert "exit codes: 0 success; 1" in " ".join(out.stdout.split())


def test_version_from_package_metadata() -> None:
    from importlib.metadata import version

    out = cap("--version")
    assert out.returncode == 0
    assert out.stdout.strip() == f"cap {version('constraint-aware')}"


def test_run_help_shows_defaults_and_choices(capsys: pytest.CaptureFixture[str]) -> None:
    out = cap_here(capsys, "run", "--help")
    assert out.returncode == 0
    text = " ".join(out.stdout.split())
    assert "{policy,policy-raw,fixed,projection,classical}" in text
    assert "drawer-opening,plate-sliding" in text
    assert "(default: 30.0)" in text  # --offset-deg, from RunSpec


def test_train_flags_reach_every_training_and_environment_field() -> None:
    pytest.importorskip("stable_baselines3")
    from constraint_aware.training.config import EnvConfig
    from constraint_aware.training.train_config import TrainConfig

    options = options_of("train")
    for f in dataclasses.fields(TrainConfig):
        if f.name != "env":
            assert "--" + f.name.replace("_", "-") in options, f.name
    for f in dataclasses.fields(EnvConfig):
        assert "--env." + f.name.replace("_", "-") in options, f.name


def test_train_flags_parse_into_the_configs() -> None:
    pytest.importorskip("stable_baselines3")
    from constraint_aware.cli_flags import collect

    args = build_parser(["train"]).parse_args(
        ["train", "--preset", "paper", "--steps", "1000", "--net-arch", "64", "64",
         "--env.friction", "0", "0.2", "--no-env.noise-every-step"]
    )  # fmt: skip
    assert collect(args, args.train_specs) == {"total_timesteps": 1000, "net_arch": (64, 64)}
    assert collect(args, args.env_specs) == {"friction": (0.0, 0.2), "noise_every_step": False}


def test_run_flags_reach_every_run_spec_field() -> None:
    from constraint_aware.control.simulate import RunSpec

    options = options_of("run", "drawer-opening")
    for f in dataclasses.fields(RunSpec):
        if f.name not in ("task", "overrides", "controller_params"):  # positional; --set
            assert "--" + f.name.replace("_", "-") in options, f.name


def test_run_unknown_task_is_a_usage_error_on_stderr(capsys: pytest.CaptureFixture[str]) -> None:
    out = cap_here(capsys, "run", "nosuchtask")
    assert out.returncode == 2
    assert "drawer-opening" in out.stderr and out.stdout == ""


def test_markup_in_user_text_is_printed_verbatim(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = cap_here(capsys, "run", "drawer[/]")
    assert out.returncode == 2 and "drawer[/]" in out.stderr and "Traceback" not in out.stderr
    # a CapError's message
    out = cap_here(capsys, "eval", "--policy", str(tmp_path / "[bold]x[/].npz"))
    assert out.returncode == 2
    assert "[bold]x[/].npz" in out.stderr and "Traceback" not in out.stderr


def test_failed_run_exits_1_and_writes_strict_json(tmp_path: Path) -> None:
    out = cap(
        "run", "drawer-opening", "--controller", "fixed", "--offset", "75",
        "--json", str(tmp_path / "r.json"),
    )  # fmt: skip
    assert out.returncode == 1, out.stderr
    text = (tmp_path / "r.json").read_text()
    data = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard JSON {c}"))
    assert data["summary"]["success"] is False and data["outcome"] == "force_limit"


@pytest.mark.parametrize(
    ("flag", "path", "message"),
    [
        ("--plot", "x.txt", "'.txt'"),
        ("--video", "x.avi", "'.avi'"),
        ("--json", "x.csv", "'.csv'"),
    ],
)
def test_output_suffixes_checked_before_the_run(
    tmp_path: Path, flag: str, path: str, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    out = cap_here(capsys, "run", "drawer-opening", "--json", str(tmp_path / "r.json"), flag, path)
    assert out.returncode == 2 and message in out.stderr
    assert not (tmp_path / "r.json").exists()  # a run would have written its record first
    assert "steps" not in out.stdout


@pytest.mark.parametrize(
    ("module", "flag", "suffix", "extra"),
    [("imageio_ffmpeg", "--video", "mp4", "video"), ("mcap", "--mcap", "mcap", "mcap")],
)
def test_output_without_its_extra_fails_at_once(
    tmp_path: Path, module: str, flag: str, suffix: str, extra: str
) -> None:
    code = (
        f"import sys; sys.modules[{module!r}] = None; "
        "from constraint_aware.cli import main; "
        f"sys.exit(main(['run', 'drawer-opening', '--json', {str(tmp_path / 'r.json')!r}, "
        f"{flag!r}, {str(tmp_path / ('out.' + suffix))!r}]))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 2
    assert f"'{extra}' extra" in out.stderr
    assert not (tmp_path / "r.json").exists()


def test_json_to_stdout_keeps_human_lines_on_stderr() -> None:
    out = cap("run", "drawer-opening", "--offset", "-30", "--json", "-")
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout)["summary"]["success"] is True
    assert "success" in out.stderr


def test_write_error_after_the_result_is_clean() -> None:
    out = cap("run", "drawer-opening", "--offset", "-30", "--json", "/proc/no-such-dir/r.json")
    assert out.returncode == 2
    assert "cannot write" in out.stderr and "Traceback" not in out.stderr
    assert "success" in out.stdout  # the result itself was reported


class _Boom(RuntimeError):
    pass


@pytest.mark.parametrize(("exc_type", "code"), [(KeyboardInterrupt, 130), (_Boom, 1)])
def test_run_writes_the_attached_record_on_exceptions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, exc_type: type[BaseException], code: int
) -> None:
    """The executor attaches the record as exc.run_record; the CLI writes it and exits."""
    import constraint_aware.control.simulate as simulate
    from constraint_aware.control.record import RunRecord

    partial = RunRecord({"task": "drawer-opening"}, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    partial.outcome, partial.reason = "error", "interrupted"

    def raising_run(*_a: object, **_k: object) -> None:
        exc = exc_type("stop")
        exc.run_record = partial  # type: ignore[attr-defined]
        raise exc

    monkeypatch.setattr(simulate, "run", raising_run)
    rc = main(
        ["run", "drawer-opening", "--controller", "fixed", "--json", str(tmp_path / "a.json")]
    )
    assert rc == code
    data = json.loads((tmp_path / "a.json").read_text())
    assert data["outcome"] == "error" and data["summary"]["progress"] is None  # NaN -> null


# --- subcommand smoke tests -------------------------------------------------------------------
def test_eval_writes_json(tmp_path: Path) -> None:
    out = cap("eval", "--episodes", "500", "--json", str(tmp_path / "e.json"))
    assert out.returncode == 0, out.stderr
    data = json.loads((tmp_path / "e.json").read_text())
    assert set(data) == {"training_environment", "standard_evaluation", "card_standard_evaluation"}
    for where in ("training_environment", "standard_evaluation"):
        assert set(data[where]) == {"noop", "projection", "mu_agnostic", "oracle", "policy"}
        assert data[where]["policy"]["episodes"] == 500


def test_eval_missing_policy_is_a_clear_error(tmp_path: Path) -> None:
    out = cap("eval", "--policy", str(tmp_path / "missing.npz"))
    assert out.returncode == 2
    assert "not found" in out.stderr


def test_eval_policy_flag_evaluates_that_policy(tmp_path: Path) -> None:
    from constraint_aware.cli import strict
    from constraint_aware.policy import ConstraintAwarePolicy
    from constraint_aware.training.config import EnvConfig
    from constraint_aware.training.evaluate import evaluate

    out = cap("eval", "--policy", "paper", "--episodes", "300", "--json", str(tmp_path / "e.json"))
    assert out.returncode == 0, out.stderr
    paper = ConstraintAwarePolicy.load("paper")
    config = EnvConfig.from_dict(paper.card.get("env_config", {}))
    expected = evaluate(lambda obs, _f: paper.act_batch(obs), config, episodes=300, seed=12345)
    data = json.loads((tmp_path / "e.json").read_text())
    assert data["training_environment"]["policy"] == strict(expected.to_dict())
    # the paper's policy was trained in the standard environment: one evaluation is both
    assert data["standard_evaluation"] == data["training_environment"]
    out = cap("eval", "--policy", "nope")
    assert out.returncode == 2 and "valid names: default, paper" in out.stderr


def test_run_policy_flag_drives_the_run_with_that_policy(tmp_path: Path) -> None:
    for name in ("paper", "default"):
        out = cap("run", "drawer-opening", "--policy", name, "--json", str(tmp_path / "r.json"))
        assert out.returncode in (0, 1), out.stderr
        assert json.loads((tmp_path / "r.json").read_text())["label"]["policy"] == name
    out = cap("run", "drawer-opening", "--policy", str(tmp_path / "none.npz"))
    assert out.returncode == 2 and "not found" in out.stderr


@pytest.mark.slow
def test_train_tiny_budget(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    out = cap(
        "train", "--steps", "1000", "--n-envs", "200", "--batch-size", "500",
        "--out", str(tmp_path / "run"), "--quiet", "--torch-threads", "1",
        "--eval-episodes", "300", "--final-episodes", "300", "--env.friction", "0", "0.1",
        "--json", str(tmp_path / "t.json"),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    for name in ("policy.npz", "policy.json", "training_log.csv", "learning_curve.png"):
        assert (tmp_path / "run" / name).is_file()
    assert (tmp_path / "run" / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    result = json.loads((tmp_path / "t.json").read_text())
    assert result["config"]["env"]["friction"] == [0.0, 0.1]


def test_train_unknown_preset() -> None:
    pytest.importorskip("stable_baselines3")
    out = cap("train", "--preset", "nope", "--quiet")
    assert out.returncode == 2
    assert "'fast', 'paper'" in out.stderr


def test_train_refuses_bad_arguments_without_importing_torch() -> None:
    """`cap train`'s flags come from the torch-free training.train_config: a bad preset or
    environment range is refused before torch is imported (seconds), and without the extra
    installed any arguments say which extra to install."""
    for argv, said in (
        ("'--preset', 'nope'", "'fast', 'paper'"),
        ("'--env.friction', '0.3', '0.1'", "friction"),
    ):
        probe = (
            "import sys\n"
            "from constraint_aware.cli import main\n"
            f"code = main(['train', {argv}, '--quiet'])\n"
            "assert 'torch' not in sys.modules, 'torch imported'\n"
            "sys.exit(code)\n"
        )
        out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
        assert out.returncode == 2 and said in out.stderr, out.stderr
    blocked = (
        "import sys\n"
        "sys.modules['torch'] = None\n"
        "sys.modules['stable_baselines3'] = None\n"
        "from constraint_aware.cli import main\n"
        "sys.exit(main(['train', '--steps', '10']))\n"
    )
    out = subprocess.run([sys.executable, "-c", blocked], capture_output=True, text=True)
    assert out.returncode == 2
    assert "pip install 'constraint-aware[train]'" in out.stderr, out.stderr


def test_train_invalid_environment_range_names_the_field() -> None:
    pytest.importorskip("stable_baselines3")
    out = cap("train", "--env.friction", "0.3", "0.1", "--quiet")
    assert out.returncode == 2
    assert "friction" in out.stderr


def test_run_writes_json_plot_and_video(tmp_path: Path) -> None:
    out = cap(
        "run", "drawer-opening", "--offset", "-30", "--json", str(tmp_path / "r.json"),
        "--plot", str(tmp_path / "r.png"), "--video", str(tmp_path / "r.gif"),
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "success" in out.stdout and "\n" not in out.stdout.strip()  # one line
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["summary"]["success"] is True
    assert (tmp_path / "r.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "r.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")


def test_run_mp4_through_the_video_extra(tmp_path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg")
    out = cap("run", "handle-rotating", "--video", str(tmp_path / "r.mp4"))
    assert out.returncode in (0, 1), out.stderr  # the video is written either way
    assert (tmp_path / "r.mp4").read_bytes()[4:8] == b"ftyp"


def test_run_unknown_controller_lists_valid_names(capsys: pytest.CaptureFixture[str]) -> None:
    out = cap_here(capsys, "run", "drawer-opening", "--controller", "pid")
    assert out.returncode == 2
    assert "projection" in out.stderr


def test_lfo_json_is_a_path(tmp_path: Path) -> None:
    demo = Path(__file__).resolve().parents[1] / "examples" / "door_demo.json"
    out = cap("lfo", str(demo), "--json", str(tmp_path / "s.json"))
    assert out.returncode == 0, out.stderr
    assert json.loads((tmp_path / "s.json").read_text())["skill"]["constraint_type"] == "revolute"
    out = cap("lfo", str(demo), "--json", "-")
    assert json.loads(out.stdout)["skill"]["constraint_type"] == "revolute"


def test_lfo_prints_every_note_of_its_json(tmp_path: Path) -> None:
    """The assumptions and disagreements are in the human-readable output, not only in --json."""
    demo = Path(__file__).resolve().parents[1] / "examples" / "drawer_path.csv"
    out = cap(
        "lfo", str(demo), "--execute", "--start", "at-grasp", "--json", str(tmp_path / "s.json")
    )
    assert out.returncode == 0, out.stderr
    data = json.loads((tmp_path / "s.json").read_text())
    notes = data["skill"]["warnings"] + data["execution"]["notes"]
    assert data["execution"]["notes"]  # a csv has no words: the object kind is assumed
    printed = [line.removeprefix("note: ") for line in out.stdout.splitlines()]
    assert [n for n in notes if n not in printed] == []


def test_export_onnx_matches_the_numpy_policy(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    out = cap("export-onnx", str(tmp_path / "p.onnx"), "--json", str(tmp_path / "e.json"))
    assert out.returncode == 0, out.stderr
    result = json.loads((tmp_path / "e.json").read_text())
    assert result["parity"]["n_observations"] == 10_000
    assert result["parity"]["max_abs_error"] <= 1e-5
    assert result["metadata"]["observation_layout"]
    assert (tmp_path / "p.onnx").stat().st_size > 1000


def test_export_onnx_checks_its_output_and_policy(tmp_path: Path) -> None:
    out = cap("export-onnx", str(tmp_path / "p.txt"))
    assert out.returncode == 2 and "'.txt'" in out.stderr
    out = cap("export-onnx", "--policy", str(tmp_path / "none.npz"), str(tmp_path / "p.onnx"))
    assert out.returncode == 2 and "not found" in out.stderr


def test_run_mcap_is_the_record(tmp_path: Path) -> None:
    pytest.importorskip("mcap")
    from constraint_aware.control.mcap_export import read_mcap

    out = cap(
        "run", "drawer-opening", "--controller", "fixed", "--offset", "75",
        "--mcap", str(tmp_path / "r.mcap"), "--json", str(tmp_path / "r.json"),
    )  # fmt: skip
    assert out.returncode == 1, out.stderr  # written for a failed run too
    record = read_mcap(tmp_path / "r.mcap")
    assert record.outcome == "force_limit"
    assert len(record.steps) == len(json.loads((tmp_path / "r.json").read_text())["steps"])


def test_bench_force_flag_reaches_run_bench(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    import constraint_aware.bench.run as bench_run

    seen: dict[str, object] = {}

    def fake_run_bench(out: str, **kwargs: object) -> Path:
        seen.update(kwargs)
        (Path(out) / "results.json").parent.mkdir(parents=True, exist_ok=True)
        (Path(out) / "results.json").write_text('{"x": NaN}')
        return Path(out) / "report.md"

    monkeypatch.setattr(bench_run, "run_bench", fake_run_bench)
    rc = main(["bench", "--out", str(tmp_path), "--force", "--json", str(tmp_path / "b.json")])
    assert rc == 0 and seen["force"] is True
    assert json.loads((tmp_path / "b.json").read_text()) == {"x": None}  # strict JSON


def test_run_set_reaches_task_and_executor_fields(tmp_path: Path) -> None:
    out = cap(
        "run", "drawer-opening", "--set", "force_limit=5", "--set", "executor.limits.max_steps=3",
        "--json", str(tmp_path / "r.json"),
    )  # fmt: skip
    assert out.returncode == 1, out.stderr  # a 5 N limit stops the run
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["outcome"] == "force_limit" and data["label"]["force_limit_N"] == 5
    out = cap("run", "drawer-opening", "--set", "object.nosuch=1")
    assert out.returncode == 2 and "object.mass" in out.stderr  # lists the valid keys
    out = cap("run", "drawer-opening", "--set", "executor.limits.max_steps=2", "--offset", "0")
    assert out.returncode == 1 and "timeout" in out.stdout


def test_bench_scheduler_reaches_run_bench(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    import constraint_aware.bench.run as bench_run

    seen: dict[str, object] = {}

    def fake_run_bench(out: str, **kwargs: object) -> Path:
        seen.update(kwargs)
        return Path(out) / "report.md"

    monkeypatch.setattr(bench_run, "run_bench", fake_run_bench)
    assert main(["bench", "--out", str(tmp_path), "--scheduler", "local", "--workers", "2"]) == 0
    assert seen["scheduler"] == "local" and seen["workers"] == 2


def test_view_without_display_is_a_clear_error() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "view", "door-opening"],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2
    assert "display" in out.stderr


# --- cap check-sensor -------------------------------------------------------------------------
def test_check_sensor_exit_codes_and_json(tmp_path: Path) -> None:
    assert main(["check-sensor", "drawer-opening"]) == 0
    out = tmp_path / "probe.json"
    assert (
        main(["check-sensor", "drawer-opening", "--fault", "flipped_sign", "--json", str(out)]) == 1
    )
    data = json.loads(out.read_text())
    assert data["verdict"] == "flipped_sign" and data["meaning"]
    assert len(data["pushes"]) == 8
    assert main(["check-sensor", "drawer-opening", "--amplitude", "0.5"]) == 2  # named range
    assert main(["check-sensor", "drawer-opening", "--plot", str(tmp_path / "p.txt")]) == 2
    assert main(["check-sensor", "drawer-opening", "--plot", str(tmp_path / "p.png")]) == 0
    assert (tmp_path / "p.png").stat().st_size > 10_000
    with pytest.raises(SystemExit) as refused:  # timed by executor moves: not a probe fault
        main(["check-sensor", "drawer-opening", "--fault", "nan_wrench"])
    assert refused.value.code == 2
    assert "--probe" in options_of("run")
