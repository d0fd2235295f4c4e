"""The contact-points recognizer: where to grasp, from a depth crop around the demonstrated point.

The paper's execution phase (its LfO section) selects, by the demonstrated force-exertion type,
a contact-points recognizer whose input is a depth image of the target object and whose output
is the contact points to grasp. Here:

- The crop (`depth_crop`). The demonstration says roughly where the hand held the object and
  how it approached (a `GraspFrame`: origin at the demonstrated point, z along the nominal
  approach, x and y across it). The camera's points within `CROP_SIZE` / 2 of the origin
  across the approach and `DEPTH_RANGE` along it are rasterized into a `CROP_PIXELS` square
  height map seen from the hand: each cell holds how far the nearest surface stands out toward
  the hand (-z) [m], NaN where the camera saw nothing. The map is the same whatever the
  camera's viewpoint (an orthographic view along the approach).
- The output (`Recognition`): the contact point (3,) [m] and the approach direction (3,)
  (unit, from the hand into the object) in the world frame. The contact point is the grasp
  centre of the handle shape the force-exertion type implies (`HANDLE_SHAPES`): a bar's (lazy
  closure) axis at its middle; a plate's or a knob's (passive closure) top-face centre; for a
  pole (active closure), which the hand may squeeze anywhere along, the point of its axis at
  the demonstrated height, kept `POLE_TOP_MARGIN` below its top.
- The approach is the crop's for bars (the panel behind them) and plates (their top face),
  the demonstration's nominal one for poles (`NOMINAL_APPROACH`), and for knobs the nominal
  one unless the knob's top face, found around the contact point, contradicts it
  (`knob_approach`).
- Two methods: `GeometricRecognizer` segments the surface that stands out near the
  demonstrated point and takes its centre and the normal of the surface around it;
  `ContactPointRecognizer` is a small CNN (weights `.npz` + JSON card, like the policy,
  validated at load; trained by `cap train-grasp`, torch only there) that runs on numpy.

Everything here is numpy and scipy: no simulator, no torch.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from constraint_aware.errors import CapError, InvalidInputError, UnknownNameError
from constraint_aware.geometry import FloatArray, angle_deg, unit

BoolArray = NDArray[np.bool_]

CROP_PIXELS = 64  # the height map's side [cells]
CROP_SIZE = 0.28  # [m] the height map's side across the approach
DEPTH_RANGE = 0.12  # [m] surfaces this far in front of or behind the origin are kept
CELL = CROP_SIZE / CROP_PIXELS  # [m] one cell
#: A cell's height is the mean of its points within this of the nearest one [m] (averages
#: the sensor's noise without mixing a handle with the surface behind it).
CELL_LAYER = 0.01
POLE_TOP_MARGIN = 0.03  # [m] a pole's contact point stays this far below its top
HANDLE_SHAPES = ("bar", "pole", "plate", "knob")
#: The handle shape each force-exertion type grasps (revolute passive closures: a knob).
SHAPE_OF_GRASP = {"lazy_closure": "bar", "active_force_closure": "pole"}
CARD_FORMAT = "constraint-aware-recognizer/1"
METHODS = ("cnn", "geometric")
DEFAULT_METHOD = "cnn"


class RecognitionError(CapError):
    """The crop does not show what the recognizer needs (too few points, no handle)."""


def handle_shape(grasp: str, constraint: str) -> str:
    """The handle shape a force-exertion type grasps: lazy closure a bar, active force closure
    a pole, passive force closure a plate on a slide or a crank's knob on a hinge."""
    if grasp in SHAPE_OF_GRASP:
        return SHAPE_OF_GRASP[grasp]
    if grasp != "passive_force_closure":
        raise UnknownNameError(
            "force-exertion type", grasp, [*SHAPE_OF_GRASP, "passive_force_closure"]
        )
    return "knob" if constraint == "revolute" else "plate"


@dataclass(frozen=True)
class GraspFrame:
    """The crop's frame: origin (3,) [m] and rotation (3, 3) whose columns are x, y (across
    the approach) and z (the approach, from the hand into the object), world frame."""

    origin: FloatArray
    rotation: FloatArray

    def to_local(self, points: FloatArray) -> FloatArray:
        """(N, 3) world points [m] in the frame."""
        return np.asarray((np.asarray(points) - self.origin) @ self.rotation, dtype=float)

    def to_world(self, points: FloatArray) -> FloatArray:
        """(N, 3) frame points [m] in the world frame."""
        return np.asarray(np.asarray(points) @ self.rotation.T + self.origin, dtype=float)


