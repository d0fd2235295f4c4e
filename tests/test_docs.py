"""The documentation: the site builds strictly, the README's examples run as written, and the
product carries no work-history marks."""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
README_MAX_LINES = 300

#: Marks of how the work was organized, which mean nothing to a reader who was not there:
#: "stop 27", "STOP28", "stop-16", "issue 9", "issue #12", "session 3", "this session". A word
#: before the mark ("nonstop 3") or no number ("policy.session()", "stops 3 mm short" aside)
#: is not one.
HISTORY = re.compile(
    r"(?<![a-z])(?:stop|issue|session)[\s_-]*#?\d+"
    r"|\b(?:earlier|previous|this|last|next) session\b",
    re.IGNORECASE,
)
#: Text files of the product: what a user reads or loads.
TEXT_SUFFIXES = {".py", ".json", ".md", ".txt", ".cff", ".yml", ".yaml", ".toml", ".csv"}
#: The product's files and folders, relative to the repository (CHANGELOG.md is versions, not
#: work units, and is held to the same rule).
PRODUCT = ("src", "docs", "examples", "README.md", "CHANGELOG.md", "CITATION.cff", "mkdocs.yml")


def history_marks(text: str) -> list[str]:
    """The work-history marks in `text`, in order (whitespace inside a mark collapsed)."""
    return [" ".join(m.group(0).split()) for m in HISTORY.finditer(text)]


def product_files() -> list[Path]:
    files: list[Path] = []
    for name in PRODUCT:
        path = ROOT / name
        if path.is_file():
            files.append(path)
        elif path.is_dir():
            files.extend(
                p
                for p in sorted(path.rglob("*"))
                if p.is_file() and p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts
            )
    return files


@pytest.mark.parametrize(
    ("text", "marks"),
    [
        ("measured at stop 27, adopted", ["stop 27"]),
        ("STOP28 has one home", ["STOP28"]),
        ("the stop-16 default", ["stop-16"]),
        ("the drawer (stop\n    23) moved", ["stop 23"]),
        ("issue 9's study; issue #12", ["issue 9", "issue #12"]),
        ("as in session 3, and in an earlier session", ["session 3", "earlier session"]),
        ("measured this session", ["this session"]),
        ("updater = policy.session()  # one per run", []),
        ("stops after 3 moves; stop_reason; nonstop 5; issues: none", []),
        ("`sessions` of 20 runs, a stopped arm", []),
    ],
)
def test_the_history_pattern_finds_marks_and_leaves_words(text: str, marks: list[str]) -> None:
    assert history_marks(text) == marks


def test_no_work_history_marks_in_the_product() -> None:
    files = product_files()
    assert any(p.name == "default.json" for p in files)  # the shipped cards are scanned
    found = {}
    for path in files:
        marks = history_marks(path.read_text(encoding="utf-8", errors="replace"))
        if marks:
            found[str(path.relative_to(ROOT))] = marks
    listing = "\n".join(
        f"{name}: {len(marks)} ({', '.join(sorted(set(marks))[:6])})"
        for name, marks in sorted(found.items())
    )
    assert not found, f"work-history marks (write what the code does and why):\n{listing}"


def test_the_docs_pages_the_product_names_exist() -> None:
    """A docstring, a card or a page that sends the reader to docs/NAME.md names a page that
    is there."""
    named = {
        (str(path.relative_to(ROOT)), ref)
        for path in product_files()
        for ref in re.findall(r"\bdocs/[\w/.-]+?\.md\b", path.read_text(encoding="utf-8"))
    }
    assert named
    missing = sorted(f"{where}: {ref}" for where, ref in named if not (ROOT / ref).is_file())
    assert not missing, "pages named but missing:\n" + "\n".join(missing)


# --- the site --------------------------------------------------------------------------------


def test_the_site_builds_strictly(tmp_path: Path) -> None:
    """A broken link, a missing anchor or a module the API reference names fails the build."""
    for module in ("mkdocs", "material", "mkdocstrings"):
        pytest.importorskip(module, reason="the docs extra is not installed")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    config, site = str(ROOT / "mkdocs.yml"), str(tmp_path / "site")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--quiet", "-f", config, "-d", site],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    api = (tmp_path / "site" / "api" / "control" / "index.html").read_text(encoding="utf-8")
    assert 'id="constraint_aware.control.executor.Executor"' in api  # rendered, not empty


