"""A robot profile: what a calibration measured about one robot, as a typed object and a file.

Each quantity the controllers use is a `Measurement`: its value (None when it could not be
measured, with the reason), its standard uncertainty, its unit, how it was measured and from
how many samples. `RobotProfile` holds them with what was calibrated, when and how long it
took. A quantity a calibration could not measure may be taken from another calibration of the
same robot (a free-space calibration's tracking time constant and lag error:
control.calibrate); its `source` then names that calibration, as a record only. The file is
JSON (`RobotProfile.save` / `RobotProfile.load`), versioned by its "format" field and
validated field by field at load: a `ProfileFileError` names the file and the field. A
profile file never makes the program read another file.
"""

from __future__ import annotations

import datetime
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from constraint_aware.errors import CapError

#: The file format this version reads and writes.
PROFILE_FORMAT = "constraint-aware-robot-profile/1"

#: Every quantity a profile carries: its unit and what it is for.
QUANTITIES: dict[str, tuple[str, str]] = {
    "force_noise": (
        "N",
        "standard deviation of the wrist force reading per axis at rest (sigma)",
    ),
    "dead_band": (
        "N",
        "|F| below which a reading counts as no force: deadband.threshold_from_noise(sigma)",
    ),
    "force_offset_x": ("N", "x component of the wrist force reading at rest (hand weight, bias)"),
    "force_offset_y": ("N", "y component of the wrist force reading at rest"),
    "force_offset_z": ("N", "z component of the wrist force reading at rest"),
    "stiffness": (
        "N/m",
        "the force per metre of setpoint step against a blocked direction at the tool point, "
        "as the wrist sensor reads it (the step force is k times the step length)",
    ),
    "tracking_time_constant": (
        "s",
        "tau: the tool trails a setpoint moving at speed v by tau v (the arm's damping over "
        "its stiffness)",
    ),
    "grasp_play": ("m", "free travel of the hand in the grasp before the force rises"),
    "deflection_error": (
        "N",
        "the arm's deflection model's error with the hand at rest: the most by which stiffness "
        "x |lagged deflection| exceeded the read |F| during the calibration's pushes",
    ),
    "deflection_error_per_speed": (
        "N s/m",
        "the deflection model's error per hand speed on top of deflection_error (the "
        "tracking time constant's error grows with the speed)",
    ),
    "lag_error": (
        "s",
        "the tracking lag model's error per unit speed with the hand following a setpoint "
        "ramp in free space: the largest |lagged deflection| over the hand's speed (times the "
        "stiffness, a deflection error per speed)",
    ),
    "sensor_convention": (
        "1",
        "median cosine between the force change and the arm's stretch change on blocked "
        "pushes: -1 for the Robot protocol's convention, +1 for a flipped sign",
    ),
}
#: The quantities in the order a profile lists them.
QUANTITY_NAMES: tuple[str, ...] = tuple(QUANTITIES)
#: How a calibration ended: "complete", or the named stop that ended it early.
OUTCOMES: dict[str, str] = {
    "complete": "every phase ran (a quantity may still be unmeasured, with its reason)",
    "force_limit": "a reading passed the calibration's force limit: setpoint restored, held",
    "bad_reading": "a non-finite wrench or pose: setpoint restored, held",
    "stale_wrench": "identical wrench samples in a row (a stale driver): setpoint restored, held",
    "time_limit": "the calibration used up its period budget: setpoint restored, held",
    "contact": "a free-space calibration's move met something: setpoint restored, held",
    "error": "the robot raised: setpoint restored where possible, held",
}
#: The sensor convention verdicts a profile may carry (control.probe.PROBE_VERDICTS' keys
#: that judge pushes), and "" when none was reached.
CONVENTION_VERDICTS = (
    "",
    "consistent",
    "flipped_sign",
    "inconsistent",
    "stiffness_mismatch",
    "inconclusive",
    "not_following",
)


class ProfileFileError(CapError):
    """A robot profile file is missing, malformed or inconsistent (names the file and field)."""


