"""`cap bench`: run the experiments, write results.json, draw the figures, write the report.

Before anything runs, `preflight` checks what each section needs beyond the core install (the
Jaco's models for the embodiment section): a section that cannot run is skipped, said on
stderr at the start and in the report, instead of failing at the end of a long run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import math
import multiprocessing
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.bench import endtoend, placement
from constraint_aware.bench import experiments as ex
from constraint_aware.bench.ablation import ablation_section
from constraint_aware.bench.analysis import policy_section
from constraint_aware.bench.embodiment import ROBOTS as EMBODIMENT_ROBOTS
from constraint_aware.bench.embodiment import for_bench as embodiment_for_bench
from constraint_aware.bench.faults import FAULTS, QUICK_FAULTS, fault_suite
from constraint_aware.bench.figures import draw_all
from constraint_aware.bench.provenance import write_results
from constraint_aware.bench.report import write_report
from constraint_aware.bench.sweep import (
    SUITE_OFFSET_RANGE,
    InProcessExecutor,
    available_cpus,
    dask_executor,
    local_pool,
    reuse_runs,
    use_executor,
)
from constraint_aware.errors import CapError
from constraint_aware.policy import ConstraintAwarePolicy, is_shipped
from constraint_aware.sim.embodiment import DEFAULT_ROBOT, parse_robot
from constraint_aware.sim.tasks import TASKS, task_config

RESULTS = "results.json"
#: `cap bench --quick` injects the reduced fault set on these tasks (the full bench: all).
FAULT_BENCH_TASKS_QUICK = ("drawer-opening", "door-opening")
#: The extra that installs everything a complete bench needs (pyproject.toml).
BENCH_EXTRA = "bench"
#: The bench's sections in run order (results.json keys) and their report titles.
SECTIONS: dict[str, str] = {
    "learning": "training",
    "paper": "the paper's experiments",
    "headline": "the randomized suite",
    "embodiment": "embodiments",
    "placement": "placement",
    "end_to_end": "end-to-end",
    "heatmap": "the offset map",
    "sensitivity": "sensitivity",
    "policy_section": "policies",
    "faults": "fault injection",
}


@dataclass(frozen=True)
class Need:
    """Something a section needs beyond the core install, and the extra that installs it."""

    what: str  # what is needed, in words ("dm-control's Kinova Jaco models")
    extra: str  # the optional-dependencies extra of pyproject.toml that installs it
    available: Callable[[], bool]  # whether it is installed here (cheap: no model is built)
    how: str = ""  # how to get it when no extra installs it (a system library)

    def install(self) -> str:
        """The command that installs it, as one phrase."""
        if self.how:
            return self.how
        return (
            f"pip install 'constraint-aware[{self.extra}]' "
            f"(in a source checkout: pip install -e '.[{self.extra}]')"
        )


def _jaco_models_installed() -> bool:
    from constraint_aware.sim.jaco import jaco_model_dir

    try:
        jaco_model_dir()
    except CapError:
        return False
    return True


#: What an embodiment needs beyond the core install (one not listed needs nothing more).
ROBOT_NEEDS: dict[str, Need] = {
    "jaco": Need("dm-control's Kinova Jaco models", BENCH_EXTRA, _jaco_models_installed),
}


def _depth_rendering() -> bool:
    from constraint_aware.sim.camera import depth_rendering_available

    return depth_rendering_available()


#: The end-to-end section's head camera renders depth images offscreen.
DEPTH_RENDERING = Need(
    "offscreen OpenGL rendering for the depth camera",
    "",
    _depth_rendering,
    how="install EGL (libegl1) or OSMesa, or run with a display; MUJOCO_GL selects the backend",
)


def _mink_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("mink") is not None


#: The end-to-end section's Jaco plans its paths with mink.
JACO_PATHS = Need("mink, for the Jaco's paths", BENCH_EXTRA, _mink_installed)


def _end_to_end_needs(quick: bool) -> tuple[Need, ...]:
    robots = endtoend.BENCH_ROBOTS[quick]
    paths = (JACO_PATHS,) if "jaco" in robots else ()
    return (DEPTH_RENDERING, *_robot_needs(*robots), *paths)


def _robot_needs(*robots: str) -> tuple[Need, ...]:
    names = dict.fromkeys(parse_robot(r).name for r in robots)
    return tuple(ROBOT_NEEDS[n] for n in names if n in ROBOT_NEEDS)


def section_needs(cfg: ex.BenchConfig) -> dict[str, tuple[Need, ...]]:
    """What each section of a bench with `cfg` needs beyond the core install (in run order;
    the offset map and the sensitivity only in a full bench)."""
    on_robot = _robot_needs(cfg.robot)
    needs: dict[str, tuple[Need, ...]] = {
        "learning": (),
        "paper": on_robot,
        "headline": on_robot,
        "embodiment": _robot_needs(*EMBODIMENT_ROBOTS),
        "placement": (),
        "end_to_end": _end_to_end_needs(cfg.quick),
        "heatmap": on_robot,
        "sensitivity": on_robot,
        "policy_section": (),
        "faults": (),
    }
    if cfg.quick:
        del needs["heatmap"], needs["sensitivity"]
    return needs


def preflight(cfg: ex.BenchConfig) -> dict[str, str]:
    """The sections that cannot run here, each with one line saying what to install.

    The robot of the paper's experiments (`cfg.robot`) was asked for explicitly: when it cannot
    run, CapError (before any run), since nothing of the paper's experiments would be left.
    """
    for need in _robot_needs(cfg.robot):
        if not need.available():
            raise CapError(f"--robot {cfg.robot}: needs {need.what}: {need.install()}")
    skipped: dict[str, str] = {}
    for section, needs in section_needs(cfg).items():
        missing = [n for n in needs if not n.available()]
        if missing:
            skipped[section] = (
                f"the {SECTIONS[section]} section needs "
                + ", ".join(n.what for n in missing)
                + ": "
                + "; ".join(dict.fromkeys(n.install() for n in missing))
            )
    return skipped


def _to_stderr(line: str) -> None:
    print(f"cap bench: skipping: {line}", file=sys.stderr, flush=True)


def _summaries_with_units(paper: dict[str, Any]) -> dict[str, Any]:
    for s in paper.values():
        s["progress_deg"] = math.degrees(s["progress"])
        s["progress_cm"] = 100.0 * s["progress"]
    return paper


def _full_success_halfwidth(heatmap: dict[str, Any]) -> dict[str, dict[str, float | None]]:
    offsets = np.array(heatmap["offsets_deg"])
    out: dict[str, dict[str, float | None]] = {}
    for task, row in heatmap["success_rate"].items():
        for ctrl, rates in row.items():
            best = None
            for w in sorted(set(np.abs(offsets))):
                inside = np.abs(offsets) <= w
                if np.all(np.array(rates)[inside] == 1.0):
                    best = float(w)
                else:
                    break
            out.setdefault(task, {})[ctrl] = best
    return out


def _first_failures(sens: dict[str, Any]) -> None:
    for entry in sens.values():
        first: dict[str, float | None] = {}
        where: dict[str, str | None] = {}
        for ctrl in ex.CONTROLLERS:
            first[ctrl], where[ctrl] = None, None
            for i, level in enumerate(entry["levels"]):
                failing = [
                    t for t, data in entry["tasks"].items() if data[ctrl]["success_rate"][i] < 1.0
                ]
                if failing:
                    first[ctrl], where[ctrl] = float(level), ", ".join(failing)
                    break
        entry["first_failure"] = first
        entry["first_failure_task"] = where


def load_results(out_dir: Path) -> dict[str, Any]:
    """DIR/results.json of a previous bench; CapError naming the file when it is missing,
    not UTF-8, not JSON (or nested beyond the parser's depth) or not in this bench's format."""
    path = out_dir / RESULTS
    try:
        results = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as exc:
        raise CapError(f"{path} not found: run `cap bench --out {out_dir}` first") from exc
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise CapError(f"{path}: not a readable JSON file ({type(exc).__name__})") from exc
    meta = results.get("meta") if isinstance(results, dict) else None
    if not (isinstance(meta, dict) and "quick" in meta and "paper_figures" in meta):
        raise CapError(f"{path}: not the results of `cap bench` (no meta.quick/paper_figures)")
    return results


def is_previous_bench(out_dir: Path) -> bool:
    """Whether `out_dir` holds a previous bench: a results.json in this bench's format."""
    try:
        load_results(out_dir)
    except CapError:
        return False
    return True


def check_out_dir(out_dir: Path, force: bool = False) -> None:
    """Refuse to write into a non-empty directory that is not a previous bench (unless force):
    the bench overwrites report.md, results.json and figures, and no file of the user's may
    be overwritten silently."""
    if out_dir.exists() and not out_dir.is_dir():
        raise CapError(f"--out {out_dir}: exists and is not a directory")
    if force or not out_dir.exists() or not any(out_dir.iterdir()):
        return
    if not is_previous_bench(out_dir):
        raise CapError(
            f"--out {out_dir}: the directory is not empty and holds no previous bench "
            f"({RESULTS} of `cap bench`); choose an empty or new directory, or pass --force"
        )


def policy_identity(policy: ConstraintAwarePolicy, source: str | Path | None) -> dict[str, Any]:
    """What identifies the policy a bench ran: its card's name, where it was loaded from, and
    SHA-256 digests of its card (canonical JSON) and of its weights (float64 bytes, layer by
    layer), so two results can be told apart even when two files share a name."""
    card_sha256, weights_sha256 = policy.digests()
    shipped = source is None or is_shipped(source)
    return {
        "name": policy.name,
        "source": str(source) if source is not None else policy.name,
        "shipped": shipped,
        "observation": policy.observation,
        "card_sha256": card_sha256,
        "weights_sha256": weights_sha256,
    }


def run_bench(
    out: str | Path,
    quick: bool = False,
    workers: int | None = None,
    force: bool = False,
    scheduler: str | None = None,
    policy: str | Path | None = None,
    robot: str = DEFAULT_ROBOT,
    on_skip: Callable[[str], None] = _to_stderr,
) -> Path:
    """Run everything (quick: the paper's experiments with few seeds) into `out`.

    policy: a shipped policy's name (`policy.POLICY_NAMES`) or a policy .npz; every run of
    the policy controller uses it (None: the shipped default), except the policy section's
    named comparison (paper vs default) and the paper-policy appendix run. An unknown name
    raises UnknownNameError listing the valid ones, a bad file PolicyFileError.
    robot: the embodiment (a robot spec, sim.embodiment) of the paper's experiments, the
    suite, the offset map and the sensitivity; the embodiment section keeps comparing the hook
    hand with the Jaco, and the placement, policy and fault sections run on the hook hand.
    `out` must be new, empty or a previous bench's directory unless `force` (CapError).
    scheduler: a Dask scheduler's address, or "local" for a cluster of `workers` processes on
    this machine; the sweeps' runs then go to that cluster (through its client's executor) and
    `workers` is its thread count. When every worker runs on this machine the rendering
    sections (the paper's snapshots, the end-to-end sequences) and the figures are the
    cluster's tasks too; otherwise they run in a side process here, where their files go.
    The results do not depend on it.
    Everything is validated before any run or connection; `preflight` decides which sections
    are skipped, and `on_skip` receives its line for each before anything runs (default: to
    stderr); results.json lists them under "skipped" and the report names them.
    """
    loaded = ConstraintAwarePolicy.load(policy)
    cfg = ex.BenchConfig.for_mode(quick, workers, robot)
    check_out_dir(Path(out), force)
    skipped = preflight(cfg)
    for line in skipped.values():
        on_skip(line)
    with _each_warning_once(), reuse_runs():
        if scheduler is None:  # one pool for every section: its workers keep their caches
            with (
                local_pool(workers) as pool,
                use_executor(pool),
                _side_process(cfg.workers or available_cpus()) as side,
            ):
                return _run_bench(out, cfg, loaded, policy, skipped, pool, side)
        # each worker says each warning once, as the pool's processes do
        cluster = dask_executor(scheduler, local_workers=workers, worker_filter=_OncePerMessage())
        with cluster as (executor, threads, local), use_executor(executor):
            cfg = dataclasses.replace(cfg, workers=threads)
            if local:
                # workers on this machine write to its files: the rendering sections and the
                # figures are tasks on the cluster like the runs
                return _run_bench(out, cfg, loaded, policy, skipped, executor, executor)
            # a remote cluster's workers would write their files elsewhere: those run here
            with _side_process(2) as side:
                return _run_bench(out, cfg, loaded, policy, skipped, side, side)


#: [s] how long a failed bench's side process may take to end after SIGTERM before SIGKILL
SIDE_GRACE_S = 2.0


@contextlib.contextmanager
def _side_process(workers: int) -> Iterator[Executor]:
    """Where the sections that render run (the paper's snapshots, the end-to-end sequences'
    depth camera), beside the sweeps: one process started fresh (spawn), since offscreen
    rendering hangs in a process forked from one that has rendered; this process itself
    when the bench has one worker."""
    if workers <= 1:
        yield InProcessExecutor()
        return
    side = ProcessPoolExecutor(
        max_workers=1, mp_context=multiprocessing.get_context("spawn"), initializer=_quiet
    )
    try:
        yield side
    except BaseException:
        # the bench failed or was interrupted: do not wait for a section nobody will read
        processes = list(getattr(side, "_processes", {}).values())
        side.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:  # one still starting up may outlive SIGTERM's grace
            process.join(timeout=SIDE_GRACE_S)
            if process.is_alive():
                process.kill()
        raise
    side.shutdown(wait=True)


def _quiet() -> None:
    """The side process's share of `_each_warning_once`."""
    logging.getLogger("constraint_aware").addFilter(_OncePerMessage())


def _timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, float]:
    """fn(*args) and its wall time [s] (a section run beside the others)."""
    start = time.perf_counter()
    return fn(*args), time.perf_counter() - start