@dataclass(frozen=True)
class Recognition:
    """Where to grasp: contact point (3,) [m] and approach (3,) unit (from the hand into the
    object), world frame, and which method found them."""

    contact_point: FloatArray
    approach: FloatArray
    method: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "contact_point": [float(v) for v in self.contact_point],
            "approach": [float(v) for v in self.approach],
            "method": self.method,
        }


def cell_centres() -> FloatArray:
    """(CROP_PIXELS,) [m] the cells' centre coordinates along either crop axis."""
    return np.asarray((np.arange(CROP_PIXELS) + 0.5) * CELL - 0.5 * CROP_SIZE)


def depth_crop(points: FloatArray, frame: GraspFrame) -> FloatArray:
    """(CROP_PIXELS, CROP_PIXELS) the height map [m] of world points (N, 3) in `frame`: rows
    along its x, columns along its y; each cell how far its surface stands out toward the hand
    (-z), NaN where no point fell (module docstring)."""
    q = frame.to_local(np.asarray(points, dtype=float).reshape(-1, 3))
    half = 0.5 * CROP_SIZE
    keep = (np.abs(q[:, 0]) < half) & (np.abs(q[:, 1]) < half) & (np.abs(q[:, 2]) < DEPTH_RANGE)
    q = q[keep]
    n = CROP_PIXELS
    i = np.clip(((q[:, 0] + half) / CELL).astype(int), 0, n - 1)
    j = np.clip(((q[:, 1] + half) / CELL).astype(int), 0, n - 1)
    flat = i * n + j
    nearest = np.full(n * n, np.inf)
    np.minimum.at(nearest, flat, q[:, 2])
    layer = q[:, 2] <= nearest[flat] + CELL_LAYER
    total = np.bincount(flat[layer], weights=q[layer, 2], minlength=n * n)
    count = np.bincount(flat[layer], minlength=n * n)
    with np.errstate(invalid="ignore", divide="ignore"):
        z = total / count
    height = np.where(count > 0, -z, np.nan)
    return np.asarray(height.reshape(n, n))


MIN_CELLS = 16  # a crop needs at least this many cells with a surface (a 1.75 cm square)


def check_crop(height: FloatArray) -> None:
    """InvalidInputError for a wrong shape; RecognitionError unless at least `MIN_CELLS`
    cells hold a surface."""
    if height.shape != (CROP_PIXELS, CROP_PIXELS):
        raise InvalidInputError(
            f"height map: expected shape ({CROP_PIXELS}, {CROP_PIXELS}), got {height.shape}"
        )
    cells = int(np.sum(np.isfinite(height)))
    if cells < MIN_CELLS:
        raise RecognitionError(
            f"the camera sees almost nothing near the demonstrated point: {cells} of the "
            f"{CROP_SIZE * 100:.0f} cm crop's cells hold a surface (at least {MIN_CELLS})"
        )


class Recognizer(Protocol):
    """A contact-points recognizer: crop in, contact point and approach out."""

    name: str

    def recognize(self, height: FloatArray, frame: GraspFrame, shape: str) -> Recognition: ...


#: Handle shapes whose approach comes from the demonstration, not from the crop: a pole's
#: cylinder fixes no direction across it.
NOMINAL_APPROACH = ("pole",)
#: A knob's top face (`face_normal`): seeded by the cells within `FACE_SEED` [m] of the
#: contact point across the approach and `FACE_SEED_DEPTH` [m] of the nearest surface among
#: them, grown to the connected cells within `FACE_TOLERANCE` [m] of the plane fitted to the
#: face (about twice the sensor's axial noise at a metre, 1.9 mm: sim.camera.DepthNoise) and
#: `FACE_REACH` [m] of the point (a knob's half-diagonal is at most 3 cm), refitted up to
#: `FACE_ITERATIONS` times (it stops growing within a few).
FACE_SEED = 0.012
FACE_SEED_DEPTH = 0.01
FACE_TOLERANCE = 0.004
FACE_REACH = 0.035
FACE_ITERATIONS = 5
MIN_FACE_CELLS = 6  # a plane through fewer cells is not trusted: the nominal approach then


