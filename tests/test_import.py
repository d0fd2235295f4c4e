"""Importing the package, or any of its modules, has no side effects on the process."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

# Modules that other work still has to fix; each one is checked below as a strict xfail, so the
# test fails (and this entry must go) as soon as the module is clean.
KNOWN_OFFENDERS = {
    "constraint_aware.bench.figures": "calls matplotlib.use('Agg') at import (bench owns it)",
}

PROBE = r"""
import json, os, pkgutil, sys
import matplotlib
matplotlib.use("svg")  # the user's explicit choice, which no import may change
import gymnasium  # its own import sets PYGAME_HIDE_SUPPORT_PROMPT (see the test below)
import constraint_aware
names = ["constraint_aware"] + sorted(
    m.name for m in pkgutil.walk_packages(constraint_aware.__path__, "constraint_aware.")
)
wanted = set(sys.argv[1:])
changes = {}
for name in names:
    if wanted and name not in wanted:
        continue
    env = dict(os.environ)
    backend = matplotlib.get_backend()
    __import__(name)
    diff = sorted(k for k in set(env) | set(os.environ) if env.get(k) != os.environ.get(k))
    found = [f"env {k}" for k in diff]
    if matplotlib.get_backend() != backend:
        found.append(f"backend {backend} -> {matplotlib.get_backend()}")
    changes[name] = found
print(json.dumps({"modules": names, "changes": changes}))
"""


def probe(*modules: str) -> dict[str, list[str]]:
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM")}
    out = subprocess.run(
        [sys.executable, "-c", PROBE, *modules],
        capture_output=True, text=True, env=env, timeout=300, check=True,
    )  # fmt: skip
    changes: dict[str, list[str]] = json.loads(out.stdout.splitlines()[-1])["changes"]
    return changes


def test_importing_every_module_leaves_environment_and_backend_alone() -> None:
    changes = probe()
    assert "constraint_aware.sim.render" in changes  # the walk reached the subpackages
    assert len(changes) > 30
    dirty = {m: c for m, c in changes.items() if c and m not in KNOWN_OFFENDERS}
    assert dirty == {}


@pytest.mark.parametrize("module", sorted(KNOWN_OFFENDERS))
@pytest.mark.xfail(strict=True, reason="known offender, see KNOWN_OFFENDERS")
def test_known_offender_is_clean(module: str) -> None:
    assert probe(module)[module] == []


def test_import_package_sets_only_gymnasiums_own_variable() -> None:
    # Registering the environments needs gymnasium, whose own import sets exactly one variable
    # (to silence pygame); the package itself sets none.
    code = (
        "import os, json; before = dict(os.environ); import constraint_aware; "
        "print(json.dumps(sorted(k for k in set(before) | set(os.environ) "
        "if before.get(k) != os.environ.get(k))))"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYGAME_HIDE_SUPPORT_PROMPT"}
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    changed = json.loads(out.stdout)
    assert set(changed) <= {"PYGAME_HIDE_SUPPORT_PROMPT"}
    assert "MUJOCO_GL" not in changed


def test_import_does_not_import_heavy_modules() -> None:
    code = (
        "import sys, constraint_aware; "
        "print(sorted(m for m in ('mujoco', 'torch', 'matplotlib', 'stable_baselines3') "
        "if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
