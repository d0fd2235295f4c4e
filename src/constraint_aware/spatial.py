"""Pose and wrench value types shared by the executor and any robot (real or simulated)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.geometry import FloatArray


@dataclass(frozen=True)
class Wrench:
    """force: (3,) [N], torque: (3,) [N m] about the tool point; world frame.

    Sign: the action of everything outside the hand on the hand as the wrist sensor sees it
    (the object's force, plus the hand's weight), i.e. the raw F_s of paper 3.4.2.
    """

    force: FloatArray
    torque: FloatArray


@dataclass(frozen=True)
class Pose:
    """position: (3,) [m] of the tool point; orientation: the hand's rotation; world frame."""

    position: FloatArray
    orientation: Rotation

    def moved(self, translation: FloatArray, rotation: Rotation | None = None) -> Pose:
        """Translated, and rotated about the tool point (world-frame rotation applied first)."""
        rot = self.orientation if rotation is None else rotation * self.orientation
        return Pose(np.asarray(self.position + translation, dtype=float), rot)
