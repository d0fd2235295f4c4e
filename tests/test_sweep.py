"""Sweeps on any executor: pool size from the CPU affinity, order-free results, Dask."""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from constraint_aware.bench import sweep
from constraint_aware.bench.sweep import (
    available_cpus,
    dask_executor,
    default_workers,
    gather_in_order,
    run_many,
    suite_specs,
    use_executor,
)
from constraint_aware.errors import CapError


class LastInFirstOut(Executor):
    """Runs the submitted calls in reverse order, on one thread, once submissions pause."""

    def __init__(self, pause_s: float = 0.2) -> None:
        self.pause_s = pause_s
        self.pending: list[tuple[Future[Any], Callable[..., Any], tuple[Any, ...]]] = []
        self.finished: list[Any] = []  # the arguments, in the order their calls finished
        self.timer: threading.Timer | None = None

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future[Any]:
        future: Future[Any] = Future()
        self.pending.append((future, fn, args))
        if self.timer is not None:
            self.timer.cancel()
        self.timer = threading.Timer(self.pause_s, self._drain)
        self.timer.start()
        return future

    def _drain(self) -> None:
        while self.pending:
            future, fn, args = self.pending.pop()
            result = fn(*args)
            self.finished.append(args)
            future.set_result(result)


def _square(x: int) -> int:
    return x * x


def test_results_keep_the_spec_order_whatever_order_runs_finish() -> None:
    executor = LastInFirstOut()
    jobs = list(range(12))
    assert gather_in_order(executor, _square, jobs) == [x * x for x in jobs]
    assert [a[0] for a in executor.finished] == jobs[::-1]  # they did finish in reverse


@pytest.fixture(scope="module")
def specs() -> list[sweep.RunSpec]:
    """Four suite runs: a prismatic and a revolute task, the policy and the classical
    controller, randomized (friction, mass, damping, offset)."""
    return suite_specs(1, ("policy", "classical"), tasks=("drawer-opening", "door-opening"))


@pytest.fixture(scope="module")
def serial(specs: list[sweep.RunSpec]) -> list[dict[str, Any]]:
    return run_many(specs, workers=1, quiet=True)


def test_any_executor_gives_the_serial_results(
    specs: list[sweep.RunSpec], serial: list[dict[str, Any]]
) -> None:
    assert [r["spec"]["task"] for r in serial] == [s.task for s in specs]
    assert run_many(specs, executor=LastInFirstOut(), quiet=True) == serial
    with ThreadPoolExecutor(max_workers=2) as pool, use_executor(pool):
        assert run_many(specs, quiet=True) == serial  # the executor set for the block


def test_default_pool_size_from_the_cpu_affinity(monkeypatch: pytest.MonkeyPatch) -> None:
    # A 4-CPU batch allocation on a 128-core node.
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(4)), raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 128)
    assert available_cpus() == 4
    assert default_workers(100) == 4
    assert default_workers(3) == 3  # never more processes than runs
    assert default_workers(0) == 1
    monkeypatch.delattr(os, "sched_getaffinity", raising=False)  # macOS, Windows
    assert available_cpus() == 128


def test_run_many_sizes_its_pool_by_default(
    monkeypatch: pytest.MonkeyPatch, specs: list[sweep.RunSpec], serial: list[dict[str, Any]]
) -> None:
    sizes: list[int] = []

    class RecordingPool(ThreadPoolExecutor):  # threads: the size is what is checked here
        def __init__(self, max_workers: int) -> None:
            sizes.append(max_workers)
            super().__init__(max_workers=max_workers)

    monkeypatch.setattr(sweep, "ProcessPoolExecutor", RecordingPool)
    monkeypatch.setattr(sweep, "available_cpus", lambda: 64)
    assert run_many(specs[:3], quiet=True) == serial[:3]
    assert sizes == [3]


@pytest.fixture(scope="module")
def one_worker_cluster() -> Iterator[Any]:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster:
        yield cluster


def test_dask_local_cluster_gives_the_local_pool_results(
    one_worker_cluster: Any, specs: list[sweep.RunSpec], serial: list[dict[str, Any]]
) -> None:
    with dask_executor(one_worker_cluster.scheduler_address) as (executor, threads, local):
        assert threads == 1 and local  # the cluster's one worker runs on this machine
        assert run_many(specs, executor=executor, quiet=True) == serial


def _package_filters() -> list[str]:
    return [getattr(f, "name", "?") for f in logging.getLogger("constraint_aware").filters]


def test_a_worker_filter_holds_on_the_workers_for_the_block_only(one_worker_cluster: Any) -> None:
    """The bench's once-per-message filter reaches Dask workers (else every run of a sweep
    prints its missing-input warnings), and leaves a remote cluster as it found it."""
    distributed = pytest.importorskip("distributed")
    address = one_worker_cluster.scheduler_address
    with dask_executor(address, worker_filter=logging.Filter("kept")) as (executor, _, _):
        assert executor.submit(_package_filters).result() == ["kept"]
    with distributed.Client(address) as client:
        assert list(client.run(_package_filters).values()) == [[]]


def test_unreachable_scheduler_is_a_clear_error() -> None:
    pytest.importorskip("distributed")
    with (
        pytest.raises(CapError, match="scheduler"),
        dask_executor("tcp://127.0.0.1:9", timeout_s=1.0),
    ):
        pass


