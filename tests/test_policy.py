"""Runtime policy API: loading, numpy-only inference, input validation, the shipped policy's bar."""

from __future__ import annotations

import copy
import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from constraint_aware import deadband
from constraint_aware.errors import InvalidInputError, PolicyFileError, UnknownNameError
from constraint_aware.geometry import angle_deg
from constraint_aware.policy import (
    POLICY_NAMES,
    ConstraintAwarePolicy,
    shipped_policy_path,
)
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.evaluate import evaluate

POLICY = ConstraintAwarePolicy.load()
PAPER = ConstraintAwarePolicy.load("paper")
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
#: sha256 of the paper's policy weights (the reproduction of the paper, kept unchanged)
PAPER_SHA256 = "11abcd690b1206989531edfee1c7b33886bd90ae484d41ba79195332c83b0418"


@pytest.mark.parametrize("name", POLICY_NAMES)
def test_shipped_policy_files_and_card(name: str) -> None:
    path = shipped_policy_path(name)
    assert path.is_file() and path.with_suffix(".json").is_file()
    card = json.loads(path.with_suffix(".json").read_text())
    for key in ("observation_layout", "env_config", "train_config", "seed", "metrics", "versions"):
        assert key in card
    assert card["name"] == name and "force" in card["inputs"]
    with np.load(path, allow_pickle=False) as data:  # no pickle needed to read it
        assert all(data[k].dtype == np.float32 for k in data.files)


def test_names_and_the_default() -> None:
    assert POLICY_NAMES == ("default", "paper")
    assert POLICY.name == "default" and PAPER.name == "paper"
    assert PAPER.observation == "paper"
    assert ConstraintAwarePolicy.load(shipped_policy_path("paper")).name == "paper"
    with pytest.raises(UnknownNameError, match="default, paper"):
        ConstraintAwarePolicy.load("papr")


def test_paper_weights_are_unchanged() -> None:
    import hashlib

    digest = hashlib.sha256(shipped_policy_path("paper").read_bytes()).hexdigest()
    assert digest == PAPER_SHA256


@pytest.mark.parametrize(
    "policy",
    [
        POLICY,
        PAPER,
    ],
    ids=["default", "paper"],
)
def test_shipped_policy_meets_its_bar(policy: ConstraintAwarePolicy) -> None:
    """Fixed-seed standard evaluation (no resistance): mean final angle <= 2.2 deg (the bar for a
    policy trained with the object's resistance: it must still solve the paper's environment)."""
    config = EnvConfig(observation=policy.observation)
    result = evaluate(lambda obs, _f: policy.act_batch(obs), config, episodes=10_000, seed=99)
    assert result.mean_final_angle_deg <= 2.2
    noop = evaluate(lambda obs, _f: np.zeros((obs.shape[0], 3)), config, 10_000, seed=99)
    assert result.mean_final_angle_deg < noop.mean_final_angle_deg / 5


def test_default_keeps_d_under_pure_resistance() -> None:
    """F = -m d (the joint resists, d already right): d turns < 3 deg with the defaults, for
    any m from the dead band floor to 20 N; the paper's policy turns it far."""
    from constraint_aware.training.study import pure_resistance_probe

    probe = pure_resistance_probe(POLICY, step_force=20.0)
    assert probe.worst_deg < 3.0  # the call's defaults: no step force
    if probe.max_turn_with_step_force_deg is not None:
        # told k*delta = 20 N, a resistance within the training's range (<= 0.4 k*delta) is
        # kept; a force near the full step force means blocked, which it may correct
        within = [
            t
            for m, t in zip(probe.magnitudes_N, probe.max_turn_with_step_force_deg, strict=True)
            if m <= 0.4 * 20.0
        ]
        assert max(within) < 3.0
    assert pure_resistance_probe(PAPER).worst_deg > 30.0


def test_default_dead_band_is_deadband_floor() -> None:
    assert POLICY.threshold == PAPER.threshold == deadband.MIN_THRESHOLD
    assert POLICY.card["dead_band"]["floor_N"] == deadband.MIN_THRESHOLD


def test_session_reset_forgets_history() -> None:
    session = POLICY.session()
    d = np.array([1.0, 0.0, 0.0])
    f = np.array([-2.0, -6.0, 0.0])
    first = session.update_direction(f, d, step_force=20.0)
    session.update_direction(f, first, step_force=20.0)
    session.reset()
    np.testing.assert_array_equal(session.update_direction(f, d, step_force=20.0), first)


