"""The policy's MLP as an ONNX graph, built from its numpy weights with `onnx.helper`.

Real-time arm controllers are mostly C++ (ros2_control); ONNX Runtime runs this file there.
The graph is exactly `ConstraintAwarePolicy.act_batch`: MatMul + Add per layer, Tanh between
layers, a final Clip to [-1, 1]. Input `observation` (batch, n_obs) float32, n_obs and the
column order from the policy's card (`observation_layout`); output `action` (batch, 3) float32.
The direction update itself (dead band, d <- (d + s a)/|d + s a|) stays in the controller; the
numbers it needs (action scale, threshold, dead band rule) are in the model's metadata_props.

No torch: only `onnx` (and numpy) are imported, and only when a model is built.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from constraint_aware.deadband import MIN_THRESHOLD, NOISE_SIGMAS
from constraint_aware.errors import CapError, InvalidInputError, PolicyFileError, check_int
from constraint_aware.policy import OBSERVATION_LAYOUT, ConstraintAwarePolicy

if TYPE_CHECKING:
    import onnx as onnx_types

#: Names of the graph's input and output tensors.
INPUT_NAME = "observation"
OUTPUT_NAME = "action"
#: Format tag in metadata_props, bumped when the graph's contract changes.
ONNX_FORMAT = "constraint-aware-onnx/1"
#: ONNX operator set: 17 is read by every ONNX Runtime since 1.12 (2022), so older C++
#: controller builds load the file too.
OPSET = 17
#: IR version matching opset 17 (a newer IR would be refused by those older runtimes).
IR_VERSION = 8
#: The parity check compares at most this many observations: a million random rows already
#: cover the input space densely, and more only costs time.
MAX_PARITY_OBSERVATIONS = 1_000_000
#: Rows per evaluation chunk: the hidden activations of a chunk stay near 100 MB for the
#: widest shipped network (2 x 256) whatever the number of observations.
PARITY_CHUNK = 50_000


def _require_onnx() -> Any:
    try:
        import onnx
    except ImportError as exc:
        raise CapError(
            "ONNX export needs the 'onnx' package: pip install 'constraint-aware[onnx]'"
        ) from exc
    return onnx


def observation_layout(policy: ConstraintAwarePolicy) -> list[str]:
    """The policy's input columns: its card's `observation_layout`, checked against the weights.

    A card without a layout (a policy built in memory) gets this version's default layout when
    the input size matches it.
    """
    n_obs = int(policy.layers[0][0].shape[1])
    card_layout = policy.card.get("observation_layout")
    layout = [str(x) for x in card_layout] if card_layout else list(OBSERVATION_LAYOUT)
    if len(layout) != n_obs:
        raise PolicyFileError(
            f"observation_layout: the card lists {len(layout)} inputs but the first layer "
            f"takes {n_obs}"
        )
    return layout


def policy_metadata(policy: ConstraintAwarePolicy) -> dict[str, str]:
    """String key/values stored in the model's metadata_props (JSON where not a plain number)."""
    card = policy.card
    name = getattr(policy, "name", None) or card.get("name") or "policy"
    return {
        "format": ONNX_FORMAT,
        "policy_name": str(name),
        "observation_layout": json.dumps(observation_layout(policy)),
        # What the robot must supply each step beyond the graph's input (e.g. its step force
        # k*delta for a magnitude observation), where this version's policy says so.
        "inputs": json.dumps(list(getattr(policy, "inputs", ("force", "direction")))),
        "action_layout": json.dumps(["action_x", "action_y", "action_z"]),
        "action_scale": repr(float(policy.action_scale)),
        "direction_update": "d_next = (d + action_scale * action) / |d + action_scale * action|",
        # The policy's own dead band (its training threshold) and the executor's rule for the
        # dead band of a real sensor, from deadband.py (its one home).
        "threshold_N": repr(float(policy.threshold)),
        "deadband": json.dumps(
            {
                "rule": "max(min_threshold_N, noise_sigmas * per-axis std of the F_d samples)",
                "min_threshold_N": MIN_THRESHOLD,
                "noise_sigmas": NOISE_SIGMAS,
                "below": "force_unit observed as the zero vector; the direction is kept",
            }
        ),
        "units": json.dumps(card.get("units", {})),
        "card": json.dumps(_finite_or_null(card), allow_nan=False, default=str),
    }


