"""Vector math shared by the policy, the training env and the executor (numpy only).

Everything here works on a single vector of shape (3,) or on a batch of shape (N, 3).

The executor calls these once or more per control period on single vectors, where numpy's
per-call overhead (np.cross, np.linalg.norm, np.all(np.isfinite(...))) exceeds the arithmetic
many times over: single vectors take a path in Python floats with the same operations in the
same order as numpy's, so both paths give the same floats (`angle_deg`, a reported quantity,
uses math's atan2 and may differ from the batched path in the last place). Dot products of
two (3,) vectors are summed x, y, z in turn there and in the executor's other float paths
(control.motion, control.lag, control.steady, policy.mirror_average), as numpy's dot sums
three elements with OpenBLAS's x86-64 (Haswell) kernel; a BLAS that fuses the multiply-adds
may differ from those paths in the last place.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from constraint_aware.errors import InvalidInputError

FloatArray = NDArray[np.float64]

#: Below this norm the sum d + a is treated as zero and the direction is kept.
DIRECTION_EPS = 1e-6


def as_vector(value: ArrayLike, name: str, *, batch: bool = False) -> FloatArray:
    """Return `value` as a finite float64 array of shape (3,) (or (N, 3) with `batch`).

    Raises:
        InvalidInputError: naming `name` when the shape is wrong or a value is NaN/inf.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name}: not a numeric array ({exc})") from exc
    if batch:
        if arr.ndim != 2 or arr.shape[1] != 3:
            raise InvalidInputError(f"{name}: expected shape (N, 3), got {arr.shape}")
    elif arr.shape != (3,):
        raise InvalidInputError(f"{name}: expected shape (3,), got {arr.shape}")
    if not all_finite(arr):
        raise InvalidInputError(f"{name}: contains NaN or inf")
    return arr


