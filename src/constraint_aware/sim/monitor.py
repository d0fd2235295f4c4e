"""The simulator's ground truth (the executor's `TaskMonitor` protocol), for any embodiment.

Progress, the true admissible direction, slip of the hand relative to the handle and lost
grasps are read from the object's joint and the handle/TCP sites; the embodiment only names its
hand geoms (contact) and its TCP site.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from constraint_aware.geometry import FloatArray
from constraint_aware.sim.objects import HANDLE_SITE, OBJECT_GEOM_PREFIX, OBJECT_JOINT
from constraint_aware.sim.robot_adapter import cross, rotvec
from constraint_aware.sim.tasks import TaskConfig


class GroundTruthMonitor:
    """Mixin: the task's ground truth from `self.model`/`self.data` (set by the embodiment)."""

    model: mujoco.MjModel
    data: mujoco.MjData
    task: TaskConfig
    _tcp_site: int

    def _bind_monitor(self, hand_geoms: set[int], prefix: str = "") -> None:
        """Resolve the object's names to ids once; `hand_geoms`: the hand's geom ids; `prefix`:
        the object's name prefix in a composed scene (sim/scene.py)."""
        m = self.model
        self._obj_joint = m.joint(prefix + OBJECT_JOINT).id
        self._obj_qpos = int(m.jnt_qposadr[self._obj_joint])
        self._handle_site = m.site(prefix + HANDLE_SITE).id
        names = [m.geom(i).name for i in range(m.ngeom)]
        self._hand_geoms = hand_geoms
        start = prefix + OBJECT_GEOM_PREFIX
        self._object_geoms = {i for i, n in enumerate(names) if n.startswith(start)}
        # the same sets as masks over geom ids, for `in_contact` (runs every filtered substep)
        self._hand_mask = np.zeros(m.ngeom, dtype=bool)
        self._hand_mask[list(hand_geoms)] = True
        self._object_mask = np.zeros(m.ngeom, dtype=bool)
        self._object_mask[list(self._object_geoms)] = True
        self._grasp_rel: tuple[FloatArray, FloatArray] | None = None

    def _record_grasp(self) -> None:
        """Remember the hand's pose in the handle's frame: slip is measured from here."""
        self._grasp_rel = self._hand_in_handle()

    def joint_position(self) -> float:
        return float(self.data.qpos[self._obj_qpos])

    def progress(self) -> float:
        return self.joint_position()

    def succeeded(self) -> bool:
        return self.progress() >= self.task.success_progress

    def admissible_direction(self) -> FloatArray:
        d = self.data
        axis = d.xaxis[self._obj_joint]
        if self.task.object.joint_type == "prismatic":
            return _unit(axis)
        radial = d.site_xpos[self._tcp_site] - d.xanchor[self._obj_joint]
        return _unit(cross(axis, radial - (radial @ axis) * axis))

    def handle_position(self) -> FloatArray:
        return self.data.site_xpos[self._handle_site].copy()

    def _hand_in_handle(self) -> tuple[FloatArray, FloatArray]:
        """The TCP in the handle's frame: position (3,) [m] and rotation matrix (3, 3)."""
        d = self.data
        handle = d.site_xmat[self._handle_site].reshape(3, 3)
        tcp = d.site_xmat[self._tcp_site].reshape(3, 3)
        rel = (d.site_xpos[self._tcp_site] - d.site_xpos[self._handle_site]) @ handle
        return rel, handle.T @ tcp

    def slip(self) -> tuple[float, float]:
        if self._grasp_rel is None:
            return 0.0, 0.0
        rel, rot = self._hand_in_handle()
        rel0, rot0 = self._grasp_rel
        turn = rotvec(rot0.T @ rot)
        return float(np.linalg.norm(rel - rel0)), math.degrees(math.sqrt(float(turn @ turn)))

    def in_contact(self) -> bool:
        """Whether any hand geom touches any object geom."""
        d = self.data
        if d.ncon == 0:
            return False
        g1, g2 = d.contact.geom1, d.contact.geom2  # (ncon,) each, in one call
        hand, obj = self._hand_mask, self._object_mask
        return bool(np.any((hand[g1] & obj[g2]) | (hand[g2] & obj[g1])))

    def grasp_failure(self) -> str | None:
        dist, ang = self.slip()
        if dist > self.task.slip_limit:
            return f"grasp lost: hand drifted {dist * 100:.1f} cm from the handle"
        limit = self.task.slip_angle_limit
        if limit is not None and ang > limit:
            return f"grasp lost: hand turned {ang:.0f} deg relative to the handle"
        return None


def _unit(v: FloatArray) -> FloatArray:
    """v (3,) normalized, a new array (geometry.unit's rule: the zero vector below 1e-12)."""
    norm = math.sqrt(float(v @ v))
    return v / norm if norm > 1e-12 else np.zeros(3)
