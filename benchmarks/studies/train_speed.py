"""Where the training time goes: PPO update vs env rollouts vs evaluations, per preset.

    nice -n 10 python benchmarks/studies/train_speed.py [--steps 120000] [--threads 1 2]
        [--out PATH]

Trains each configuration for a fixed number of env steps (no target) and times SB3's
`collect_rollouts` (the batched numpy env + the policy's forward pass), `train` (the PPO
update: minibatch forward/backward/Adam) and the evaluation callback separately. Configurations:
`baseline` (the `default` preset before its smaller net: 2x256, 10 epochs, the same values as
benchmarks/train_time.py's baseline; labelled `stop15_default` in the committed results) and
today's `default`, each at the given torch thread counts, interleaved so that they share the
machine's load; the load average is recorded before and after. Ratios between configurations
of one run are the figures to quote. Writes JSON with provenance.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from constraint_aware.bench.provenance import write_results
from constraint_aware.training import ppo, train_config
from constraint_aware.training.config import resistance_config
from constraint_aware.training.vec_env import BatchedSingleSystemVecEnv

OUT = Path(__file__).parent / "results" / "train_speed.json"


def baseline() -> train_config.TrainConfig:
    """The `default` preset before its smaller net (the values of train_time.BASELINE_FLAGS)."""
    return train_config.make_config(
        "default",
        net_arch=(256, 256),
        n_epochs=10,
        final_learning_rate=None,
        total_timesteps=1_200_000,
        env=resistance_config(train_config.DEFAULT_OBSERVATION),
    )


def timed(store: dict[str, float], key: str, fn: Callable[..., Any]) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            store[key] = store.get(key, 0.0) + time.perf_counter() - start

    return wrapper


def profile(config: train_config.TrainConfig, steps: int) -> dict[str, Any]:
    """Train `config` for `steps` env steps; seconds in rollouts, updates and evaluations."""
    config = dataclasses.replace(config, total_timesteps=steps, target_angle_deg=None)
    torch.set_num_threads(config.torch_threads)
    vec_env = BatchedSingleSystemVecEnv(config.n_envs, config.env, seed=config.seed)
    model = ppo.build_model(vec_env, config)
    callback = ppo.EvalCallback(config, vec_env)
    spent: dict[str, float] = {}
    model.collect_rollouts = timed(spent, "rollouts_s", model.collect_rollouts)  # type: ignore[method-assign]
    model.train = timed(spent, "update_s", model.train)  # type: ignore[method-assign]
    callback.evaluate_now = timed(spent, "evaluation_s", callback.evaluate_now)  # type: ignore[method-assign]
    callback._on_training_start = timed(spent, "first_evaluation_s", callback._on_training_start)  # type: ignore[method-assign]
    start = time.perf_counter()
    model.learn(total_timesteps=steps, callback=callback)
    wall = time.perf_counter() - start
    # all but the first evaluation run inside collect_rollouts (on_rollout_end): count once
    spent["rollouts_s"] -= spent["evaluation_s"] - spent["first_evaluation_s"]
    return {
        "net_arch": list(config.net_arch),
        "n_epochs": config.n_epochs,
        "torch_threads": config.torch_threads,
        "steps": int(model.num_timesteps),
        "wall_s": wall,
        "steps_per_s": model.num_timesteps / wall,
        **spent,
        "update_share": spent["update_s"] / wall,
        "last_eval_mean_angle_deg": callback.rows[-1]["eval_mean_final_angle_deg"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=120_000)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    configs = {"baseline": baseline(), "default": train_config.make_config("default")}
    load_before = os.getloadavg()
    runs = []
    for threads in args.threads:
        for name, config in configs.items():
            run = profile(dataclasses.replace(config, torch_threads=threads), args.steps)
            runs.append({"config": name, **run})
            print(json.dumps(runs[-1]), flush=True)
    result = {
        "cores": os.cpu_count(),
        "load_average_1_5_15_before": load_before,
        "load_average_1_5_15_after": os.getloadavg(),
        "runs": runs,
    }
    write_results(args.out, result)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
