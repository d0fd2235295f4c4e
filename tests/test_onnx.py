"""ONNX export: the graph reproduces act_batch, carries the card, and needs no torch."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from constraint_aware import policy as policy_module
from constraint_aware.errors import InvalidInputError, PolicyFileError
from constraint_aware.export.onnx import (
    INPUT_NAME,
    OUTPUT_NAME,
    build_onnx_model,
    export_onnx,
    onnx_parity,
    random_observations,
    read_onnx_metadata,
)
from constraint_aware.policy import OBSERVATION_LAYOUT, ConstraintAwarePolicy

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def policy() -> ConstraintAwarePolicy:
    return ConstraintAwarePolicy.load()


@pytest.fixture(scope="module")
def model_path(policy: ConstraintAwarePolicy, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return export_onnx(policy, tmp_path_factory.mktemp("onnx") / "policy.onnx")


def test_parity_on_10000_random_observations(
    policy: ConstraintAwarePolicy, model_path: Path
) -> None:
    assert onnx_parity(policy, model_path, n_observations=10_000, seed=0) <= 1e-5


def test_dynamic_batch_and_clip(policy: ConstraintAwarePolicy, model_path: Path) -> None:
    session = ort.InferenceSession(str(model_path), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(3)
    n_obs = policy.layers[0][0].shape[1]
    for n in (1, 7, 256):
        obs = rng.normal(scale=50.0, size=(n, n_obs)).astype(np.float32)  # far out: clipped
        (action,) = session.run([OUTPUT_NAME], {INPUT_NAME: obs})
        assert action.shape == (n, 3)
        assert action.dtype == np.float32
        assert np.all(np.abs(action) <= 1.0)
        np.testing.assert_allclose(action, policy.act_batch(obs.astype(np.float64)), atol=1e-5)


def test_float32_graph_of_matmul_add_tanh_clip(policy: ConstraintAwarePolicy) -> None:
    model = build_onnx_model(policy)
    ops = [node.op_type for node in model.graph.node]
    n_layers = len(policy.layers)
    assert ops.count("MatMul") == ops.count("Add") == n_layers
    assert ops.count("Tanh") == n_layers - 1
    assert ops[-1] == "Clip"
    assert all(t.data_type == onnx.TensorProto.FLOAT for t in model.graph.initializer)
    (inp,) = model.graph.input
    assert inp.name == INPUT_NAME
    dims = inp.type.tensor_type.shape.dim
    assert dims[0].dim_param == "batch"
    assert (
        dims[1].dim_value == policy.layers[0][0].shape[1] == len(policy.card["observation_layout"])
    )


def test_metadata_carries_the_card(policy: ConstraintAwarePolicy, model_path: Path) -> None:
    meta = read_onnx_metadata(model_path)
    assert meta["observation_layout"] == list(policy.card["observation_layout"])
    assert meta["action_scale"] == policy.action_scale
    assert meta["threshold_N"] == policy.threshold
    assert meta["deadband"]["min_threshold_N"] > 0
    assert meta["policy_name"]
    assert meta["card"]["env_config"] == policy.card["env_config"]


def test_layout_must_match_the_weights(policy: ConstraintAwarePolicy, tmp_path: Path) -> None:
    with pytest.raises(PolicyFileError, match="observation_layout"):  # here or at with_card
        bad_card = dict(policy.card, observation_layout=list(OBSERVATION_LAYOUT[:5]))
        export_onnx(policy.with_card(bad_card), tmp_path / "bad.onnx")
    with pytest.raises(InvalidInputError, match="path"):
        export_onnx(policy, tmp_path / "policy.pb")


def test_input_size_comes_from_the_weights(tmp_path: Path) -> None:
    """A policy with more than 6 inputs (history, extra features) exports with its own size."""
    rng = np.random.default_rng(0)
    # This version's named observations wider than 6, if it has any; else a plausible one.
    wide = [list(x) for x in getattr(policy_module, "OBSERVATIONS", {}).values() if len(x) > 6]
    layout = (
        wide[0] if wide else [*OBSERVATION_LAYOUT, *(f"previous_{n}" for n in OBSERVATION_LAYOUT)]
    )
    layers = [
        (rng.normal(size=(16, len(layout))), rng.normal(size=16)),
        (rng.normal(size=(3, 16)), rng.normal(size=3)),
    ]
    try:
        wide_policy = ConstraintAwarePolicy(layers, {"observation_layout": layout})
    except PolicyFileError as exc:
        pytest.skip(f"this version's policy class takes 6 inputs only ({exc})")
    path = export_onnx(wide_policy, tmp_path / "wide.onnx")
    assert read_onnx_metadata(path)["observation_layout"] == layout
    obs = random_observations(layout, 1000, rng)
    assert obs.shape == (1000, len(layout))
    assert onnx_parity(wide_policy, path, n_observations=1000) <= 1e-5


def test_export_does_not_import_torch(tmp_path: Path) -> None:
    out = tmp_path / "p.onnx"
    code = (
        "import sys\n"
        "from constraint_aware.policy import ConstraintAwarePolicy\n"
        "from constraint_aware.export.onnx import export_onnx\n"
        f"export_onnx(ConstraintAwarePolicy.load(), {str(out)!r})\n"
        "assert 'torch' not in sys.modules, 'torch imported'\n"
        "assert 'stable_baselines3' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
    assert out.stat().st_size > 0
