"""Recognizer data: depth crops of randomly placed, randomly sized objects of every kind, with
the contact point and approach each should give, generated from the scene builders.

One scene: an object of one kind (sim.tasks.KINDS) at a random placement
(lfo.synthetic.random_placement) with its handle's and main part's sizes drawn from
`SIZE_RANGES`, up to `MAX_DISTRACTORS` unrelated boxes, cylinders and spheres around it, and a
demonstration of it whose tracked point is offset from the handle (lfo.synthetic.HandOffset).
The skill inferred from that demonstration places each robot's head camera
(lfo.perception.head_camera) and the crop, exactly as at run time. Each camera gives a noisy
depth image (sim.camera, the run time's renderer, the noise drawn over the crops' region);
besides the demonstration's own offset, `crops_per_view - 1` more offsets are drawn for the
same image. Labels are the object's truth: the contact point of its handle shape
(recognizer.py) and the hand mount's approach, in the crop frame.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from constraint_aware.errors import CapError, InvalidInputError
from constraint_aware.geometry import FloatArray, angle_deg, random_unit, unit
from constraint_aware.lfo.infer import SkillParameters, infer_skill
from constraint_aware.lfo.perception import crop_corners, head_camera, nominal_frame
from constraint_aware.lfo.scene import STEP_LENGTH
from constraint_aware.lfo.synthetic import (
    HandOffset,
    Placement,
    TrackingNoise,
    demo_of_object,
    random_placement,
)
from constraint_aware.recognizer import (
    HANDLE_SHAPES,
    POLE_TOP_MARGIN,
    GraspFrame,
    depth_crop,
)
from constraint_aware.sim.camera import (
    CameraMount,
    CameraPose,
    DepthCamera,
    DepthNoise,
    add_camera,
    region_of_interest,
)
from constraint_aware.sim.objects import SCENERY_RGBA, VISUAL_GROUP
from constraint_aware.sim.scene import OBJECT_PREFIX, scene_spec
from constraint_aware.sim.tasks import KINDS, TaskConfig, task_from_object

#: Sizes drawn per handle shape [m] (uniform in each range): ObjectConfig fields.
SIZE_RANGES: dict[str, dict[str, tuple[tuple[float, float], ...]]] = {
    "bar": {
        "handle_radius": ((0.010, 0.016),),
        "handle_length": ((0.10, 0.16),),
        "standoff": ((0.03, 0.05),),
    },
    "pole": {"handle_radius": ((0.012, 0.022),), "handle_length": ((0.15, 0.26),)},
    "plate": {"handle_half": ((0.05, 0.09), (0.05, 0.09), (0.004, 0.008))},
    "knob": {"handle_half": ((0.015, 0.025), (0.010, 0.016), (0.009, 0.015))},
}
MAX_DISTRACTORS = 3
#: [m] the contact point's surroundings on the handle (about half a hand's width): what the
#: recognizer must see of the handle to place the contact point (`handle_visibility`).
CONTACT_RADIUS = 0.03
#: A crop's contact point counts as seen when its camera sees at least this share of the
#: handle within CONTACT_RADIUS of it (`contact_visible`): mostly hidden, it lies behind
#: whatever hides it, where no single view locates it.
SEEN_SHARE = 0.5
DEMO_NOISE = 0.005  # [m] the demonstrations' tracking noise (bench.placement's)
HEAD = "head"
SECOND_LOOK = "second look"
#: [m] per axis: how far from the contact point a training crop's second look aims (the head
#: camera's recognition error, whose tail reaches some centimetres where a handle is hidden)
LOOK_SPREAD = 0.008


@dataclass
class GraspDataset:
    """Crops and labels. heights (N, P, P) float32 [m] (NaN: no return); shapes (N,) indices
    into HANDLE_SHAPES; points (N, 3) [m] and approaches (N, 3) unit: the truth in the crop
    frame; kinds, robots (N,) names; offsets (N,) [m] the demonstrated point's distance from
    the contact point; nominal_errors (N,) [deg] the nominal approach's error; visible (N,)
    [0, 1] the share of the handle its camera sees unoccluded (`handle_visibility`), and
    contact_visible (N,) [0, 1] that of the handle within `CONTACT_RADIUS` of the contact
    point (NaN in a file written without them); views (N,) `HEAD` (the head camera's image) or
    `SECOND_LOOK` (the head camera's and the wrist camera's, `second_look_rows`; a file
    written without it holds head crops only)."""

    heights: np.ndarray
    shapes: np.ndarray
    points: np.ndarray
    approaches: np.ndarray
    kinds: np.ndarray
    robots: np.ndarray
    offsets: np.ndarray
    nominal_errors: np.ndarray
    visible: np.ndarray
    contact_visible: np.ndarray
    views: np.ndarray

    def __len__(self) -> int:
        return len(self.shapes)

    def save(self, path: str | Path) -> Path:
        out = Path(path).with_suffix(".npz")
        out.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(
            out, **{f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        )
        return out

    @classmethod
    def load(cls, path: str | Path) -> GraspDataset:
        with np.load(Path(path), allow_pickle=False) as data:
            fields = {f.name: data[f.name] for f in dataclasses.fields(cls) if f.name in data}
        for name in ("visible", "contact_visible"):
            if name not in fields and "shapes" in fields:
                fields[name] = np.full(len(fields["shapes"]), np.nan)
        if "views" not in fields and "shapes" in fields:
            fields["views"] = np.full(len(fields["shapes"]), HEAD)
        missing = [f.name for f in dataclasses.fields(cls) if f.name not in fields]
        if missing:
            raise InvalidInputError(f"{path}: not a recognizer dataset (no {', '.join(missing)})")
        return cls(**fields)

    def select(self, mask: np.ndarray) -> GraspDataset:
        """The crops where `mask` (N,) bool is True."""
        return GraspDataset(
            **{f.name: getattr(self, f.name)[mask] for f in dataclasses.fields(self)}
        )

    @classmethod
    def concatenate(cls, parts: list[GraspDataset]) -> GraspDataset:
        return cls(
            **{
                f.name: np.concatenate([getattr(p, f.name) for p in parts])
                for f in dataclasses.fields(cls)
            }
        )


def sized_placement(kind: str, rng: np.random.Generator, sizes: bool = True) -> Placement:
    """A random placement (lfo.synthetic.random_placement) with the handle's sizes drawn from
    `SIZE_RANGES` (`sizes`), and the main part's by +-25 %."""
    place = random_placement(kind, rng)
    if not sizes:
        return place
    obj = place.task.object
    fields: dict[str, Any] = {}
    for name, ranges in SIZE_RANGES[obj.handle].items():
        values = tuple(float(rng.uniform(lo, hi)) for lo, hi in ranges)
        fields[name] = values[0] if len(values) == 1 else values
    fields["panel_half"] = tuple(float(v * rng.uniform(0.75, 1.25)) for v in obj.panel_half)
    obj = dataclasses.replace(obj, **fields)
    task = task_from_object(kind, obj, success_progress=place.goal, step_length=STEP_LENGTH)
    return Placement(kind, task, place.goal)


def contact_label(
    task: TaskConfig, shape: str, origin: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The true contact point (3,) [m] and approach (3,) unit of `task`'s handle, world frame
    (recognizer.py's definitions; a pole's at the height of `origin`)."""
    obj = task.object
    point = np.asarray(obj.handle_position, dtype=float)
    approach = np.asarray(task.hand_mount(), dtype=float)[:, 2]
    if shape == "pole":
        up = np.array([0.0, 0.0, 1.0])
        top = float(point @ up) + 0.5 * obj.handle_length - POLE_TOP_MARGIN
        height = min(float(np.asarray(origin) @ up), top)
        point = point + (height - float(point @ up)) * up
    return point, approach


#: The rays per image axis `handle_visibility` casts over the handle's image.
VISIBILITY_RAYS = 40


def handle_visibility(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    mount: CameraMount,
    around: FloatArray | None = None,
    radius: float = CONTACT_RADIUS,
) -> float:
    """The share [0, 1] of the handle (the object's grasped geom) that the camera at `mount`
    sees unoccluded: of the camera's rays through a `VISIBILITY_RAYS` square grid over the
    handle's image that meet the handle, those whose first surface (of the geoms the camera
    renders) is the handle. What hides it may be a distractor or the object itself; the
    sensor's missing returns do not count here. `around` (3,) [m]: the rays over the image of
    the handle's part within `radius` [m] of that point along each of the handle's axes (the
    contact point's surroundings) only. NaN when no ray meets the handle."""
    handle = model.geom(OBJECT_PREFIX + "object_handle").id
    pos = np.asarray(data.geom_xpos[handle], dtype=float)
    mat = np.asarray(data.geom_xmat[handle], dtype=float).reshape(3, 3)
    size = np.asarray(model.geom_size[handle], dtype=float)
    # the handle's bounding box (a capsule's or a cylinder's too: size[0] its radius)
    kind = int(model.geom_type[handle])
    half = size.copy()
    if kind in (int(mujoco.mjtGeom.mjGEOM_CAPSULE), int(mujoco.mjtGeom.mjGEOM_CYLINDER)):
        half = np.array([size[0], size[0], size[1] + size[0]])
    centre = np.zeros(3)
    if around is not None:  # the box's part within `radius` of the point, in the handle frame
        local = mat.T @ (np.asarray(around, dtype=float) - pos)
        lo, hi = np.maximum(-half, local - radius), np.minimum(half, local + radius)
        centre, half = 0.5 * (lo + hi), np.maximum(0.5 * (hi - lo), 1e-4)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = pos + (centre + signs * half) @ mat.T
    cam = mount.pose.to_camera(corners)
    if np.any(cam[:, 2] <= 1e-6):
        return float("nan")
    x, y = cam[:, 0] / cam[:, 2], cam[:, 1] / cam[:, 2]
    gx, gy = np.meshgrid(
        np.linspace(x.min(), x.max(), VISIBILITY_RAYS),
        np.linspace(y.min(), y.max(), VISIBILITY_RAYS),
    )
    rays = np.stack([gx.ravel(), gy.ravel(), np.ones(gx.size)], axis=1)
    rays = np.asarray(unit(rays @ mount.pose.rotation.T))
    origin = np.asarray(mount.pose.position, dtype=float)
    flat = mat.ravel()
    meets = np.array([mujoco.mju_rayGeom(pos, flat, size, origin, r, kind) >= 0.0 for r in rays])
    if not np.any(meets):
        return float("nan")
    first = np.zeros(len(rays), dtype=np.int32)
    dist = np.zeros(len(rays))
    rendered = np.asarray(mujoco.MjvOption().geomgroup, dtype=np.uint8)
    mujoco.mj_multiRay(
        model, data, origin, rays.ravel(), rendered, 1, -1, first, dist, None, len(rays), 100.0
    )
    return float(np.mean(first[meets] == handle))


def add_distractors(
    spec: mujoco.MjSpec, around: FloatArray, approach: FloatArray, rng: np.random.Generator
) -> None:
    """Up to `MAX_DISTRACTORS` visual boxes, cylinders and spheres 12-35 cm from `around`
    (3,) [m], none in the hand's corridor (within 10 cm of the approach line in front)."""
    kinds = (
        mujoco.mjtGeom.mjGEOM_BOX,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        mujoco.mjtGeom.mjGEOM_SPHERE,
    )
    a = unit(np.asarray(approach, dtype=float))
    for i in range(int(rng.integers(0, MAX_DISTRACTORS + 1))):
        for _ in range(20):
            p = around + random_unit(rng, 1)[0] * rng.uniform(0.12, 0.35)
            rel = p - around
            along = float(rel @ a)
            if along < 0.0 and float(np.linalg.norm(rel - along * a)) < 0.10:
                continue  # in front of the handle, where the hand comes in
            break
        geom = spec.worldbody.add_geom(
            name=f"distractor{i}",
            type=kinds[int(rng.integers(0, len(kinds)))],
            size=[float(v) for v in rng.uniform(0.01, 0.04, 3)],
            pos=[float(v) for v in p],
            rgba=list(SCENERY_RGBA),
        )
        geom.contype = 0
        geom.conaffinity = 0
        geom.group = VISUAL_GROUP


def _demonstrated_skill(
    place: Placement, rng: np.random.Generator, offset: HandOffset
) -> SkillParameters | None:
    """The skill of an offset demonstration of `place`, None when it gives none (or the wrong
    constraint: the crop would then be of another handle shape)."""
    demo = demo_of_object(
        place.task, place.goal, rng, TrackingNoise(noise=DEMO_NOISE),
        point_offset=offset.draw(rng),
    )  # fmt: skip
    try:
        skill = infer_skill(demo)
    except CapError:
        return None
    if skill.constraint_type != place.task.constraint_type or skill.start_position is None:
        return None
    return skill


@dataclass(frozen=True)
class DrawnScene:
    """One random scene before its cameras: the placement, its offset demonstration's skill,
    the handle shape and nominal crop frame the demonstration gives, the scene's spec (with
    its distractors), and the truth at the frame's origin: contact point (3,) [m] and approach
    (3,) unit, for scoring only."""

    place: Placement
    skill: SkillParameters
    shape: str
    frame: GraspFrame
    spec: mujoco.MjSpec
    truth: FloatArray
    approach: FloatArray


def draw_scene(
    kind: str,
    rng: np.random.Generator,
    sizes: bool = True,
    distractors: bool = True,
    offset: HandOffset | None = None,
) -> DrawnScene | None:
    """A random scene of `kind` drawn from `rng` (module docstring), None when its
    demonstration gives no usable skill."""
    place = sized_placement(kind, rng, sizes)
    skill = _demonstrated_skill(place, rng, offset or HandOffset())
    if skill is None:
        return None
    shape, frame = nominal_frame(skill)
    spec = scene_spec(place.task)
    truth, approach = contact_label(place.task, shape, frame.origin)
    if distractors:
        add_distractors(spec, truth, approach, rng)
    return DrawnScene(place, skill, shape, frame, spec, truth, approach)


#: Draws `generate` tries for one scene before it gives up on it.
SCENE_ATTEMPTS = 20


def scene_rngs(seed: int, kind: str, index: int) -> Iterator[np.random.Generator]:
    """The generators of scene `index` of `kind` (its index in sim.tasks.KINDS, so that a
    subset of kinds gives the same scenes), one per attempt: np.random.default_rng([seed, k,
    index, attempt])."""
    k = KINDS.index(kind)
    for attempt in range(SCENE_ATTEMPTS):
        yield np.random.default_rng([seed, k, index, attempt])


def second_look_rows(
    scene: DrawnScene,
    heads: dict[str, FloatArray],
    looks: list[tuple[str, FloatArray, FloatArray]],
    rng: np.random.Generator,
    noise: DepthNoise | None = None,
) -> dict[str, list[Any]]:
    """The second-look crops of `scene`, as the execution sequence's look phase makes them:
    for each (robot, look point (3,) [m], approach (3,) unit) of `looks`, the robot's wrist
    camera (lfo.perception.WRIST_CAMERAS) on the approach `standoff` back from the point,
    its image and the robot's head image's points (`heads`: robot -> (N, 3) [m]) in one crop
    at the point (the scene's nominal crop rotation). The hand is not in the scene (the
    sequence's self filter drops its pixels; what it hides is not modelled here)."""
    from constraint_aware.lfo.perception import WRIST_CAMERA_NAME, wrist_camera

    spec = scene.spec.copy()
    eye = spec.worldbody.add_body(name="second_look", mocap=True)
    frame0 = scene.frame
    rows: dict[str, list[Any]] = {f.name: [] for f in dataclasses.fields(GraspDataset)}
    mounts = {robot: wrist_camera(robot) for robot, _, _ in looks}
    # one camera per robot on the look's mocap body, its pose that body's
    on_eye = {
        robot: CameraMount(
            f"{WRIST_CAMERA_NAME}_{robot}", CameraPose(np.zeros(3), np.eye(3)), camera.intrinsics
        )
        for robot, camera in mounts.items()
    }
    for mount in on_eye.values():
        add_camera(spec, mount, body=eye.name)
    model = spec.compile()
    data = mujoco.MjData(model)
    renderers = {robot: DepthCamera(model, mount, noise) for robot, mount in on_eye.items()}
    try:
        for robot, point, approach in looks:
            camera = mounts[robot]
            z = unit(np.asarray(approach, dtype=float))
            x = unit(np.cross(frame0.rotation[:, 1], z))
            rotation = np.stack([x, np.cross(z, x), z], axis=1)
            data.mocap_pos[0] = np.asarray(point) - camera.standoff * z
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation).reshape(9))
            data.mocap_quat[0] = quat
            mujoco.mj_forward(model, data)
            frame = GraspFrame(np.asarray(point, dtype=float), frame0.rotation)
            wrist = renderers[robot]
            mount = dataclasses.replace(wrist.mount, pose=wrist.pose(data))
            image = wrist.capture(data, rng, region_of_interest(mount, crop_corners(frame)))
            points = np.concatenate([heads[robot], image.points()])
            seen = handle_visibility(model, data, mount)
            _append_crop(rows, scene, robot, frame, points, SECOND_LOOK, seen, model, data, mount)
    finally:
        for wrist in renderers.values():
            wrist.close()
    return rows


def _append_crop(
    rows: dict[str, list[Any]],
    scene: DrawnScene,
    robot: str,
    frame: GraspFrame,
    points: FloatArray,
    view: str,
    visible: float,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    mount: CameraMount,
) -> None:
    """One crop of `points` (N, 3) [m] in `frame` and its labels onto `rows` (`GraspDataset`'s
    fields): the truth at the frame's origin, `visible` the handle's share its camera (at
    `mount`) sees, the contact point's surroundings' share measured here."""
    truth, approach = contact_label(scene.place.task, scene.shape, frame.origin)
    rows["heights"].append(depth_crop(points, frame).astype(np.float32))
    rows["shapes"].append(HANDLE_SHAPES.index(scene.shape))
    rows["points"].append(frame.to_local(truth[None])[0])
    rows["approaches"].append(frame.rotation.T @ approach)
    rows["kinds"].append(scene.place.kind)
    rows["robots"].append(robot)
    rows["offsets"].append(float(np.linalg.norm(frame.origin - truth)))
    rows["nominal_errors"].append(float(angle_deg(frame.rotation[:, 2], approach)))
    rows["visible"].append(visible)
    rows["contact_visible"].append(handle_visibility(model, data, mount, around=truth))
    rows["views"].append(view)


#: Where a second look aims from a head crop: (robot, crop frame, height map, handle shape)
#: -> the look point (3,) [m] and approach (3,), or None for no look (the benchmark: the
#: recognizer's answer for the crop, as the sequence aims its wrist camera).
LookFrom = Callable[[str, GraspFrame, FloatArray, str], tuple[FloatArray, FloatArray] | None]


def scene_samples(
    kind: str,
    rng: np.random.Generator,
    robots: tuple[str, ...] = ("hook-hand", "jaco"),
    crops_per_view: int = 4,
    sizes: bool = True,
    distractors: bool = True,
    offset: HandOffset | None = None,
    noise: DepthNoise | None = None,
    looks_per_view: int = 0,
    look_from: LookFrom | None = None,
) -> GraspDataset | None:
    """The crops of one random scene of `kind` (module docstring), None when its
    demonstration gives no usable skill. Second looks (`second_look_rows`), drawn after the
    head crops: `looks_per_view` per robot aimed `LOOK_SPREAD` around the contact point (for
    training), and with `look_from` one per head crop, aimed where it answers for the crop
    (for scoring the sequence's second recognition)."""
    offset = offset or HandOffset()
    scene = draw_scene(kind, rng, sizes, distractors, offset)
    if scene is None:
        return None
    frame0, spec = scene.frame, scene.spec
    mounts: list[CameraMount] = []
    for robot in robots:
        mount = head_camera(robot, scene.skill)
        mount = dataclasses.replace(mount, name=f"{mount.name}_{robot}")
        add_camera(spec, mount)
        mounts.append(mount)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rows: dict[str, list[Any]] = {f.name: [] for f in dataclasses.fields(GraspDataset)}
    heads: dict[str, FloatArray] = {}
    origins_of: list[FloatArray] = []
    for robot, mount in zip(robots, mounts, strict=True):
        drawn = [scene.truth + offset.draw(rng) for _ in range(crops_per_view - 1)]
        origins = [frame0.origin, *drawn]
        origins_of.extend(np.asarray(o) for o in origins)
        corners = np.concatenate([crop_corners(GraspFrame(o, frame0.rotation)) for o in origins])
        roi = region_of_interest(mount, corners)
        with DepthCamera(model, mount, noise) as camera:
            image = camera.capture(data, rng, roi)
        points = image.points()
        visible = handle_visibility(model, data, mount)
        for origin in origins:
            frame = GraspFrame(np.asarray(origin), frame0.rotation)
            _append_crop(rows, scene, robot, frame, points, HEAD, visible, model, data, mount)
        heads[robot] = points
    looks: list[tuple[str, FloatArray, FloatArray]] = []
    for robot in robots:
        for _ in range(looks_per_view):
            looks.append((robot, scene.truth + rng.normal(0.0, LOOK_SPREAD, 3), scene.approach))
    if look_from is not None:
        for i, robot in enumerate(rows["robots"]):
            frame = GraspFrame(origins_of[i], frame0.rotation)
            found = look_from(robot, frame, rows["heights"][i], scene.shape)
            if found is not None:
                looks.append((robot, *found))
    if looks:
        for name, values in second_look_rows(scene, heads, looks, rng, noise).items():
            rows[name].extend(values)
    return GraspDataset(**{k: np.asarray(v) for k, v in rows.items()})


def generate(
    scenes_per_kind: int,
    seed: int = 0,
    kinds: tuple[str, ...] = KINDS,
    robots: tuple[str, ...] = ("hook-hand", "jaco"),
    crops_per_view: int = 4,
    sizes: bool = True,
    distractors: bool = True,
    progress: Callable[[int, int], None] | None = None,
    noise: DepthNoise | None = None,
    looks_per_view: int = 0,
    look_from: LookFrom | None = None,
) -> GraspDataset:
    """`scenes_per_kind` usable scenes of each kind (`scene_samples`, the sensor's `noise`:
    sim.camera's default when None; its second looks), seeded: scene i of a kind draws from
    `scene_rngs(seed, kind, i)` until one gives a usable demonstration."""
    if scenes_per_kind < 1:
        raise InvalidInputError(f"scenes_per_kind: {scenes_per_kind}; valid: >= 1")
    if crops_per_view < 1:
        raise InvalidInputError(f"crops_per_view: {crops_per_view}; valid: >= 1")
    parts: list[GraspDataset] = []
    total = scenes_per_kind * len(kinds)
    done = 0
    for kind in kinds:
        if kind not in KINDS:
            raise InvalidInputError(f"kinds: {kind!r}; valid: {', '.join(KINDS)}")
        for i in range(scenes_per_kind):
            for rng in scene_rngs(seed, kind, i):
                part = scene_samples(
                    kind, rng, robots, crops_per_view, sizes, distractors, noise=noise,
                    looks_per_view=looks_per_view, look_from=look_from,
                )  # fmt: skip
                if part is not None:
                    parts.append(part)
                    break
            done += 1
            if progress is not None:
                progress(done, total)
    return GraspDataset.concatenate(parts)
