"""The training environment's physics and update rule against hand-derived ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from constraint_aware.geometry import (
    angle_deg,
    normalize_force,
    random_perpendicular,
    random_unit,
    rotate_about,
    update_direction_rule,
)
from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.physics import analytic_constraint_force

X = np.array([[1.0, 0.0, 0.0]])
Y = np.array([[0.0, 1.0, 0.0]])


def _dir(deg: float) -> np.ndarray:
    t = np.radians(deg)
    return np.array([[np.cos(t), np.sin(t), 0.0]])


def test_frictionless_force_is_the_push_across_the_guide() -> None:
    k, step = 2000.0, 0.01
    f = analytic_constraint_force(X, _dir(30.0), np.zeros(1), np.array([k]), step)
    # guide answers the spring's perpendicular component, nothing along the axis
    np.testing.assert_allclose(f[0], [0.0, -k * step * 0.5, 0.0], atol=1e-12)


@pytest.mark.parametrize("mu", [0.05, 0.1, 0.15])
@pytest.mark.parametrize("deg", [-40.0, -10.0, 5.0, 30.0])
def test_sliding_friction_tilts_force_by_atan_mu(mu: float, deg: float) -> None:
    k, step = 1500.0, 0.01
    f = analytic_constraint_force(X, _dir(deg), np.array([mu]), np.array([k]), step)[0]
    push = k * step * abs(np.sin(np.radians(deg)))
    # magnitude: normal force with Coulomb friction on top
    assert np.linalg.norm(f) == pytest.approx(push * np.hypot(1.0, mu), rel=1e-12)
    # friction opposes the motion (+x) and scales with the normal force
    assert f[0] == pytest.approx(-mu * push, rel=1e-12)
    tilt = angle_deg(f, np.array([0.0, -np.sign(deg), 0.0]))
    assert tilt == pytest.approx(np.degrees(np.arctan(mu)), abs=1e-9)


def test_friction_is_coulomb_not_constant() -> None:
    """A 45 deg and a 0.5 deg offset must give different force directions relative to d."""
    mu, k = np.array([0.1]), np.array([2000.0])
    obs = []
    for deg in (45.0, 0.5):
        f = analytic_constraint_force(X, _dir(deg), mu, k, 0.01)
        obs.append(float(angle_deg(f[0], _dir(deg)[0])))
    assert abs(obs[0] - obs[1]) > 40.0


def test_stuck_body_receives_the_whole_spring_force() -> None:
    # tan(85 deg) > 1/mu: friction holds the body, the guide returns the full spring force
    d = _dir(85.0)
    f = analytic_constraint_force(X, d, np.array([0.2]), np.array([1000.0]), 0.01)
    np.testing.assert_allclose(f, -1000.0 * 0.01 * d, atol=1e-12)


def test_threshold_maps_small_forces_to_zero() -> None:
    f = np.array([[0.1, 0.0, 0.0], [0.0, 3.0, 4.0]])
    out = normalize_force(f, threshold=0.2)
    np.testing.assert_array_equal(out[0], 0.0)
    np.testing.assert_allclose(out[1], [0.0, 0.6, 0.8])


def test_update_rule_and_guard() -> None:
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    a = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    out = update_direction_rule(d, a)
    np.testing.assert_allclose(out[0], np.array([1.0, 1.0, 0.0]) / np.sqrt(2))
    np.testing.assert_array_equal(out[1], d[1])  # |d + a| = 0: keep d, never NaN


def test_projection_action_is_exact_without_friction(rng: np.random.Generator) -> None:
    n = 1000
    u = random_unit(rng, n)
    d = rotate_about(u, random_perpendicular(rng, u), rng.uniform(-1.2, 1.2, n))
    f = analytic_constraint_force(u, d, np.zeros(n), np.full(n, 2000.0), 0.01)
    f_hat = normalize_force(f, 1e-9)
    new = update_direction_rule(d, -np.sum(d * f_hat, axis=1, keepdims=True) * f_hat)
    assert np.max(angle_deg(new, u)) < 1e-6


def test_episode_structure_reward_and_offsets(rng: np.random.Generator) -> None:
    cfg = EnvConfig()
    env = SingleSystemBatch(2000, cfg)
    env.reset(rng)
    start = env.angle_to_axis_deg()
    assert start.max() <= 45.0 + 1e-9 and start.min() >= 0.0
    assert np.all(env.params.offset_deg < 0) is np.False_  # both signs drawn
    # d0 lies in the workplane with u
    assert np.max(np.abs(np.sum(env.direction * env.params.workplane_normal, axis=1))) < 1e-12
    done, steps = False, 0
    while not done:
        _, reward, done = env.step(np.zeros((2000, 3)))
        steps += 1
        expected = -np.sin(np.radians(start)) * np.hypot(1.0, env.params.friction)
        np.testing.assert_allclose(reward, expected, atol=1e-9)
    assert steps == cfg.episode_length


def test_observation_noise_only_at_first_step(rng: np.random.Generator) -> None:
    env = SingleSystemBatch(500, EnvConfig())
    obs0 = env.reset(rng)
    np.testing.assert_allclose(np.linalg.norm(obs0[:, 3:], axis=1), 1.0)
    assert np.max(angle_deg(obs0[:, 3:], env.direction)) > 1.0  # noisy direction
    obs1, _, _ = env.step(np.zeros((500, 3)))
    np.testing.assert_allclose(obs1[:, 3:], env.direction)  # clean afterwards
    measured = env.params.force_gain[:, None] * env.force
    np.testing.assert_allclose(obs1[:, :3], normalize_force(measured, 0.2))


def test_horizontal_workplane_keeps_everything_horizontal(rng: np.random.Generator) -> None:
    env = SingleSystemBatch(100, EnvConfig(workplane="horizontal"))
    env.reset(rng)
    assert np.max(np.abs(env.params.axis[:, 2])) < 1e-12
    assert np.max(np.abs(env.direction[:, 2])) < 1e-12
