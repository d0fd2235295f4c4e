"""A depth camera in the simulated scene: placement, MuJoCo depth rendering, noise, points.

Frames. A camera's pose is given in the OpenCV convention: its z axis is the optical axis
(pointing into the scene), x points right in the image and y down. `CameraPose.rotation`
(3, 3) has these axes as columns in the world frame. MuJoCo's own cameras look along their
-z with y up; `add_camera` converts. Pixel (row v, column u) covers the image-plane square
[u, u + 1) x [v, v + 1) of a pinhole camera with focal length f = (height / 2) / tan(fovy / 2)
[px] and principal point (width / 2, height / 2): its centre back-projects to
depth * ((u + 0.5 - cx) / f, (v + 0.5 - cy) / f, 1) in the camera frame. `depth` is the
distance along the optical axis [m] (not along the ray).

Rendering. `DepthCamera` reads MuJoCo's offscreen depth buffer; on Linux without a display it
runs on EGL (sim/render.py decides the backend the same way for colour images). Its depth
agrees with `mujoco.mj_ray` cast through each pixel to 0.02 % of the distance (its
float32 buffer; tests/test_perception.py).
`capture(..., roi=...)` draws the noise over a region of interest only (the rest is NaN).

Noise (`DepthNoise`), as structured-light and stereo depth sensors show it (Nguyen, Izadi and
Lovell 2012, for the Kinect; RealSense data sheets give the same quadratic growth):
- axial Gaussian noise with std sigma(z) = base + quadratic * (z - reference)^2 [m], growing
  with the incidence angle theta between the surface normal and the ray as
  + angular * theta^2 / (pi/2 - theta)^2 / sqrt(z);
- no return at grazing incidence: a pixel is dropped with a probability rising linearly from
  0 at `grazing_start_deg` to 1 at `grazing_end_deg`;
- no return at depth edges: where a neighbour is more than `edge_jump` farther or nearer, the
  pixel is dropped with probability `edge_drop` (mixed pixels are what sensors discard there);
- a small share of random dropouts, and nothing outside [min_range, max_range].
A missing pixel is NaN. Noise is drawn from the generator passed to `DepthCamera.capture`,
so a seeded generator gives the same image.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from constraint_aware.errors import (
    CapError,
    ConfigError,
    UnknownNameError,
    check_int,
    check_number,
    check_vector,
)
from constraint_aware.geometry import FloatArray, unit
from constraint_aware.sim import render

#: OpenCV camera axes -> MuJoCo camera axes (MuJoCo looks along -z with y up).
_CV_TO_MJ = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class CameraIntrinsics:
    """A pinhole camera: image size [px] and vertical field of view [deg]."""

    width: int = 640
    height: int = 480
    fovy_deg: float = 58.0  # a RealSense D435's depth stream: 87 x 58 deg

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = check_int(f"CameraIntrinsics.{name}", getattr(self, name), low=8)
            if value > 4096:
                raise ConfigError(f"CameraIntrinsics.{name}", value, "an integer in [8, 4096]")
        check_number("CameraIntrinsics.fovy_deg", self.fovy_deg, low=5.0, high=150.0, unit="deg")

    @property
    def focal(self) -> float:
        """[px] the focal length (square pixels)."""
        return 0.5 * self.height / math.tan(math.radians(self.fovy_deg) / 2.0)

    @property
    def centre(self) -> tuple[float, float]:
        """(cx, cy) [px] the principal point, in continuous image coordinates."""
        return 0.5 * self.width, 0.5 * self.height

    def matrix(self) -> FloatArray:
        """(3, 3) the camera matrix K (OpenCV convention, continuous pixel coordinates)."""
        cx, cy = self.centre
        f = self.focal
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraPose:
    """Extrinsics: position (3,) [m] and rotation (3, 3) whose columns are the camera's x
    (image right), y (image down) and z (optical axis) in the world frame."""

    position: FloatArray
    rotation: FloatArray

    def to_camera(self, points: FloatArray) -> FloatArray:
        """(N, 3) world points [m] in the camera frame."""
        return np.asarray((np.asarray(points) - self.position) @ self.rotation, dtype=float)

    def to_world(self, points: FloatArray) -> FloatArray:
        """(N, 3) camera-frame points [m] in the world frame."""
        return np.asarray(np.asarray(points) @ self.rotation.T + self.position, dtype=float)


def look_at(position: FloatArray, target: FloatArray, up: FloatArray | None = None) -> CameraPose:
    """The pose of a camera at `position` (3,) [m] whose optical axis passes through `target`
    (3,) [m], image up as close to `up` (default world z) as the axis allows.

    Raises:
        ConfigError: when position and target coincide, or the axis is parallel to `up`.
    """
    p = np.array(check_vector("camera position", position, unit="m"))
    t = np.array(check_vector("camera target", target, unit="m"))
    z = t - p
    if float(np.linalg.norm(z)) < 1e-6:
        raise ConfigError("camera target", tuple(t), "a point away from the camera")
    z = unit(z)
    u = np.array([0.0, 0.0, 1.0]) if up is None else unit(np.asarray(up, dtype=float))
    x = np.cross(z, u)  # image right: with y = down, x = y cross z points right
    if float(np.linalg.norm(x)) < 1e-6:
        raise ConfigError("camera up", tuple(u), "not parallel to the optical axis")
    x = unit(x)
    y = np.cross(z, x)
    return CameraPose(p, np.stack([x, y, z], axis=1))


@dataclass(frozen=True)
class CameraMount:
    """A named camera of the scene: where it is and what it sees."""

    name: str
    pose: CameraPose
    intrinsics: CameraIntrinsics = field(default_factory=CameraIntrinsics)


def add_camera(spec: mujoco.MjSpec, mount: CameraMount, body: str | None = None) -> None:
    """Compose `mount` into a scene's spec (and make the offscreen buffer large enough for its
    image): a fixed world camera, or with `body` (a body's name) one that moves with that
    body, `mount.pose` then given in the body's frame (a wrist camera).

    Raises:
        UnknownNameError: when the spec has no body `body`.
    """
    quat = np.zeros(4)
    mj_rot = mount.pose.rotation @ _CV_TO_MJ
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(mj_rot).reshape(9))
    parent = spec.worldbody
    if body is not None:
        parent = spec.body(body)
        if parent is None:
            names = [b.name for b in spec.bodies]
            raise UnknownNameError("body to mount the camera on", body, names)
    parent.add_camera(
        name=mount.name,
        pos=[float(v) for v in mount.pose.position],
        quat=[float(v) for v in quat],
        fovy=mount.intrinsics.fovy_deg,
    )
    glob = spec.visual.global_
    glob.offwidth = max(glob.offwidth, mount.intrinsics.width)
    glob.offheight = max(glob.offheight, mount.intrinsics.height)


def add_tool_camera(spec: mujoco.MjSpec, mount: CameraMount, site: str) -> None:
    """Compose `mount`, its pose given in the frame of the site `site` (a robot's tool
    point), onto the body that carries the site: a camera that moves with the hand.

    Raises:
        UnknownNameError: when the spec has no site `site`.
    """
    found = spec.site(site)
    if found is None:
        raise UnknownNameError("site to mount the camera at", site, [s.name for s in spec.sites])
    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, np.asarray(found.quat, dtype=float))
    at_site = rotation.reshape(3, 3)
    pose = CameraPose(
        np.asarray(found.pos, dtype=float) + at_site @ np.asarray(mount.pose.position),
        at_site @ np.asarray(mount.pose.rotation),
    )
    add_camera(spec, CameraMount(mount.name, pose, mount.intrinsics), body=found.parent.name)


def body_tree_geoms(model: mujoco.MjModel, body: str) -> tuple[int, ...]:
    """The ids of every geom of the tree (the bodies under the same child of the world) that
    holds `body`: a robot's own geoms, from one of its bodies."""
    root = int(model.body_rootid[model.body(body).id])
    return tuple(int(g) for g in np.flatnonzero(model.body_rootid[model.geom_bodyid] == root))


@dataclass(frozen=True)
class DepthNoise:
    """The depth sensor's error model (module docstring). Lengths [m], angles [deg]."""

    base: float = 0.0012  # [m] axial std at the reference distance
    quadratic: float = 0.0019  # [m / m^2] growth of the axial std with distance
    reference: float = 0.4  # [m]
    angular: float = 0.0001  # [m^1.5] growth of the axial std with the incidence angle
    grazing_start_deg: float = 70.0  # returns start to fail beyond this incidence angle
    grazing_end_deg: float = 85.0  # ... and none come back beyond this one
    edge_jump: float = 0.02  # [m] a depth step to a neighbour that makes a pixel an edge
    edge_drop: float = 0.5  # [-] probability that an edge pixel returns nothing
    dropout: float = 0.005  # [-] probability of a random missing pixel
    min_range: float = 0.2  # [m]
    max_range: float = 4.0  # [m]

    def __post_init__(self) -> None:
        n = "DepthNoise."
        for name in ("base", "quadratic", "angular", "edge_jump"):
            check_number(n + name, getattr(self, name), low=0.0)
        check_number(n + "reference", self.reference, low=0.0, unit="m")
        for name in ("edge_drop", "dropout"):
            check_number(n + name, getattr(self, name), low=0.0, high=1.0)
        check_number(n + "grazing_start_deg", self.grazing_start_deg, low=0.0, high=90.0)
        check_number(
            n + "grazing_end_deg", self.grazing_end_deg, low=self.grazing_start_deg, high=90.0
        )
        check_number(n + "min_range", self.min_range, low=0.0, unit="m")
        check_number(n + "max_range", self.max_range, low=self.min_range, low_open=True, unit="m")

    def axial_std(self, depth: FloatArray, incidence: FloatArray) -> FloatArray:
        """[m] the axial noise std at `depth` [m] and `incidence` [rad] (same shapes)."""
        theta = np.minimum(incidence, math.radians(89.0))
        angular = self.angular * theta**2 / (0.5 * math.pi - theta) ** 2 / np.sqrt(depth)
        return np.asarray(self.base + self.quadratic * (depth - self.reference) ** 2 + angular)


#: A sensor without any error: the rendered depth as it is (tests, ground truth).
NO_NOISE = DepthNoise(
    base=0.0, quadratic=0.0, angular=0.0, grazing_start_deg=90.0, grazing_end_deg=90.0,
    edge_drop=0.0, dropout=0.0, min_range=0.0,
)  # fmt: skip


@dataclass(frozen=True)
class DepthImage:
    """One depth image: depth (H, W) [m] along the optical axis, NaN where the sensor gave no
    return, with the intrinsics and extrinsics it was taken with."""

    depth: FloatArray
    intrinsics: CameraIntrinsics
    pose: CameraPose

    def camera_points(self) -> FloatArray:
        """(H, W, 3) [m] each pixel's point in the camera frame (NaN where no return)."""
        return backproject(self.depth, self.intrinsics)

    def points(self) -> FloatArray:
        """(N, 3) [m] the valid pixels' points in the world frame."""
        pts = self.camera_points().reshape(-1, 3)
        pts = pts[np.isfinite(pts[:, 2])]
        return self.pose.to_world(pts)

    def project(self, points: FloatArray) -> FloatArray:
        """(N, 2) [px] world points' continuous image coordinates (u right, v down); points
        behind the camera get NaN."""
        cam = self.pose.to_camera(np.atleast_2d(points))
        f = self.intrinsics.focal
        cx, cy = self.intrinsics.centre
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.stack([f * cam[:, 0] / cam[:, 2] + cx, f * cam[:, 1] / cam[:, 2] + cy], axis=1)
        uv[cam[:, 2] <= 0] = np.nan
        return uv


def backproject(
    depth: FloatArray, intrinsics: CameraIntrinsics, origin: tuple[int, int] = (0, 0)
) -> FloatArray:
    """(h, w, 3) [m] camera-frame points of a depth image (h, w) [m] (NaN stays NaN): the
    whole image, or the window of it whose first pixel is `origin` (row, column)."""
    h, w = depth.shape
    v0, u0 = origin
    if v0 < 0 or u0 < 0 or v0 + h > intrinsics.height or u0 + w > intrinsics.width:
        raise ConfigError(
            "depth window", f"{w}x{h} at {origin}", f"inside {intrinsics.width}x{intrinsics.height}"
        )
    f = intrinsics.focal
    cx, cy = intrinsics.centre
    u = (np.arange(u0, u0 + w) + 0.5 - cx) / f
    v = (np.arange(v0, v0 + h) + 0.5 - cy) / f
    z = np.asarray(depth, dtype=float)
    return np.stack([z * u[None, :], z * v[:, None], z], axis=-1)


def incidence_angles(camera_points: FloatArray) -> FloatArray:
    """(H, W) [rad] the angle between each pixel's ray and the surface normal there, from the
    neighbours' points (central differences); pi/2 where the neighbourhood is not finite."""
    p = camera_points
    du = np.zeros_like(p)
    dv = np.zeros_like(p)
    du[:, 1:-1] = p[:, 2:] - p[:, :-2]
    dv[1:-1, :] = p[2:, :] - p[:-2, :]
    # the normal du x dv, by components (np.cross is ~10x slower on images)
    ax, ay, az = du[..., 0], du[..., 1], du[..., 2]
    bx, by, bz = dv[..., 0], dv[..., 1], dv[..., 2]
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    px, py, pz = p[..., 0], p[..., 1], p[..., 2]
    with np.errstate(invalid="ignore"):
        norm = np.sqrt((nx * nx + ny * ny + nz * nz) * (px * px + py * py + pz * pz))
        cos = np.abs(nx * px + ny * py + nz * pz) / np.where(norm > 0, norm, np.inf)
    cos = np.where(np.isfinite(cos), np.minimum(cos, 1.0), 0.0)
    return np.asarray(np.arccos(cos))


def _edges(depth: FloatArray, jump: float) -> NDArray[np.bool_]:
    """(H, W) bool: pixels with a 4-neighbour whose depth differs by more than `jump` [m]."""
    z = np.where(np.isfinite(depth), depth, np.inf)
    edge = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        dx = np.abs(np.diff(z, axis=1)) > jump
        dy = np.abs(np.diff(z, axis=0)) > jump
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    edge[1:, :] |= dy
    edge[:-1, :] |= dy
    return edge


def apply_noise(
    depth: FloatArray,
    intrinsics: CameraIntrinsics,
    noise: DepthNoise,
    rng: np.random.Generator,
) -> FloatArray:
    """A noisy copy (H, W) [m] of a true depth image (H, W) [m]: `DepthNoise`'s model, drawn
    from `rng`; missing pixels are NaN. Only the bounding box of the finite pixels is drawn
    (a region of interest costs what its size costs)."""
    z = np.asarray(depth, dtype=float)
    out = np.full(z.shape, np.nan)
    rows = np.flatnonzero(np.isfinite(z).any(axis=1))
    cols = np.flatnonzero(np.isfinite(z).any(axis=0))
    if rows.size == 0:
        return out
    v0, v1, u0, u1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    window = z[v0:v1, u0:u1]
    theta = incidence_angles(backproject(window, intrinsics, (int(v0), int(u0))))
    noisy = window + rng.normal(size=window.shape) * noise.axial_std(window, theta)
    start, end = math.radians(noise.grazing_start_deg), math.radians(noise.grazing_end_deg)
    if end > start:
        drop = rng.uniform(size=window.shape) < np.clip((theta - start) / (end - start), 0, 1)
    else:
        drop = theta >= end if end < 0.5 * math.pi else np.zeros(window.shape, dtype=bool)
    if noise.edge_drop > 0:
        drop |= _edges(window, noise.edge_jump) & (rng.uniform(size=window.shape) < noise.edge_drop)
    if noise.dropout > 0:
        drop |= rng.uniform(size=window.shape) < noise.dropout
    drop |= ~np.isfinite(window) | (window < noise.min_range) | (window > noise.max_range)
    noisy[drop] = np.nan
    out[v0:v1, u0:u1] = noisy
    return out


def region_of_interest(
    mount: CameraMount, points: FloatArray, margin: int = 4
) -> tuple[int, int, int, int]:
    """(row start, row stop, column start, column stop) [px] of the image rectangle that holds
    the world points (N, 3) [m], `margin` pixels wider on each side."""
    cam = mount.pose.to_camera(np.atleast_2d(points))
    cam = cam[cam[:, 2] > 1e-6]
    if len(cam) == 0:
        return (0, 0, 0, 0)
    f = mount.intrinsics.focal
    cx, cy = mount.intrinsics.centre
    u = f * cam[:, 0] / cam[:, 2] + cx
    v = f * cam[:, 1] / cam[:, 2] + cy
    return (
        int(np.floor(v.min())) - margin,
        int(np.ceil(v.max())) + margin,
        int(np.floor(u.min())) - margin,
        int(np.ceil(u.max())) + margin,
    )


class _EglDepthRenderer(render._EglRenderer):
    """Depth on an EGL context of our own (see sim/render.py: MuJoCo chose GLFW at import)."""

    MAX_GEOM = 2000  # the scenes hold a few hundred
    # the smallest font: a depth image shows no text (the 150 % font costs ~0.5 s here)
    FONT_SCALE = mujoco.mjtFontScale.mjFONTSCALE_50

    def __init__(self, model: mujoco.MjModel, height: int, width: int) -> None:
        super().__init__(model, height, width)
        # the depth map mujoco.Renderer reads (and `_linear_depth` converts): 0 at the far plane
        self._context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR

    def depth(self, geoms: bool = False) -> tuple[FloatArray, NDArray[np.int32] | None]:
        """(H, W) [m] the depth and, with `geoms`, (H, W) the id of the geom each pixel shows
        (-1: none)."""
        self._gl.make_current()
        # segmentation mode draws flat geometry only (no lighting, shadows or reflections):
        # the depth buffer then holds the surfaces alone, as mujoco.Renderer reads it; each
        # geom's colour is its segment id, which `geoms` reads back
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = True
        self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = True
        mujoco.mjr_render(self._rect, self._scene, self._context)
        h, w = self._rgb.shape[:2]
        buffer = np.empty((h, w), dtype=np.float32)
        mujoco.mjr_readPixels(self._rgb if geoms else None, buffer, self._rect, self._context)
        depth = _linear_depth(self._model, np.flipud(buffer))
        if not geoms:
            return depth, None
        return depth, _segment_geoms(self._scene, np.flipud(self._rgb))


def _segment_geoms(scene: mujoco.MjvScene, rgb: NDArray[np.uint8]) -> NDArray[np.int32]:
    """(H, W) the model geom id of each pixel of a segmentation rendering (-1: none or not a
    geom), decoded as mujoco.Renderer decodes its segmentation images."""
    c = rgb.astype(np.int64)
    seg = c[..., 0] + c[..., 1] * 256 + c[..., 2] * 65536  # segment id + 1, 0: background
    lookup = np.full(scene.ngeom + 1, -1, dtype=np.int32)
    for g in scene.geoms[: scene.ngeom]:
        if g.segid >= 0 and g.objtype == int(mujoco.mjtObj.mjOBJ_GEOM):
            lookup[g.segid + 1] = g.objid
    seg[(seg < 0) | (seg > scene.ngeom)] = 0
    return np.asarray(lookup[seg], dtype=np.int32)


def _linear_depth(model: mujoco.MjModel, buffer: FloatArray) -> FloatArray:
    """Metric depth [m] from OpenGL's (reversed-Z) depth buffer, as mujoco.Renderer does."""
    extent = model.stat.extent
    znear = np.float32(model.vis.map.znear * extent)
    zfar = np.float32(model.vis.map.zfar * extent)
    c = -(zfar + znear) / (zfar - znear)
    d = -(np.float32(2) * zfar * znear) / (zfar - znear)
    c = np.float32(-0.5) * c - np.float32(0.5)
    d = np.float32(-0.5) * d
    return np.asarray(d / (buffer.astype(np.float64) + c), dtype=float)


class DepthCamera:
    """Renders a scene camera's depth images (a model camera named `name`, see `add_camera`).

    Only geoms show (no sites, no frames), as a real sensor sees them. A camera mounted on a
    body (a wrist camera) takes its pose from the state it renders; a world camera's is
    `mount.pose`. `own_geoms`: geom ids of the robot that carries the camera; its pixels give
    no return (a self filter: the robot knows its own shape and where it is), so that the
    hand's fingers in view are never taken for the object; they still hide what is behind
    them. Call `close()` when done (or use it as a context manager): it owns an OpenGL
    context.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        mount: CameraMount,
        noise: DepthNoise | None = None,
        own_geoms: tuple[int, ...] = (),
    ) -> None:
        try:
            self._id = model.camera(mount.name).id
        except KeyError:
            raise CapError(
                f"the scene has no camera {mount.name!r}: compose it with add_camera"
            ) from None
        self.model = model
        self.mount = mount
        self.noise = DepthNoise() if noise is None else noise
        self.own_geoms = np.asarray(own_geoms, dtype=np.int32)
        self._on_body = int(model.cam_bodyid[self._id]) != 0
        w, h = mount.intrinsics.width, mount.intrinsics.height
        self._option = mujoco.MjvOption()
        self._option.sitegroup[:] = 0  # sites are markers, not surfaces
        self._renderer: Any
        # a depth image needs no shadow map: without it the context builds ~10x faster
        shadow = model.vis.quality.shadowsize
        model.vis.quality.shadowsize = 0
        try:
            if render.headless_egl_needed():
                render._chose_egl = True
                os.environ["MUJOCO_GL"] = "egl"
                self._renderer = _EglDepthRenderer(model, height=h, width=w)
                self._renderer._option = self._option
                self._egl = True
            else:
                self._renderer = mujoco.Renderer(
                    model, height=h, width=w, max_geom=_EglDepthRenderer.MAX_GEOM,
                    font_scale=_EglDepthRenderer.FONT_SCALE,
                )  # fmt: skip
                self._renderer.enable_depth_rendering()
                self._egl = False
        except CapError:
            raise
        except Exception as exc:
            raise CapError(
                f"offscreen rendering unavailable ({exc}); set MUJOCO_GL=egl or osmesa"
            ) from exc
        finally:
            model.vis.quality.shadowsize = shadow
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._camera.fixedcamid = self._id

    def true_depth(self, data: mujoco.MjData) -> FloatArray:
        """(H, W) [m] the rendered depth without sensor error (beyond the far plane and on
        `own_geoms`: NaN)."""
        own = self.own_geoms.size > 0
        geoms: NDArray[np.int32] | None = None
        if self._egl:
            self._renderer.update_scene(data, self._camera)
            depth, geoms = self._renderer.depth(geoms=own)
        else:
            self._renderer.update_scene(data, self._camera, scene_option=self._option)
            depth = np.asarray(self._renderer.render(), dtype=float)
            if own:
                self._renderer.disable_depth_rendering()
                self._renderer.enable_segmentation_rendering()
                try:
                    seg = np.asarray(self._renderer.render(), dtype=np.int32)  # (id, type)
                    geoms = np.where(seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[..., 0], -1)
                finally:
                    self._renderer.disable_segmentation_rendering()
                    self._renderer.enable_depth_rendering()
        far = self.model.vis.map.zfar * self.model.stat.extent
        depth = np.where(depth < 0.999 * far, depth, np.nan)
        if geoms is not None:
            depth[np.isin(geoms, self.own_geoms)] = np.nan
        return np.asarray(depth)

    def pose(self, data: mujoco.MjData) -> CameraPose:
        """The camera's pose at `data`'s state: `mount.pose` for a world camera, the body's
        present pose composed with it for a camera on a body."""
        if not self._on_body:
            return self.mount.pose
        rotation = np.asarray(data.cam_xmat[self._id], dtype=float).reshape(3, 3) @ _CV_TO_MJ
        return CameraPose(np.array(data.cam_xpos[self._id], dtype=float), rotation)

    def capture(
        self,
        data: mujoco.MjData,
        rng: np.random.Generator,
        roi: tuple[int, int, int, int] | None = None,
    ) -> DepthImage:
        """A depth image of the scene at `data`'s state, with the sensor's noise from `rng`;
        only inside `roi` (row start, row stop, column start, column stop [px]) when given,
        NaN elsewhere."""
        depth = self.true_depth(data)
        if roi is not None:
            v0, v1, u0, u1 = roi
            inside = np.full(depth.shape, np.nan)
            rows = slice(max(v0, 0), max(v1, 0))
            cols = slice(max(u0, 0), max(u1, 0))
            inside[rows, cols] = depth[rows, cols]
            depth = inside
        depth = apply_noise(depth, self.mount.intrinsics, self.noise, rng)
        return DepthImage(depth, self.mount.intrinsics, self.pose(data))

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> DepthCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def depth_rendering_available() -> bool:
    """Whether `DepthCamera` can render here (an OpenGL context for offscreen rendering: EGL
    or OSMesa headless, a display otherwise), tried on a one-camera scene of 8 x 8 pixels."""
    spec = mujoco.MjSpec()
    small = CameraIntrinsics(width=8, height=8)
    pose = CameraPose(np.zeros(3), np.eye(3))
    mount = CameraMount("probe", pose, small)
    add_camera(spec, mount)
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_BOX, size=[1.0, 1.0, 0.01], pos=[0.0, 0.0, 1.0]
    )
    try:
        with DepthCamera(spec.compile(), mount) as camera:
            camera.true_depth(mujoco.MjData(camera.model))
    except CapError:
        return False
    return True