class _OncePerMessage(logging.Filter):
    """Lets each distinct message through once: a sweep repeats the same run-input warning
    for every run that lacks the input (each run's record still lists it)."""

    def __init__(self) -> None:
        super().__init__()
        self._seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if message in self._seen:
            return False
        self._seen.add(message)
        return True


@contextlib.contextmanager
def _each_warning_once() -> Iterator[None]:
    """The package's warnings once per distinct message (per process: the pool's workers are
    forked after this is installed) for the duration of the block."""
    logger = logging.getLogger("constraint_aware")
    once = _OncePerMessage()
    logger.addFilter(once)
    try:
        yield
    finally:
        logger.removeFilter(once)


def _run_bench(
    out: str | Path,
    cfg: ex.BenchConfig,
    policy: ConstraintAwarePolicy,
    source: str | Path | None,
    skipped: dict[str, str],
    figures_on: Executor,
    side: Executor,
) -> Path:
    start = time.perf_counter()
    quick = cfg.quick
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {
        "meta": {
            "quick": quick,
            "workers": cfg.workers or available_cpus(),
            "n_tasks": len(TASKS),
            "n_controllers": len(ex.CONTROLLERS),
            "controllers": list(ex.CONTROLLERS),
            "policy": policy_identity(policy, source),
            "robot": cfg.robot,
            "force_limit_N": task_config("drawer-opening").force_limit,
            "paper_figures": {
                "drawer": 6,
                "comparison": [7, 8],
                "revolute": 9,
                "force": 11,
                "trajectory": 12,
            },
            "randomization": {
                "scale": [0.5, 1.5],
                "prismatic_offset_deg": SUITE_OFFSET_RANGE["prismatic"],
                "revolute_offset_deg": SUITE_OFFSET_RANGE["revolute"],
            },
        },
        "skipped": skipped,
    }
    seconds: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(section: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        seconds[section] = now - clock
        clock = now

    # the rendering sections start first, beside the sweeps; their results are placed in the
    # sections' order when they arrive
    paper = side.submit(_timed, ex.paper_experiments, out_dir, cfg.render, policy, cfg.robot)
    end_to_end: Future[tuple[Any, float]] | None = None
    if "end_to_end" not in skipped:
        end_to_end = side.submit(_timed, endtoend.bench_section, quick, policy)
    results["learning"] = ex.learning(out_dir, policy, source)
    lap("learning")
    results["paper"] = None
    table, suite_runs = ex.headline(cfg, policy)
    for row in table.values():
        for cell in row.values():
            cell["successes"] = round(cell["success_rate"] * cell["n"])
    results["headline"] = {
        "seeds": cfg.suite_seeds,
        "table": table,
        "peak_force_samples": ex.peak_force_samples(suite_runs),
    }
    lap("headline")
    if "embodiment" not in skipped:
        results["embodiment"] = embodiment_for_bench(quick, cfg.suite_seeds, policy).to_dict()
        lap("embodiment")
    all_runs = list(suite_runs)
    results["placement"] = placement.bench_section(quick, policy)
    lap("placement")
    if end_to_end is not None:
        results["end_to_end"] = None
    if not quick:
        heatmap, hm_runs = ex.offset_heatmap(cfg, policy)
        heatmap["full_success_halfwidth_deg"] = _full_success_halfwidth(heatmap)
        results["heatmap"] = heatmap
        lap("heatmap")
        sens, sens_runs = ex.sensitivity(cfg, policy)
        _first_failures(sens)
        results["sensitivity"] = sens
        lap("sensitivity")
        all_runs += hm_runs + sens_runs
    results["policy_section"] = policy_section(quick).to_dict()
    lap("policy_section")
    results["ablation"] = ablation_section(quick, cfg.workers).to_dict()
    lap("ablation")
    results["faults"] = fault_suite(
        FAULT_BENCH_TASKS_QUICK if quick else tuple(TASKS),
        QUICK_FAULTS if quick else tuple(FAULTS),
        policy=policy,
    ).to_dict()
    lap("faults")
    section, seconds["paper"] = paper.result()
    results["paper"] = _summaries_with_units(section)
    if end_to_end is not None:
        results["end_to_end"], seconds["end_to_end"] = end_to_end.result()
    results["meta"]["section_seconds"] = seconds
    worst = ex.worst_cases(all_runs)
    for w in worst:
        w["sensor_bias_magnitude_N"] = float(np.linalg.norm(w["sensor_bias_N"]))
    results["worst_cases"] = worst
    results["meta"]["wall_time_s"] = time.perf_counter() - start
    write_results(out_dir / RESULTS, results)
    return replot(out_dir, figures_on)


def replot(out: str | Path, executor: Executor | None = None) -> Path:
    """Redraw every figure and the report from DIR/results.json (nothing is re-run); the
    figures on `executor` when given (the bench's pool), else one after the other here."""
    out_dir = Path(out)
    results = load_results(out_dir)
    figures = draw_all(out_dir, results, executor)
    return write_report(out_dir, results, figures)