def face_normal(height: FloatArray, point: FloatArray) -> FloatArray:
    """(3,) unit, crop frame, z > 0 (into the object): the normal of the flat face around
    `point` (3,) [m] (crop frame: x, y across the approach, z its depth) in the height map
    `height` (P, P) [m]. The face is grown from the cells at the point (`FACE_SEED`) to the
    connected cells on the plane fitted to it, refitted each time; a face seen in a frame
    tilted from its normal is followed along its slope, where a fixed height layer would cut
    it to a sliver. The frame's z when the face holds fewer than `MIN_FACE_CELLS` cells."""
    p = np.asarray(point, dtype=float)
    valid = np.isfinite(height)
    xx, yy = _cell_grid()
    across = np.hypot(xx - p[0], yy - p[1])
    depth = -np.where(valid, height, np.nan)  # frame z of each cell's surface
    near = valid & (across < FACE_SEED)
    if not np.any(near):
        return np.array([0.0, 0.0, 1.0])
    # the face is the surface nearest the hand there (the point's own depth is the least
    # certain of its coordinates when the frame is tilted from the face)
    nearest = float(np.min(depth[near]))
    with np.errstate(invalid="ignore"):
        face = near & (depth < nearest + FACE_SEED_DEPTH)
    cells = np.stack([xx, yy, depth], axis=-1)
    for _ in range(FACE_ITERATIONS):
        if int(face.sum()) < MIN_FACE_CELLS:
            break
        normal, centre = _plane_fit(cells[face])
        with np.errstate(invalid="ignore"):
            on_plane = valid & (np.abs((cells - centre) @ normal) < FACE_TOLERANCE)
        labels, _ = ndimage.label(on_plane & (across < FACE_REACH))
        kept = np.unique(labels[face])
        grown = np.isin(labels, kept[kept > 0])
        if int(grown.sum()) < MIN_FACE_CELLS or np.array_equal(grown, face):
            break
        face = grown
    if int(face.sum()) < MIN_FACE_CELLS:
        return np.array([0.0, 0.0, 1.0])
    return _plane_fit(cells[face])[0]


#: [deg] A knob's face normal replaces the demonstration's approach only beyond this angle
#: from it: the two fits' own errors together stay below it where the demonstration is right
#: (docs/design/recognizer.md), and within it the demonstration's, a hinge fit over the whole
#: turn, varies less than a face fitted to a few depth cells.
FACE_OVER_NOMINAL_DEG = 15.0


def knob_approach(height: FloatArray, point: FloatArray) -> FloatArray:
    """(3,) unit, crop frame: a knob's approach. The crop frame's z (the demonstration's
    nominal approach) unless the knob's top face (`face_normal` around `point` (3,) [m] in
    `height` (P, P) [m]) tilts more than `FACE_OVER_NOMINAL_DEG` from it: then the face's
    normal (a demonstration whose hinge fit is off)."""
    nominal = np.array([0.0, 0.0, 1.0])
    normal = face_normal(height, point)
    return normal if float(angle_deg(normal, nominal)) > FACE_OVER_NOMINAL_DEG else nominal


