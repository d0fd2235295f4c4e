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
from constraint_aware.training.batch import SingleSystemBatch, observation_space
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


# --- the object's own resistance along the joint -------------------------------------------------
def test_dry_resistance_limits_the_force_along_the_axis() -> None:
    k, step, r0 = 2000.0, 0.01, 4.0
    # aligned: no push across the guide, the spring's remaining stretch balances R0
    f = analytic_constraint_force(X, X, np.zeros(1), np.array([k]), step, np.array([r0]))
    np.testing.assert_allclose(f[0], [-r0, 0.0, 0.0], atol=1e-12)
    # with Coulomb friction on top, the limit is mu*|p| + R0
    mu, deg = 0.1, 20.0
    f = analytic_constraint_force(X, _dir(deg), np.array([mu]), np.array([k]), step, np.array([r0]))
    push = k * step * np.sin(np.radians(deg))
    assert f[0, 0] == pytest.approx(-(mu * push + r0), rel=1e-12)
    assert f[0, 1] == pytest.approx(-push, rel=1e-12)


def test_resistance_above_the_drive_holds_the_body() -> None:
    k, step = 1000.0, 0.01
    d = _dir(30.0)
    f = analytic_constraint_force(X, d, np.zeros(1), np.array([k]), step, np.array([9.0]))
    np.testing.assert_allclose(f, -k * step * d, atol=1e-12)  # 8.66 N drive < 9 N: stuck


def _resisting_env(rng: np.random.Generator, n: int = 2000, **over: object) -> SingleSystemBatch:
    from constraint_aware.training.config import resistance_config

    env = SingleSystemBatch(n, resistance_config(**over))  # type: ignore[arg-type]
    env.reset(rng)
    return env


def test_resistance_draws_follow_their_documented_ranges(rng: np.random.Generator) -> None:
    from constraint_aware.training.config import RESISTANCE

    env = _resisting_env(rng, 20_000)
    p, c = env.params, env.config
    step_force = p.stiffness * c.step_length
    v_nom = c.step_length / c.control_period
    free = (p.dry_friction == 0) & (p.damping == 0) & (p.mass == 0)
    assert abs(free.mean() - RESISTANCE["resistance_free_share"]) < 0.02
    hi = RESISTANCE["dry_friction"][1]
    assert np.all(p.dry_friction <= hi * step_force + RESISTANCE["dry_friction_abs"][1] + 1e-9)
    assert np.all(p.damping * v_nom <= RESISTANCE["damping"][1] * step_force + 1e-9)
    a_nom = v_nom / c.control_period
    assert np.all(p.mass * a_nom <= RESISTANCE["inertia"][1] * step_force + 1e-9)
    preload = np.linalg.norm(p.preload, axis=1)
    assert np.all(preload <= RESISTANCE["preload"][1] * step_force + 1e-9)
    cone = angle_deg(p.preload[preload > 0], p.axis[preload > 0])
    assert np.max(cone) <= c.preload_cone_deg + 1e-9


def test_aligned_body_sees_its_resistance_and_no_excess_reward(rng: np.random.Generator) -> None:
    env = _resisting_env(rng, 500, offset_deg=(0.0, 0.0), friction=(0.0, 0.0))
    env.config = EnvConfig.from_dict({**env.config.to_dict(), "force_noise": 0.0})
    _, reward, _ = env.step(np.zeros((500, 3)))
    p = env.params
    # first step from rest: R0 + c v + m v / T; then steady: R0 + c v (no acceleration)
    v = env.config.step_length / env.config.control_period
    np.testing.assert_allclose(env.resistance, p.dry_friction + p.damping * v, atol=1e-9)
    np.testing.assert_allclose(env.force, -env.resistance[:, None] * p.axis, atol=1e-9)
    np.testing.assert_allclose(reward, 0.0, atol=1e-12)  # only the object's own resistance
    # the preload has been released (the body slid): the sensor shows -preload on top
    measured = env.measured_force()
    expected = p.force_gain[:, None] * env.force - p.preload
    np.testing.assert_allclose(measured, expected, atol=1e-12)


def test_excess_reward_equals_the_papers_without_resistance(rng: np.random.Generator) -> None:
    env = SingleSystemBatch(300, EnvConfig())
    env.reset(rng)
    _, reward, _ = env.step(rng.uniform(-0.3, 0.3, (300, 3)))
    scale = env.params.stiffness * env.config.step_length
    np.testing.assert_allclose(reward, -np.linalg.norm(env.force, axis=1) / scale, atol=1e-12)


