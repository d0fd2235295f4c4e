"""Runtime policy API: loading, numpy-only inference, input validation, the shipped policy's bar."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from constraint_aware.errors import InvalidInputError, PolicyFileError
from constraint_aware.geometry import angle_deg
from constraint_aware.policy import ConstraintAwarePolicy, shipped_policy_path
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.evaluate import evaluate

POLICY = ConstraintAwarePolicy.load()
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


def test_shipped_policy_files_and_card() -> None:
    path = shipped_policy_path()
    assert path.is_file() and path.with_suffix(".json").is_file()
    card = json.loads(path.with_suffix(".json").read_text())
    for key in ("observation_layout", "env_config", "train_config", "seed", "metrics", "versions"):
        assert key in card
    with np.load(path, allow_pickle=False) as data:  # no pickle needed to read it
        assert all(data[k].dtype == np.float32 for k in data.files)


def test_shipped_policy_meets_its_bar() -> None:
    """Fixed-seed standard evaluation: mean final angle <= 2.5 deg (issue 2)."""
    config = EnvConfig.from_dict(POLICY.card["env_config"])
    result = evaluate(lambda obs, _f: POLICY.act_batch(obs), config, episodes=10_000, seed=99)
    assert result.mean_final_angle_deg <= 2.5
    noop = evaluate(lambda obs, _f: np.zeros((obs.shape[0], 3)), config, 10_000, seed=99)
    assert result.mean_final_angle_deg < noop.mean_final_angle_deg / 5


def test_update_direction_turns_toward_the_guide() -> None:
    u = np.array([1.0, 0.0, 0.0])
    d = np.array([np.cos(0.5), np.sin(0.5), 0.0])  # 28.6 deg off
    force = np.array([0.0, -10.0, 0.0])  # the guide pushes back across the axis
    new = POLICY.update_direction(force, d)
    assert angle_deg(new, u) < 0.5 * angle_deg(d, u)
    assert np.linalg.norm(new) == pytest.approx(1.0)


def test_force_offset_is_subtracted() -> None:
    d = np.array([1.0, 0.0, 0.0])
    weight = np.array([0.0, 0.0, -9.0])
    # the hand's own weight recorded as F_d: nothing left, direction unchanged
    np.testing.assert_array_equal(POLICY.update_direction(weight, d, force_offset=weight), d)


@pytest.mark.parametrize("force", [np.zeros(3), np.array([0.05, 0.0, 0.0])])
def test_zero_or_small_force_keeps_direction(force: np.ndarray) -> None:
    d = np.array([0.0, 0.6, 0.8])
    np.testing.assert_array_equal(POLICY.update_direction(force, d, threshold=0.2), d)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("arg", ["force", "direction", "force_offset"])
def test_non_finite_input_names_the_argument(arg: str, bad: float) -> None:
    kwargs: dict[str, np.ndarray] = {
        "force": np.array([1.0, 0.0, 0.0]),
        "direction": np.array([0.0, 1.0, 0.0]),
        "force_offset": np.zeros(3),
    }
    kwargs[arg] = np.array([bad, 0.0, 0.0])
    with pytest.raises(ValueError, match=arg):
        POLICY.update_direction(kwargs["force"], kwargs["direction"], kwargs["force_offset"])


@given(arrays(np.float64, st.integers(0, 6), elements=finite))
def test_wrong_shape_raises_value_error(v: np.ndarray) -> None:
    if v.shape == (3,):
        return
    with pytest.raises(InvalidInputError, match="force_unit"):
        POLICY.act(v, np.array([1.0, 0.0, 0.0]))


@settings(max_examples=300)
@given(arrays(np.float64, 3, elements=finite), arrays(np.float64, 3, elements=finite))
def test_update_direction_never_returns_nan(force: np.ndarray, direction: np.ndarray) -> None:
    if np.linalg.norm(direction) < 1e-9:
        with pytest.raises(InvalidInputError, match="direction"):
            POLICY.update_direction(force, direction)
        return
    new = POLICY.update_direction(force, direction)
    assert np.all(np.isfinite(new))
    assert np.linalg.norm(new) == pytest.approx(1.0)


def test_action_that_cancels_direction_does_not_give_nan() -> None:
    # a policy whose action is exactly -d: |d + a| = 0, the rule keeps d
    w = np.zeros((3, 6))
    w[:, 3:] = -np.eye(3)
    policy = ConstraintAwarePolicy([(w, np.zeros(3))], {"env_config": {"threshold": 0.0}})
    d = np.array([0.6, 0.0, 0.8])
    np.testing.assert_array_equal(policy.update_direction(np.array([1.0, 0, 0]), d), d)


def test_save_load_roundtrip(tmp_path: Path) -> None:
    path = POLICY.save(tmp_path / "copy.npz")
    again = ConstraintAwarePolicy.load(path)
    obs = np.random.default_rng(0).normal(size=(50, 6))
    np.testing.assert_allclose(again.act_batch(obs), POLICY.act_batch(obs), atol=1e-12)


def test_missing_or_broken_files(tmp_path: Path) -> None:
    with pytest.raises(PolicyFileError, match="not found"):
        ConstraintAwarePolicy.load(tmp_path / "nope.npz")
    path = POLICY.save(tmp_path / "p.npz")
    path.with_suffix(".json").write_text("{not json")
    with pytest.raises(PolicyFileError, match="JSON"):
        ConstraintAwarePolicy.load(path)


def test_runtime_does_not_import_torch() -> None:
    code = (
        "import sys, numpy as np\n"
        "from constraint_aware import ConstraintAwarePolicy\n"
        "p = ConstraintAwarePolicy.load()\n"
        "p.update_direction(np.array([0., -5., 0.]), np.array([1., 0., 0.]))\n"
        "assert 'torch' not in sys.modules, 'torch imported'\n"
        "assert 'stable_baselines3' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_matches_stable_baselines3_deterministic_action(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    pytest.importorskip("stable_baselines3")
    from constraint_aware.training.ppo import build_model, export_policy, make_config
    from constraint_aware.training.vec_env import BatchedSingleSystemVecEnv

    config = make_config("fast", n_envs=8, batch_size=40, seed=3)
    model = build_model(BatchedSingleSystemVecEnv(8), config)
    # give the untrained net outputs beyond [-1, 1] so clipping is covered too
    with torch.no_grad():
        head = model.policy.action_net
        assert isinstance(head, torch.nn.Linear)
        head.weight.mul_(500.0)
    policy = ConstraintAwarePolicy.load(export_policy(model, {}).save(tmp_path / "sb3.npz"))
    obs = np.random.default_rng(1).normal(size=(500, 6)).astype(np.float32)
    expected, _ = model.predict(obs, deterministic=True)
    assert np.abs(expected).max() == pytest.approx(1.0)
    np.testing.assert_allclose(policy.act_batch(obs.astype(np.float64)), expected, atol=1e-5)