def cross3(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """a x b of two 3-vectors given as Python numbers (e.g. an array's `tolist()`), as Python
    floats: `np.cross`'s products and differences in its order, the form the per-period paths
    compute in (numpy's per-call overhead on 3-vectors is many times the arithmetic)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """a x b along the last axis: (3,) for two (3,) vectors, else broadcast as `np.cross`."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape == (3,) and b.shape == (3,):
        return np.array(cross3(a.tolist(), b.tolist()))
    return np.asarray(np.cross(a, b), dtype=np.float64)


def norm(v: FloatArray) -> float:
    """|v| of a (3,) vector (the same float as `np.linalg.norm(v)`); inf when it overflows."""
    return math.sqrt(float(v.dot(v)))


def all_finite(v: FloatArray) -> bool:
    """Whether every element of `v` (any shape) is finite."""
    if v.size <= 8:
        return all(map(math.isfinite, v.ravel().tolist()))
    return bool(np.all(np.isfinite(v)))


def _row_norm(v: FloatArray) -> float:
    """|v| of a (3,) vector summed as numpy's reduction along an axis sums it."""
    x, y, z = v.tolist()
    return math.sqrt(x * x + y * y + z * z)


def unit(v: FloatArray, eps: float = 1e-12) -> FloatArray:
    """Normalize along the last axis; vectors with norm <= eps become zero vectors."""
    v = np.asarray(v)
    if v.shape == (3,):
        n = _row_norm(v)
        return v / n if n > eps else np.zeros(3)
    norms = np.linalg.norm(v, axis=-1, keepdims=True)
    safe = np.where(norms > eps, norms, 1.0)
    return np.where(norms > eps, v / safe, 0.0)


def in_plane(v: FloatArray, normal: FloatArray | None) -> FloatArray:
    """v (3,) less its component along the unit `normal` (3,); v itself without a normal."""
    return v if normal is None else v - float(v @ normal) * normal


def angle_deg(a: FloatArray, b: FloatArray) -> FloatArray | float:
    """Angle [deg] between vectors along the last axis (robust near 0 and 180 deg)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape == (3,) and b.shape == (3,):
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        c0, c1, c2 = cross3((a0, a1, a2), (b0, b1, b2))
        c = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
        return math.degrees(math.atan2(c, a0 * b0 + a1 * b1 + a2 * b2))
    cross_norm = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    out = np.degrees(np.arctan2(cross_norm, dot))
    return float(out) if np.ndim(out) == 0 else out


def normalize_force(force: FloatArray, threshold: float) -> FloatArray:
    """F / |F|, or the zero vector where |F| < threshold (paper 3.3.2).

    force: (3,) or (N, 3) [N]; threshold [N].
    """
    force = np.asarray(force)
    if force.shape == (3,):
        n = _row_norm(force)
        return force / n if n >= max(threshold, 1e-12) else np.zeros(3)
    norms = np.linalg.norm(force, axis=-1, keepdims=True)
    keep = norms >= max(threshold, 1e-12)
    return np.where(keep, force / np.where(keep, norms, 1.0), 0.0)


def update_direction_rule(direction: FloatArray, action: FloatArray) -> FloatArray:
    """d_{t+1} = (d_t + a_t) / |d_t + a_t| (paper eq. 1), keeping d_t where |d_t + a_t| ~ 0."""
    s = np.asarray(direction + action)
    if s.shape == (3,):
        n = _row_norm(s)
        return s / n if n > DIRECTION_EPS else np.array(direction, dtype=np.float64)
    norms = np.linalg.norm(s, axis=-1, keepdims=True)
    ok = norms > DIRECTION_EPS
    return np.where(ok, s / np.where(ok, norms, 1.0), direction)


def rotate_about(v: FloatArray, axis: FloatArray, angle_rad: FloatArray | float) -> FloatArray:
    """Rodrigues rotation of v about the unit `axis` by `angle_rad` (batched on the last axis)."""
    v, axis = np.asarray(v, dtype=np.float64), np.asarray(axis, dtype=np.float64)
    scalar = type(angle_rad) is float or np.ndim(angle_rad) == 0  # a float: skip np.ndim
    if v.shape == (3,) and axis.shape == (3,) and scalar:
        # numpy's cos and sin (not math's): the same floats as the batched path
        cos, sin = float(np.cos(angle_rad)), float(np.sin(angle_rad))
        a0, a1, a2 = axis.tolist()
        v0, v1, v2 = v.tolist()
        along = a0 * v0 + a1 * v1 + a2 * v2
        c0, c1, c2 = a1 * v2 - a2 * v1, a2 * v0 - a0 * v2, a0 * v1 - a1 * v0  # axis x v
        rest = 1.0 - cos
        # each element in the batched path's order: v cos + (axis x v) sin + axis along (1 - cos)
        return np.array(
            [
                v0 * cos + c0 * sin + a0 * along * rest,
                v1 * cos + c1 * sin + a1 * along * rest,
                v2 * cos + c2 * sin + a2 * along * rest,
            ]
        )
    ang = np.asarray(angle_rad, dtype=np.float64)[..., None]
    c, s = np.cos(ang), np.sin(ang)
    kv = np.sum(axis * v, axis=-1, keepdims=True)
    return v * c + np.cross(axis, v) * s + axis * kv * (1.0 - c)


def random_unit(rng: np.random.Generator, n: int) -> FloatArray:
    """n unit vectors uniform on the sphere: (n, 3)."""
    v = rng.normal(size=(n, 3))
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    # a zero draw has probability 0; guard anyway so no NaN can escape
    v = np.where(norm > 1e-9, v, np.array([1.0, 0.0, 0.0]))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def random_perpendicular(rng: np.random.Generator, axis: FloatArray) -> FloatArray:
    """For each row of `axis` (N, 3), a unit vector perpendicular to it, uniform in angle."""
    v = random_unit(rng, axis.shape[0])
    p = v - np.sum(v * axis, axis=1, keepdims=True) * axis
    bad = np.linalg.norm(p, axis=1) < 1e-6
    if np.any(bad):  # v happened to be parallel to the axis: use any fixed perpendicular
        alt = np.cross(axis[bad], np.array([0.0, 0.0, 1.0]))
        small = np.linalg.norm(alt, axis=1) < 1e-6
        alt[small] = np.cross(axis[bad][small], np.array([1.0, 0.0, 0.0]))
        p[bad] = alt
    return unit(p)


def turn_vector(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rotation vector (3,) [rad] turning unit a onto unit b about a x b (zero if equal;
    for opposite vectors, any perpendicular axis)."""
    a0, a1, a2 = np.asarray(a, dtype=np.float64).tolist()
    b0, b1, b2 = np.asarray(b, dtype=np.float64).tolist()
    x, y, z = cross3((a0, a1, a2), (b0, b1, b2))
    s = math.sqrt(x * x + y * y + z * z)
    c = a0 * b0 + a1 * b1 + a2 * b2
    if s < 1e-12:
        if c > 0:
            return np.zeros(3)
        perp = cross(a, np.array([1.0, 0.0, 0.0]))
        if norm(perp) < 1e-6:
            perp = cross(a, np.array([0.0, 1.0, 0.0]))
        return np.asarray(unit(perp) * math.pi)
    angle = math.atan2(s, c)
    return np.array([x / s * angle, y / s * angle, z / s * angle])