def _finite_or_null(value: Any) -> Any:
    """`value` with NaN/inf floats as None, so the stored card is strict JSON."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_or_null(v) for v in value]
    return value


def build_onnx_model(policy: ConstraintAwarePolicy) -> onnx_types.ModelProto:
    """The checked float32 ONNX model of `policy` (dynamic batch dimension `batch`)."""
    onnx = _require_onnx()
    helper, tp = onnx.helper, onnx.TensorProto
    layers = policy.layers  # (weight (out, in), bias (out,)) per layer
    n_obs = int(layers[0][0].shape[1])
    n_act = int(layers[-1][0].shape[0])
    initializers = []
    nodes = []
    h = INPUT_NAME
    for i, (w, b) in enumerate(layers):
        w32 = np.ascontiguousarray(np.asarray(w, dtype=np.float32).T)  # (in, out): h @ W
        b32 = np.asarray(b, dtype=np.float32)
        if not (np.all(np.isfinite(w32)) and np.all(np.isfinite(b32))):
            raise PolicyFileError(f"layer {i}: non-finite weights cannot be exported")
        initializers += [
            onnx.numpy_helper.from_array(w32, name=f"w{i}"),
            onnx.numpy_helper.from_array(b32, name=f"b{i}"),
        ]
        nodes.append(helper.make_node("MatMul", [h, f"w{i}"], [f"matmul{i}"], name=f"MatMul{i}"))
        nodes.append(helper.make_node("Add", [f"matmul{i}", f"b{i}"], [f"z{i}"], name=f"Add{i}"))
        h = f"z{i}"
        if i < len(layers) - 1:
            nodes.append(helper.make_node("Tanh", [h], [f"h{i}"], name=f"Tanh{i}"))
            h = f"h{i}"
    initializers += [
        onnx.numpy_helper.from_array(np.array(-1.0, dtype=np.float32), name="action_min"),
        onnx.numpy_helper.from_array(np.array(1.0, dtype=np.float32), name="action_max"),
    ]
    nodes.append(
        helper.make_node("Clip", [h, "action_min", "action_max"], [OUTPUT_NAME], name="Clip")
    )
    graph = helper.make_graph(
        nodes,
        "constraint_aware_policy",
        [helper.make_tensor_value_info(INPUT_NAME, tp.FLOAT, ["batch", n_obs])],
        [helper.make_tensor_value_info(OUTPUT_NAME, tp.FLOAT, ["batch", n_act])],
        initializer=initializers,
    )
    model = helper.make_model(
        graph,
        opset_imports=[helper.make_opsetid("", OPSET)],
        producer_name="constraint-aware",
        doc_string="Constraint-aware policy (Saito et al.): observation -> action in [-1, 1]",
    )
    model.ir_version = IR_VERSION
    helper.set_model_props(model, policy_metadata(policy))
    onnx.checker.check_model(model, full_check=True)
    return model


def export_onnx(policy: ConstraintAwarePolicy, path: str | Path) -> Path:
    """Write `policy` as an ONNX model to `path` (suffix .onnx). Returns the path written."""
    out = Path(path)
    if out.suffix != ".onnx":
        raise InvalidInputError(f"path: an ONNX model file ends in .onnx, got {str(out)!r}")
    model = build_onnx_model(policy)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_bytes(model.SerializeToString())
    return out


def read_onnx_metadata(path: str | Path) -> dict[str, Any]:
    """The metadata_props of an exported model, JSON values decoded (for checks and tools)."""
    onnx = _require_onnx()
    try:
        model = onnx.load(str(path), load_external_data=False)
    except (OSError, ValueError) as exc:
        raise PolicyFileError(f"{path}: not a readable ONNX model ({exc})") from exc
    out: dict[str, Any] = {}
    for prop in model.metadata_props:
        try:
            out[prop.key] = json.loads(prop.value)
        except json.JSONDecodeError:
            out[prop.key] = prop.value  # plain text (the update rule, the format tag)
    return out


def random_observations(layout: list[str], n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, len(layout)) float32 test inputs: half of the rows as the policy sees them (unit or
    zero forces, unit directions, in every x/y/z column triple named `...force_unit_*` or
    `...direction_*`, the previous step's too), half uniform in [-2, 2] (beyond the valid
    range, so the final Clip is exercised too)."""
    obs = rng.uniform(-2.0, 2.0, size=(n, len(layout)))
    half = n // 2
    bases = {name[:-2] for name in layout if name.endswith(("_x", "_y", "_z"))}
    for base in sorted(bases):
        if not base.endswith(("force_unit", "direction")):
            continue
        cols = [layout.index(f"{base}_{a}") for a in "xyz" if f"{base}_{a}" in layout]
        if len(cols) == 3:
            v = rng.normal(size=(half, 3))
            v /= np.linalg.norm(v, axis=1, keepdims=True)
            if base.endswith("force_unit"):
                v[rng.random(half) < 0.1] = 0.0  # below the dead band the force is observed as 0
            obs[:half, cols] = v
    return obs.astype(np.float32)


def onnx_parity(
    policy: ConstraintAwarePolicy, path: str | Path, n_observations: int = 10_000, seed: int = 0
) -> float:
    """max |act_batch - ONNX Runtime| over `n_observations` random inputs (needs onnxruntime).

    n_observations: 1 to MAX_PARITY_OBSERVATIONS, evaluated in chunks of PARITY_CHUNK rows (the
    memory stays bounded); anything else raises InvalidInputError naming it."""
    n = check_int("n_observations", n_observations, low=1)
    if n > MAX_PARITY_OBSERVATIONS:
        raise InvalidInputError(
            f"n_observations = {n:,}: at most {MAX_PARITY_OBSERVATIONS:,} (random observations "
            "for the parity check)"
        )
    try:
        import onnxruntime
    except ImportError as exc:
        raise CapError(
            "the parity check needs 'onnxruntime': pip install 'constraint-aware[onnx]'"
        ) from exc
    session = onnxruntime.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    layout = observation_layout(policy)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for start in range(0, n, PARITY_CHUNK):
        obs = random_observations(layout, min(PARITY_CHUNK, n - start), rng)
        (onnx_action,) = session.run([OUTPUT_NAME], {INPUT_NAME: obs})
        numpy_action = policy.act_batch(obs.astype(np.float64))
        worst = max(worst, float(np.max(np.abs(numpy_action - onnx_action))))
    return worst
