"""Pose and wrench value types shared by the executor and any robot (real or simulated)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray, as_vector

#: [m/s^2] standard gravity, world frame with z up
GRAVITY = (0.0, 0.0, -9.81)


@dataclass(frozen=True)
class Wrench:
    """force: (3,) [N], torque: (3,) [N m] about the tool point; world frame.

    Sign: the action of everything outside the hand on the hand as the wrist sensor sees it
    (the object's force, plus the hand's weight), i.e. the raw F_s of paper 3.4.2. Pulling a
    drawer open, the drawer resists: F points against the hand's motion.
    """

    force: FloatArray
    torque: FloatArray

    @classmethod
    def from_sensor(
        cls,
        force_sensor: ArrayLike,
        torque_sensor: ArrayLike,
        sensor_rotation: Rotation | ArrayLike,
        sensor_position: ArrayLike,
        tool_position: ArrayLike,
        sign: float = 1.0,
        hand_mass: float | None = None,
        hand_com: ArrayLike | None = None,
        gravity: ArrayLike = GRAVITY,
    ) -> Wrench:
        """The executor's wrench from a raw wrist F/T reading.

        force_sensor (3,) [N] and torque_sensor (3,) [N m]: the reading in the sensor's frame,
        torque about the sensor's origin. sensor_rotation: sensor frame -> world (a Rotation
        or a (3, 3) matrix whose columns are the sensor axes in world). sensor_position,
        tool_position (3,) [m]: world positions of the sensor origin and the tool point.
        sign: +1 when the sensor reports the force the hand side receives from outside (the
        executor's convention), -1 when it reports the force the mounting side exerts on the
        hand side (MuJoCo's `force`/`torque` sensors, many drivers). hand_mass [kg] and
        hand_com (3,) [m, world; default: the sensor origin]: remove the weight of the hand
        beyond the sensor (useful when the hand turns about a horizontal axis; otherwise the
        executor's F_d already removes it). gravity (3,) [m/s^2], world frame.

        Returns force (3,) [N] and torque (3,) [N m] about the tool point, world frame.
        """
        if sign not in (1.0, -1.0):
            raise InvalidInputError(f"sign: must be +1 or -1, got {sign}")
        rot = (
            sensor_rotation
            if isinstance(sensor_rotation, Rotation)
            else Rotation.from_matrix(np.asarray(sensor_rotation, dtype=float))
        )
        force = sign * rot.apply(as_vector(force_sensor, "force_sensor"))
        torque = sign * rot.apply(as_vector(torque_sensor, "torque_sensor"))
        sensor = as_vector(sensor_position, "sensor_position")
        tool = as_vector(tool_position, "tool_position")
        if hand_mass is not None:
            if not (np.isfinite(hand_mass) and hand_mass >= 0):
                raise InvalidInputError(f"hand_mass: must be finite and >= 0 [kg], got {hand_mass}")
            weight = hand_mass * as_vector(gravity, "gravity")
            com = sensor if hand_com is None else as_vector(hand_com, "hand_com")
            force = force - weight
            torque = torque - np.cross(com - sensor, weight)
        # the same force about the tool point: tau_tool = tau_sensor + (p_sensor - p_tool) x F
        return cls(force, torque + np.cross(sensor - tool, force))


@dataclass(frozen=True)
class Pose:
    """position: (3,) [m] of the tool point; orientation: the hand's rotation; world frame."""

    position: FloatArray
    orientation: Rotation

    def moved(self, translation: FloatArray, rotation: Rotation | None = None) -> Pose:
        """Translated, and rotated about the tool point (world-frame rotation applied first)."""
        rot = self.orientation if rotation is None else rotation * self.orientation
        return Pose(np.asarray(self.position + translation, dtype=float), rot)


def turned(rotvec: FloatArray, orientation: Rotation) -> Rotation:
    """`Rotation.from_rotvec(rotvec) * orientation`: `orientation` (a single Rotation) turned
    by the rotation vector `rotvec` (3,) [rad] in the world frame, with the same floats.

    The executor turns the hand this way every control period on revolute constraints, where
    scipy's per-call overhead dominates: the rotation vector's quaternion and the product are
    computed in Python floats with scipy's formulas (its small-angle series below 1e-3 rad,
    its quaternion product), and only the result is built as a Rotation (normalized, as
    scipy's composition normalizes it).
    """
    x, y, z = np.asarray(rotvec, dtype=float).tolist()
    angle = math.sqrt(x * x + y * y + z * z)
    if angle <= 1e-3:  # scipy's series for sin(angle / 2) / angle
        angle2 = angle * angle
        scale = 0.5 - angle2 / 48 + angle2 * angle2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    p0, p1, p2, p3 = scale * x, scale * y, scale * z, math.cos(angle / 2)
    q0, q1, q2, q3 = orientation.as_quat(canonical=False).tolist()
    c0, c1, c2 = p1 * q2 - p2 * q1, p2 * q0 - p0 * q2, p0 * q1 - p1 * q0  # p x q
    return Rotation.from_quat(
        [
            p3 * q0 + q3 * p0 + c0,
            p3 * q1 + q3 * p1 + c1,
            p3 * q2 + q3 * p2 + c2,
            p3 * q3 - p0 * q0 - p1 * q1 - p2 * q2,
        ]
    )
