"""MCAP export of a run record: Foxglove schemas, one message per step and topic, round trip."""

from __future__ import annotations

import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.mcap_export import (
    FORCE_ARROW_M_PER_N,
    TOPICS,
    iter_mcap_messages,
    quaternion_x_to,
    read_mcap,
    write_mcap,
)
from constraint_aware.control.record import RunRecord, StepRecord
from constraint_aware.errors import InvalidInputError

pytest.importorskip("mcap")

SCHEMA_OF = {
    "/tool/pose": "foxglove.PoseInFrame",
    "/scene": "foxglove.SceneUpdate",
    "/force": "foxglove.Vector3",
    "/torque": "foxglove.Vector3",
    "/direction": "foxglove.Vector3",
    "/step": "constraint_aware.StepRecord",
}
# Required fields of foxglove.SceneEntity (Foxglove's JSON schema).
SCENE_ENTITY_FIELDS = {
    "timestamp", "frame_id", "id", "lifetime", "frame_locked", "metadata", "arrows", "cubes",
    "spheres", "cylinders", "lines", "triangles", "texts", "models",
}  # fmt: skip


@pytest.fixture(scope="module")
def record() -> RunRecord:
    from constraint_aware.control.simulate import RunSpec, run

    rec, _ = run(RunSpec("door-opening", "policy", 15.0))
    return rec


@pytest.fixture(scope="module")
def messages(record: RunRecord, tmp_path_factory: pytest.TempPathFactory) -> list[Any]:
    path = write_mcap(record, tmp_path_factory.mktemp("mcap") / "run.mcap")
    return list(iter_mcap_messages(path))


def _same(a: Any, b: Any) -> bool:
    """Equality with NaN == NaN, through nested dicts and lists."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def test_channels_schemas_and_message_count(record: RunRecord, messages: list[Any]) -> None:
    counts = Counter((topic, schema) for topic, schema, _, _ in messages)
    assert set(counts) == {(t, SCHEMA_OF[t]) for t in TOPICS}
    assert all(n == len(record.steps) for n in counts.values())
    assert len(record.steps) > 10


def test_timestamps_are_step_times_control_period(messages: list[Any]) -> None:
    for topic, _, log_time, msg in messages:
        if topic == "/step":
            assert log_time == round(msg["step"] * 0.1 * 1e9)
        if topic == "/tool/pose":
            assert msg["timestamp"]["sec"] * 10**9 + msg["timestamp"]["nsec"] == log_time


def test_values_round_trip(record: RunRecord, messages: list[Any], tmp_path: Path) -> None:
    by_topic: dict[str, list[Any]] = {}
    for topic, _, _, msg in messages:
        by_topic.setdefault(topic, []).append(msg)
    for step, pose, force, d in zip(
        record.steps,
        by_topic["/tool/pose"],
        by_topic["/force"],
        by_topic["/direction"],
        strict=True,
    ):
        p = pose["pose"]["position"]
        assert [p["x"], p["y"], p["z"]] == step.hand_position
        assert [force["x"], force["y"], force["z"]] == step.force
        assert [d["x"], d["y"], d["z"]] == step.direction
        q = pose["pose"]["orientation"]
        x_axis = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).apply([1.0, 0.0, 0.0])
        unit_d = np.array(step.direction) / np.linalg.norm(step.direction)
        np.testing.assert_allclose(x_axis, unit_d, atol=1e-9)
    back = read_mcap(write_mcap(record, tmp_path / "again.mcap"))
    assert _same(back.to_dict(), record.to_dict())


def test_scene_arrows_show_the_wrench(record: RunRecord, messages: list[Any]) -> None:
    scenes = [msg for topic, _, _, msg in messages if topic == "/scene"]
    for step, scene in zip(record.steps, scenes, strict=True):
        entities = {e["id"]: e for e in scene["entities"]}
        assert {"force", "direction", "admissible_direction"} <= set(entities)
        for entity in entities.values():
            assert set(entity) == SCENE_ENTITY_FIELDS
        arrow = entities["force"]["arrows"][0]
        length = arrow["shaft_length"] + arrow["head_length"]
        assert length == pytest.approx(FORCE_ARROW_M_PER_N * step.force_norm, rel=1e-9)
        q = arrow["pose"]["orientation"]
        x_axis = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).apply([1.0, 0.0, 0.0])
        np.testing.assert_allclose(x_axis, np.array(step.force) / step.force_norm, atol=1e-9)


def _real_robot_record() -> RunRecord:
    """A record as a real arm leaves it: no simulation truth (NaN angle, None handle)."""
    rec = RunRecord({"task": "drawer", "control_period_s": 0.05}, [0.0, 0.0, 0.5], [0.0] * 3)
    for i in range(3):
        rec.steps.append(
            StepRecord(
                step=i, direction=[1.0, 0.0, 0.0], force=[0.0, 0.0, 0.0], force_norm=0.0,
                torque=[0.0, 0.1, 0.0], hand_position=[0.01 * i, 0.0, 0.3], handle_position=None,
                admissible_direction=None, angle_deg=math.nan, progress=math.nan, slip_m=math.nan,
                slip_deg=math.nan, rotation_rate=None,
            )
        )  # fmt: skip
    rec.finish("timeout", "step limit", None)
    rec.threshold = math.nan  # a NaN in a run-level float field, too
    return rec


def test_non_finite_values_are_strict_json_null(tmp_path: Path) -> None:
    rec = _real_robot_record()
    path = write_mcap(rec, tmp_path / "robot.mcap")

    def no_constants(token: str) -> float:
        raise AssertionError(f"non-standard JSON token {token}")

    for topic, _, log_time, msg in iter_mcap_messages(path):
        json.loads(json.dumps(msg), parse_constant=no_constants)
        if topic == "/step":
            assert msg["angle_deg"] is None
            assert log_time == round(msg["step"] * 0.05 * 1e9)  # the label's period
        if topic == "/scene":  # no force, no truth: only d is drawn
            assert [e["id"] for e in msg["entities"]] == ["direction"]
    assert _same(read_mcap(path).to_dict(), rec.to_dict())


def test_invalid_arguments_name_the_field(tmp_path: Path) -> None:
    rec = _real_robot_record()
    with pytest.raises(InvalidInputError, match="path"):
        write_mcap(rec, tmp_path / "run.json")
    with pytest.raises(InvalidInputError, match="control_period"):
        write_mcap(rec, tmp_path / "run.mcap", control_period=0.0)


@pytest.mark.parametrize(
    "v", [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, 0, -1], [0.3, -0.5, 0.8], [-1, 1e-14, 0]]
)
def test_quaternion_x_to(v: list[float]) -> None:
    q = quaternion_x_to(np.array(v, dtype=float))
    x_axis = Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).apply([1.0, 0.0, 0.0])
    np.testing.assert_allclose(x_axis, np.array(v) / np.linalg.norm(v), atol=1e-9)
