"""ONNX export parity and latency: the exported graph against the numpy policy. Writes JSON.

    python benchmarks/onnx_parity.py [--n 10000] [--repeats 7]
        [--out benchmarks/results/onnx_parity.json]

Parity: max |act_batch - ONNX Runtime| over n random observations (half as the policy sees
them, half uniform in [-2, 2]) for every packaged policy. Latency: the median over `repeats`
of one single-observation call and of one batch call, numpy and ONNX Runtime (one thread),
measured in this one run, with their ratio.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import onnxruntime

from constraint_aware import policy as policy_module
from constraint_aware.bench.provenance import write_results
from constraint_aware.export.onnx import (
    INPUT_NAME,
    OUTPUT_NAME,
    export_onnx,
    observation_layout,
    onnx_parity,
    random_observations,
)
from constraint_aware.policy import ConstraintAwarePolicy


def median_time(fn: Callable[[], object], repeats: int, calls: int = 1) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        samples.append((time.perf_counter() - start) / calls)
    return statistics.median(samples)


def measure(policy: ConstraintAwarePolicy, n: int, repeats: int, workdir: Path) -> dict[str, Any]:
    path = export_onnx(policy, workdir / "policy.onnx")
    options = onnxruntime.SessionOptions()
    options.intra_op_num_threads = 1  # a controller's real-time thread
    session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    obs32 = random_observations(observation_layout(policy), n, np.random.default_rng(1))
    obs64 = obs32.astype(np.float64)
    one32, one64 = obs32[:1], obs64[:1]
    single_numpy = median_time(lambda: policy.act_batch(one64), repeats, calls=2000)
    single_onnx = median_time(
        lambda: session.run([OUTPUT_NAME], {INPUT_NAME: one32}), repeats, calls=2000
    )
    batch_numpy = median_time(lambda: policy.act_batch(obs64), repeats)
    batch_onnx = median_time(lambda: session.run([OUTPUT_NAME], {INPUT_NAME: obs32}), repeats)
    return {
        "observations": n,
        "n_inputs": len(observation_layout(policy)),
        "max_abs_difference": onnx_parity(policy, path, n_observations=n, seed=0),
        "file_bytes": path.stat().st_size,
        "single_numpy_median_us": 1e6 * single_numpy,
        "single_onnxruntime_median_us": 1e6 * single_onnx,
        "single_onnxruntime_over_numpy": single_onnx / single_numpy,
        "batch_numpy_median_ms": 1e3 * batch_numpy,
        "batch_onnxruntime_median_ms": 1e3 * batch_onnx,
        "batch_onnxruntime_over_numpy": batch_onnx / batch_numpy,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "onnx_parity.json"
    )
    args = parser.parse_args()
    # Every packaged policy by name where this version names them, else the shipped one.
    names = list(getattr(policy_module, "POLICY_NAMES", [None]))
    result: dict[str, Any] = {"repeats": args.repeats, "onnxruntime": onnxruntime.__version__}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            policy = ConstraintAwarePolicy.load(name)
            result[name or "shipped"] = measure(policy, args.n, args.repeats, Path(tmp))
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