# --- the README --------------------------------------------------------------------------------


def python_blocks(markdown: str) -> dict[str, list[str]]:
    """The ```python blocks of a Markdown text by the `## ` section they are in."""
    blocks: dict[str, list[str]] = {}
    section = ""
    lines = iter(markdown.splitlines())
    for line in lines:
        if line.startswith("## "):
            section = line[3:].strip()
        elif line.strip() == "```python":
            code = []
            for inner in lines:
                if inner.strip() == "```":
                    break
                code.append(inner)
            blocks.setdefault(section, []).append("\n".join(code) + "\n")
    return blocks


def test_the_readme_is_short_and_its_links_resolve() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= README_MAX_LINES
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert local, "the README links the docs"
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_the_readme_starts_with_the_two_commands() -> None:
    text = README.read_text(encoding="utf-8")
    first_code = text[text.index("```bash") :].split("```")[1]
    assert 'pip install -e ".[bench]" && cap bench' in first_code
    assert 'pip install -c constraints.txt -e ".[train,dev]" && python -m pytest' in first_code


def _run(code: str, namespace: dict[str, Any]) -> dict[str, Any]:
    exec(compile(code, str(README), "exec"), namespace)
    return namespace


def test_the_readmes_policy_example_runs() -> None:
    (code,) = python_blocks(README.read_text(encoding="utf-8"))["The policy in five lines"]
    d0 = np.array([1.0, 0.0, 0.0])
    # 3 N against d and 1 N across it: well above the dead band, so d turns
    ns = _run(
        code, {"force": np.array([-3.0, 1.0, 0.0]), "d": d0, "f_grasp": np.zeros(3)} | {"k": 2000.0}
    )
    d = ns["d"]
    assert d.shape == (3,)
    assert np.linalg.norm(d) == pytest.approx(1.0)
    assert math.degrees(math.acos(float(np.clip(d @ d0, -1, 1)))) > 0.5


def test_the_readmes_robot_example_runs_on_a_simulated_drawer() -> None:
    """The README's executor example, verbatim, opens the simulated drawer (which moves in the
    plane the example names) from a 30 deg error; the docs page shows the same code."""
    from constraint_aware.control.simulate import RunSpec, grasped
    from constraint_aware.geometry import rotate_about

    (code,) = python_blocks(README.read_text(encoding="utf-8"))["Your own robot"]
    assert code in (ROOT / "docs" / "robot.md").read_text(encoding="utf-8")
    task, robot = grasped(RunSpec(task="drawer-opening"))
    assert task.workplane_normal == (0.0, 1.0, 0.0)
    d0 = rotate_about(
        robot.admissible_direction(), np.asarray(task.workplane_normal), math.radians(30)
    )
    ns = _run(code, {"robot": robot, "d0": d0})
    assert ns["record"].outcome == "success", ns["record"].reason


def test_the_readmes_gymnasium_example_runs() -> None:
    (code,) = python_blocks(README.read_text(encoding="utf-8"))["Gymnasium"]
    ns = _run(code, {})
    assert ns["obs"]["wrench"].shape == (6,)
    assert ns["info"]["outcome"] in ("running", "success")


def test_every_python_block_in_the_docs_compiles() -> None:
    pages = [README, *sorted((ROOT / "docs").rglob("*.md"))]
    blocks = [
        (page, code)
        for page in pages
        for codes in python_blocks(page.read_text(encoding="utf-8")).values()
        for code in codes
    ]
    assert len(blocks) >= 5
    for page, code in blocks:
        compile(code, str(page), "exec")


def test_no_merge_conflict_markers_are_left_in_the_repository() -> None:
    suffixes = {".py", ".md", ".toml", ".yml", ".yaml", ".json", ".txt", ".cfg"}
    found = []
    for path in sorted(ROOT.rglob("*")):
        parts = path.relative_to(ROOT).parts
        if path.suffix not in suffixes or not path.is_file():
            continue
        if parts[0].startswith(".") or parts[0] in {"build", "site", "bench-out"}:
            continue
        if any(p in {"node_modules", "__pycache__"} or p.endswith(".egg-info") for p in parts):
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if line.startswith(("<<<<<<< ", ">>>>>>> ")) or line == "=======":
                found.append(f"{path.relative_to(ROOT)}:{number}")
    assert not found, f"merge conflict markers: {found}"
