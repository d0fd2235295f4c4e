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
INPUT_NAMES) of the inputs it needs. With `ExecutorConfig.strict_inputs` a missing input that
switches a stage off refuses the run instead (`MissingInputError`, before anything moves).

Where each value comes from (`resolve_robot_values`), first that has it:

- the arm's stiffness k (for the step force k x step and the play force k x play): the
  configuration's override (`ExecutorConfig.robot.stiffness`), the robot's
  `translational_stiffness` report, the robot profile's measured value (control.profile);
- the tracking time constant tau: the robot's `tracking_time_constant` report, the profile's
  measured value;
- the grasp play: the configuration's override, the profile's measured value;
- the dead band: the configuration's `threshold`, the profile's (from the calibrated noise
  over its long rest), else derived at the start of the run from the spread of the F_d
  samples (source "measured");
- the force noise sigma (the frozen-reading test, control.sensor_health): the profile's
  only; without it that test is off;
- the deflection model (the dead-sensor test, control.sensor_health): the profile's
  stiffness, tau and measured deflection error, together or not at all.

A robot's report of a member the Robot protocol documents (`translational_stiffness`,
`tracking_time_constant`) ranks above the profile: it is the arm controller's own value,
which a robot that reports it is trusted to mean (how each compares with the force per
blocked setpoint step: docs/design/robot-profile.md). The profile supplies what the robot does
not report, which is what makes a robot with only the required members whole; the record
notes both values when they differ in source.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from constraint_aware.control.profile import ProfileFileError, RobotProfile
from constraint_aware.control.sensor_health import DeflectionModel
from constraint_aware.errors import CapError, InvalidInputError
from constraint_aware.geometry import FloatArray

#: The run inputs a controller's stage may need, each with its unit: dead_band [N] (|F|
#: below it is no force), step_force [N] (stiffness x step length), tracking_time_constant
#: [s] (the arm's lag), workplane_normal (3,) unit, rotation_rate [rad/s] (w_d of a revolute
#: motion), play_force [N] (stiffness x grasp play).
INPUT_NAMES = (
    "dead_band",
    "step_force",
    "tracking_time_constant",
    "workplane_normal",
    "rotation_rate",
    "play_force",
)
#: Where a run input's value came from: the robot's own report, the executor's configuration,
#: the robot profile (a calibration, control.profile), the controller, measured at the start
#: of the run (the dead band from the F_d samples), or nowhere.
INPUT_SOURCES = ("robot", "config", "profile", "controller", "measured", "missing")
InputSource = Literal["robot", "config", "profile", "controller", "measured", "missing"]

#: How a note names each source.
SOURCE_WORDS: dict[str, str] = {
    "robot": "robot's report",
    "config": "configuration",
    "profile": "robot profile",
    "controller": "controller",
    "measured": "F_d samples",
    "missing": "nowhere",
}

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


class MissingInputError(CapError):
    """`ExecutorConfig.strict_inputs` is set and a stage of the controller lacks an input."""


@dataclass(frozen=True)
class RobotValues:
    """What the run knows about the robot besides its readings, each with its source
    (`resolve_robot_values`). Units: stiffness [N/m], tracking_time_constant [s], grasp_play
    [m], dead_band [N] (None: derived from the F_d samples), force_noise [N] per axis;
    deflection_model: the profile's stiffness, tau and measured deflection error (the
    dead-sensor test, control.sensor_health), None without them."""

    stiffness: float | None
    stiffness_source: InputSource
    tracking_time_constant: float | None
    tracking_time_constant_source: InputSource
    grasp_play: float | None
    grasp_play_source: InputSource
    dead_band: float | None
    dead_band_source: InputSource
    force_noise: float | None
    deflection_model: DeflectionModel | None = None


def check_profile_period(profile: RobotProfile, control_period: float) -> None:
    """Raise ProfileFileError when `profile` was calibrated at another control period than
    `control_period` [s]: tau, the noise of one reading and the stairs all depend on it."""
    if not math.isclose(profile.control_period, control_period, rel_tol=1e-6, abs_tol=1e-12):
        raise ProfileFileError(
            f"robot profile {profile.robot!r}: control_period_s {profile.control_period:g} s "
            f"differs from the robot's control period {control_period:g} s; calibrate the "
            "robot at the period it runs at"
        )


