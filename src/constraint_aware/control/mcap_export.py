"""A run record as an MCAP file that Foxglove (and ROS tooling) can show, and back.

One message per channel per control step, all JSON-encoded with JSON schemas; Foxglove picks
its panels from the schema names:

| topic | schema | content |
|---|---|---|
| `/tool/pose` | `foxglove.PoseInFrame` | tool point [m]; orientation: x axis along d_t |
| `/scene` | `foxglove.SceneUpdate` | arrows at the tool point: F, d_t, the admissible direction |
| `/force` | `foxglove.Vector3` | F = F_s - F_d [N], world frame |
| `/torque` | `foxglove.Vector3` | tau - tau_d [N m] about the tool point |
| `/direction` | `foxglove.Vector3` | d_t, unit |
| `/step` | `constraint_aware.StepRecord` | the raw step record (every field) |

Timestamps: step * control period [ns]. The run's label, outcome and summary are the MCAP
metadata record `run`. The record holds no hand orientation, so the tool pose's orientation
shows the motion direction (x axis along d_t), which Foxglove draws as the pose's arrow.
Non-finite numbers are written as null (strict JSON) and read back as NaN.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.control.record import RunRecord, StepRecord
from constraint_aware.errors import CapError, InvalidInputError

#: Arrow length per newton of force in the scene [m/N]: 60 N (the force limit) is 0.6 m.
FORCE_ARROW_M_PER_N = 0.01
#: Length of the unit-direction arrows in the scene [m].
DIRECTION_ARROW_M = 0.1
#: Name of the MCAP metadata record holding the run's label, outcome and summary.
RUN_METADATA = "run"
TOPICS = ("/tool/pose", "/scene", "/force", "/torque", "/direction", "/step")
STEP_SCHEMA = "constraint_aware.StepRecord"
FRAME = "world"

_COLORS = {
    "force": (0.9, 0.2, 0.1, 1.0),  # F: red
    "direction": (0.1, 0.4, 0.95, 1.0),  # d_t: blue
    "admissible_direction": (0.1, 0.75, 0.2, 0.8),  # the guide's direction (simulation): green
}


# --- JSON schemas (the subset of the Foxglove schemas these messages use) ---------------------
def _object(title: str, props: dict[str, Any], required: list[str] | None = None) -> Any:
    return {
        "title": title,
        "type": "object",
        "properties": props,
        "required": list(props) if required is None else required,
    }


def _numbers(title: str, names: str) -> Any:
    return _object(title, {n: {"type": "number"} for n in names})


_TIME = {
    "type": "object",
    "title": "time",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
}
_POSE = _object(
    "foxglove.Pose",
    {
        "position": _numbers("foxglove.Vector3", "xyz"),
        "orientation": _numbers("foxglove.Quaternion", "xyzw"),
    },
)
_ARROW = _object(
    "foxglove.ArrowPrimitive",
    {
        "pose": _POSE,
        "shaft_length": {"type": "number"},
        "shaft_diameter": {"type": "number"},
        "head_length": {"type": "number"},
        "head_diameter": {"type": "number"},
        "color": _numbers("foxglove.Color", "rgba"),
    },
)
_ENTITY_ARRAYS = ("cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models")
_ENTITY = _object(
    "foxglove.SceneEntity",
    {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "id": {"type": "string"},
        "lifetime": {"type": "object", "title": "duration"},
        "frame_locked": {"type": "boolean"},
        "metadata": {
            "type": "array",
            "items": _object(
                "foxglove.KeyValuePair", {"key": {"type": "string"}, "value": {"type": "string"}}
            ),
        },
        "arrows": {"type": "array", "items": _ARROW},
        **{name: {"type": "array"} for name in _ENTITY_ARRAYS},
    },
)
SCHEMAS: dict[str, Any] = {
    "foxglove.PoseInFrame": _object(
        "foxglove.PoseInFrame",
        {"timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE},
    ),
    "foxglove.SceneUpdate": _object(
        "foxglove.SceneUpdate",
        {
            "deletions": {"type": "array"},
            "entities": {"type": "array", "items": _ENTITY},
        },
    ),
    "foxglove.Vector3": _numbers("foxglove.Vector3", "xyz"),
}
_TOPIC_SCHEMA = {
    "/tool/pose": "foxglove.PoseInFrame",
    "/scene": "foxglove.SceneUpdate",
    "/force": "foxglove.Vector3",
    "/torque": "foxglove.Vector3",
    "/direction": "foxglove.Vector3",
    "/step": STEP_SCHEMA,
}


def _step_schema() -> Any:
    """JSON schema of a StepRecord: numbers, vectors, or null where a value is absent/NaN."""
    props: dict[str, Any] = {}
    for f in dataclasses.fields(StepRecord):
        kind = "integer" if f.name == "step" else "number"
        if "list" in str(f.type):
            props[f.name] = {"type": ["array", "null"], "items": {"type": ["number", "null"]}}
        else:
            props[f.name] = {"type": [kind, "null"]}
    return _object(STEP_SCHEMA, props)


# --- messages -------------------------------------------------------------------------------
def _strict(value: Any) -> Any:
    """`value` with non-finite floats as None (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_strict(v) for v in value]
    return value


