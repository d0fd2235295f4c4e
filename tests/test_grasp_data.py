"""Recognizer data: how much of the handle each camera sees, and the dataset's files."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from constraint_aware.errors import InvalidInputError
from constraint_aware.lfo.grasp_data import GraspDataset, handle_visibility
from constraint_aware.sim.camera import CameraMount, add_camera, look_at


def _door_seen(
    blocker_group: int | None,
    blocker_size: float = 0.05,
    target: np.ndarray | None = None,
    around: np.ndarray | None = None,
) -> float:
    """The door handle's visibility from a camera 1 m away, with a box of half-size
    `blocker_size` [m] (in `blocker_group`) halfway along the line of sight to `target` (the
    handle's centre when None), or none; `around`: handle_visibility's."""
    from constraint_aware.sim.scene import scene_spec
    from constraint_aware.sim.tasks import task_config

    task = task_config("door-opening")
    spec = scene_spec(task)
    handle = np.asarray(task.object.handle_position, dtype=float)
    eye = handle + np.array([0.8, 0.1, 0.6])
    mount = CameraMount("head", look_at(eye, handle))
    add_camera(spec, mount)
    if blocker_group is not None:
        aim = handle if target is None else target
        geom = spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[blocker_size] * 3,
            pos=[float(v) for v in 0.5 * (eye + aim)],
        )
        geom.contype = 0
        geom.conaffinity = 0
        geom.group = blocker_group
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return handle_visibility(model, data, mount, around=around)


def _door_handle_ends() -> tuple[np.ndarray, np.ndarray]:
    """The two ends of the door's handle (its geom's axis), world frame [m]."""
    from constraint_aware.sim.scene import OBJECT_PREFIX, scene_spec
    from constraint_aware.sim.tasks import task_config

    model = scene_spec(task_config("door-opening")).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    g = model.geom(OBJECT_PREFIX + "object_handle").id
    axis = data.geom_xmat[g].reshape(3, 3)[:, 2] * model.geom_size[g][1]
    return data.geom_xpos[g] - axis, data.geom_xpos[g] + axis


def test_a_box_in_the_line_of_sight_hides_the_handle() -> None:
    assert _door_seen(None) > 0.95
    assert _door_seen(1) < 0.05  # a rendered box halfway: the handle is hidden
    assert 0.1 < _door_seen(1, blocker_size=0.006) < 0.95  # a small one hides a part
    assert _door_seen(3) > 0.95  # a geom the camera does not render hides nothing


def test_the_contact_points_surroundings_are_seen_apart_from_the_rest_of_the_handle() -> None:
    # a box hiding one end of the handle: the handle partly seen, that end hidden, the other
    # end seen
    near, far = _door_handle_ends()
    assert _door_seen(None, around=near) > 0.95
    assert 0.1 < _door_seen(1, 0.015, target=near) < 0.9
    assert _door_seen(1, 0.015, target=near, around=near) < 0.2
    assert _door_seen(1, 0.015, target=near, around=far) > 0.95


def test_a_dataset_file_without_visibility_loads_with_nan_and_a_foreign_file_is_named(
    tmp_path: Path,
) -> None:
    n = 3
    fields = dict(
        heights=np.zeros((n, 4, 4), np.float32),
        shapes=np.zeros(n, int),
        points=np.zeros((n, 3)),
        approaches=np.tile([0.0, 0.0, 1.0], (n, 1)),
        kinds=np.array(["lid"] * n),
        robots=np.array(["jaco"] * n),
        offsets=np.zeros(n),
        nominal_errors=np.zeros(n),
    )
    np.savez(tmp_path / "old.npz", **fields)  # type: ignore[arg-type]
    old = GraspDataset.load(tmp_path / "old.npz")
    assert len(old) == n and np.all(np.isnan(old.visible))
    assert np.all(np.isnan(old.contact_visible))
    assert list(old.views) == ["head"] * n  # written before the second look
    np.savez(tmp_path / "other.npz", x=np.zeros(2))
    with pytest.raises(InvalidInputError, match="not a recognizer dataset"):
        GraspDataset.load(tmp_path / "other.npz")


def test_generated_crops_take_the_sensor_noise_asked_for() -> None:
    from constraint_aware.lfo.grasp_data import generate
    from constraint_aware.sim.camera import NO_NOISE

    crops = {}
    for name, noise in (("noisy", None), ("exact", NO_NOISE)):
        # one crop at the demonstrated point: the same placement and crop, the noise aside
        data = generate(1, seed=5, kinds=("plate",), robots=("hook-hand",), crops_per_view=1,
                        distractors=False, noise=noise)  # fmt: skip
        crops[name] = data.heights[0].astype(float)
    both = np.isfinite(crops["noisy"]) & np.isfinite(crops["exact"])
    assert int(both.sum()) > 500
    difference = np.abs(crops["noisy"] - crops["exact"])[both]
    assert float(np.median(difference)) > 0.2e-3  # the sensor's noise: about a millimetre
    assert int(np.sum(~np.isfinite(crops["noisy"]))) > int(np.sum(~np.isfinite(crops["exact"])))


def test_second_looks_come_after_the_head_crops_and_are_labelled_in_their_own_frame() -> None:
    from constraint_aware.lfo.grasp_data import HEAD, LOOK_SPREAD, SECOND_LOOK, generate

    asked = dict(seed=5, kinds=("drawer",), robots=("hook-hand",), crops_per_view=2)
    head = generate(1, **asked)  # type: ignore[arg-type]
    both = generate(1, looks_per_view=2, **asked)  # type: ignore[arg-type]
    assert list(both.views) == [HEAD, HEAD, SECOND_LOOK, SECOND_LOOK]
    first = both.select(both.views == HEAD)
    # the head crops are drawn first: the same with or without second looks
    assert np.array_equal(first.heights, head.heights, equal_nan=True)
    looked = both.select(both.views == SECOND_LOOK)
    # each crop sits where its look aimed, LOOK_SPREAD around the contact point, and its
    # label is the contact point in that crop's frame
    assert np.allclose(np.linalg.norm(looked.points, axis=1), looked.offsets)
    assert np.all(looked.offsets < 5 * math.sqrt(3) * LOOK_SPREAD)
    # the wrist camera on the approach sees the contact point's surroundings
    assert np.all(looked.contact_visible > 0.9)
    assert np.all(np.isfinite(looked.heights).sum(axis=(1, 2)) > 500)
