"""Analytic measurements of a policy on the single-system env (numpy only, no training).

- `standard`: the paper's test set (no resistance): mean final angle (bar: <= 2.2 deg);
- `resistance`: the same with the object's own resistance drawn as in `config.RESISTANCE`
  (the robot reports its step force in every episode);
- `pure_resistance_probe`: `update_direction(-m*d, d)` with the defaults on a fresh session,
  the largest turn of d [deg] over magnitudes m and directions d (bar: < 3 deg).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from constraint_aware import deadband
from constraint_aware.geometry import angle_deg, random_unit
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.training.config import EnvConfig, resistance_config
from constraint_aware.training.evaluate import STANDARD_EPISODES, evaluate

#: [N] magnitudes of the probe: from the dead band floor to 20 N (one blocked 1 cm step of a
#: 2000 N/m arm).
PROBE_MAGNITUDES = (deadband.MIN_THRESHOLD, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 16.0, 20.0)
PROBE_DIRECTIONS = 20
PROBE_SEED = 4


@dataclass(frozen=True)
class ProbeResult:
    """Largest turn of d [deg] under a force straight against it, per magnitude."""

    magnitudes_N: tuple[float, ...]
    max_turn_deg: tuple[float, ...]  # without step_force (the call's defaults)
    max_turn_with_step_force_deg: tuple[float, ...] | None  # with k*delta = step_force
    step_force_N: float

    @property
    def worst_deg(self) -> float:
        return max(self.max_turn_deg)


def pure_resistance_probe(policy: ConstraintAwarePolicy, step_force: float = 20.0) -> ProbeResult:
    """`update_direction(-m*d, d)` on a fresh session for each magnitude m and 20 directions."""
    dirs = random_unit(np.random.default_rng(PROBE_SEED), PROBE_DIRECTIONS)
    dirs[0] = (1.0, 0.0, 0.0)

    def worst(m: float, sf: float | None) -> float:
        turns = []
        for d in dirs:
            new = policy.session().update_direction(-m * d, d, step_force=sf)
            turns.append(float(angle_deg(new, d)))
        return max(turns)

    uses = "step_force" in policy.inputs
    return ProbeResult(
        magnitudes_N=PROBE_MAGNITUDES,
        max_turn_deg=tuple(worst(m, None) for m in PROBE_MAGNITUDES),
        max_turn_with_step_force_deg=(
            tuple(worst(m, step_force) for m in PROBE_MAGNITUDES) if uses else None
        ),
        step_force_N=step_force,
    )


@dataclass(frozen=True)
class AnalyticStudy:
    """A policy's analytic numbers (mean final angles [deg] over 10,000 episodes)."""

    observation: str
    standard_mean_deg: float
    standard_p95_deg: float
    resistance_mean_deg: float
    resistance_p95_deg: float
    probe: ProbeResult


def analytic_study(
    policy: ConstraintAwarePolicy, episodes: int = STANDARD_EPISODES
) -> AnalyticStudy:
    def ctrl(obs: np.ndarray, _f: np.ndarray) -> np.ndarray:
        return policy.act_batch(obs)

    standard = dataclasses.replace(EnvConfig(), observation=policy.observation)
    res = resistance_config(policy.observation, step_force_unknown_share=0.0)  # robot knows k
    s = evaluate(ctrl, standard, episodes=episodes)
    r = evaluate(ctrl, res, episodes=episodes)
    return AnalyticStudy(
        observation=policy.observation,
        standard_mean_deg=s.mean_final_angle_deg,
        standard_p95_deg=s.p95_final_angle_deg,
        resistance_mean_deg=r.mean_final_angle_deg,
        resistance_p95_deg=r.p95_final_angle_deg,
        probe=pure_resistance_probe(policy),
    )