def test_history_and_magnitude_observations(rng: np.random.Generator) -> None:
    from constraint_aware.policy import MAGNITUDE_CLIP, OBSERVATIONS

    env = SingleSystemBatch(200, EnvConfig(observation="history"))
    obs0 = env.reset(rng)
    assert obs0.shape == (200, len(OBSERVATIONS["history"]))
    np.testing.assert_array_equal(obs0[:, 6:], 0.0)  # no previous step at the start
    obs1, _, _ = env.step(np.zeros((200, 3)))
    np.testing.assert_array_equal(obs1[:, 6:], obs0[:, :6])
    env = SingleSystemBatch(200, EnvConfig(observation="magnitude"))
    obs = env.reset(rng)
    norm = np.linalg.norm(env.measured_force(), axis=1)
    ratio = norm / (env.params.stiffness * env.config.step_length)
    expected = np.where(norm >= env.config.threshold, np.minimum(ratio, MAGNITUDE_CLIP), 0.0)
    np.testing.assert_allclose(obs[:, 6], expected, atol=1e-12)
    unknown = SingleSystemBatch(
        2000, EnvConfig(observation="magnitude", step_force_unknown_share=0.25)
    )
    obs = unknown.reset(rng)
    assert 0.2 < np.mean(obs[:, 6] == 0.0) < 0.3


def test_magnitude_flag_tells_an_unknown_step_force_from_a_small_force(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """magnitude_flag: the ratio as in "magnitude", then 1 where the robot reports k*delta
    and 0 where not; the session builds the same observation (the flag from step_force)."""
    from constraint_aware.policy import MAGNITUDE_CLIP, OBSERVATIONS, ConstraintAwarePolicy

    config = EnvConfig(observation="magnitude_flag", step_force_unknown_share=0.25)
    env = SingleSystemBatch(2000, config)
    obs = env.reset(rng)
    assert obs.shape == (2000, len(OBSERVATIONS["magnitude_flag"])) == (2000, 8)
    known = env.params.step_force_known
    assert 0.2 < np.mean(known == 0.0) < 0.3
    np.testing.assert_array_equal(obs[:, 7], known)
    norm = np.linalg.norm(env.measured_force(), axis=1)
    ratio = np.minimum(norm / (env.params.stiffness * config.step_length), MAGNITUDE_CLIP)
    expected = np.where(norm >= config.threshold, ratio, 0.0) * known
    np.testing.assert_allclose(obs[:, 6], expected, atol=1e-12)
    space = observation_space(config)
    assert space.high[6] == MAGNITUDE_CLIP and space.high[7] == 1.0

    # the session: what the policy is fed, recorded through act_batch
    policy = ConstraintAwarePolicy.load("default")
    assert policy.observation == "magnitude_flag"
    seen: list[np.ndarray] = []
    act = policy.act_batch

    def recording(obs: np.ndarray) -> np.ndarray:
        seen.append(obs.copy())
        return act(obs)

    monkeypatch.setattr(policy, "act_batch", recording)
    d, force = np.array([1.0, 0.0, 0.0]), np.array([-0.8, 0.3, 0.0])
    policy.session().update_direction(force, d, threshold=0.4, step_force=20.0)
    policy.session().update_direction(force, d, threshold=0.4)
    np.testing.assert_allclose(seen[0][0, 6:], [float(np.linalg.norm(force)) / 20.0, 1.0])
    np.testing.assert_array_equal(seen[1][0, 6:], [0.0, 0.0])


def test_log_uniform_stiffness_spreads_over_decades() -> None:
    """k ~ log-uniform(500, 20,000): the median is the geometric mean (3162 N/m), and each
    decade gets its share (a uniform draw would put 97 % of episodes above 1000 N/m)."""
    config = EnvConfig(stiffness=(500.0, 20_000.0), stiffness_log_uniform=True)
    env = SingleSystemBatch(20_000, config)
    env.reset(np.random.default_rng(0))
    k = env.params.stiffness
    assert k.min() >= 500.0 and k.max() <= 20_000.0
    assert abs(np.median(k) / np.sqrt(500.0 * 20_000.0) - 1.0) < 0.05
    assert abs(np.mean(k < 1000.0) - np.log(2.0) / np.log(40.0)) < 0.02


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("episode_length", 0),
        ("offset_deg", (10.0, 5.0)),
        ("offset_deg", (0.0, 90.0)),
        ("stiffness", (0.0, 10.0)),
        ("dry_friction", (-0.1, 0.2)),
        ("damping", (0.0, float("nan"))),
        ("resistance_free_share", 1.5),
        ("threshold", -1.0),
        ("action_scale", float("nan")),
        ("control_period", 0.0),
        ("observation", "vision"),
        ("workplane", "tilted"),
    ],
)
def test_env_config_validation_names_the_field(field: str, value: object) -> None:
    from constraint_aware.errors import InvalidInputError

    with pytest.raises(InvalidInputError, match=f"EnvConfig.{field}"):
        EnvConfig(**{field: value})  # type: ignore[arg-type]
