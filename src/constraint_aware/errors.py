"""Exception hierarchy: every error the library raises on purpose is a `CapError`."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


class CapError(Exception):
    """Base class of the library's errors."""


class InvalidInputError(CapError, ValueError):
    """An argument has the wrong shape, a non-finite value or an out-of-range value."""


class ConfigError(InvalidInputError):
    """A configuration field (executor, task, object, hand, run) holds an invalid value.

    `field` is the dotted field name (`ExecutorConfig.step_length`), `value` the rejected value
    and `valid` a human-readable statement of the valid range (`finite, in (0, 0.05] [m]`).
    """

    def __init__(self, field: str, value: object, valid: str) -> None:
        self.field = field
        self.value = value
        self.valid = valid
        super().__init__(f"{field} = {value!r}: must be {valid}")

    def __reduce__(self) -> tuple[type, tuple[str, object, str]]:
        # rebuilt from its fields: an error raised in a worker process reaches the parent
        return (type(self), (self.field, self.value, self.valid))


class UnknownNameError(CapError, KeyError):
    """A name (task, controller, preset, backend) is not one of the valid names."""

    def __init__(self, kind: str, name: str, valid: list[str] | tuple[str, ...]) -> None:
        self.kind = kind
        self.name = name
        self.valid = sorted(valid)
        super().__init__(f"unknown {kind} {name!r}; valid names: {', '.join(self.valid)}")

    def __reduce__(self) -> tuple[type, tuple[str, str, list[str]]]:
        return (type(self), (self.kind, self.name, self.valid))

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class PolicyFileError(CapError):
    """A policy file or its JSON card is missing, malformed or inconsistent."""


# --- field checks shared by the config dataclasses (each raises ConfigError) ---------------
def _as_float(value: object) -> float | None:
    """float(value) for real numbers (numpy scalars included), None for anything else."""
    if isinstance(value, bool | str | bytes | np.bool_):
        return None
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None


def check_number(
    field: str,
    value: object,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
    high_open: bool = False,
    unit: str = "",
) -> float:
    """`value` as a float, finite and inside [low, high] (open ends where asked)."""
    # a float is the common case (the executor checks inputs every control period)
    x = value if type(value) is float else _as_float(value)
    if (
        x is None
        or not math.isfinite(x)
        or (low is not None and (x < low or (low_open and x == low)))
        or (high is not None and (x > high or (high_open and x == high)))
    ):
        left = "(-inf" if low is None else f"{'(' if low_open else '['}{low:g}"
        right = "inf)" if high is None else f"{high:g}{')' if high_open else ']'}"
        valid = f"a finite number in {left}, {right}" + (f" [{unit}]" if unit else "")
        raise ConfigError(field, value, valid)
    return x


def check_int(field: str, value: object, *, low: int) -> int:
    """`value` as an int (not a bool, not a float) >= low."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, int | np.integer):
        raise ConfigError(field, value, f"an integer >= {low}")
    if int(value) < low:
        raise ConfigError(field, value, f"an integer >= {low}")
    return int(value)


def check_vector(
    field: str, value: object, *, size: int = 3, nonzero: bool = False, unit: str = ""
) -> tuple[float, ...]:
    """`value` as a tuple of `size` finite floats (non-zero norm where asked)."""
    valid = f"{size} finite numbers" + (", not all zero" if nonzero else "")
    valid += f" [{unit}]" if unit else ""
    if isinstance(value, str | bytes):
        raise ConfigError(field, value, valid)
    try:
        items = list(value)  # type: ignore[call-overload]
    except TypeError:
        raise ConfigError(field, value, valid) from None
    out = [_as_float(v) for v in items]
    if len(out) != size or any(x is None or not math.isfinite(x) for x in out):
        raise ConfigError(field, value, valid)
    vec = tuple(float(x) for x in out if x is not None)
    if nonzero and math.sqrt(sum(x * x for x in vec)) < 1e-9:
        raise ConfigError(field, value, valid)
    return vec


def check_unit_vector(field: str, value: object) -> tuple[float, float, float]:
    """A non-zero 3-vector, normalized to unit length (a user may give (0, 0, 2))."""
    v = check_vector(field, value, nonzero=True)
    n = math.sqrt(sum(x * x for x in v))
    return (v[0] / n, v[1] / n, v[2] / n)


def check_choice(field: str, value: object, valid: Sequence[str]) -> str:
    """`value` one of the names in `valid`."""
    if not isinstance(value, str) or value not in valid:
        raise ConfigError(field, value, f"one of: {', '.join(valid)}")
    return value