def test_update_direction_turns_toward_the_guide() -> None:
    u = np.array([1.0, 0.0, 0.0])
    d = np.array([np.cos(0.5), np.sin(0.5), 0.0])  # 28.6 deg off
    force = np.array([0.0, -10.0, 0.0])  # the guide pushes back across the axis
    for new in (
        POLICY.session().update_direction(force, d, step_force=20.0),  # k*delta from the robot
        PAPER.update_direction(force, d),
    ):
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
    obs = np.random.default_rng(0).normal(size=(50, len(POLICY.observation_layout)))
    np.testing.assert_allclose(again.act_batch(obs), POLICY.act_batch(obs), atol=1e-12)


def test_missing_or_broken_files(tmp_path: Path) -> None:
    with pytest.raises(PolicyFileError, match="not found"):
        ConstraintAwarePolicy.load(tmp_path / "nope.npz")
    path = POLICY.save(tmp_path / "p.npz")
    path.with_suffix(".json").write_text("{not json")
    with pytest.raises(PolicyFileError, match="JSON"):
        ConstraintAwarePolicy.load(path)


def _copy(tmp_path: Path, policy: ConstraintAwarePolicy = PAPER) -> Path:
    return policy.save(tmp_path / "p.npz")


def _rewrite_weights(path: Path, **arrays: np.ndarray) -> None:
    with np.load(path) as data:
        current = {k: data[k] for k in data.files}
    current.update(arrays)
    np.savez(path, **current)


@pytest.mark.parametrize("cut", [0, 100, -100])
def test_truncated_or_empty_npz(tmp_path: Path, cut: int) -> None:
    path = _copy(tmp_path)
    data = path.read_bytes()
    path.write_bytes(data[:cut])
    with pytest.raises(PolicyFileError, match=r"p\.npz"):
        ConstraintAwarePolicy.load(path)


def test_card_not_utf8(tmp_path: Path) -> None:
    path = _copy(tmp_path)
    path.with_suffix(".json").write_bytes(b'{"format": "\xff\xfe"}')
    with pytest.raises(PolicyFileError, match=r"p\.json: not UTF-8"):
        ConstraintAwarePolicy.load(path)


def test_card_nested_too_deeply(tmp_path: Path) -> None:
    path = _copy(tmp_path)
    path.with_suffix(".json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(PolicyFileError, match=r"p\.json"):
        ConstraintAwarePolicy.load(path)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("w0", np.full((256, 6), np.nan, dtype=np.float32), "'w0' contains NaN"),
        ("b1", np.full(256, np.inf, dtype=np.float32), "'b1' contains NaN or inf"),
        ("w2", np.ones((3, 256), dtype=np.int64), "'w2' has dtype int64"),
        ("w0", np.zeros((256, 7), dtype=np.float32), "'w0' has shape"),
        ("w2", np.zeros((4, 256), dtype=np.float32), "'w2' has shape"),
        ("b0", np.zeros(255, dtype=np.float32), "'b0' has shape"),
    ],
)
def test_bad_weights_name_the_field(
    tmp_path: Path, field: str, value: np.ndarray, message: str
) -> None:
    path = _copy(tmp_path)
    _rewrite_weights(path, **{field: value})
    with pytest.raises(PolicyFileError, match=message) as info:
        ConstraintAwarePolicy.load(path)
    assert "p.npz" in str(info.value)


def test_missing_layer_names_the_field(tmp_path: Path) -> None:
    path = _copy(tmp_path)
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k != "b2"}
    np.savez(path, **arrays)
    with pytest.raises(PolicyFileError, match="'b2' missing"):
        ConstraintAwarePolicy.load(path)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        ({"env_config": {"action_scale": float("nan")}}, "env_config.action_scale"),
        ({"env_config": {"action_scale": -1.0}}, "env_config.action_scale"),
        ({"n_layers": 2.5}, "n_layers"),
        ({"n_layers": 10_000}, "n_layers"),
        ({"format": "other/1"}, "format"),
        ({"observation_layout": ["force_unit_x"]}, "observation_layout"),
    ],
)
def test_bad_card_fields_are_named(tmp_path: Path, edit: dict[str, object], field: str) -> None:
    path = _copy(tmp_path)
    card = json.loads(path.with_suffix(".json").read_text())
    card.update(edit)
    path.with_suffix(".json").write_text(json.dumps(card))  # NaN is written as the JSON NaN
    with pytest.raises(PolicyFileError, match=field) as info:
        ConstraintAwarePolicy.load(path)
    assert "p.json" in str(info.value)