@dataclass(frozen=True)
class Measurement:
    """One measured quantity.

    Attributes:
        value: the estimate in `unit`; None when it could not be measured (`reason` says why).
        uncertainty: its standard uncertainty in `unit` (from the spread of the samples that
            made it); None when unmeasured.
        unit: the quantity's unit (`QUANTITIES`).
        method: how it was measured, in one sentence.
        count: how many samples (readings, pushes, periods) the estimate rests on.
        reason: why it is unmeasured ("" when measured).
        source: "" when this calibration measured it; else the calibration it was taken
            from (robot, date, setup, and the file when it was read from one).
    """

    value: float | None
    uncertainty: float | None
    unit: str
    method: str
    count: int = 0
    reason: str = ""
    source: str = ""

    @property
    def measured(self) -> bool:
        return self.value is not None

    @classmethod
    def unmeasured(cls, name: str, reason: str, method: str = "", count: int = 0) -> Measurement:
        """Quantity `name` (a key of QUANTITIES) not measured, for `reason`."""
        return cls(None, None, QUANTITIES[name][0], method, count, reason)

    def to_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "uncertainty": self.uncertainty,
            "unit": self.unit,
            "method": self.method,
            "count": self.count,
            "reason": self.reason,
            "source": self.source,
        }


@dataclass
class RobotProfile:
    """What a calibration measured about one robot (module docstring).

    Attributes:
        robot: the name the user gave the robot.
        measured_at: when the calibration ran (ISO 8601, UTC).
        quantities: one Measurement per name in QUANTITY_NAMES.
        convention: the sensor convention verdict (control.probe.PROBE_VERDICTS), "" if none.
        outcome: how the calibration ended (OUTCOMES).
        control_period: [s] the robot's control period.
        periods: control periods the calibration used.
        setup: what the hand held while calibrating, as the user described it.
        workplane_normal: (3,) the plane the pushes were made in; None: the world axes.
        notes: what else the calibration found (ignored reports, warnings).
        loaded_from: the file `load` read it from ("" otherwise; not written to the file).
    """

    robot: str
    quantities: dict[str, Measurement]
    measured_at: str = field(
        default_factory=lambda: datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    )
    convention: str = ""
    outcome: str = "complete"
    control_period: float = 0.1
    periods: int = 0
    setup: str = ""
    workplane_normal: tuple[float, float, float] | None = None
    notes: list[str] = field(default_factory=list)
    loaded_from: str = field(default="", compare=False)

    @property
    def robot_time(self) -> float:
        """[s] the robot time the calibration took: periods x control period."""
        return self.periods * self.control_period

    def value(self, name: str) -> float | None:
        """The measured value of quantity `name`, None when unmeasured."""
        return self.quantities[name].value

    def to_dict(self) -> dict[str, Any]:
        """The file's content (JSON-ready)."""
        return {
            "format": PROFILE_FORMAT,
            "robot": self.robot,
            "measured_at": self.measured_at,
            "setup": self.setup,
            "outcome": self.outcome,
            "control_period_s": self.control_period,
            "periods": self.periods,
            "robot_time_s": self.robot_time,
            "workplane_normal": None
            if self.workplane_normal is None
            else list(self.workplane_normal),
            "convention": self.convention,
            "quantities": {name: self.quantities[name].to_dict() for name in QUANTITY_NAMES},
            "notes": list(self.notes),
        }

    def save(self, path: str | Path) -> Path:
        """Write the profile as JSON to `path` (suffix .json), creating the parent folder."""
        out = Path(path)
        if out.suffix.lower() != ".json":
            raise ProfileFileError(f"{out}: a robot profile is a .json file")
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n")
        return out

    @classmethod
    def load(cls, path: str | Path) -> RobotProfile:
        """Read and validate a profile file; ProfileFileError names the file and the field."""
        src = Path(path)
        try:
            text = src.read_bytes().decode("utf-8")
        except FileNotFoundError:
            raise ProfileFileError(f"robot profile not found: {src}") from None
        except IsADirectoryError:
            raise ProfileFileError(f"{src}: a directory, not a robot profile") from None
        except OSError as exc:
            raise ProfileFileError(f"{src}: cannot read ({exc.strerror or exc})") from exc
        except UnicodeDecodeError as exc:
            raise ProfileFileError(f"{src}: not UTF-8 text ({exc.reason})") from exc
        try:
            data = json.loads(text, parse_constant=_reject_constant)
        except json.JSONDecodeError as exc:
            raise ProfileFileError(f"{src}: not valid JSON ({exc})") from exc
        except RecursionError as exc:
            raise ProfileFileError(f"{src}: JSON nested too deeply") from exc
        except ValueError as exc:  # NaN / Infinity
            raise ProfileFileError(f"{src}: {exc}") from exc
        profile = cls.from_dict(data, str(src))
        profile.loaded_from = str(src)
        return profile

    def describe(self) -> str:
        """The calibration in one phrase: robot, date, setup and file (a Measurement's
        `source` when a quantity is taken from it)."""
        where = f", file {self.loaded_from}" if self.loaded_from else ""
        setup = f", {self.setup}" if self.setup else ""
        return f"calibration of {self.robot!r} at {self.measured_at}{setup}{where}"

    @classmethod
    def from_dict(cls, data: object, source: str = "profile") -> RobotProfile:
        """A profile from the file's content, validated; errors name `source` and the field."""
        check = _Checker(source)
        if not isinstance(data, dict):
            raise ProfileFileError(f"{source}: the profile must be a JSON object")
        if data.get("format") != PROFILE_FORMAT:
            raise ProfileFileError(
                f"{source}: field 'format' is {data.get('format')!r}, not {PROFILE_FORMAT!r}"
            )
        known = {
            "format", "robot", "measured_at", "setup", "outcome", "control_period_s", "periods",
            "robot_time_s", "workplane_normal", "convention", "quantities", "notes",
        }  # fmt: skip
        unknown = sorted(set(data) - known)
        if unknown:
            raise ProfileFileError(
                f"{source}: unknown field {unknown[0]!r} (valid: {', '.join(sorted(known))})"
            )
        robot = check.text(data, "robot", nonempty=True)
        measured_at = check.text(data, "measured_at", nonempty=True)
        try:
            datetime.datetime.fromisoformat(measured_at)
        except ValueError:
            raise ProfileFileError(
                f"{source}: field 'measured_at' {measured_at!r} is not an ISO 8601 date"
            ) from None
        setup = check.text(data, "setup")
        outcome = check.text(data, "outcome")
        if outcome not in OUTCOMES:
            raise ProfileFileError(
                f"{source}: field 'outcome' {outcome!r} is not one of {', '.join(OUTCOMES)}"
            )
        convention = check.text(data, "convention")
        if convention not in CONVENTION_VERDICTS:
            raise ProfileFileError(
                f"{source}: field 'convention' {convention!r} is not one of "
                + ", ".join(repr(v) for v in CONVENTION_VERDICTS)
            )
        period = check.number(data, "control_period_s", low=0.0, low_open=True)
        periods = check.integer(data, "periods")
        if "robot_time_s" in data:
            stated = check.number(data, "robot_time_s", low=0.0)
            if not math.isclose(stated, periods * period, rel_tol=1e-6, abs_tol=1e-9):
                raise ProfileFileError(
                    f"{source}: field 'robot_time_s' {stated!r} is not periods x "
                    f"control_period_s ({periods * period:g})"
                )
        normal = check.normal(data)
        notes = data.get("notes", [])
        if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
            raise ProfileFileError(f"{source}: field 'notes' must be a list of strings")
        raw = data.get("quantities")
        if not isinstance(raw, dict):
            raise ProfileFileError(f"{source}: field 'quantities' must be a JSON object")
        for name in raw:
            if name not in QUANTITIES:
                raise ProfileFileError(
                    f"{source}: unknown quantity 'quantities.{name}' (valid: "
                    + ", ".join(QUANTITY_NAMES)
                    + ")"
                )
        quantities = {
            name: Measurement.unmeasured(name, "not in the profile file: calibrate again")
            if name in OPTIONAL_QUANTITIES and name not in raw
            else check.measurement(raw, name)
            for name in QUANTITY_NAMES
        }
        return cls(
            robot=robot,
            quantities=quantities,
            measured_at=measured_at,
            convention=convention,
            outcome=outcome,
            control_period=period,
            periods=periods,
            setup=setup,
            workplane_normal=normal,
            notes=list(notes),
        )


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number a profile may hold (JSON has no NaN or infinity)")


