"""Direction controllers behind one interface: given the offset force and d_t, return d_{t+1}."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import FloatArray, normalize_force, unit, update_direction_rule
from constraint_aware.policy import ConstraintAwarePolicy


@dataclass(frozen=True)
class ControlInput:
    """What a controller sees each control step.

    force: (3,) [N] F = F_s - F_d, world frame (raw: not thresholded, not normalized);
    torque: (3,) [N m] about the tool point, offset removed; direction: (3,) unit d_t;
    dt: [s] control period; threshold: [N] below which |F| counts as no force;
    workplane_normal: (3,) unit, when the workplane is known (assumption 4);
    step_force: [N] k*delta, the robot's translational impedance stiffness times the step
    length (the force of one fully blocked step), when the robot reports its stiffness.
    """

    force: FloatArray
    torque: FloatArray
    direction: FloatArray
    dt: float
    threshold: float
    workplane_normal: FloatArray | None = None
    step_force: float | None = None


class DirectionController(Protocol):
    name: str

    def reset(self, direction: FloatArray) -> None:
        """Start of a run with the initial direction d0 (3,)."""
        ...

    def next_direction(self, inp: ControlInput) -> FloatArray:
        """d_{t+1}: (3,) unit vector."""
        ...

    def step_length(self, nominal: float) -> float:
        """[m] translation this step; most controllers always move the nominal 1 cm."""
        ...

    def hand_rotation(self) -> Rotation | None:
        """This step's hand rotation if the controller decides it; None: the executor's rule
        (paper 3.4.1 on revolute constraints, or the torque policy)."""
        ...


class _Base:
    name = "base"

    def reset(self, direction: FloatArray) -> None:
        pass

    def step_length(self, nominal: float) -> float:
        return nominal

    def hand_rotation(self) -> Rotation | None:
        return None


class FixedDirection(_Base):
    """No correction: keep d0 (the baseline that shows what the correction buys)."""

    name = "fixed"

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return inp.direction


class ProjectionController(_Base):
    """d <- d - (d.F^)F^, renormalized: exact for a frictionless guide."""

    name = "projection"

    def next_direction(self, inp: ControlInput) -> FloatArray:
        f_hat = normalize_force(inp.force, inp.threshold)
        a = -float(inp.direction @ f_hat) * f_hat
        return np.asarray(update_direction_rule(inp.direction, a))


class PolicyController(_Base):
    """The constraint-aware policy (paper 3.3): d <- (d + pi(s)) / |d + pi(s)|.

    s is the policy card's observation: (F^, d), plus the previous step's for history
    policies (a fresh session per run) or |F|/(k*delta) from the robot's step force.
    """

    name = "policy"

    def __init__(self, policy: ConstraintAwarePolicy | None = None) -> None:
        self.policy = policy or ConstraintAwarePolicy.load()
        self.session = self.policy.session()

    def reset(self, direction: FloatArray) -> None:
        self.session.reset()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return self.session.update_direction(
            inp.force, inp.direction, threshold=inp.threshold, step_force=inp.step_force
        )


def make_controller(
    name: str,
    policy: ConstraintAwarePolicy | None = None,
    rotation_rate: float | None = None,
    rotation_axis: FloatArray | None = None,
    params: dict[str, float] | None = None,
) -> DirectionController:
    """A controller by name: policy, fixed, projection or classical.

    rotation_rate [rad/s] and rotation_axis (3,) give the classical controller its rotational
    part (revolute tasks); the other controllers leave hand rotation to the executor. params:
    the classical controller's gains (ClassicalGains fields).
    """
    if name == "policy":
        return PolicyController(policy)
    if name == "fixed":
        return FixedDirection()
    if name == "projection":
        return ProjectionController()
    if name == "classical":
        from constraint_aware.control.classical import ClassicalController, ClassicalGains

        gains = ClassicalGains(**(params or {}))
        return ClassicalController(gains, w_d=rotation_rate, axis=rotation_axis)
    raise UnknownNameError("controller", name, list(CONTROLLERS))


CONTROLLERS = ("policy", "fixed", "projection", "classical")


def project_on_plane(direction: FloatArray, normal: FloatArray | None) -> FloatArray:
    """d with its component along the workplane normal removed (assumption 4), renormalized.

    Keeps d when it is (nearly) parallel to the normal, rather than returning a zero vector.
    """
    if normal is None:
        return direction
    p = direction - float(direction @ normal) * normal
    return unit(p) if np.linalg.norm(p) > 1e-6 else direction
