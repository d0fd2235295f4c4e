"""Importing the package, or any of its modules, has no side effects on the process."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

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
    dirty = {m: c for m, c in changes.items() if c}
    assert dirty == {}


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


# --- packaging ----------------------------------------------------------------------------------
ROOT = Path(__file__).resolve().parents[1]


def test_version_comes_from_package_metadata() -> None:
    import tomllib
    from importlib.metadata import version

    import constraint_aware

    assert constraint_aware.__version__ == version("constraint-aware")
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert constraint_aware.__version__ == pyproject["project"]["version"]
    assert "__version__ =" not in (ROOT / "pyproject.toml").read_text()


def test_package_is_typed_and_ships_the_marker() -> None:
    import tomllib

    assert (ROOT / "src" / "constraint_aware" / "py.typed").is_file()
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "py.typed" in pyproject["tool"]["setuptools"]["package-data"]["constraint_aware"]


def test_torch_bounded_below_in_metadata_and_pinned_in_constraints() -> None:
    import tomllib

    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    extras = pyproject["project"]["optional-dependencies"]
    torch_reqs = [r for r in extras["train"] if r.startswith("torch")]
    assert torch_reqs and all(">=" in r and "==" not in r for r in torch_reqs)
    pins = [
        line.split("#")[0].strip()
        for line in (ROOT / "constraints.txt").read_text().splitlines()
        if line.split("#")[0].strip()
    ]
    assert "torch==2.13.0" in pins


def test_readme_test_command_is_what_ci_runs() -> None:
    readme = (ROOT / "README.md").read_text()
    block = readme.split("```bash\n", 1)[1].split("```", 1)[0].splitlines()
    assert "cap bench" in block[0]
    readme_test = block[1].split("#")[0].strip()
    ci = [
        line.strip()
        for line in (ROOT / ".ci" / "run").read_text().splitlines()
        if line.strip() and not line.startswith(("#", "set ", "cd "))
    ]
    assert ci == [readme_test]
    assert "-c constraints.txt" in readme_test and "python -m pytest" in readme_test


def _extra(extras: dict[str, list[str]], name: str) -> set[str]:
    """The distributions an extra installs, its references to other extras resolved."""
    out: set[str] = set()
    for req in extras[name]:
        dist = re.split(r"[\[<>=;\s]", req, maxsplit=1)[0]
        if dist == "constraint-aware":
            for inner in req.split("[", 1)[1].split("]", 1)[0].split(","):
                out |= _extra(extras, inner.strip())
        else:
            out.add(dist)
    return out


def test_the_first_command_installs_what_cap_bench_needs() -> None:
    """The README's first command installs the extra every bench section's needs name, and
    that extra installs the Jaco's models (dm-control): `cap bench` then skips nothing."""
    import tomllib

    from constraint_aware.bench.run import BENCH_EXTRA, ROBOT_NEEDS

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    assert {need.extra for need in ROBOT_NEEDS.values()} == {BENCH_EXTRA}
    assert "dm-control" in _extra(extras, BENCH_EXTRA)
    readme = (ROOT / "README.md").read_text()
    first = readme.split("```bash\n", 1)[1].splitlines()[0].split("#")[0].strip()
    assert first == f'pip install -e ".[{BENCH_EXTRA}]" && cap bench'


def test_citation_names_the_paper() -> None:
    text = (ROOT / "CITATION.cff").read_text()
    assert "Constraint-aware Policy for Compliant Manipulation" in text
    assert "Saito" in text and "cff-version" in text


# --- the GL backend: chosen only when rendering, only on headless Linux, only if unset ---------
RENDER = """
import os, sys
import constraint_aware
from constraint_aware.sim.tasks import task_config
from constraint_aware.sim.world import ManipulationSim
assert "MUJOCO_GL" not in os.environ or os.environ["MUJOCO_GL"] == sys.argv[1], "set on import"
before = os.environ.get("MUJOCO_GL")
sim = ManipulationSim(task_config("drawer-opening"))
sim.reset()
from constraint_aware.sim.render import SceneRenderer
try:
    frame = SceneRenderer(sim.model, width=64, height=48).frame(sim.data)
    print("frame", frame.shape, before, os.environ.get("MUJOCO_GL"))
except constraint_aware.CapError as exc:
    print("error", before, os.environ.get("MUJOCO_GL"))
"""


def render_probe(mujoco_gl: str | None) -> list[str]:
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("MUJOCO_GL", "PYOPENGL_PLATFORM", "DISPLAY", "WAYLAND_DISPLAY")
    }
    if mujoco_gl is not None:
        env["MUJOCO_GL"] = mujoco_gl
    out = subprocess.run(
        [sys.executable, "-c", RENDER, mujoco_gl or ""],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    return out.stdout.split()


@pytest.mark.skipif(sys.platform != "linux", reason="the headless EGL choice is Linux-only")
def test_headless_rendering_chooses_egl_only_when_rendering() -> None:
    # MuJoCo was imported (by the simulator) before the renderer: the choice still works
    assert render_probe(None) == ["frame", "(48,", "64,", "3)", "None", "egl"]


@pytest.mark.skipif(sys.platform != "linux", reason="the headless EGL choice is Linux-only")
def test_a_users_mujoco_gl_is_left_alone() -> None:
    words = render_probe("glfw")  # without a display: a clean error, and no second guess
    assert words == ["error", "glfw", "glfw"]


@pytest.mark.parametrize("package", ["constraint_aware.bench", "constraint_aware.lfo"])
def test_lazy_subpackage_exports_resolve_without_importing_mujoco(package: str) -> None:
    code = (
        f"import sys, importlib; m = importlib.import_module({package!r}); "
        "before = 'mujoco' in sys.modules; [getattr(m, n) for n in m.__all__]; "
        "print(before, len(m.__all__))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    before, n = out.stdout.split()
    assert before == "False" and int(n) > 0