#: The valid range of each quantity's value: (low, low_open, high).
_RANGES: dict[str, tuple[float | None, bool, float | None]] = {
    "force_noise": (0.0, False, None),
    "dead_band": (0.0, False, None),
    "force_offset_x": (None, False, None),
    "force_offset_y": (None, False, None),
    "force_offset_z": (None, False, None),
    "stiffness": (0.0, True, None),
    "tracking_time_constant": (0.0, True, None),
    "grasp_play": (0.0, False, None),
    "sensor_convention": (-1.0, False, 1.0),
    "deflection_error": (0.0, False, None),
    "deflection_error_per_speed": (0.0, False, None),
    "lag_error": (0.0, False, None),
}
#: Quantities a profile file may leave out: read as unmeasured.
OPTIONAL_QUANTITIES = ("deflection_error", "deflection_error_per_speed", "lag_error")


class _Checker:
    """Field checks that raise ProfileFileError naming the file and the field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, name: str, message: str) -> ProfileFileError:
        return ProfileFileError(f"{self.source}: field {name!r} {message}")

    def text(self, data: dict[str, Any], name: str, nonempty: bool = False) -> str:
        value = data.get(name, None if nonempty else "")
        if not isinstance(value, str) or (nonempty and not value.strip()):
            raise self.fail(name, "must be a " + ("non-empty " if nonempty else "") + "string")
        return value

    def number(
        self,
        data: dict[str, Any],
        name: str,
        low: float | None = None,
        low_open: bool = False,
        high: float | None = None,
        label: str | None = None,
    ) -> float:
        label = label or name
        value = data.get(name)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(label, f"must be a number, got {value!r}")
        x = float(value)
        bad = not math.isfinite(x)
        bad = bad or (low is not None and (x < low or (low_open and x == low)))
        bad = bad or (high is not None and x > high)
        if bad:
            left = "(-inf" if low is None else ("(" if low_open else "[") + f"{low:g}"
            right = "inf)" if high is None else f"{high:g}]"
            raise self.fail(label, f"is {value!r}; valid: a finite number in {left}, {right}")
        return x

    def integer(self, data: dict[str, Any], name: str, label: str | None = None) -> int:
        value = data.get(name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise self.fail(label or name, f"must be an integer >= 0, got {value!r}")
        return value

    def normal(self, data: dict[str, Any]) -> tuple[float, float, float] | None:
        raw = data.get("workplane_normal")
        if raw is None:
            return None
        ok = isinstance(raw, list) and len(raw) == 3
        ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in raw)
        ok = ok and all(math.isfinite(v) for v in raw)
        if not ok or abs(math.sqrt(sum(v * v for v in raw)) - 1.0) > 1e-6:
            raise self.fail("workplane_normal", f"must be null or a unit 3-vector, got {raw!r}")
        return (float(raw[0]), float(raw[1]), float(raw[2]))

    def measurement(self, quantities: dict[str, Any], name: str) -> Measurement:
        label = f"quantities.{name}"
        raw = quantities.get(name)
        if not isinstance(raw, dict):
            raise self.fail(label, "must be a JSON object (value, uncertainty, unit, ...)")
        known = {"value", "uncertainty", "unit", "method", "count", "reason", "source"}
        unknown = sorted(set(raw) - known)
        if unknown:
            raise self.fail(
                f"{label}.{unknown[0]}", f"is unknown (valid: {', '.join(sorted(known))})"
            )
        unit = QUANTITIES[name][0]
        if raw.get("unit") != unit:
            raise self.fail(
                f"{label}.unit", f"is {raw.get('unit')!r}; the unit of {name} is {unit!r}"
            )
        method = self.text(raw, "method")
        reason = self.text(raw, "reason")
        source = self.text(raw, "source")
        count = self.integer(raw, "count", f"{label}.count")
        if raw.get("value") is None:
            if raw.get("uncertainty") is not None:
                raise self.fail(f"{label}.uncertainty", "must be null when the value is null")
            if not reason.strip():
                raise self.fail(f"{label}.reason", "must say why the value is null")
            return Measurement(None, None, unit, method, count, reason, source)
        low, low_open, high = _RANGES[name]
        value = self.number(raw, "value", low, low_open, high, f"{label}.value")
        uncertainty = self.number(raw, "uncertainty", 0.0, False, None, f"{label}.uncertainty")
        return Measurement(value, uncertainty, unit, method, count, reason, source)
