"""What a run was given besides the readings, where each value came from, and what it enabled.

A controller's stages may each need values a robot, its configuration or the controller
itself may or may not provide: the step force k*delta, the arm's tracking time constant, the
workplane normal, the rotation rate, the force the grasp's play hides. A missing value
switches a stage off. Silently, that reads as a controller performing worse for no visible
reason; so at the start of every run the executor records each input's value and source
(`RunRecord.inputs`), each stage's state (`RunRecord.stages`), and says once, in a warning on
the "constraint_aware" logger, which missing input switched which stages off.

A controller declares its stages with an optional method
`stage_inputs(constraint_type) -> dict[str, tuple[str, ...]]`: stage name -> the names (from
INPUT_NAMES) of the inputs it needs.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray

#: The run inputs a controller's stage may need, each with its unit:
#: step_force [N] (stiffness x step length), tracking_time_constant [s] (the arm's lag),
#: workplane_normal (3,) unit, rotation_rate [rad/s] (w_d of a revolute motion), play_force
#: [N] (stiffness x grasp play).
INPUT_NAMES = (
    "step_force",
    "tracking_time_constant",
    "workplane_normal",
    "rotation_rate",
    "play_force",
)
#: Where a run input's value came from: the robot's own report, the executor's configuration,
#: the controller, or nowhere. A new source (e.g. a stored robot profile) is added here.
INPUT_SOURCES = ("robot", "config", "controller", "missing")
InputSource = Literal["robot", "config", "controller", "missing"]

#: The logger the missing-input warnings go to.
LOGGER = logging.getLogger("constraint_aware")


@dataclass(frozen=True)
class RunInput:
    """One run input: its value (None when missing), its source, and when missing, why."""

    value: float | tuple[float, ...] | None
    source: InputSource
    why_missing: str = ""

    def to_record(self) -> dict[str, Any]:
        """The record's form: {"value": number, list or None, "source": name}."""
        value = list(self.value) if isinstance(self.value, tuple) else self.value
        return {"value": value, "source": self.source}


def _missing(why: str) -> RunInput:
    return RunInput(None, "missing", why)


def gather_inputs(
    *,
    stiffness: float | None,
    stiffness_source: InputSource,
    step_length: float,
    tracking_time_constant: float | None,
    normal: FloatArray | None,
    grasp_play: float | None,
    controller: object,
) -> dict[str, RunInput]:
    """Every input of INPUT_NAMES for one run.

    Args:
        stiffness: [N/m] the arm's stiffness in use, or None.
        stiffness_source: "robot" (its translational_stiffness) or "config" (the override).
        step_length: [m] the nominal step.
        tracking_time_constant: [s] the robot's valid report, or None.
        normal: (3,) unit workplane normal in use (oriented), or None (3-D motion).
        grasp_play: [m] the configured grasp play, or None (unknown).
        controller: the run's controller; its optional `rotation_rate` [rad/s] is read.
    """
    out: dict[str, RunInput] = {}
    if stiffness is None:
        out["step_force"] = _missing(
            "the robot reports no translational_stiffness and "
            "ExecutorConfig.robot.stiffness is not set"
        )
    else:
        out["step_force"] = RunInput(stiffness * step_length, stiffness_source)
    if tracking_time_constant is None:
        out["tracking_time_constant"] = _missing("the robot reports no tracking_time_constant")
    else:
        out["tracking_time_constant"] = RunInput(tracking_time_constant, "robot")
    if normal is None:
        out["workplane_normal"] = _missing("ExecutorConfig.workplane_normal is None: 3-D motion")
    else:
        vec = np.asarray(normal, dtype=float)
        out["workplane_normal"] = RunInput((float(vec[0]), float(vec[1]), float(vec[2])), "config")
    out["rotation_rate"] = _controller_rate(controller)
    if grasp_play is None:
        out["play_force"] = _missing("ExecutorConfig.robot.grasp_play is not set")
    elif stiffness is None:
        out["play_force"] = _missing("no stiffness to turn the configured grasp play into a force")
    else:
        out["play_force"] = RunInput(stiffness * grasp_play, "config")
    return out


def _controller_rate(controller: object) -> RunInput:
    raw = getattr(controller, "rotation_rate", None)
    if raw is None:
        return _missing("the controller has no rotation_rate")
    try:
        rate = float(raw)
    except (TypeError, ValueError):
        rate = math.nan
    if not math.isfinite(rate):
        return _missing(f"the controller's rotation_rate {raw!r} is not a finite number")
    return RunInput(rate, "controller")


def stage_states(
    controller: object, constraint_type: str, inputs: Mapping[str, RunInput]
) -> tuple[dict[str, str], list[str]]:
    """Each stage the controller declares (`stage_inputs`), "active" or "off: missing <input>[,
    <input>]", and one warning line per missing input that switches at least one stage off.
    A controller without `stage_inputs` has no stages. Raises InvalidInputError naming
    `stage_inputs` when its answer is not a mapping of stage names to INPUT_NAMES."""
    declare = getattr(controller, "stage_inputs", None)
    if declare is None:
        return {}, []
    needs = _checked_stages(declare(constraint_type))
    stages: dict[str, str] = {}
    off_by: dict[str, list[str]] = {}
    for stage, names in needs.items():
        missing = [n for n in names if inputs[n].source == "missing"]
        stages[stage] = "active" if not missing else "off: missing " + ", ".join(missing)
        for name in missing:
            off_by.setdefault(name, []).append(stage)
    warnings = [
        f"{name} missing ({inputs[name].why_missing}): "
        f"stage{'s' if len(off) > 1 else ''} {', '.join(off)} off"
        for name in INPUT_NAMES
        if (off := off_by.get(name))
    ]
    return stages, warnings


def _checked_stages(answer: object) -> dict[str, tuple[str, ...]]:
    where = "controller.stage_inputs()"
    if not isinstance(answer, Mapping):
        raise InvalidInputError(f"{where}: expected a dict of stage -> input names, got {answer!r}")
    out: dict[str, tuple[str, ...]] = {}
    for stage, names in answer.items():
        if not isinstance(stage, str) or isinstance(names, str):
            raise InvalidInputError(f"{where}: stage {stage!r}: expected a name and a tuple")
        try:
            items = tuple(names)
        except TypeError:
            raise InvalidInputError(
                f"{where}: stage {stage!r}: expected a tuple of input names, got {names!r}"
            ) from None
        unknown = [n for n in items if n not in INPUT_NAMES]
        if unknown:
            raise InvalidInputError(
                f"{where}: stage {stage!r}: unknown input {unknown[0]!r}; valid names: "
                + ", ".join(INPUT_NAMES)
            )
        out[stage] = items
    return out


def warn_missing(warnings: list[str]) -> None:
    """Each line once on the "constraint_aware" logger, as a warning."""
    for line in warnings:
        LOGGER.warning(line)
