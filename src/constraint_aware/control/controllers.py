"""Direction controllers by name: given the offset force and d_t, return d_{t+1}.

The interface (`ControlInput`, `DirectionController`, `INPUT_NAMES`) lives in
`control.interface`, the default controller's steadying in `control.steady`, the classical
baseline in `control.classical`; this module holds the simple controllers, the policy alone,
and `make_controller`, which builds any of them by name.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.classical import ClassicalController, ClassicalGains
from constraint_aware.control.interface import (
    INPUT_NAMES,
    ControlInput,
    DirectionController,
    StagedController,
)
from constraint_aware.control.steady import STEADY_STAGES, SteadyConfig, SteadyDirection
from constraint_aware.errors import ConfigError, UnknownNameError
from constraint_aware.geometry import FloatArray, normalize_force, update_direction_rule
from constraint_aware.policy import ConstraintAwarePolicy

__all__ = [
    "CONTROLLERS",
    "INPUT_NAMES",
    "POLICY_CONTROLLERS",
    "POLICY_STAGES",
    "ControlInput",
    "DirectionController",
    "FixedDirection",
    "PolicyController",
    "ProjectionController",
    "StagedController",
    "driving_policy",
    "make_controller",
    "project_on_plane",
]


class _Base:
    name = "base"

    def reset(self, direction: FloatArray) -> None:
        pass

    def step_length(self, nominal: float) -> float:
        return nominal

    def hand_rotation(self) -> Rotation | None:
        return None

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """No stages: this controller needs nothing beyond the force and d."""
        return {}


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
    """The constraint-aware policy alone (paper 3.3): d <- (d + pi(s)) / |d + pi(s)|.

    s is the policy card's observation: (F^, d), plus the previous step's for history
    policies (a fresh session per run) or |F|/(k*delta) from the robot's step force. This is
    controller "policy-raw" (the paper's rule as published); controller "policy" runs it
    inside `SteadyDirection`.
    """

    name = "policy-raw"

    def __init__(self, policy: ConstraintAwarePolicy | None = None, mirror: bool = False) -> None:
        self.policy = policy or ConstraintAwarePolicy.load()
        self.session = self.policy.session()
        # mirror: the action averaged with its mirror image about the workplane normal, when
        # the workplane is known (policy.mirror_average); off for the paper's rule as published
        self.mirror = mirror
        if mirror:
            self.name = "policy-mirrored"

    def reset(self, direction: FloatArray) -> None:
        self.session.reset()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return self.session.update_direction(
            inp.force,
            inp.direction,
            threshold=inp.threshold,
            step_force=inp.step_force,
            workplane_normal=inp.workplane_normal if self.mirror else None,
        )

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """The network's |F| / (k delta) input needs the step force (policies whose card
        lists it); the mirror average needs the workplane normal and the step force (at or
        above k delta, or without it, the network's action is used as it is)."""
        stages: dict[str, tuple[str, ...]] = {}
        if "step_force" in self.policy.inputs:
            stages["magnitude_input"] = ("step_force",)
        if self.mirror:
            stages["mirror_average"] = ("workplane_normal", "step_force")
        return stages


#: The controllers `make_controller` builds.
CONTROLLERS = ("policy", "policy-raw", "fixed", "projection", "classical")
#: The controllers a learned policy drives (the ones `--policy` applies to).
POLICY_CONTROLLERS = ("policy", "policy-raw")
#: The stages of controller "policy" that `make_controller`'s params can switch off: the
#: mirror average of the policy's action, then `SteadyConfig`'s.
POLICY_STAGES = ("mirror_average", *STEADY_STAGES)


def make_controller(
    name: str,
    policy: ConstraintAwarePolicy | None = None,
    rotation_rate: float | None = None,
    rotation_axis: FloatArray | None = None,
    params: dict[str, float] | None = None,
) -> StagedController:
    """A controller by name: policy, policy-raw, fixed, projection or classical.

    "policy" is the learned policy as this library runs it: its action mirror-averaged about
    the known workplane normal (`policy.mirror_average`) inside `SteadyDirection`
    (docs/design/default-controller.md); "policy-raw" is the paper's rule
    d <- (d + pi(s)) / |...| alone, the faithful reproduction. rotation_rate [rad/s] and
    rotation_axis (3,) give the classical controller its rotational part (revolute tasks),
    and "policy" its feed-forward; the other controllers leave hand rotation to the executor.

    Args:
        name: one of `CONTROLLERS`.
        policy: the network driving "policy" and "policy-raw" (None: the shipped default).
        rotation_rate: [rad/s] w = v / r of a revolute joint, or None.
        rotation_axis: (3,) the classical controller's rotation axis, or None.
        params: for "classical" its gains (`ClassicalGains` fields, SI units); for "policy"
            stage switches, `POLICY_STAGES` names -> 0 (off) or 1 (on, the default).
    """
    if name == "policy":
        switches = dict(params or {})
        for key, value in switches.items():
            if key not in POLICY_STAGES:
                raise UnknownNameError("policy stage", key, list(POLICY_STAGES))
            if value not in (0, 1):
                raise ConfigError(f"params[{key!r}]", value, "0 (off) or 1 (on)")
        mirror = bool(switches.pop("mirror_average", True))
        config = SteadyConfig(**{k: bool(v) for k, v in switches.items()})
        inner = PolicyController(policy, mirror=mirror)
        return SteadyDirection(inner, rotation_rate, config, name="policy")
    if name == "policy-raw":
        return PolicyController(policy)
    if name == "fixed":
        return FixedDirection()
    if name == "projection":
        return ProjectionController()
    if name == "classical":
        gains = ClassicalGains(**(params or {}))
        return ClassicalController(gains, w_d=rotation_rate, axis=rotation_axis)
    raise UnknownNameError("controller", name, list(CONTROLLERS))


def driving_policy(controller: object) -> ConstraintAwarePolicy | None:
    """The learned policy behind a controller ("policy", "policy-raw"), or None."""
    while isinstance(controller, SteadyDirection):
        controller = controller.inner
    return controller.policy if isinstance(controller, PolicyController) else None


def project_on_plane(direction: FloatArray, normal: FloatArray | None) -> FloatArray:
    """d with its component along the workplane normal removed (assumption 4), renormalized.

    Keeps d when it is (nearly) parallel to the normal, rather than returning a zero vector.
    """
    if normal is None:
        return direction
    # in Python floats (every control period), each product and sum in numpy's order
    d0, d1, d2 = np.asarray(direction, dtype=float).tolist()
    n0, n1, n2 = np.asarray(normal, dtype=float).tolist()
    k = d0 * n0 + d1 * n1 + d2 * n2
    p0, p1, p2 = d0 - k * n0, d1 - k * n1, d2 - k * n2
    size = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    return np.array([p0 / size, p1 / size, p2 / size]) if size > 1e-6 else direction
