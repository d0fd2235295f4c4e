"""The import structure: import-linter's contracts (pyproject.toml) and no module-level cycles."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from grimp import ImportGraph

grimp = pytest.importorskip("grimp")  # installed with import-linter (the dev extra)

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
CONTRACTS = [
    c["id"]
    for c in tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"][
        "contracts"
    ]
]


def _graph() -> ImportGraph:
    return grimp.build_graph("constraint_aware", include_external_packages=True, cache_dir=None)


def test_every_contract_has_a_test() -> None:
    assert set(CONTRACTS) == {"layers", "executor-without-mujoco", "acyclic"}


@pytest.mark.skipif(shutil.which("lint-imports") is None, reason="import-linter not installed")
@pytest.mark.parametrize("contract", CONTRACTS)
def test_import_contract_is_kept(contract: str) -> None:
    # the source tree under test first on the path (the package may be installed from elsewhere)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(SRC), *sys.path])}
    out = subprocess.run(
        ["lint-imports", "--no-cache", "--contract", contract],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 0, out.stdout + out.stderr


def test_the_executor_contract_can_see_mujoco() -> None:
    # the forbidden contract is not vacuous: the graph holds mujoco, and the simulated runs
    # (which must import it) reach it
    graph = _graph()
    assert "mujoco" in graph.modules
    assert graph.chain_exists("constraint_aware.control.simulate", "mujoco")


def _cycles(graph: ImportGraph) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    modules = sorted(m for m in graph.modules if m.startswith("constraint_aware"))
    edges = {
        m: sorted(t for t in graph.find_modules_directly_imported_by(m) if t in modules)
        for m in modules
    }
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for start in modules:
        if start in index:
            continue
        work = [(start, 0)]
        while work:
            node, i = work.pop()
            if i == 0:
                index[node] = low[node] = len(index)
                stack.append(node)
                on_stack.add(node)
            if i < len(edges[node]):
                work.append((node, i + 1))
                nxt = edges[node][i]
                if nxt not in index:
                    work.append((nxt, 0))
                elif nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
                continue
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_cycle_finder_finds_an_injected_cycle() -> None:
    graph = _graph()
    graph.add_import(importer="constraint_aware.errors", imported="constraint_aware.geometry")
    assert ["constraint_aware.errors", "constraint_aware.geometry"] in _cycles(graph)


def test_no_module_imports_itself_through_others() -> None:
    # acyclic_siblings compares siblings; this also catches a cycle through a package's
    # __init__ (e.g. a module importing the root package that imports it back)
    assert _cycles(_graph()) == []