def resolve_robot_values(
    *,
    stiffness_override: float | None,
    grasp_play_override: float | None,
    threshold: float | None,
    reported_stiffness: float | None,
    reported_time_constant: float | None,
    profile: RobotProfile | None,
    notes: list[str],
) -> RobotValues:
    """Each value from its first source that has it (the module docstring's precedence).

    Args:
        stiffness_override: [N/m] ExecutorConfig.robot.stiffness, or None.
        grasp_play_override: [m] ExecutorConfig.robot.grasp_play, or None.
        threshold: [N] ExecutorConfig.threshold, or None.
        reported_stiffness: [N/m] the robot's valid translational_stiffness, or None.
        reported_time_constant: [s] the robot's valid tracking_time_constant, or None.
        profile: the robot's calibration, or None.
        notes: the record's notes: a line for each report a higher source replaced, and for
            each quantity the profile could not measure.
    """

    def measured(name: str) -> float | None:
        if profile is None:
            return None
        item = profile.quantities[name]
        if item.value is None:
            notes.append(f"profile: {name} unmeasured ({item.reason})")
        return item.value

    k_profile, tau_profile = measured("stiffness"), measured("tracking_time_constant")
    play_profile, band_profile = measured("grasp_play"), measured("dead_band")
    noise_profile = measured("force_noise")
    k: float | None = reported_stiffness
    k_source: InputSource = "robot"
    if stiffness_override is not None:
        k, k_source = stiffness_override, "config"
    elif reported_stiffness is None and k_profile is not None:
        k, k_source = k_profile, "profile"
    if k_source == "config":
        reported = "none" if reported_stiffness is None else f"{reported_stiffness:g} N/m"
        notes.append(f"stiffness {k:.0f} N/m from the configuration (robot reports {reported})")
    elif k_profile is not None and reported_stiffness is not None:
        notes.append(
            f"stiffness {reported_stiffness:g} N/m from the robot's report (the robot profile "
            f"measured {k_profile:.0f} N/m)"
        )
    tau: float | None = reported_time_constant
    tau_source: InputSource = "robot"
    if tau is None and tau_profile is not None:
        tau, tau_source = tau_profile, "profile"
    elif tau is not None and tau_profile is not None:
        notes.append(
            f"tracking time constant {tau:.3g} s from the robot's report (the robot profile "
            f"measured {tau_profile:.3g} s)"
        )
    play: float | None = grasp_play_override
    play_source: InputSource = "config"
    if play is None and play_profile is not None:
        play, play_source = play_profile, "profile"
    band: float | None = threshold
    band_source: InputSource = "config"
    if band is None and band_profile is not None:
        band, band_source = band_profile, "profile"
    elif band is None:
        band_source = "measured"
    return RobotValues(
        k, k_source, tau, tau_source, play, play_source, band, band_source, noise_profile,
        _deflection_model(profile),
    )  # fmt: skip


def _deflection_model(profile: RobotProfile | None) -> DeflectionModel | None:
    """The profile's deflection model when its stiffness and both errors were measured."""
    if profile is None:
        return None
    k = profile.value("stiffness")
    error = profile.value("deflection_error")
    per_speed = profile.value("deflection_error_per_speed")
    if k is None or error is None or per_speed is None:
        return None
    return DeflectionModel(k, profile.value("tracking_time_constant"), error, per_speed)


def gather_inputs(
    *,
    values: RobotValues,
    step_length: float,
    normal: FloatArray | None,
    controller: object,
) -> dict[str, RunInput]:
    """Every input of INPUT_NAMES for one run.

    Args:
        values: the robot's values and their sources (`resolve_robot_values`).
        step_length: [m] the nominal step.
        normal: (3,) unit workplane normal in use (oriented), or None (3-D motion).
        controller: the run's controller; its optional `rotation_rate` [rad/s] is read.
    The dead band derived from the F_d samples is not known yet: its value is None with
    source "measured" until the samples are in (`RunInput` of `measured_dead_band`).
    """
    out: dict[str, RunInput] = {}
    out["dead_band"] = RunInput(values.dead_band, values.dead_band_source)
    stiffness = values.stiffness
    if stiffness is None:
        out["step_force"] = _missing(
            "the robot reports no translational_stiffness, the robot profile has none and "
            "ExecutorConfig.robot.stiffness is not set"
        )
    else:
        out["step_force"] = RunInput(stiffness * step_length, values.stiffness_source)
    if values.tracking_time_constant is None:
        out["tracking_time_constant"] = _missing(
            "the robot reports no tracking_time_constant and the robot profile has none"
        )
    else:
        out["tracking_time_constant"] = RunInput(
            values.tracking_time_constant, values.tracking_time_constant_source
        )
    if normal is None:
        out["workplane_normal"] = _missing("ExecutorConfig.workplane_normal is None: 3-D motion")
    else:
        vec = np.asarray(normal, dtype=float)
        out["workplane_normal"] = RunInput((float(vec[0]), float(vec[1]), float(vec[2])), "config")
    out["rotation_rate"] = _controller_rate(controller)
    if values.grasp_play is None:
        out["play_force"] = _missing(
            "ExecutorConfig.robot.grasp_play is not set and the robot profile has none"
        )
    elif stiffness is None:
        out["play_force"] = _missing("no stiffness to turn the grasp play into a force")
    else:
        out["play_force"] = RunInput(stiffness * values.grasp_play, values.grasp_play_source)
    return out


def measured_dead_band(value: float) -> RunInput:
    """The dead band [N] derived from the F_d samples at the start of the run."""
    return RunInput(value, "measured")


def refuse_missing(warnings: list[str]) -> None:
    """Raise MissingInputError listing every `warnings` line (strict inputs)."""
    if warnings:
        raise MissingInputError(
            "strict inputs: refusing to run: " + "; ".join(warnings) + " (supply the input: "
            "a robot profile from `cap calibrate`, a robot report, or ExecutorConfig.robot)"
        )


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
