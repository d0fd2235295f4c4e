"""The depth camera, the crop, the contact-points recognizers and the offset demonstrations."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from constraint_aware.errors import ConfigError
from constraint_aware.recognizer import (
    CROP_PIXELS,
    HANDLE_SHAPES,
    ContactPointRecognizer,
    GeometricRecognizer,
    GraspFrame,
    RecognitionError,
    RecognizerFileError,
    check_crop,
    depth_crop,
    forward,
    network_input,
    shipped_recognizer_path,
    weight_shapes,
)
from constraint_aware.sim.camera import (
    NO_NOISE,
    CameraIntrinsics,
    CameraMount,
    CameraPose,
    DepthCamera,
    DepthImage,
    DepthNoise,
    add_camera,
    add_tool_camera,
    apply_noise,
    backproject,
    look_at,
)

SMALL = CameraIntrinsics(96, 72, 58.0)


def _door_world(intrinsics: CameraIntrinsics = SMALL) -> tuple[mujoco.MjModel, CameraMount]:
    from constraint_aware.sim.scene import scene_spec
    from constraint_aware.sim.tasks import task_config

    task = task_config("door-opening")
    spec = scene_spec(task)
    handle = task.object.handle_position
    mount = CameraMount("head", look_at(handle + np.array([0.7, 0.1, 0.5]), handle), intrinsics)
    add_camera(spec, mount)
    return spec.compile(), mount


def test_rendered_depth_is_the_geometry_along_each_pixel_ray() -> None:
    model, mount = _door_world()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with DepthCamera(model, mount, NO_NOISE) as camera:
        rendered = camera.true_depth(data)
    near = np.isfinite(rendered) & (rendered < 2.0)
    assert near.mean() > 0.3
    points = backproject(rendered, mount.intrinsics)
    rows, cols = np.nonzero(near)
    for v, u in zip(rows[::29], cols[::29], strict=True):
        ray = mount.pose.rotation @ (points[v, u] / np.linalg.norm(points[v, u]))
        hit = mujoco.mj_ray(
            model, data, mount.pose.position, ray, None, 1, -1, np.zeros(1, np.int32)
        )
        assert hit == pytest.approx(np.linalg.norm(points[v, u]), rel=2e-4)  # float32 buffer


def test_backprojection_and_projection_are_inverse() -> None:
    pose = look_at(np.array([1.0, 0.0, 1.5]), np.array([0.0, 0.2, 0.8]))
    image = DepthImage(np.full((SMALL.height, SMALL.width), 1.3), SMALL, pose)
    world = image.points()
    assert world.shape == (SMALL.width * SMALL.height, 3)
    uv = image.project(world)
    u, v = np.meshgrid(np.arange(SMALL.width) + 0.5, np.arange(SMALL.height) + 0.5)
    assert np.allclose(uv[:, 0], u.ravel()) and np.allclose(uv[:, 1], v.ravel())
    # every point lies 1.3 m in front of the camera along its optical axis
    assert np.allclose(pose.to_camera(world)[:, 2], 1.3)


def test_noise_grows_with_distance_drops_grazing_returns_and_is_seeded() -> None:
    noise = DepthNoise(dropout=0.0, edge_drop=0.0)
    wide = CameraIntrinsics(200, 150, 10.0)  # narrow field: rays nearly along the axis
    errors = {}
    for z in (0.8, 2.0):
        depth = np.full((wide.height, wide.width), z)
        noisy = apply_noise(depth, wide, noise, np.random.default_rng(0))
        errors[z] = float(np.nanstd(noisy - depth))
        expected = noise.base + noise.quadratic * (z - noise.reference) ** 2
        assert errors[z] == pytest.approx(expected, rel=0.1)
    assert errors[2.0] > 2.0 * errors[0.8]
    # a plane seen at ~80 deg incidence loses most of its pixels
    v = (np.arange(wide.height) + 0.5 - wide.height / 2) / wide.focal
    tilt = math.tan(math.radians(80.0))
    grazing = np.repeat((1.0 / (1.0 - tilt * v))[:, None], wide.width, axis=1)
    grazing[grazing <= 0] = np.nan
    dropped = np.isnan(apply_noise(grazing, wide, noise, np.random.default_rng(1)))
    assert dropped.mean() > 0.3
    a = apply_noise(grazing, wide, noise, np.random.default_rng(2))
    b = apply_noise(grazing, wide, noise, np.random.default_rng(2))
    assert np.array_equal(np.isnan(a), np.isnan(b)) and np.allclose(a, b, equal_nan=True)


def test_depth_edges_lose_returns() -> None:
    depth = np.full((60, 80), 1.0)
    depth[:, 40:] = 1.5
    noisy = apply_noise(depth, CameraIntrinsics(80, 60, 30.0), DepthNoise(dropout=0.0),
                        np.random.default_rng(0))  # fmt: skip
    edge = np.isnan(noisy[5:-5, 39:41]).mean()
    flat = np.isnan(noisy[5:-5, 10:30]).mean()
    assert edge > 0.3 and flat < 0.05


@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: CameraIntrinsics(width=0), "CameraIntrinsics.width"),
        (lambda: CameraIntrinsics(fovy_deg=float("nan")), "CameraIntrinsics.fovy_deg"),
        (lambda: DepthNoise(grazing_start_deg=80.0, grazing_end_deg=70.0), "grazing_end_deg"),
        (lambda: look_at(np.zeros(3), np.zeros(3)), "camera target"),
    ],
)
def test_bad_camera_settings_name_the_field(build: object, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        build()  # type: ignore[operator]


def test_a_scene_without_the_camera_is_refused() -> None:
    model, mount = _door_world()
    from constraint_aware.errors import CapError

    with pytest.raises(CapError, match="no camera 'elsewhere'"):
        DepthCamera(model, CameraMount("elsewhere", mount.pose, SMALL))


# --- the crop --------------------------------------------------------------------------------
def test_crop_holds_the_nearest_surface_toward_the_hand() -> None:
    frame = GraspFrame(np.array([0.5, 0.0, 1.0]), np.eye(3))  # approach along +z
    rng = np.random.default_rng(0)
    xy = rng.uniform(-0.2, 0.2, (40_000, 2))
    wall = np.column_stack([xy + frame.origin[:2], np.full(len(xy), 1.05)])  # 5 cm behind
    knob = wall[np.hypot(xy[:, 0], xy[:, 1]) < 0.02] - [0.0, 0.0, 0.03]  # 3 cm in front of it
    height = depth_crop(np.vstack([wall, knob]), frame)
    assert height.shape == (CROP_PIXELS, CROP_PIXELS)
    centre = height[CROP_PIXELS // 2, CROP_PIXELS // 2]
    corner = height[2, 2]
    assert centre == pytest.approx(-0.02, abs=2e-3)  # the knob: 2 cm in front of the origin
    assert corner == pytest.approx(-0.05, abs=1e-9)  # the wall behind
    with pytest.raises(RecognitionError, match="sees almost nothing"):
        check_crop(depth_crop(np.empty((0, 3)), frame))


# --- recognizers ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def crops() -> object:
    """One fresh scene per kind (the hook hand's camera, two offsets): held out from training
    (another seed)."""
    from constraint_aware.lfo.grasp_data import GraspDataset, generate

    data: GraspDataset = generate(1, seed=999, robots=("hook-hand",), crops_per_view=2)
    return data


def test_shipped_cnn_finds_contact_points_on_unseen_scenes(crops: object) -> None:
    from constraint_aware.lfo.grasp_training import score

    cnn = score(ContactPointRecognizer.load(), crops)  # type: ignore[arg-type]
    assert np.median(cnn.position) < 0.008
    assert np.all(cnn.position < 0.04)  # nothing grossly off on any kind
    assert np.percentile(cnn.approach, 95) < 10.0


def test_geometric_baseline_finds_bars_and_plates(crops: object) -> None:
    from constraint_aware.lfo.grasp_training import score

    geo = score(GeometricRecognizer(), crops)  # type: ignore[arg-type]
    kinds = geo.kinds
    for kind in ("drawer", "door", "plate"):
        assert np.median(geo.position[kinds == kind]) < 0.015, kind


def test_numpy_network_matches_torch() -> None:
    torch = pytest.importorskip("torch")
    from constraint_aware.training.grasp import RecognizerNet

    torch.manual_seed(0)
    net = RecognizerNet()
    heights = np.random.default_rng(0).normal(0.0, 0.03, (4, CROP_PIXELS, CROP_PIXELS))
    heights[:, :8] = np.nan
    shapes = np.arange(4)
    x = network_input(heights)
    with torch.no_grad():
        expected = net(torch.from_numpy(x), torch.from_numpy(shapes)).numpy()
    assert np.allclose(forward(net.numpy_weights(), x, shapes), expected, atol=1e-5)


def _copy_shipped(tmp_path: Path) -> Path:
    src = shipped_recognizer_path()
    shutil.copy(src, tmp_path / "r.npz")
    shutil.copy(src.with_suffix(".json"), tmp_path / "r.json")
    return tmp_path / "r.npz"


def test_recognizer_card_is_validated(tmp_path: Path) -> None:
    path = _copy_shipped(tmp_path)
    card = json.loads(path.with_suffix(".json").read_text())
    path.with_suffix(".json").write_text(json.dumps({**card, "crop_pixels": 32}))
    with pytest.raises(RecognizerFileError, match="'crop_pixels' is 32"):
        ContactPointRecognizer.load(path)
    path.with_suffix(".json").write_text(json.dumps({**card, "format": "other/1"}))
    with pytest.raises(RecognizerFileError, match="'format'"):
        ContactPointRecognizer.load(path)
    path.with_suffix(".json").unlink()
    with pytest.raises(RecognizerFileError, match="card not found"):
        ContactPointRecognizer.load(path)


def test_recognizer_weights_are_validated(tmp_path: Path) -> None:
    path = _copy_shipped(tmp_path)
    with np.load(path) as data:
        weights = {k: data[k] for k in data.files}
    bad = dict(weights, heat_w=np.full(weights["heat_w"].shape, np.nan, np.float32))
    np.savez(path, **bad)
    with pytest.raises(RecognizerFileError, match="'heat_w' must be finite"):
        ContactPointRecognizer.load(path)
    short = {k: v for k, v in weights.items() if k != "fc1_b"}
    np.savez(path, **short)
    with pytest.raises(RecognizerFileError, match="'fc1_b' missing"):
        ContactPointRecognizer.load(path)
    assert set(weight_shapes()) == set(weights)


def test_an_unknown_handle_shape_is_named() -> None:
    from constraint_aware.errors import UnknownNameError

    height = np.zeros((CROP_PIXELS, CROP_PIXELS))
    with pytest.raises(UnknownNameError, match="handle shape 'lever'"):
        GeometricRecognizer().recognize(height, GraspFrame(np.zeros(3), np.eye(3)), "lever")
    assert "lever" not in HANDLE_SHAPES


# --- demonstrations that locate the object roughly --------------------------------------------
def test_offset_demo_moves_the_tracked_point_rigidly_and_perception_restores_the_radius() -> None:
    from constraint_aware.lfo.infer import infer_skill
    from constraint_aware.lfo.perception import corrected_skill
    from constraint_aware.lfo.synthetic import (
        HandOffset,
        TrackingNoise,
        demo_of_object,
        random_placement,
    )
    from constraint_aware.recognizer import Recognition

    place = random_placement("door", np.random.default_rng(3))
    obj = place.task.object
    radial = np.asarray(obj.radial)
    offset = 0.05 * radial  # the tracked point 5 cm further from the hinge
    quiet = TrackingNoise(noise=0.001, tremor=0.0, outlier_fraction=0.0)
    demo = demo_of_object(
        place.task, place.goal, np.random.default_rng(0), quiet, point_offset=offset
    )
    skill = infer_skill(demo)
    assert skill.radius == pytest.approx(obj.radius + 0.05, abs=0.01)
    assert np.linalg.norm(np.asarray(skill.start_position) - obj.handle_position) == pytest.approx(
        0.05, abs=0.01
    )
    fixed = corrected_skill(skill, Recognition(obj.handle_position, -radial, "truth"))
    assert fixed.radius == pytest.approx(obj.radius, abs=0.005)
    assert np.degrees(np.arccos(np.clip(np.dot(fixed.initial_direction, obj.opening_direction),
                                        -1, 1))) < 3.0  # fmt: skip
    draws = np.array([HandOffset().draw(np.random.default_rng(i)) for i in range(400)])
    assert np.percentile(np.linalg.norm(draws, axis=1), 99) < 0.05 + 4 * 0.01
    assert np.max(np.linalg.norm(draws, axis=1)) > 0.04


# --- a camera on the hand --------------------------------------------------------------------
def _hand_on_a_slide() -> tuple[mujoco.MjModel, CameraMount]:
    """A 'hand' (a box on a slide joint along x, a tool-point site turned about x) in front of
    a wall at z = 1, with a camera mounted at the site."""
    spec = mujoco.MjSpec()
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[2.0, 2.0, 0.01], pos=[0, 0, 1.0])
    hand = spec.worldbody.add_body(name="hand")
    hand.add_joint(name="slide", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1.0, 0.0, 0.0])
    hand.add_geom(name="palm", type=mujoco.mjtGeom.mjGEOM_BOX, size=[0.03, 0.03, 0.01],
                  pos=[0.0, 0.0, 0.3])  # fmt: skip
    hand.add_site(name="tool", pos=[0.0, 0.0, 0.2], quat=[1.0, 0.0, 0.0, 0.0])
    mount = CameraMount("wrist", CameraPose(np.array([0.0, 0.0, -0.1]), np.eye(3)), SMALL)
    add_tool_camera(spec, mount, "tool")
    return spec.compile(), mount


def test_a_camera_on_the_hand_moves_with_it_and_does_not_see_the_hand() -> None:
    from constraint_aware.sim.camera import body_tree_geoms

    model, mount = _hand_on_a_slide()
    data = mujoco.MjData(model)
    data.qpos[0] = 0.25
    mujoco.mj_forward(model, data)
    with DepthCamera(model, mount, NO_NOISE) as camera:
        seen = camera.capture(data, np.random.default_rng(0))
    # the pose is where the hand is now: the site (0.25, 0, 0.2) and 0.1 m back along its z
    assert np.allclose(seen.pose.position, [0.25, 0.0, 0.1], atol=1e-9)
    assert np.allclose(seen.pose.rotation, np.eye(3), atol=1e-9)
    centre = seen.depth[SMALL.height // 2, SMALL.width // 2]
    assert centre == pytest.approx(0.19, abs=1e-3)  # the palm's face, 0.19 m ahead
    own = body_tree_geoms(model, "hand")
    assert own == (model.geom("palm").id,)
    with DepthCamera(model, mount, NO_NOISE, own_geoms=own) as camera:
        filtered = camera.capture(data, np.random.default_rng(0))
    palm = np.isclose(seen.depth, 0.19, atol=1e-3)
    assert palm.sum() > 50 and np.all(np.isnan(filtered.depth[palm]))  # no return there
    wall = ~palm & np.isfinite(seen.depth)
    assert np.allclose(filtered.depth[wall], seen.depth[wall])  # the rest as it was
    assert np.allclose(filtered.points()[:, 2], 0.99, atol=1e-3)  # only the wall's face


def test_a_camera_on_an_unknown_body_or_site_names_the_valid_ones() -> None:
    from constraint_aware.errors import UnknownNameError

    spec = mujoco.MjSpec()
    spec.worldbody.add_body(name="arm").add_site(name="tool")
    mount = CameraMount("c", CameraPose(np.zeros(3), np.eye(3)), SMALL)
    with pytest.raises(UnknownNameError, match=r"valid names: .*arm"):
        add_camera(spec, mount, body="wrist")
    with pytest.raises(UnknownNameError, match="valid names: tool"):
        add_tool_camera(spec, mount, "tcp")


def test_the_look_pose_puts_the_wrist_camera_on_the_approach() -> None:
    from scipy.spatial.transform import Rotation

    from constraint_aware.lfo.perception import WRIST_CAMERAS

    point = np.array([0.6, -0.1, 0.9])
    orientation = Rotation.from_euler("xyz", [0.3, -1.1, 0.4])
    for camera in WRIST_CAMERAS.values():
        tool = camera.look_pose(point, orientation)
        r = orientation.as_matrix()
        eye = tool.position + r @ np.asarray(camera.position)
        assert np.allclose(eye, point - camera.standoff * r[:, 2])
        assert tool.orientation.approx_equal(orientation)