def test_run_bench_sends_its_sweeps_to_the_scheduler(
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    specs: list[sweep.RunSpec],
    serial: list[dict[str, Any]],
) -> None:
    """run_bench(scheduler="local") starts a LocalCluster and every run_many inside goes there
    (the whole quick bench twice is too slow for a test: benchmarks/sweep_dask.py does it),
    and so do the rendering sections and figures, its worker being on this machine."""
    pytest.importorskip("distributed")
    from constraint_aware.bench import run as bench_run

    seen: dict[str, Any] = {}

    def sweeps_only(out: str | Path, cfg: Any, policy: Any, source: Any, *rest: Any) -> Path:
        seen["executor"] = type(sweep._CURRENT_EXECUTOR.get()).__name__
        seen["rendering"] = type(rest[-1]).__name__
        seen["workers"] = cfg.workers
        seen["runs"] = run_many(specs[:2], quiet=True, policy=policy)
        return Path(out)

    monkeypatch.setattr(bench_run, "_run_bench", sweeps_only)
    bench_run.run_bench(tmp_path / "bench", quick=True, workers=1, scheduler=sweep.LOCAL_SCHEDULER)
    assert seen == {
        "executor": "ClientExecutor",
        "rendering": "ClientExecutor",
        "workers": 1,
        "runs": serial[:2],
    }
    assert sweep._CURRENT_EXECUTOR.get() is None  # the local pool again after the bench


def _pid(_: object) -> int:
    return os.getpid()


def test_a_local_pool_keeps_its_workers_from_one_sweep_to_the_next() -> None:
    with sweep.local_pool(2) as pool, use_executor(pool):
        assert pool is not None
        first = sweep.map_in_order(_pid, range(8), quiet=True)
        second = sweep.map_in_order(_pid, range(8), quiet=True)
        workers = set(pool._processes)  # type: ignore[attr-defined]
    assert os.getpid() not in first
    assert set(first) | set(second) <= workers and len(workers) == 2
    with sweep.local_pool(1) as here, use_executor(here):  # one worker: this process
        assert sweep.map_in_order(_pid, range(3), quiet=True) == [os.getpid()] * 3


def test_map_in_order_keeps_the_jobs_order_on_any_executor() -> None:
    executor = LastInFirstOut()
    assert sweep.map_in_order(_square, list(range(6)), quiet=True, executor=executor) == [
        x * x for x in range(6)
    ]
    assert executor.finished[0] == (5,)  # the last job finished first


def _ended(process: Any) -> bool:
    """Whether `process` has ended: its exit code is known, or the system shows it gone or a
    zombie (the pool's own thread may reap it first, after which `is_alive` cannot tell)."""
    if process.exitcode is not None:
        return True
    try:
        with open(f"/proc/{process.pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def test_a_failed_bench_does_not_wait_for_its_side_process() -> None:
    """An exception (or Ctrl-C) in the bench ends its side process at once instead of waiting
    for the section it is running."""
    import time

    from constraint_aware.bench import run as bench_run

    start = time.perf_counter()
    processes: list[Any] = []
    with (
        pytest.raises(RuntimeError, match="the bench failed"),
        bench_run._side_process(2) as side,
    ):
        side.submit(time.sleep, 60.0)
        processes += side._processes.values()  # type: ignore[attr-defined]
        raise RuntimeError("the bench failed")
    for process in processes:
        process.join(timeout=10.0)
    assert time.perf_counter() - start < 20.0
    assert processes and all(_ended(process) for process in processes)


def test_a_failed_bench_ends_a_side_process_that_outlives_sigterm(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A side process that does not end on SIGTERM (here: told to ignore it) is killed."""
    import signal
    import time

    from constraint_aware.bench import run as bench_run

    monkeypatch.setattr(bench_run, "SIDE_GRACE_S", 0.2)

    processes: list[Any] = []
    with (
        pytest.raises(RuntimeError, match="the bench failed"),
        bench_run._side_process(2) as side,
    ):
        side.submit(signal.signal, signal.SIGTERM, signal.SIG_IGN).result(timeout=60.0)
        sleeping = side.submit(time.sleep, 60.0)
        while not sleeping.running():  # handed to the worker, not cancellable any more
            time.sleep(0.01)
        time.sleep(0.5)
        processes += side._processes.values()  # type: ignore[attr-defined]
        raise RuntimeError("the bench failed")
    for process in processes:
        process.join(timeout=10.0)
    assert processes and all(_ended(process) for process in processes)


def test_reuse_runs_makes_each_distinct_run_once(
    monkeypatch: pytest.MonkeyPatch, specs: list[sweep.RunSpec], serial: list[dict[str, Any]]
) -> None:
    """Inside `reuse_runs` a spec asked for again (same keep_steps, same policy weights and
    card) is served from the first run; another policy, keep_steps or spec runs; outside the
    block nothing is kept."""
    from constraint_aware.policy import ConstraintAwarePolicy

    made: list[sweep.RunSpec] = []
    real = sweep._run_one

    def counted(args: tuple[sweep.RunSpec, bool, Any]) -> dict[str, Any]:
        made.append(args[0])
        return real(args)

    monkeypatch.setattr(sweep, "_run_one", counted)
    default = ConstraintAwarePolicy.load()
    with sweep.reuse_runs():
        first = run_many([specs[0], specs[1], specs[0]], workers=1, quiet=True)
        assert made == specs[:2] and first == [serial[0], serial[1], serial[0]]
        first[0]["summary"]["peak_force_N"] = -1.0  # a copy: the kept run is untouched
        # the same default policy, passed explicitly or loaded again: the same runs
        again = run_many(specs[:2], workers=1, quiet=True, policy=default)
        assert made == specs[:2] and again == serial[:2]
        other = default.with_card({**default.card, "name": "another"})
        run_many(specs[:1], workers=1, quiet=True, policy=other)
        run_many(specs[:1], workers=1, quiet=True, keep_steps=True)
        assert made == [specs[0], specs[1], specs[0], specs[0]]
    run_many(specs[:1], workers=1, quiet=True)
    assert len(made) == 5
