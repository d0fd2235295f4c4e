"""The embodiments by name, and robot specs with physical variants: "jaco:stiffness=2000".

A robot spec is an embodiment name optionally followed by `:key=value,...` (keys in
`ROBOT_PARAMS`, each at most once): the arm's translational Cartesian stiffness [N/m] and the
control period [s]. Both embodiments take both keys, so the variants compare like with like.
Each embodiment advertises, per key, the range across which every paper task succeeds at its
paper offsets (`VARIANT_RANGES`, measured by benchmarks/robot_variants.py); a value outside it
is refused when the spec is parsed, naming the valid range.
"""

from __future__ import annotations

import math
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
#: The variant keys: key -> unit.
ROBOT_PARAMS: dict[str, str] = {
    "stiffness": "N/m",  # translational Cartesian stiffness of the arm
    "period": "s",  # control period
}
#: Per embodiment and key, the advertised range [low, high]: every paper task succeeded at its
#: paper offsets with 3 sensor-noise seeds at both ends and at every value measured between
#: (benchmarks/robot_variants.py, benchmarks/results/robot_variants.json, which also holds the
#: values beyond, and why they fail).
VARIANT_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "hook-hand": {"stiffness": (200.0, 10_000.0), "period": (0.02, 0.5)},
    "jaco": {"stiffness": (700.0, 4_000.0), "period": (0.06, 0.5)},
}


def variant_ranges(name: str | None = None) -> str:
    """The advertised variant ranges as text (of embodiment `name`, or of every one)."""
    names = [name] if name is not None else list(VARIANT_RANGES)
    parts = []
    for n in names:
        ranges = VARIANT_RANGES[n].items()
        keys = ", ".join(f"{k} {lo:g}-{hi:g} {ROBOT_PARAMS[k]}" for k, (lo, hi) in ranges)
        parts.append(f"{n}: {keys}")
    return "; ".join(parts)


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
    """`name` or `name:key=value,...`; errors name the field and the valid range.

    Raises UnknownNameError for an unknown embodiment or key, InvalidInputError for an empty
    or repeated variant, a value that is not a finite number, or one outside the embodiment's
    advertised range (`VARIANT_RANGES`)."""
    if not isinstance(text, str):
        raise InvalidInputError(
            f"robot spec: expected text such as 'jaco:stiffness=2000', got {text!r}"
        )
    name, colon, rest = text.partition(":")
    name = name.strip()
    if name not in EMBODIMENTS:
        raise UnknownNameError("robot", name, list(EMBODIMENTS))
    values: dict[str, float] = {}
    for item in rest.split(",") if colon else []:
        key, sep, raw = (part.strip() for part in item.partition("="))
        if not key and not sep:
            raise InvalidInputError(
                f"robot spec {text!r}: an empty variant; write NAME or NAME:KEY=VALUE,..."
            )
        if key not in ROBOT_PARAMS:
            raise UnknownNameError("robot parameter", key, list(ROBOT_PARAMS))
        if not sep:
            raise InvalidInputError(f"robot spec {text!r}: {key} needs a value ({key}=VALUE)")
        if key in values:
            raise InvalidInputError(f"robot spec {text!r}: {key} given twice")
        lo, hi = VARIANT_RANGES[name][key]
        unit = ROBOT_PARAMS[key]
        try:
            value = float(raw)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and lo <= value <= hi):
            raise InvalidInputError(
                f"robot parameter {name}:{key}={raw!r}: valid range for {name} is "
                f"{lo:g}-{hi:g} {unit} (where every paper task succeeds)"
            )
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
