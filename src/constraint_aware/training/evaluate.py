"""Evaluations of a batched controller on fresh episodes: final angle and return.

The standard evaluation is `STANDARD_EPISODES` episodes from `STANDARD_SEED` in the paper's
resistance-free environment (`standard_config`: `EnvConfig`'s defaults, with the policy's
observation); a policy's card records it as `standard_evaluation`. An evaluation in another
environment (the one a policy was trained in, with resistance) is not the standard one.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.reference import BatchController

STANDARD_EPISODES = 10_000
STANDARD_SEED = 12345


def standard_config(observation: str) -> EnvConfig:
    """The standard evaluation's environment: the paper's (EnvConfig's defaults, no resistance
    along the joint) with `observation`, the layout the evaluated policy reads."""
    return EnvConfig(observation=observation)


@dataclass(frozen=True)
class EvalResult:
    """Statistics over `episodes` episodes: angle between d and u after the T-th action."""

    episodes: int
    mean_final_angle_deg: float
    p95_final_angle_deg: float
    median_final_angle_deg: float
    mean_return: float
    mean_angle_by_step_deg: tuple[float, ...]  # step 0 = initial direction

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def evaluate(
    controller: BatchController,
    config: EnvConfig | None = None,
    episodes: int = STANDARD_EPISODES,
    seed: int = STANDARD_SEED,
    batch_size: int = 10_000,
) -> EvalResult:
    """Run `episodes` episodes of the analytic env with `controller`, deterministic for `seed`."""
    config = config or EnvConfig()
    rng = np.random.default_rng(seed)
    finals: list[np.ndarray] = []
    returns: list[np.ndarray] = []
    by_step: list[np.ndarray] = []
    remaining = episodes
    while remaining > 0:
        n = min(batch_size, remaining)
        env = SingleSystemBatch(n, config)
        obs = env.reset(rng)
        angles = [env.angle_to_axis_deg()]
        total = np.zeros(n)
        done = False
        while not done:
            obs, reward, done = env.step(controller(obs, env.params.friction))
            total += reward
            angles.append(env.angle_to_axis_deg())
        finals.append(angles[-1])
        returns.append(total)
        by_step.append(np.stack(angles, axis=1))
        remaining -= n
    final = np.concatenate(finals)
    steps = np.concatenate(by_step).mean(axis=0)
    return EvalResult(
        episodes=episodes,
        mean_final_angle_deg=float(final.mean()),
        p95_final_angle_deg=float(np.percentile(final, 95)),
        median_final_angle_deg=float(np.median(final)),
        mean_return=float(np.concatenate(returns).mean()),
        mean_angle_by_step_deg=tuple(float(x) for x in steps),
    )
