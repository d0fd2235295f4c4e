"""Many simulated runs at once: spec lists, an executor, a progress bar, summaries.

The runs go to any `concurrent.futures.Executor`: by default a local process pool sized from
the CPUs this process may use; `dask_executor(address)` gives a Dask cluster's (a machine's
worth of runs is not the limit). Results keep the order of the specs whatever order the runs
finish in, so a sweep's numbers do not depend on where or how fast it ran.

`map_in_order` runs any picklable function over any jobs the same way (the bench's sections
with their own kinds of runs), and `local_pool` keeps one process pool for a whole bench: its
workers keep what they built (compiled models, the Jaco's grasp postures and tracking time
constants, the compiled controller, the default policy) from one sweep to the next.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import functools
import logging
import os
import socket
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextvars import ContextVar
from typing import Any, TypeVar

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from constraint_aware.control.run_inputs import LOGGER as PACKAGE_LOGGER
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.errors import CapError
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import TASKS, task_config

T = TypeVar("T")
R = TypeVar("R")

#: The paper's initial direction errors (sections 5.3-5.5) and the suite's ranges [deg].
PAPER_OFFSETS = {
    "drawer-opening": (30.0, -30.0),
    "plate-sliding": (-30.0,),
    "pole-pulling": (-30.0,),
    "door-opening": (15.0,),
    "handle-rotating": (15.0,),
}
SUITE_OFFSET_RANGE = {"prismatic": 30.0, "revolute": 15.0}


def suite_specs(
    n_seeds: int,
    controllers: Sequence[str],
    tasks: Iterable[str] = TASKS,
    first_seed: int = 0,
) -> list[RunSpec]:
    """Randomized suite: per task and seed, friction/mass/damping drawn (sim.tasks.randomized)
    and an offset uniform in +-30 deg (prismatic) or +-15 deg (revolute); every controller
    sees the same draws."""
    specs: list[RunSpec] = []
    for task in tasks:
        limit = SUITE_OFFSET_RANGE[task_config(task).constraint_type]
        for seed in range(first_seed, first_seed + n_seeds):
            rng = np.random.default_rng([seed, 17])
            offset = float(rng.uniform(-limit, limit))
            specs.extend(
                RunSpec(task=task, controller=c, offset_deg=offset, seed=seed, randomize=True)
                for c in controllers
            )
    return specs


@functools.cache
def _default_policy() -> ConstraintAwarePolicy:
    """The shipped default policy, loaded once per process: every run of a sweep uses it
    (runs only read a policy: each controller keeps its own session)."""
    return ConstraintAwarePolicy.load()


def _run_one(args: tuple[RunSpec, bool, ConstraintAwarePolicy | None]) -> dict[str, Any]:
    spec, keep_steps, policy = args
    record, _ = run(spec, policy=policy or _default_policy())
    out: dict[str, Any] = {"spec": dataclasses.asdict(spec), "summary": record.summary()}
    if keep_steps:
        out["angles_deg"] = record.angles
        out["forces_N"] = [s.force_norm for s in record.steps]
    return out


def available_cpus() -> int:
    """CPUs this process may run on: its affinity mask (a batch allocation's share of a large
    node), else the machine's count."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # macOS and Windows have no affinity mask
        return os.cpu_count() or 1


def default_workers(n_runs: int) -> int:
    """Local pool size for `n_runs` runs: the available CPUs, never more processes than runs."""
    return max(1, min(available_cpus(), n_runs))


#: The executor `run_many` uses when none is passed (set by `use_executor`).
_CURRENT_EXECUTOR: ContextVar[Executor | None] = ContextVar("sweep_executor", default=None)


def current_executor() -> Executor | None:
    """The executor set by `use_executor` for this context, or None (the local pool)."""
    return _CURRENT_EXECUTOR.get()


@contextlib.contextmanager
def use_executor(executor: Executor | None) -> Iterator[None]:
    """Every `run_many` inside the block runs on `executor` (None: the local pool)."""
    token = _CURRENT_EXECUTOR.set(executor)
    try:
        yield
    finally:
        _CURRENT_EXECUTOR.reset(token)


#: `scheduler` value that starts a Dask cluster on this machine for the sweep.
LOCAL_SCHEDULER = "local"