def test_card_layout_must_match_weights(tmp_path: Path) -> None:
    path = _copy(tmp_path)  # the paper's 6-input weights
    card = json.loads(path.with_suffix(".json").read_text())
    card["observation_layout"] = list(POLICY.observation_layout) + ["x"] * 0
    if len(card["observation_layout"]) == 6:
        pytest.skip("the default policy has the paper's layout")
    path.with_suffix(".json").write_text(json.dumps(card))
    with pytest.raises(PolicyFileError, match="'w0' has shape"):
        ConstraintAwarePolicy.load(path)


def test_runtime_does_not_import_torch() -> None:
    code = (
        "import sys, numpy as np\n"
        "from constraint_aware import ConstraintAwarePolicy\n"
        "p = ConstraintAwarePolicy.load()\n"
        "p.update_direction(np.array([0., -5., 0.]), np.array([1., 0., 0.]))\n"
        "ConstraintAwarePolicy.load('paper').session().update_direction([0, -5, 0], [1, 0, 0])\n"
        "assert 'torch' not in sys.modules, 'torch imported'\n"
        "assert 'stable_baselines3' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_matches_stable_baselines3_deterministic_action(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym

    from constraint_aware.training.ppo import build_model, export_policy
    from constraint_aware.training.train_config import make_config
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
    actual = policy.act_batch(obs.astype(np.float64))
    # the export itself: SB3's own modules run in float64 agree to rounding
    net = copy.deepcopy(model.policy).double()
    with torch.no_grad():
        latent = net.mlp_extractor.forward_actor(torch.as_tensor(obs, dtype=torch.float64))
        mean = net.action_net(latent).numpy()
    space = model.action_space
    assert isinstance(space, gym.spaces.Box)
    reference = np.clip(mean, space.low, space.high).astype(np.float64)
    np.testing.assert_allclose(actual, reference, rtol=0, atol=1e-9)
    # SB3's predict (its preprocessing and clipping) runs in float32: the 500x head amplifies
    # its rounding (measured up to 1.2e-4 when torch sums a batch above 250 rows another way)
    expected, _ = model.predict(obs, deterministic=True)
    assert np.abs(expected).max() == pytest.approx(1.0)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-3)


def test_default_opens_a_stiff_door_with_the_derived_dead_band() -> None:
    """The door with 8x hinge friction at the dead band derived from the simulated
    sensor's noise (0.1 N): the default policy succeeds, the paper's policy does not."""
    from constraint_aware.control.simulate import RunSpec, run

    spec = RunSpec(
        "door-opening", offset_deg=15.0, seed=0, overrides=(("object__frictionloss", 4.0),)
    )
    threshold = deadband.threshold_from_noise(spec.sensor_noise)
    record, _ = run(spec, executor_overrides={"threshold": threshold})
    assert record.success, record.reason
    # the paper's policy as published: its rule alone (controller "policy-raw")
    raw = dataclasses.replace(spec, controller="policy-raw")
    paper, _ = run(raw, policy=PAPER, executor_overrides={"threshold": threshold})
    assert not paper.success


def test_policy_controller_resets_its_session_each_run() -> None:
    from constraint_aware.control.controllers import ControlInput, PolicyController

    ctrl = PolicyController()
    d = np.array([1.0, 0.0, 0.0])
    inp = ControlInput(np.array([-2.0, -6.0, 0.0]), np.zeros(3), d, 0.1, 0.4, None, 20.0)
    ctrl.reset(d)
    first = ctrl.next_direction(inp)
    ctrl.next_direction(inp)
    ctrl.reset(d)
    np.testing.assert_array_equal(ctrl.next_direction(inp), first)


# --- mirror-symmetric action (policy.mirror_average) ---------------------------------------
N_UP = np.array([0.0, 0.0, 1.0])
MIRROR_Y = np.diag([1.0, -1.0, 1.0])  # reflection through the plane of d = x and n = z


