"""The embodiments by name, and robot specs with physical variants: "jaco:stiffness=5000".

A robot spec is an embodiment name optionally followed by `:key=value,...` (valid keys in
`ROBOT_PARAMS`): the arm's Cartesian stiffness [N/m] and the control period [s]. Both
embodiments take both keys, so the variants compare like with like.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from constraint_aware.errors import InvalidInputError, UnknownNameError
from constraint_aware.geometry import FloatArray
from constraint_aware.sim.base import Embodiment
from constraint_aware.sim.jaco import JacoSim, OscConfig
from constraint_aware.sim.robot_adapter import CONTROL_PERIOD, period_substeps
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.sim.world import ManipulationSim

__all__ = [
    "DEFAULT_ROBOT",
    "EMBODIMENTS",
    "ROBOT_PARAMS",
    "Embodiment",
    "RobotSpec",
    "make_embodiment",
    "parse_robot",
]

DEFAULT_ROBOT = "hook-hand"
ROBOT_PARAMS = {
    "stiffness": (100.0, 1e5),  # [N/m] translational Cartesian stiffness of the arm
    "period": (0.02, 0.5),  # [s] control period
}


@dataclass(frozen=True)
class RobotSpec:
    """A parsed robot spec: the embodiment and its variant parameters (None: its default)."""

    name: str
    stiffness: float | None = None  # [N/m]
    period: float | None = None  # [s]


def _hook_hand(task: TaskConfig, spec: RobotSpec) -> Embodiment:
    if spec.stiffness is not None:
        task = task.with_overrides(hand__translational_stiffness=spec.stiffness)
    return ManipulationSim(task, control_period=spec.period or CONTROL_PERIOD)


def _jaco(task: TaskConfig, spec: RobotSpec) -> Embodiment:
    osc = OscConfig()
    if spec.stiffness is not None:
        # translational only, as the hook hand's `hand__translational_stiffness`: the wrist's
        # rotational stiffness stays (like with like)
        osc = replace(osc, translational_stiffness=spec.stiffness)
    return JacoSim(task, osc, control_period=spec.period or CONTROL_PERIOD)


EMBODIMENTS: dict[str, Callable[[TaskConfig, RobotSpec], Embodiment]] = {
    "hook-hand": _hook_hand,  # the project's two-finger hook hand on virtual Cartesian joints
    "jaco": _jaco,  # Kinova Jaco arm + 3-finger hand (dm-control's models), OSC impedance
}


def parse_robot(text: str) -> RobotSpec:
    """`name` or `name:key=value,...`; errors name the field and the valid range."""
    name, _, rest = text.partition(":")
    if name not in EMBODIMENTS:
        raise UnknownNameError("robot", name, list(EMBODIMENTS))
    values: dict[str, float] = {}
    for item in filter(None, rest.split(",")):
        key, sep, raw = item.partition("=")
        if key not in ROBOT_PARAMS or not sep:
            raise UnknownNameError("robot parameter", key, list(ROBOT_PARAMS))
        try:
            value = float(raw)
        except ValueError:
            raise InvalidInputError(f"robot parameter {key}={raw!r} is not a number") from None
        lo, hi = ROBOT_PARAMS[key]
        if not lo <= value <= hi:
            raise InvalidInputError(f"robot parameter {key}={value}; valid range {lo}-{hi}")
        if key == "period":
            period_substeps(value)  # a whole number of simulation steps
        values[key] = value
    return RobotSpec(name, **values)


def make_embodiment(
    robot: str,
    task: TaskConfig,
    rng: np.random.Generator | None = None,
    noise: float = 0.0,
    bias: FloatArray | None = None,
) -> Embodiment:
    """The embodiment `robot` (a robot spec) on `task`, with the given sensor noise, not reset."""
    spec = parse_robot(robot)
    sim = EMBODIMENTS[spec.name](task, spec)
    if rng is not None:
        sim.set_sensor_noise(rng, noise, bias)
    return sim