@contextlib.contextmanager
def dask_executor(
    address: str,
    timeout_s: float = 30.0,
    local_workers: int | None = None,
    worker_filter: logging.Filter | None = None,
) -> Iterator[tuple[Executor, int, bool]]:
    """(executor, total worker threads, whether every worker runs on this machine) of the Dask
    cluster whose scheduler is at `address`.

    `address` "local" (LOCAL_SCHEDULER) starts a `distributed.LocalCluster` for the block:
    `local_workers` single-threaded worker processes (default: the available CPUs). Needs the
    `cluster` extra (`distributed`); a remote cluster's workers need this package installed.
    `worker_filter`: a copy of it filters the "constraint_aware" logger on every worker,
    joining ones included, for the block only (a worker plugin, removed at the end).
    """
    try:
        from distributed import Client, LocalCluster, WorkerPlugin
    except ImportError as exc:
        raise CapError(
            "scheduler: running on a Dask cluster needs 'distributed': "
            "pip install 'constraint-aware[cluster]'"
        ) from exc
    if local_workers is not None and local_workers < 1:
        raise CapError(f"workers: a local cluster needs >= 1 worker, got {local_workers}")
    with contextlib.ExitStack() as stack:
        if address == LOCAL_SCHEDULER:
            cluster = LocalCluster(
                n_workers=local_workers or available_cpus(),
                threads_per_worker=1,  # one MuJoCo run per process, as in the local pool
                processes=True,
                dashboard_address=None,  # no dashboard: its server costs CPU and a port
            )
            stack.enter_context(cluster)
            address = cluster.scheduler_address
        try:
            client = Client(address, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError, ValueError) as exc:
            raise CapError(
                f"scheduler: cannot reach a Dask scheduler at {address!r} ({exc})"
            ) from exc
        stack.callback(client.close)
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except TimeoutError as exc:
            raise CapError(
                f"scheduler: no worker joined the cluster at {address!r} in {timeout_s} s"
            ) from exc
        if worker_filter is not None:

            class LoggerFilter(WorkerPlugin):  # here: distributed is imported only in this function
                name = "constraint_aware-logger-filter"

                def __init__(self, kept: logging.Filter) -> None:
                    self.kept, self.logger = kept, PACKAGE_LOGGER.name

                def setup(self, worker: Any) -> None:
                    logging.getLogger(self.logger).addFilter(self.kept)

                def teardown(self, worker: Any) -> None:
                    logging.getLogger(self.logger).removeFilter(self.kept)

            client.register_plugin(LoggerFilter(worker_filter))
            stack.callback(client.unregister_worker_plugin, LoggerFilter.name)
        threads = sum(client.nthreads().values())
        here = socket.gethostname()
        on_this_machine = all(h == here for h in client.run(socket.gethostname).values())
        with client.get_executor() as executor:
            yield executor, threads, on_this_machine


def gather_in_order(
    executor: Executor,
    fn: Callable[[T], R],
    jobs: Sequence[T],
    on_done: Callable[[], None] | None = None,
) -> list[R]:
    """[fn(job) for job in jobs] computed on `executor`, in the jobs' order whatever order they
    finish in; `on_done` is called as each finishes (progress)."""
    futures = {executor.submit(fn, job): i for i, job in enumerate(jobs)}
    done: dict[int, R] = {}
    for future in as_completed(futures):
        done[futures[future]] = future.result()
        if on_done is not None:
            on_done()
    return [done[i] for i in range(len(jobs))]


class InProcessExecutor(Executor):
    """Runs each submitted call at once, in this process (one worker)."""

    def submit(self, fn: Callable[..., R], /, *args: Any, **kwargs: Any) -> Future[R]:
        future: Future[R] = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as exc:  # an interrupt stops the sweep at once
            future.set_exception(exc)
        return future


@contextlib.contextmanager
def local_pool(workers: int | None = None) -> Iterator[Executor]:
    """An executor for a block of sweeps, to pass to `use_executor`: a process pool of
    `workers` processes (default: the available CPUs) whose workers live until the block
    ends, or this process itself for one worker."""
    n_workers = workers or available_cpus()
    if n_workers <= 1:
        yield InProcessExecutor()
        return
    with ProcessPoolExecutor(max_workers=n_workers) as pool:
        yield pool


