"""Throughput of the training env backends and latency of one policy decision. Writes JSON.

The paper's policy is compared with SB3 (same 6-input layout); the default policy's
`update_direction` (its session, with the step force) is timed beside it.

    python benchmarks/policy_speed.py [--repeats 7] [--out benchmarks/results/policy_speed.json]

Each figure is the median over `repeats` measurements in this one run; the ratio compares the
numpy policy with Stable-Baselines3's `predict` on the same weights (if SB3 is installed).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig, resistance_config
from constraint_aware.training.env import make_force_model


def median_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def env_steps_per_s(
    backend: str, n_envs: int, episodes: int, repeats: int, config: EnvConfig | None = None
) -> float:
    config = config or EnvConfig()
    env = SingleSystemBatch(n_envs, config, make_force_model(backend, config))
    rng = np.random.default_rng(0)
    actions = rng.uniform(-0.2, 0.2, size=(n_envs, 3))

    def run() -> None:
        for _ in range(episodes):
            env.reset(rng)
            done = False
            while not done:
                _, _, done = env.step(actions)

    # reset() also moves the body once, so an episode costs T + 1 physics steps
    steps = episodes * n_envs * (config.episode_length + 1)
    return steps / median_time(run, repeats)


def act_latency_us(repeats: int, calls: int = 2000) -> dict[str, float]:
    policy = ConstraintAwarePolicy.load("paper")  # 6 inputs: the SB3 model below matches it
    default = ConstraintAwarePolicy.load()
    session = default.session()
    rng = np.random.default_rng(0)
    forces = rng.normal(size=(calls, 3))
    dirs = rng.normal(size=(calls, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)

    def per_call(fn: Callable[[int], object]) -> float:
        samples = []
        for _ in range(repeats):
            start = time.perf_counter()
            for i in range(calls):
                fn(i)
            samples.append((time.perf_counter() - start) / calls * 1e6)
        return statistics.median(samples)

    f_hat = forces / np.linalg.norm(forces, axis=1, keepdims=True)
    out = {
        "act_median_us": per_call(lambda i: policy.act(f_hat[i], dirs[i])),
        "update_direction_median_us": per_call(
            lambda i: policy.update_direction(10.0 * forces[i], dirs[i])
        ),
        "default_update_direction_median_us": per_call(
            lambda i: session.update_direction(10.0 * forces[i], dirs[i], step_force=20.0)
        ),
    }
    try:
        import torch

        from constraint_aware.training.ppo import build_model
        from constraint_aware.training.train_config import make_config
        from constraint_aware.training.vec_env import BatchedSingleSystemVecEnv
    except ImportError:
        return out
    torch.set_num_threads(1)
    model = build_model(BatchedSingleSystemVecEnv(8), make_config("fast", n_envs=8, batch_size=40))
    obs = np.concatenate([f_hat, dirs], axis=1).astype(np.float32)
    out["sb3_predict_median_us"] = per_call(lambda i: model.predict(obs[i], deterministic=True))
    out["sb3_over_numpy_ratio"] = out["sb3_predict_median_us"] / out["act_median_us"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).parent / "results" / "policy_speed.json"
    )
    args = parser.parse_args()
    result = {
        "analytic_env_steps_per_s_n6000": env_steps_per_s("analytic", 6000, 20, args.repeats),
        "mujoco_env_steps_per_s_n200": env_steps_per_s("mujoco", 200, 2, args.repeats),
        "analytic_resistance_env_steps_per_s_n6000": env_steps_per_s(
            "analytic", 6000, 20, args.repeats, resistance_config("magnitude")
        ),
        **act_latency_us(args.repeats),
        "repeats": args.repeats,
    }
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