def _plane_fit(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The least-squares plane through points (N, 3): its unit normal (z >= 0) and centroid."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    n = vt[2]
    return np.asarray(n if n[2] >= 0 else -n), np.asarray(centre)


def _local_result(
    point: FloatArray, approach: FloatArray, frame: GraspFrame, method: str, shape: str
) -> Recognition:
    if shape in NOMINAL_APPROACH:
        approach = np.array([0.0, 0.0, 1.0])
    a = unit(np.asarray(approach, dtype=float))
    if a[2] <= 0.0:  # an approach must point into the object, as the nominal one does
        a = -a
    world_point = frame.to_world(np.asarray(point, dtype=float)[None, :])[0]
    return Recognition(world_point, np.asarray(frame.rotation @ a), method)


# --- the geometric baseline -------------------------------------------------------------------
class GeometricRecognizer:
    """Segment what stands out nearest the hand near the demonstrated point, take its centre
    and the normal of the surface it is mounted on (or of its own top face).

    - bar and pole: the top is the median, over one-cell slices along the handle, of each
      slice's highest cell (the handle's front surface); the silhouette is the component
      nearest the crop's centre of the cells within `silhouette_depth` of the top (deep
      enough for a handle's full width, shallower than a bar's posts); its principal axis
      is the handle's line, half its median width the radius, and the axis lies one radius
      behind the top. A bar's centre is the middle of its extent along the line; a pole's is
      at the demonstrated height (the crop's origin), `POLE_TOP_MARGIN` below its top at
      most (the crop's x points up for a pole). The approach is the normal of the plane
      through the main layer of surface behind a bar (the panel it is mounted on), and the
      nominal one for a pole (a cylinder's surface does not fix it).
    - plate and knob: the top face is the component nearest the centre of the cells within
      `top_layer` of the highest surface within `near` of the centre; the contact point is
      its centroid at its median height, the approach its plane's normal (a knob's:
      `knob_approach` around that centroid).
    """

    name = "geometric"

    def __init__(
        self, silhouette_depth: float = 0.02, top_layer: float = 0.006, near: float = 0.08
    ) -> None:
        self.silhouette_depth = silhouette_depth  # [m]
        self.top_layer = top_layer  # [m]
        self.near = near  # [m]

    def recognize(self, height: FloatArray, frame: GraspFrame, shape: str) -> Recognition:
        check_crop(height)
        if shape in ("bar", "pole"):
            point, approach = self._elongated(height, shape)
        elif shape in ("plate", "knob"):
            point, approach = self._top_face(height)
            if shape == "knob":
                approach = knob_approach(height, point)
        else:
            raise UnknownNameError("handle shape", shape, HANDLE_SHAPES)
        return _local_result(point, approach, frame, self.name, shape)

    @staticmethod
    def _nearest_component(mask: BoolArray, min_cells: int = 4) -> BoolArray:
        """The connected component of `mask` nearest the crop's centre (bool map)."""
        labels, count = ndimage.label(mask)
        xx, yy = _cell_grid()
        best, best_d = 0, np.inf
        for k in range(1, count + 1):
            cells = labels == k
            if int(cells.sum()) < min_cells:
                continue
            d = float(np.min(np.hypot(xx[cells], yy[cells])))
            if d < best_d:
                best, best_d = k, d
        if best == 0:
            raise RecognitionError("no handle stands out near the demonstrated point")
        return np.asarray(labels == best)

    def _highest_near(self, height: FloatArray) -> float:
        xx, yy = _cell_grid()
        near = np.isfinite(height) & (np.hypot(xx, yy) < self.near)
        if int(near.sum()) < 4:
            raise RecognitionError(
                f"no surface within {self.near * 100:.0f} cm of the demonstrated point"
            )
        return float(np.percentile(height[near], 97))

    def _elongated(self, height: FloatArray, shape: str) -> tuple[FloatArray, FloatArray]:
        valid = np.isfinite(height)
        h = np.where(valid, height, -np.inf)
        top = self._highest_near(height)
        handle = self._nearest_component(h > top - self.silhouette_depth)
        xx, yy = _cell_grid()
        xy = np.stack([xx[handle], yy[handle]], axis=1)
        centre = xy.mean(axis=0)
        _, _, vt = np.linalg.svd(xy - centre, full_matrices=False)
        along = vt[0] if vt[0][0] >= 0 else -vt[0]  # toward +x (up, for a pole's crop)
        across = np.array([-along[1], along[0]])
        s = (xy - centre) @ along
        t = (xy - centre) @ across
        bins = np.round(s / CELL).astype(int)
        slices = [bins == b for b in np.unique(bins)]
        widths = [float(np.ptp(t[m])) + CELL for m in slices if int(m.sum()) > 1]
        radius = 0.5 * float(np.median(widths)) if widths else 0.5 * CELL
        front = float(np.median([h[handle][m].max() for m in slices]))
        mid_t = 0.5 * (float(np.median([t[m].min() for m in slices]))
                       + float(np.median([t[m].max() for m in slices])))  # fmt: skip
        depth = -(front - radius)  # the axis, one radius behind the front (frame z)
        # an oblique camera sees one side of a cylinder more than the other: the circle
        # through the cross-section (across, height) locates the axis when it fits
        fit = _circle_fit(t, h[handle])
        if fit is not None and 0.4 * radius < fit[2] < 2.0 * radius:
            mid_t, depth = fit[0], -fit[1]
        if shape == "bar":
            mid_s = 0.5 * (float(s.min()) + float(s.max()))
            approach = self._mounting_normal(height, handle, front - 2.0 * radius)
        else:
            mid_s = min(float(-centre @ along), float(s.max()) - POLE_TOP_MARGIN)
            approach = np.array([0.0, 0.0, 1.0])
        xy_point = centre + mid_s * along + mid_t * across
        return np.array([xy_point[0], xy_point[1], depth]), approach

    def _mounting_normal(self, height: FloatArray, handle: BoolArray, back: float) -> FloatArray:
        """The normal of the main surface layer behind the handle (whose back is at height
        `back` [m]) within `near` of it: the 5 mm height bin holding most cells, +-8 mm."""
        xx, yy = _cell_grid()
        cx, cy = xx[handle].mean(), yy[handle].mean()
        near = np.isfinite(height) & (np.hypot(xx - cx, yy - cy) < self.near) & ~handle
        behind = near & (height < back - 0.005) & (height > back - 0.08)
        if int(behind.sum()) < 6:
            return np.array([0.0, 0.0, 1.0])
        values = height[behind]
        edges = np.arange(values.min(), values.max() + 0.005, 0.005)
        if len(edges) < 2:
            layer = values.mean()
        else:
            counts, edges = np.histogram(values, bins=edges)
            peak = int(np.argmax(counts))
            layer = 0.5 * (edges[peak] + edges[peak + 1])
        return self._plane_normal(height, behind & (np.abs(height - layer) < 0.008))

    def _top_face(self, height: FloatArray) -> tuple[FloatArray, FloatArray]:
        valid = np.isfinite(height)
        top = self._highest_near(height)
        face = self._nearest_component(
            valid & (np.abs(np.where(valid, height, np.inf) - top) < self.top_layer)
        )
        xx, yy = _cell_grid()
        point = np.array([xx[face].mean(), yy[face].mean(), -float(np.median(height[face]))])
        return point, self._plane_normal(height, face)

    @staticmethod
    def _plane_normal(height: FloatArray, cells: BoolArray) -> FloatArray:
        """The unit normal (frame coordinates, z > 0: into the surface) of the least-squares
        plane through the cells' points; the frame's z when fewer than `MIN_FACE_CELLS`."""
        if int(np.sum(cells)) < MIN_FACE_CELLS:
            return np.array([0.0, 0.0, 1.0])
        xx, yy = _cell_grid()
        return _plane_fit(np.stack([xx[cells], yy[cells], -height[cells]], axis=1))[0]


def _circle_fit(t: FloatArray, h: FloatArray) -> tuple[float, float, float] | None:
    """(t0, h0, r) [m] of the least-squares (algebraic) circle through the points (t, h);
    None for fewer than 6 points or a degenerate fit."""
    if len(t) < 6:
        return None
    a = np.stack([t, h, np.ones_like(t)], axis=1)
    b = -(t * t + h * h)
    try:
        (d, e, f), *_ = np.linalg.lstsq(a, b, rcond=None)
    except np.linalg.LinAlgError:
        return None
    t0, h0 = -0.5 * d, -0.5 * e
    r2 = t0 * t0 + h0 * h0 - f
    if not np.isfinite(r2) or r2 <= 0:
        return None
    return float(t0), float(h0), float(math.sqrt(r2))


def _cell_grid() -> tuple[FloatArray, FloatArray]:
    """(P, P) each: the cells' x (rows) and y (columns) centres [m]."""
    c = cell_centres()
    xx, yy = np.meshgrid(c, c, indexing="ij")
    return xx, yy


# --- the CNN ----------------------------------------------------------------------------------
#: The network: 3x3 convolutions (padding 1) with ReLU, (out channels, stride) each, on the
#: input (height / DEPTH_RANGE, valid mask, the cells' x and y / (CROP_SIZE / 2)); then one
#: heat map per handle shape (1x1 convolution) whose spatial soft-argmax is the contact
#: point across the approach, and two dense layers on the features pooled under that heat
#: map and over the whole map (with the shape as a one-hot) giving, per shape, the contact
#: point's depth and the approach's tilt.
CONV_LAYERS: tuple[tuple[int, int], ...] = ((16, 2), (16, 1), (32, 2), (32, 1))
INPUT_CHANNELS = 4
HIDDEN = 64
TILT_SCALE = 0.5  # the approach is unit(tilt_x * s, tilt_y * s, 1) in the crop frame


def network_input(heights: FloatArray) -> NDArray[np.float32]:
    """(N, 4, CROP_PIXELS, CROP_PIXELS) float32 network inputs of height maps (N, P, P) [m]
    (or (4, P, P) of one map (P, P))."""
    h = np.asarray(heights, dtype=float)
    single = h.ndim == 2
    h = h[None] if single else h
    valid = np.isfinite(h)
    c = cell_centres() / (0.5 * CROP_SIZE)
    xx, yy = np.meshgrid(c, c, indexing="ij")
    out = np.empty((len(h), INPUT_CHANNELS, CROP_PIXELS, CROP_PIXELS), dtype=np.float32)
    out[:, 0] = np.where(valid, np.clip(h, -DEPTH_RANGE, DEPTH_RANGE) / DEPTH_RANGE, 0.0)
    out[:, 1] = valid
    out[:, 2] = xx
    out[:, 3] = yy
    return np.asarray(out[0] if single else out)


def heat_grid() -> FloatArray:
    """(n,) the heat map's cell centres along either axis, in units of CROP_SIZE / 2."""
    stride = int(np.prod([s for _, s in CONV_LAYERS]))
    n = CROP_PIXELS // stride
    return np.asarray(((np.arange(n) + 0.5) / n) * 2.0 - 1.0)


def _conv3x3(x: FloatArray, w: FloatArray, b: FloatArray, stride: int) -> FloatArray:
    """(N, O, H', W') = ReLU(conv(x (N, C, H, W), w (O, C, 3, 3), padding 1) + b), as nine
    shifted matrix products (faster than a strided window view in numpy)."""
    n, _, height, width = x.shape
    padded = np.pad(x, ((0, 0), (0, 0), (1, 1), (1, 1)))
    ho, wo = (height - 1) // stride + 1, (width - 1) // stride + 1
    channels_last = padded.transpose(0, 2, 3, 1)
    out = np.zeros((n, ho, wo, w.shape[0]))
    for i in range(3):
        for j in range(3):
            shifted = channels_last[:, i : i + stride * ho : stride, j : j + stride * wo : stride]
            out += shifted @ w[:, :, i, j].T
    out += b
    return np.asarray(np.maximum(out, 0.0).transpose(0, 3, 1, 2))


def weight_shapes(conv_layers: tuple[tuple[int, int], ...] = CONV_LAYERS) -> dict[str, tuple]:
    """The .npz arrays of a network with `conv_layers` and their shapes."""
    shapes: dict[str, tuple[int, ...]] = {}
    cin = INPUT_CHANNELS
    for i, (cout, _) in enumerate(conv_layers):
        shapes[f"conv{i}_w"] = (cout, cin, 3, 3)
        shapes[f"conv{i}_b"] = (cout,)
        cin = cout
    k = len(HANDLE_SHAPES)
    shapes["heat_w"] = (k, cin)
    shapes["heat_b"] = (k,)
    shapes["fc0_w"] = (HIDDEN, 2 * cin + k)
    shapes["fc0_b"] = (HIDDEN,)
    shapes["fc1_w"] = (3 * k, HIDDEN)
    shapes["fc1_b"] = (3 * k,)
    return shapes


def forward(
    weights: dict[str, FloatArray], x: NDArray[np.floating], shapes: NDArray[np.integer]
) -> FloatArray:
    """(N, 5) network outputs (x, y in CROP_SIZE / 2; depth in DEPTH_RANGE; tilt x, y) of
    inputs x (N, 4, CROP_PIXELS, CROP_PIXELS) for handle-shape indices (N,)."""
    h = np.asarray(x, dtype=np.float64)
    i = 0
    for i, (_, stride) in enumerate(CONV_LAYERS):
        h = _conv3x3(h, weights[f"conv{i}_w"], weights[f"conv{i}_b"], stride)
    n = h.shape[0]
    idx = np.asarray(shapes, dtype=int)
    heat = np.einsum("nchw,kc->nkhw", h, weights["heat_w"]) + weights["heat_b"][None, :, None, None]
    logits = heat[np.arange(n), idx].reshape(n, -1)
    logits -= logits.max(axis=1, keepdims=True)
    p = np.exp(logits)
    p /= p.sum(axis=1, keepdims=True)
    g = heat_grid()
    gx, gy = np.meshgrid(g, g, indexing="ij")
    ex = p @ gx.reshape(-1)
    ey = p @ gy.reshape(-1)
    feats = h.reshape(n, h.shape[1], -1)
    attended = np.einsum("ncp,np->nc", feats, p)
    pooled = feats.mean(axis=2)
    onehot = np.eye(len(HANDLE_SHAPES))[idx]
    z = np.concatenate([attended, pooled, onehot], axis=1)
    z = np.maximum(z @ weights["fc0_w"].T + weights["fc0_b"], 0.0)
    out = (z @ weights["fc1_w"].T + weights["fc1_b"]).reshape(n, len(HANDLE_SHAPES), 3)
    rest = out[np.arange(n), idx]
    return np.concatenate([ex[:, None], ey[:, None], rest], axis=1)


def decode(outputs: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Network outputs (N, 5) -> contact points (N, 3) [m] and approaches (N, 3) unit, in the
    crop frame."""
    o = np.asarray(outputs, dtype=float)
    points = np.stack(
        [o[:, 0] * 0.5 * CROP_SIZE, o[:, 1] * 0.5 * CROP_SIZE, o[:, 2] * DEPTH_RANGE], axis=1
    )
    tilt = np.stack([o[:, 3] * TILT_SCALE, o[:, 4] * TILT_SCALE, np.ones(len(o))], axis=1)
    return points, np.asarray(unit(tilt))


def encode(points: FloatArray, approaches: FloatArray) -> FloatArray:
    """Crop-frame contact points (N, 3) [m] and approaches (N, 3) -> training targets (N, 5)."""
    p = np.asarray(points, dtype=float)
    a = np.asarray(approaches, dtype=float)
    az = np.maximum(a[:, 2], 1e-3)
    return np.stack(
        [
            p[:, 0] / (0.5 * CROP_SIZE),
            p[:, 1] / (0.5 * CROP_SIZE),
            p[:, 2] / DEPTH_RANGE,
            a[:, 0] / az / TILT_SCALE,
            a[:, 1] / az / TILT_SCALE,
        ],
        axis=1,
    )


def shipped_recognizer_path() -> Path:
    """The shipped recognizer's weights (.npz; its card is the .json beside it)."""
    return Path(str(resources.files("constraint_aware") / "data" / "recognizer.npz"))


class ContactPointRecognizer:
    """The CNN recognizer (`CONV_LAYERS`, `forward`) with validated weights and card."""

    name = "cnn"

    def __init__(self, weights: dict[str, FloatArray], card: dict[str, Any]) -> None:
        expected = weight_shapes()
        for key, shape in expected.items():
            if key not in weights:
                raise RecognizerFileError(f"weights: field {key!r} missing")
            arr = weights[key]
            if tuple(arr.shape) != shape:
                raise RecognizerFileError(
                    f"weights: field {key!r} has shape {tuple(arr.shape)}, expected {shape}"
                )
            if not np.issubdtype(arr.dtype, np.floating) or not np.all(np.isfinite(arr)):
                raise RecognizerFileError(f"weights: field {key!r} must be finite floats")
        self.weights = {k: np.asarray(weights[k], dtype=np.float64) for k in expected}
        self.card = card

    @classmethod
    def load(cls, path: str | Path | None = None) -> ContactPointRecognizer:
        """The shipped recognizer (None) or a `.npz` with its `.json` card beside it."""
        npz = shipped_recognizer_path() if path is None else Path(path).with_suffix(".npz")
        card_path = npz.with_suffix(".json")
        if not npz.is_file():
            raise RecognizerFileError(f"recognizer weights not found: {npz}")
        if not card_path.is_file():
            raise RecognizerFileError(f"recognizer card not found: {card_path}")
        card = read_card(card_path)
        try:
            with np.load(npz, allow_pickle=False) as data:
                weights = {k: data[k] for k in data.files}
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            raise RecognizerFileError(f"{npz}: not a readable .npz ({exc})") from exc
        try:
            return cls(weights, card)
        except RecognizerFileError as exc:
            raise RecognizerFileError(f"{npz}: {exc}") from exc

    def save(self, path: str | Path) -> Path:
        """Write the weights (.npz, float32) and the card (.json). Returns the .npz path."""
        npz = Path(path).with_suffix(".npz")
        npz.parent.mkdir(parents=True, exist_ok=True)
        arrays = {k: v.astype(np.float32) for k, v in self.weights.items()}
        np.savez(npz, **arrays)  # type: ignore[arg-type]
        card = dict(self.card, format=CARD_FORMAT, **crop_card())
        npz.with_suffix(".json").write_text(json.dumps(card, indent=2) + "\n")
        return npz

    def predict(self, heights: FloatArray, shapes: list[str]) -> tuple[FloatArray, FloatArray]:
        """Crop-frame contact points (N, 3) [m] and approaches (N, 3) of height maps (N, H, W)
        [m] for their handle shapes (N names of `HANDLE_SHAPES`). The network gives the
        points and the approach of bars and plates; a knob's approach is `knob_approach`
        around the network's point, a pole's the nominal one."""
        idx = [_shape_index(s) for s in shapes]
        x = network_input(np.asarray(heights))
        points, approaches = decode(forward(self.weights, x, np.asarray(idx)))
        nominal = np.isin(np.asarray(shapes), NOMINAL_APPROACH)
        approaches[nominal] = [0.0, 0.0, 1.0]
        maps = np.asarray(heights, dtype=float)
        for i in np.flatnonzero(np.asarray(shapes) == "knob"):
            approaches[i] = knob_approach(maps[i], points[i])
        return points, approaches

    def recognize(self, height: FloatArray, frame: GraspFrame, shape: str) -> Recognition:
        check_crop(height)
        points, approaches = self.predict(height[None], [shape])
        return _local_result(points[0], approaches[0], frame, self.name, shape)


class RecognizerFileError(CapError):
    """A recognizer's weights or card are missing, malformed or inconsistent."""


def _shape_index(shape: str) -> int:
    if shape not in HANDLE_SHAPES:
        raise UnknownNameError("handle shape", shape, HANDLE_SHAPES)
    return HANDLE_SHAPES.index(shape)


def crop_card() -> dict[str, Any]:
    """The crop and network layout a card records (and `read_card` checks)."""
    return {
        "crop_pixels": CROP_PIXELS,
        "crop_size_m": CROP_SIZE,
        "depth_range_m": DEPTH_RANGE,
        "handle_shapes": list(HANDLE_SHAPES),
        "conv_layers": [list(c) for c in CONV_LAYERS],
        "hidden": HIDDEN,
        "tilt_scale": TILT_SCALE,
    }


def read_card(path: Path) -> dict[str, Any]:
    """A recognizer card, checked against this version's crop and network layout;
    RecognizerFileError names the file and the field."""
    try:
        card = json.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise RecognizerFileError(f"{path}: not a readable JSON card ({exc})") from exc
    if not isinstance(card, dict):
        raise RecognizerFileError(f"{path}: the card must be a JSON object")
    if card.get("format") != CARD_FORMAT:
        raise RecognizerFileError(
            f"{path}: field 'format' is {card.get('format')!r}, not {CARD_FORMAT}"
        )
    for key, value in crop_card().items():
        got = card.get(key)
        same = (
            math.isclose(float(got), float(value))
            if isinstance(value, float) and isinstance(got, int | float)
            else got == value
        )
        if not same:
            raise RecognizerFileError(
                f"{path}: field {key!r} is {got!r}; this version reads {value!r}"
            )
    return card


def make_recognizer(method: str = DEFAULT_METHOD, path: str | Path | None = None) -> Recognizer:
    """A recognizer by name (`METHODS`): the CNN (shipped weights, or `path`) or the
    geometric baseline."""
    if method == "cnn":
        return ContactPointRecognizer.load(path)
    if method == "geometric":
        return GeometricRecognizer()
    raise UnknownNameError("recognizer", method, METHODS)
