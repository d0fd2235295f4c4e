"""Constraint force on the composite body: the quasi-static closed form and the MuJoCo backend.

Both answer the same question for a batch of N bodies: the hand, a spring of stiffness k, is
commanded `step_length` along the unit direction d from the body's current position; the body
can only slide along the unit joint axis u, against Coulomb friction mu and the object's own
along-axis resistance R >= 0 (dry joint friction, and the viscous and inertial forces of the
step, which the episode computes from its kinematics). What force F does the guide exert on the
body? F is what a wrist sensor reads as the environment's force on the hand under the
single-system condition.

Decompose the spring force k*step*d into a drive along the axis t = k*step*(d.u) and a push
across it p = k*step*(d - (d.u)u). The guide answers -p (normal force) plus a force along u
limited by L = mu*|p| + R: sliding, |t| > L: -sign(t)*L (the body moves and the spring's
remaining stretch along u balances L); sticking: -t (it holds the body).
"""

from __future__ import annotations

from typing import Protocol

import mujoco
import numpy as np

from constraint_aware.geometry import FloatArray


class ForceModel(Protocol):
    """Maps a batch of (axis, direction, friction, stiffness, resistance) to the guide's force
    F: (N, 3) [N]."""

    def __call__(
        self,
        axis: FloatArray,
        direction: FloatArray,
        friction: FloatArray,
        stiffness: FloatArray,
        step_length: float,
        resistance: FloatArray | None = None,
    ) -> FloatArray: ...


def analytic_constraint_force(
    axis: FloatArray,
    direction: FloatArray,
    friction: FloatArray,
    stiffness: FloatArray,
    step_length: float,
    resistance: FloatArray | None = None,
) -> FloatArray:
    """Quasi-static guide force, batched.

    axis, direction: (N, 3) unit vectors; friction: (N,) [-]; stiffness: (N,) [N/m];
    step_length [m]; resistance: (N,) [N] >= 0 along-axis resistance (default none).
    Returns F: (N, 3) [N], world frame, force of the guide on the body.
    """
    scale = (stiffness * step_length)[:, None]
    along = np.sum(direction * axis, axis=1, keepdims=True)
    push = scale * (direction - along * axis)
    drive = scale * along
    normal = np.linalg.norm(push, axis=1, keepdims=True)
    limit = friction[:, None] * normal
    if resistance is not None:
        limit = limit + resistance[:, None]
    friction_force = np.where(np.abs(drive) > limit, -np.sign(drive) * limit, -drive)
    return -push + friction_force * axis


_MJCF = """
<mujoco model="single_system">
  <option timestep="0.002" gravity="0 0 0" integrator="implicitfast"/>
  <worldbody>
    <body name="composite_body">
      <joint name="guide" type="slide" axis="1 0 0" solreffriction="0.004 1"/>
      <geom name="body_geom" type="sphere" size="0.03" mass="{mass}"
            contype="0" conaffinity="0"/>
      <site name="sensor_site"/>
    </body>
  </worldbody>
  <sensor>
    <force name="guide_force" site="sensor_site"/>
  </sensor>
</mujoco>
"""


class MujocoConstraintForce:
    """The same question answered by MuJoCo: a body on a slide joint pulled by a spring.

    The hand spring (stiffness k, damping from `damping_ratio`) is applied as an external
    force on the body each substep; since the body cannot leave the axis, the push across it is
    constant over a step and sets the Coulomb friction of the joint (`frictionloss = mu*|p|`,
    plus the along-axis resistance R: MuJoCo's dry joint friction is the same stick-or-slide
    limit).
    The guide's force is read from a `force` sensor (the parent-to-body interaction force)
    `substeps` x 2 ms after the command: MuJoCo's friction is soft, and waiting for full
    settling lets the body creep and the friction fade. The friction constraint is made as
    stiff as the 2 ms step allows (`solreffriction` 0.004 s) for the same reason: a stuck body
    still creeps, so there the force direction differs from the closed form by ~0.2 deg.
    """

    def __init__(self, substeps: int = 10, mass: float = 1.0, damping_ratio: float = 1.0) -> None:
        self.model = mujoco.MjModel.from_xml_string(_MJCF.format(mass=mass))
        self.data = mujoco.MjData(self.model)
        self.substeps = substeps
        self.mass = mass
        self.damping_ratio = damping_ratio
        self._joint = self.model.joint("guide").id
        self._dof = int(self.model.jnt_dofadr[self._joint])
        self._qpos = int(self.model.jnt_qposadr[self._joint])
        self._body = self.model.body("composite_body").id
        sensor = self.model.sensor("guide_force")
        self._sensor = slice(int(sensor.adr[0]), int(sensor.adr[0]) + 3)

    def __call__(
        self,
        axis: FloatArray,
        direction: FloatArray,
        friction: FloatArray,
        stiffness: FloatArray,
        step_length: float,
        resistance: FloatArray | None = None,
    ) -> FloatArray:
        out = np.empty_like(direction)
        m, d = self.model, self.data
        xfrc = d.xfrc_applied[self._body]
        for i in range(direction.shape[0]):
            u = axis[i]
            k = float(stiffness[i])
            c = 2.0 * self.damping_ratio * np.sqrt(k * self.mass)
            along = float(direction[i] @ u)
            push = k * step_length * (direction[i] - along * u)
            target = step_length * along  # commanded position projected on the axis
            m.jnt_axis[self._joint] = u
            extra = 0.0 if resistance is None else float(resistance[i])
            m.dof_frictionloss[self._dof] = float(friction[i]) * float(np.linalg.norm(push)) + extra
            mujoco.mj_resetData(m, d)
            for _ in range(self.substeps):
                q = d.qpos[self._qpos]
                v = d.qvel[self._dof]
                xfrc[:3] = push + (k * (target - q) - c * v) * u
                mujoco.mj_step(m, d)
            xfrc[:3] = push + (k * (target - d.qpos[self._qpos]) - c * d.qvel[self._dof]) * u
            mujoco.mj_forward(m, d)
            # sensor frame = body frame = world frame: a slide joint never rotates the body
            out[i] = d.sensordata[self._sensor]
        return out