def _vec(v: np.ndarray) -> dict[str, float]:
    return {"x": float(v[0]), "y": float(v[1]), "z": float(v[2])}


def quaternion_x_to(v: np.ndarray) -> dict[str, float]:
    """Quaternion {x, y, z, w} of the shortest rotation taking the +x axis to `v` (3,).

    A zero or non-finite `v` gives the identity.
    """
    n = float(np.linalg.norm(v))
    if not math.isfinite(n) or n < 1e-12:
        return {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    u = np.asarray(v, dtype=float) / n
    c = float(np.clip(u[0], -1.0, 1.0))  # cos of the angle between x and u
    axis = np.array([0.0, -u[2], u[1]])  # x cross u
    s = float(np.linalg.norm(axis))
    if s < 1e-12:  # parallel (identity) or antiparallel (half turn about z)
        return (
            {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
            if c > 0
            else {"x": 0.0, "y": 0.0, "z": 1.0, "w": 0.0}
        )
    half = 0.5 * math.atan2(s, c)
    axis = axis / s * math.sin(half)
    return {"x": float(axis[0]), "y": float(axis[1]), "z": float(axis[2]), "w": math.cos(half)}


def _time(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _arrow(origin: np.ndarray, vector: np.ndarray, length: float, color: str) -> dict[str, Any]:
    head = min(0.3 * length, 0.03)
    r, g, b, a = _COLORS[color]
    return {
        "pose": {"position": _vec(origin), "orientation": quaternion_x_to(vector)},
        "shaft_length": max(length - head, 0.0),
        "shaft_diameter": 0.006,
        "head_length": head,
        "head_diameter": 0.015,
        "color": {"r": r, "g": g, "b": b, "a": a},
    }


def _finite(v: list[float] | None) -> np.ndarray | None:
    if v is None:
        return None
    a = np.asarray(v, dtype=float)
    return a if np.all(np.isfinite(a)) else None


def step_messages(step: StepRecord, ns: int) -> dict[str, dict[str, Any]]:
    """The messages of one step by topic (JSON-ready dicts)."""
    tool = np.asarray(step.hand_position, dtype=float)
    d = np.asarray(step.direction, dtype=float)
    force = np.asarray(step.force, dtype=float)
    stamp = _time(ns)
    arrows: list[tuple[str, dict[str, Any]]] = []
    if np.all(np.isfinite(tool)):
        if np.all(np.isfinite(force)) and np.linalg.norm(force) > 0:
            length = FORCE_ARROW_M_PER_N * float(np.linalg.norm(force))
            arrows.append(("force", _arrow(tool, force, length, "force")))
        if np.all(np.isfinite(d)):
            arrows.append(("direction", _arrow(tool, d, DIRECTION_ARROW_M, "direction")))
        admissible = _finite(step.admissible_direction)
        if admissible is not None:
            arrows.append(
                (
                    "admissible_direction",
                    _arrow(tool, admissible, DIRECTION_ARROW_M, "admissible_direction"),
                )
            )
    entities = [
        {
            "timestamp": stamp,
            "frame_id": FRAME,
            "id": name,
            "lifetime": {"sec": 0, "nsec": 0},  # kept until the next step replaces it
            "frame_locked": False,
            "metadata": [{"key": "step", "value": str(step.step)}],
            "arrows": [arrow],
            **{k: [] for k in _ENTITY_ARRAYS},
        }
        for name, arrow in arrows
    ]
    return {
        "/tool/pose": {
            "timestamp": stamp,
            "frame_id": FRAME,
            "pose": {"position": _vec(tool), "orientation": quaternion_x_to(d)},
        },
        "/scene": {"deletions": [], "entities": entities},
        "/force": _vec(force),
        "/torque": _vec(np.asarray(step.torque, dtype=float)),
        "/direction": _vec(d),
        "/step": dataclasses.asdict(step),
    }


def _control_period(record: RunRecord, control_period: float | None) -> float:
    if control_period is None:
        control_period = record.label.get("control_period_s")
    if control_period is None:
        # A simulated run's period; a real robot's record should carry its own in its label.
        from constraint_aware.sim.world import CONTROL_PERIOD

        control_period = CONTROL_PERIOD
    period = float(control_period)
    if not math.isfinite(period) or period <= 0:
        raise InvalidInputError(f"control_period: must be > 0 [s], got {control_period}")
    return period


def _require_mcap() -> Any:
    try:
        import mcap.writer
    except ImportError as exc:
        raise CapError(
            "MCAP export needs the 'mcap' package: pip install 'constraint-aware[mcap]'"
        ) from exc
    return mcap.writer


def write_mcap(record: RunRecord, path: str | Path, control_period: float | None = None) -> Path:
    """Write `record` to `path` (.mcap) for Foxglove. Returns the path written.

    control_period [s]: time between steps; default the label's `control_period_s`, else the
    simulated robot's period.
    """
    out = Path(path)
    if out.suffix != ".mcap":
        raise InvalidInputError(f"path: an MCAP file ends in .mcap, got {str(out)!r}")
    period = _control_period(record, control_period)
    writer_module = _require_mcap()
    out.parent.mkdir(parents=True, exist_ok=True)
    schemas = {**SCHEMAS, STEP_SCHEMA: _step_schema()}
    with out.open("wb") as fh:
        writer = writer_module.Writer(fh)
        writer.start(profile="", library="constraint-aware")
        schema_ids = {
            name: writer.register_schema(
                name=name, encoding="jsonschema", data=json.dumps(schema).encode()
            )
            for name, schema in schemas.items()
        }
        channels = {
            topic: writer.register_channel(
                topic=topic, message_encoding="json", schema_id=schema_ids[schema]
            )
            for topic, schema in _TOPIC_SCHEMA.items()
        }
        for seq, step in enumerate(record.steps):
            ns = round(step.step * period * 1e9)
            for topic, message in step_messages(step, ns).items():
                writer.add_message(
                    channel_id=channels[topic],
                    log_time=ns,
                    publish_time=ns,
                    sequence=seq,
                    data=json.dumps(_strict(message), allow_nan=False).encode(),
                )
        run = {k: v for k, v in dataclasses.asdict(record).items() if k != "steps"}
        writer.add_metadata(
            name=RUN_METADATA,
            data={
                "record": json.dumps(_strict(run), allow_nan=False),
                "summary": json.dumps(_strict(record.summary()), allow_nan=False),
                "control_period_s": repr(period),
                "force_arrow_m_per_N": repr(FORCE_ARROW_M_PER_N),
                "tool_pose_orientation": "x axis along the motion direction d_t",
            },
        )
        writer.finish()
    return out


def iter_mcap_messages(path: str | Path) -> Iterator[tuple[str, str, int, Any]]:
    """(topic, schema name, log_time [ns], decoded JSON message) for every message in `path`."""
    _require_mcap()
    from mcap.reader import make_reader

    with Path(path).open("rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            name = schema.name if schema is not None else ""
            yield channel.topic, name, message.log_time, json.loads(message.data)


def _nan_for_null(value: Any) -> Any:
    if value is None:
        return math.nan
    if isinstance(value, list):
        return [_nan_for_null(v) for v in value]
    return value


def _restore_nan(cls: type, values: dict[str, Any]) -> dict[str, Any]:
    """`values` of dataclass `cls` with the nulls that stood for NaN back as NaN: in fields
    typed float or list[float]; a field that may be None (`| None`) keeps a None itself."""
    types = {f.name: str(f.type) for f in dataclasses.fields(cls)}
    out = dict(values)
    for name, value in values.items():
        kind = types.get(name, "")
        if kind.startswith(("float", "list[float]")) and not (value is None and "None" in kind):
            out[name] = _nan_for_null(value)
    return out


def read_mcap(path: str | Path) -> RunRecord:
    """The run record stored in an MCAP file written by `write_mcap` (null read as NaN)."""
    _require_mcap()
    from mcap.reader import make_reader

    with Path(path).open("rb") as fh:
        reader = make_reader(fh)
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    if RUN_METADATA not in meta:
        raise InvalidInputError(f"{path}: no '{RUN_METADATA}' metadata (not written by cap)")
    run = _restore_nan(RunRecord, json.loads(meta[RUN_METADATA]["record"]))
    steps = [
        StepRecord(**_restore_nan(StepRecord, msg))
        for topic, _, _, msg in iter_mcap_messages(path)
        if topic == "/step"
    ]
    return RunRecord(steps=steps, **run)
