"""The executor's command geometry: the next target, the hand's rotation, the normal's sense.

- `next_target`: the move along d_{t+1} from the last target. With `command_from="measured"`
  the tracking error across the new direction (where the constraint stopped the hand) is
  released, bounded by REANCHOR_LIMIT_STEPS step lengths so that a pose glitch can never
  become a large command; the error along the direction and along the normal is kept, so the
  target stays smooth along the motion and a press keeps its depth, while each step's
  constraint force comes from that step's move alone, as in the training environment.
- `paper_turn`: on revolute constraints the hand turns by the rotation taking d_t to
  d_{t+1} (paper 3.4.1).
- `orient_normal`: the workplane normal's sense from the hinge, so that the motion turns
  positively about it (the sense paper 3.4.1's rotation and the torque policy assume).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from constraint_aware.control.guards import REANCHOR_LIMIT_STEPS
from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray, cross, norm
from constraint_aware.spatial import Pose


def orient_normal(
    normal: ArrayLike, direction: ArrayLike, position: ArrayLike, hinge_point: ArrayLike
) -> FloatArray:
    """The workplane normal (3,) oriented so that moving along `direction` (3,) at `position`
    (3,) [m] turns positively about it around the hinge through `hinge_point` (3,) [m]. Raises
    InvalidInputError when the direction points along the radius (no sense of rotation)."""
    n = np.asarray(normal, dtype=float)
    radial = np.asarray(position, dtype=float) - np.asarray(hinge_point, dtype=float)
    sense = float(cross(radial, np.asarray(direction, dtype=float)) @ n)
    if abs(sense) < 1e-9:
        raise InvalidInputError(
            "initial_direction: parallel to the radius from hinge_point; cannot orient the "
            "workplane normal"
        )
    return n if sense > 0 else -n


def paper_turn(d: FloatArray, d_next: FloatArray) -> FloatArray:
    """The rotation vector [rad] (3,) about d_t x d_{t+1} (3,) by the angle between them
    (paper 3.4.1); zero for parallel directions."""
    axis = cross(d, d_next)
    s = norm(axis)
    if s < 1e-12:
        return np.zeros(3)
    angle = math.atan2(s, float(d @ d_next))
    return np.asarray(axis / s * angle)


def next_target(
    target: Pose,
    measured: FloatArray,
    move: FloatArray,
    normal: FloatArray | None,
    step_length: float,
    reanchor: bool,
) -> Pose:
    """The last `target` moved by `move` (3,) [m]; with `reanchor`, plus the tracking error
    (`measured` (3,) [m] - target) across the move and in the workplane of `normal` (3,) unit
    (or in 3-D without one), at most REANCHOR_LIMIT_STEPS x `step_length` [m] long."""
    if not reanchor:
        return target.moved(move)
    # in Python floats, every control period (numpy's per-call overhead on 3-vectors is many
    # times the arithmetic): each product and sum in numpy's order, dot products summed
    # x, y, z in turn
    t0, t1, t2 = target.position.tolist()
    m0, m1, m2 = np.asarray(measured, dtype=float).tolist()
    v0, v1, v2 = np.asarray(move, dtype=float).tolist()
    e0, e1, e2 = m0 - t0, m1 - t1, m2 - t2  # the tracking error
    if normal is not None:  # ... in the workplane
        n0, n1, n2 = np.asarray(normal, dtype=float).tolist()
        k = e0 * n0 + e1 * n1 + e2 * n2
        e0, e1, e2 = e0 - k * n0, e1 - k * n1, e2 - k * n2
    n_move = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if n_move > 1e-12:  # ... across the move
        d0, d1, d2 = v0 / n_move, v1 / n_move, v2 / n_move
        k = e0 * d0 + e1 * d1 + e2 * d2
        e0, e1, e2 = e0 - k * d0, e1 - k * d1, e2 - k * d2
    limit = REANCHOR_LIMIT_STEPS * step_length
    size = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if size > limit:
        scale = limit / size
        e0, e1, e2 = e0 * scale, e1 * scale, e2 * scale
    position = np.array([t0 + e0 + v0, t1 + e1 + v1, t2 + e2 + v2])
    return Pose(position, target.orientation)
