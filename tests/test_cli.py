"""Tiny-budget subprocess smoke tests of every `cap` command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def cap(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_help_lists_subcommands() -> None:
    out = cap("--help")
    assert out.returncode == 0
    for name in ("train", "eval", "run", "view"):
        assert name in out.stdout


def test_eval_writes_json(tmp_path: Path) -> None:
    out = cap("eval", "--episodes", "500", "--json", str(tmp_path / "e.json"))
    assert out.returncode == 0, out.stderr
    data = json.loads((tmp_path / "e.json").read_text())
    assert set(data) == {"noop", "projection", "mu_agnostic", "oracle", "policy"}
    assert data["policy"]["episodes"] == 500


def test_eval_missing_policy_is_a_clear_error(tmp_path: Path) -> None:
    out = cap("eval", "--policy", str(tmp_path / "missing.npz"))
    assert out.returncode == 2
    assert "not found" in out.stdout


@pytest.mark.slow
def test_train_tiny_budget(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3")
    out = cap(
        "train", "--steps", "12000", "--out", str(tmp_path / "run"), "--quiet",
        "--eval-episodes", "300", "--final-episodes", "300",
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    for name in ("policy.npz", "policy.json", "training_log.csv", "learning_curve.png"):
        assert (tmp_path / "run" / name).is_file()
    assert (tmp_path / "run" / "learning_curve.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_train_unknown_preset() -> None:
    pytest.importorskip("stable_baselines3")
    out = cap("train", "--preset", "nope", "--quiet")
    assert out.returncode == 2
    assert "fast, paper" in out.stdout


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


def test_run_unknown_task_lists_valid_names() -> None:
    out = cap("run", "fridge")
    assert out.returncode == 2
    assert "drawer-opening" in out.stdout


def test_run_unknown_controller_lists_valid_names() -> None:
    out = cap("run", "drawer-opening", "--controller", "pid")
    assert out.returncode == 2
    assert "projection" in out.stdout


def test_view_without_display_is_a_clear_error() -> None:
    import os

    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    out = subprocess.run(
        [sys.executable, "-m", "constraint_aware.cli", "view", "door-opening"],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2
    assert "display" in out.stdout