def map_in_order(
    fn: Callable[[T], R],
    jobs: Sequence[T],
    workers: int | None = None,
    label: str = "runs",
    quiet: bool = False,
    executor: Executor | None = None,
) -> list[R]:
    """[fn(job) for job in jobs] (`fn` and the jobs picklable), in the jobs' order, with a
    progress bar on stderr unless `quiet`.

    On `executor` if given, else on the one set by `use_executor`, else in a local process
    pool of `workers` processes (default: `default_workers`); one worker runs them in this
    process."""
    executor = executor or _CURRENT_EXECUTOR.get()
    with Progress(
        TextColumn(f"[bold]{label}[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        disable=quiet,
    ) as progress:
        task = progress.add_task(label, total=len(jobs))

        def advance() -> None:
            progress.advance(task)

        n_workers = workers or default_workers(len(jobs))
        if isinstance(executor, InProcessExecutor) or (executor is None and n_workers <= 1):
            results = []
            for job in jobs:
                results.append(fn(job))
                advance()
            return results
        if executor is not None:
            return gather_in_order(executor, fn, jobs, advance)
        with ProcessPoolExecutor(max_workers=min(n_workers, len(jobs))) as pool:
            return gather_in_order(pool, fn, jobs, advance)


def run_many(
    specs: Sequence[RunSpec],
    workers: int | None = None,
    keep_steps: bool = False,
    label: str = "runs",
    quiet: bool = False,
    executor: Executor | None = None,
    policy: ConstraintAwarePolicy | None = None,
) -> list[dict[str, Any]]:
    """Run every spec; results keep the input order. `policy` drives every spec whose
    controller is "policy" (None: the shipped default); it travels to the workers with each run.

    On `executor` if given, else on the one set by `use_executor`, else in a local process pool
    of `workers` processes (default: `default_workers`); one worker runs them in this process.
    Inside a `reuse_runs` block a run already made there is not made again.
    """
    memo = _RUN_MEMO.get()
    if memo is None:
        jobs = [(s, keep_steps, policy) for s in specs]
        return map_in_order(_run_one, jobs, workers, label, quiet, executor)
    who = (policy or _default_policy()).digests()
    keys = [(s, keep_steps, who) for s in specs]
    new = list(dict.fromkeys(k for k in keys if k not in memo))
    done = map_in_order(
        _run_one, [(k[0], keep_steps, policy) for k in new], workers, label, quiet, executor
    )
    memo.update(zip(new, done, strict=True))
    return [copy.deepcopy(memo[k]) for k in keys]


#: The runs `run_many` has made inside a `reuse_runs` block, by (spec, keep_steps, policy
#: digests); None outside one.
_RUN_MEMO: ContextVar[dict[tuple[RunSpec, bool, tuple[str, str]], dict[str, Any]] | None] = (
    ContextVar("sweep_runs", default=None)
)


@contextlib.contextmanager
def reuse_runs() -> Iterator[None]:
    """Inside the block `run_many` makes each distinct run once: a spec asked for again, with
    the same `keep_steps` and a policy of the same card and weights, gets a copy of the first
    run's result. A run is a function of its spec and policy alone (seeded noise and
    randomization, deterministic physics), so the copy is what running it again gives; a
    bench's sections share runs this way (the randomized suite on the default robot is also
    the embodiment section's transfer on it)."""
    token = _RUN_MEMO.set({})
    try:
        yield
    finally:
        _RUN_MEMO.reset(token)


def success_table(results: Sequence[dict[str, Any]]) -> dict[str, dict[str, dict[str, Any]]]:
    """{task: {controller: {success_rate, n, peak_force_median_N, peak_force_max_N, ...}}}."""
    table: dict[str, dict[str, dict[str, Any]]] = {}
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in results:
        s = r["summary"]
        groups.setdefault((s["task"], s["controller"]), []).append(s)
    for (task, ctrl), rows in groups.items():
        peaks = np.array([x["peak_force_N"] for x in rows])
        finals = np.array([x["final_angle_deg"] for x in rows])
        table.setdefault(task, {})[ctrl] = {
            "n": len(rows),
            "success_rate": float(np.mean([x["success"] for x in rows])),
            "peak_force_median_N": float(np.median(peaks)),
            "peak_force_max_N": float(peaks.max()),
            "final_angle_median_deg": float(np.nanmedian(finals)),
            "outcomes": {o: sum(x["outcome"] == o for x in rows) for o in _outcomes(rows)},
        }
    return table


def _outcomes(rows: Sequence[dict[str, Any]]) -> list[str]:
    return sorted({x["outcome"] for x in rows})
