"""Plane, line and circle fits to a hand trajectory, each with residuals and uncertainty.

All inputs are (N, 3) positions [m]. Errors that make a fit meaningless (too few points,
collinear points for a plane, too short an arc for a circle) raise FitError with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray, unit

#: RANSAC inlier threshold [m]: points farther than this from a candidate plane are outliers.
#: Three times a hand tracker's typical 5 mm noise keeps noisy samples and drops glitches.
RANSAC_THRESHOLD = 0.015
#: A point set whose second principal extent is below this [m] is too collinear for a plane.
MIN_PLANE_WIDTH = 0.002
#: Arcs spanning less than this [deg] do not determine a circle.
MIN_ARC_DEG = 20.0


#: A sample farther than this [m] from the running median of its neighbours is a glitch.
OUTLIER_THRESHOLD = 0.025
OUTLIER_WINDOW = 9  # samples in the running median


class FitError(CapError, ValueError):
    """A fit cannot be made from these points; the message says why."""


def outlier_mask(points: FloatArray, window: int = OUTLIER_WINDOW) -> NDArray[np.bool_]:
    """(N,) bool, True for isolated glitches: samples farther than OUTLIER_THRESHOLD from the
    running median of their `window` neighbours (a tracker's jumps; noise and tremor stay)."""
    n = len(points)
    half = window // 2
    padded = np.concatenate(
        [np.repeat(points[:1], half, 0), points, np.repeat(points[-1:], half, 0)]
    )
    windows = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # (n, 3, w)
    med = np.median(windows, axis=2)
    return np.asarray(np.linalg.norm(points - med[:n], axis=1) > OUTLIER_THRESHOLD)


@dataclass(frozen=True)
class PlaneFit:
    normal: FloatArray  # (3,) unit
    centroid: FloatArray  # (3,) [m]
    rms: float  # [m] RMS distance of the inliers to the plane
    normal_std_deg: float  # [deg] 1-sigma uncertainty of the normal's direction
    inliers: FloatArray  # (N,) bool
    extent: tuple[float, float]  # [m] RMS spread along the two in-plane axes


@dataclass(frozen=True)
class LineFit:
    direction: FloatArray  # (3,) unit
    point: FloatArray  # (3,) [m]
    rms: float  # [m] RMS distance to the line
    length: float  # [m] extent along the line


@dataclass(frozen=True)
class CircleFit:
    centre: FloatArray  # (3,) [m]
    radius: float  # [m]
    axis: FloatArray  # (3,) unit, oriented so that the motion turns positively about it
    rms: float  # [m] RMS of |p - c| - r
    radius_std: float  # [m] 1-sigma
    centre_std: float  # [m] 1-sigma (in-plane, per axis, RMS)
    arc_deg: float  # [deg] angle swept from the first to the last point
    plane: PlaneFit | None = None  # the plane fitted for it (None when the normal was given)


def _require(points: FloatArray, n: int, what: str) -> None:
    if points.ndim != 2 or points.shape[1] != 3:
        raise FitError(f"{what}: expected points of shape (N, 3), got {points.shape}")
    if len(points) < n:
        raise FitError(f"{what}: too few points ({len(points)}, need {n})")
    if not np.all(np.isfinite(points)):
        raise FitError(f"{what}: points contain NaN or inf")


def _svd_plane(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    centroid = points.mean(axis=0)
    _, s, vt = np.linalg.svd(points - centroid, full_matrices=False)
    return centroid, s / math.sqrt(len(points)), vt


def fit_plane(
    points: FloatArray,
    threshold: float = RANSAC_THRESHOLD,
    iterations: int = 200,
    rng: np.random.Generator | None = None,
) -> PlaneFit:
    """Least-squares plane through the RANSAC inliers (seeded: deterministic by default).

    Raises FitError when the points are too few or too collinear to define a plane.
    """
    _require(points, 3, "plane fit")
    rng = rng or np.random.default_rng(0)
    _, spread, _ = _svd_plane(points)
    if spread[1] < MIN_PLANE_WIDTH:
        raise FitError(
            f"plane fit: points are collinear or too short for a plane (second extent "
            f"{spread[1] * 1000:.1f} mm < {MIN_PLANE_WIDTH * 1000:.0f} mm)"
        )
    best = np.ones(len(points), dtype=bool)
    best_count = -1
    for _ in range(iterations):
        idx = rng.choice(len(points), size=3, replace=False)
        a, b, c = points[idx]
        n = np.cross(b - a, c - a)
        if np.linalg.norm(n) < 1e-9:
            continue
        n = n / np.linalg.norm(n)
        inliers = np.abs((points - a) @ n) < threshold
        count = int(inliers.sum())
        if count > best_count:
            best, best_count = inliers, count
    inl = points[best]
    if len(inl) < 3:
        raise FitError("plane fit: fewer than 3 inliers")
    centroid, spread, vt = _svd_plane(inl)
    normal = vt[2]
    dist = (inl - centroid) @ normal
    rms = float(np.sqrt(np.mean(dist**2)))
    # tilt uncertainty of a least-squares plane: sigma / (extent * sqrt(N)), per axis
    tilt = [rms / max(s * math.sqrt(len(inl)), 1e-12) for s in spread[:2]]
    return PlaneFit(
        normal=normal,
        centroid=centroid,
        rms=rms,
        normal_std_deg=math.degrees(math.hypot(*tilt)),
        inliers=best,
        extent=(float(spread[0]), float(spread[1])),
    )


def fit_line(points: FloatArray) -> LineFit:
    _require(points, 2, "line fit")
    centroid, _, vt = _svd_plane(points)
    direction = vt[0]
    if (points[-1] - points[0]) @ direction < 0:
        direction = -direction
    rel = points - centroid
    perp = rel - np.outer(rel @ direction, direction)
    proj = rel @ direction
    return LineFit(
        direction=direction,
        point=centroid,
        rms=float(np.sqrt(np.mean(np.sum(perp**2, axis=1)))),
        length=float(proj.max() - proj.min()),
    )


def _plane_basis(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    e1 = unit(np.cross(normal, [1.0, 0.0, 0.0]))
    if np.linalg.norm(e1) < 0.5:
        e1 = unit(np.cross(normal, [0.0, 1.0, 0.0]))
    return e1, np.cross(normal, e1)


def fit_circle(points: FloatArray, normal: FloatArray | None = None) -> CircleFit:
    """Circle in the points' plane: algebraic (Kasa) start, geometric least-squares refinement.

    normal: the plane's normal if already known (else a plane is fitted). Raises FitError for
    too few points or an arc shorter than MIN_ARC_DEG.
    """
    _require(points, 5, "circle fit")
    plane = None
    if normal is None:
        plane = fit_plane(points)
        normal = plane.normal
        pts = points[plane.inliers]
    else:
        pts = points
    origin = pts.mean(axis=0)
    e1, e2 = _plane_basis(unit(normal))
    xy = np.stack([(pts - origin) @ e1, (pts - origin) @ e2], axis=1)
    # Kasa: x^2 + y^2 + D x + E y + F = 0, linear least squares
    a = np.column_stack([xy, np.ones(len(xy))])
    b = -np.sum(xy**2, axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    c0 = -sol[:2] / 2
    r0 = math.sqrt(max(float(c0 @ c0 - sol[2]), 1e-12))

    def residual(p: FloatArray) -> FloatArray:
        return np.asarray(np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) - p[2])

    # robust loss: a residual beyond ~1 cm counts linearly, so leftover glitches pull less
    res = least_squares(residual, np.array([*c0, r0]), loss="soft_l1", f_scale=0.01)
    cx, cy, r = res.x
    r = abs(float(r))
    resid = residual(res.x)
    dof = max(len(xy) - 3, 1)
    sigma2 = float(resid @ resid) / dof
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac) * sigma2
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(3, np.inf)
    centre = origin + cx * e1 + cy * e2
    ang = np.unwrap(np.arctan2(xy[:, 1] - cy, xy[:, 0] - cx))
    swept = float(ang[-1] - ang[0])
    arc = abs(math.degrees(swept))
    if arc < MIN_ARC_DEG:
        raise FitError(
            f"circle fit: arc too short ({arc:.0f} deg < {MIN_ARC_DEG:.0f} deg) to determine "
            "a circle"
        )
    axis = unit(normal) * (1.0 if swept > 0 else -1.0)  # motion turns positively about it
    return CircleFit(
        centre=centre,
        radius=r,
        axis=axis,
        rms=float(np.sqrt(np.mean(resid**2))),
        radius_std=float(std[2]),
        centre_std=float(np.hypot(std[0], std[1]) / math.sqrt(2)),
        arc_deg=arc,
        plane=plane,
    )


def initial_direction(
    points: FloatArray, t: FloatArray, distance: float = 0.03, min_speed: float = 0.01
) -> tuple[FloatArray, float]:
    """Direction (3,) of the first `distance` [m] of motion, and its RMS line residual [m].

    The motion starts at the first sample whose speed exceeds `min_speed` [m/s] (a hand at rest
    at the start is skipped); the direction is the principal axis of the following samples up
    to `distance` of travel, oriented along the motion.
    """
    speed = np.linalg.norm(np.diff(points, axis=0), axis=1) / np.diff(t)
    moving = np.flatnonzero(speed > min_speed)
    start = int(moving[0]) if moving.size else 0
    travel = np.linalg.norm(points[start:] - points[start], axis=1)
    end = start + int(np.argmax(travel >= distance)) if np.any(travel >= distance) else len(points)
    seg = points[start : max(end + 1, start + 3)]
    if len(seg) < 3:
        raise FitError("initial direction: fewer than 3 samples at the start of the motion")
    line = fit_line(seg)
    return line.direction, line.rms