def _random_policy(observation: str, seed: int = 0) -> ConstraintAwarePolicy:
    from constraint_aware.policy import OBSERVATIONS

    layout = list(OBSERVATIONS[observation])
    rng = np.random.default_rng(seed)
    layers = [(rng.normal(size=(16, len(layout))), rng.normal(size=16))]
    layers.append((rng.normal(size=(3, 16)), rng.normal(size=3)))
    return ConstraintAwarePolicy(layers, {"observation_layout": layout})


@pytest.mark.parametrize("magnitude", [0.3, 5.0, 15.0, 19.9])
def test_mirrored_action_keeps_d_exactly_under_pure_resistance(magnitude: float) -> None:
    """By symmetry, a force straight against d below the step force gives no side to turn
    to: zero turn in the workplane, where the network alone turns (the default by up to
    7 deg, to a side of its choosing)."""
    d = np.array([1.0, 0.0, 0.0])
    for policy in (POLICY, PAPER, _random_policy("magnitude_flag")):
        new = policy.session().update_direction(
            -magnitude * d, d, step_force=20.0, workplane_normal=N_UP
        )
        assert abs(float(new[1])) < 1e-12  # no in-plane turn at all
    plain = POLICY.session().update_direction(-19.9 * d, d, step_force=20.0)
    assert abs(float(plain[1])) > 0.05  # the bias the mirror removes is real (7 deg)


@pytest.mark.parametrize("magnitude", [20.0, 35.0])
def test_a_blocked_step_keeps_the_networks_choice_of_side(magnitude: float) -> None:
    """|F| >= k*delta: the step was blocked and F ~ -d whatever the error, so the reading has
    no side; a symmetric action would push straight on (the door at radius 0.06 m then hit
    the force limit). The network's own action is used, as without the normal or k*delta."""
    d = np.array([1.0, 0.0, 0.0])
    f = -magnitude * d + np.array([0.0, 0.3, 0.0])
    mirrored = POLICY.session().update_direction(f, d, step_force=20.0, workplane_normal=N_UP)
    plain = POLICY.session().update_direction(f, d, step_force=20.0)
    np.testing.assert_array_equal(mirrored, plain)
    no_step_force = POLICY.session().update_direction(f, d, workplane_normal=N_UP)
    np.testing.assert_array_equal(no_step_force, POLICY.session().update_direction(f, d))


@pytest.mark.parametrize("observation", ["paper", "history", "magnitude_flag"])
def test_mirrored_action_is_equivariant(observation: str) -> None:
    """update(M F) = M update(F) for the reflection M that keeps d and n: a misalignment of
    +theta and of -theta get mirror-image corrections (also through a history session)."""
    policy = _random_policy(observation, seed=3)
    rng = np.random.default_rng(1)
    d = np.array([1.0, 0.0, 0.0])  # M keeps it; history sessions see mirrored pasts too
    a, b = policy.session(), policy.session()
    for _ in range(4):
        f = rng.normal(size=3) * 5.0
        new = a.update_direction(f, d, step_force=20.0, workplane_normal=N_UP)
        mirrored = b.update_direction(MIRROR_Y @ f, d, step_force=20.0, workplane_normal=N_UP)
        np.testing.assert_allclose(mirrored, MIRROR_Y @ new, atol=1e-12)
        plain = policy.session().update_direction(f, d, step_force=20.0)
        plain_m = policy.session().update_direction(MIRROR_Y @ f, d, step_force=20.0)
        assert not np.allclose(plain_m, MIRROR_Y @ plain, atol=1e-6)  # the network alone is not


def test_mirrored_action_corrects_a_misalignment_like_the_plain_one() -> None:
    """Away from pure resistance the mirror average changes little: the guide's push still
    turns d most of the way back (the plain policy's case above)."""
    u = np.array([1.0, 0.0, 0.0])
    d = np.array([np.cos(0.5), np.sin(0.5), 0.0])
    force = np.array([0.0, -10.0, 0.0])
    new = POLICY.session().update_direction(force, d, step_force=20.0, workplane_normal=N_UP)
    assert angle_deg(new, u) < 0.5 * angle_deg(d, u)


def test_workplane_normal_is_validated_by_name() -> None:
    with pytest.raises(InvalidInputError, match="workplane_normal"):
        POLICY.session().update_direction(
            [0.0, -5.0, 0.0], [1.0, 0.0, 0.0], workplane_normal=[np.nan, 0.0, 1.0]
        )
