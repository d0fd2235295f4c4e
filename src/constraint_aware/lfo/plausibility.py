"""Plausibility of a demonstration and its estimates, checked before anything moves.

- Units: positions must be metres. A path spanning more than MAX_EXTENT or a hand moving
  faster than MAX_HAND_SPEED is not a manipulation in metres; the error names the unit
  (centimetres or millimetres) whose rescaled path is plausible.
- Opening vs closing: the verb's sense against the motion's (a warning, never a refusal).
- Certainty: an execution is refused when the estimates are too uncertain for the grasp.
  The workplane is the one estimate the executor never corrects (it projects every command on
  it, assumption 4): a normal off by e moves the hand out of the true plane by about
  path x sin(e), which the grasp absorbs only up to the task's slip limit (3 cm) before it
  counts as lost. Refused when that drift at two sigma (95 %) of the fitted normal, over the
  demonstrated path, exceeds the slip limit.
"""

from __future__ import annotations

import math

import numpy as np

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray
from constraint_aware.lfo.demo import DemoError, Demonstration
from constraint_aware.lfo.lexicon import verb_sense

MAX_EXTENT = 3.0  # [m] a robot's and a person's workspace: no one manipulation spans more
MAX_HAND_SPEED = 2.0  # [m/s] median hand speed while moving: opening drawers and doors takes
# 0.1-0.5 m/s; even fast reaches peak near 2 m/s
TYPICAL_HAND_SPEED = 0.2  # [m/s] the speed a plausible unit should bring the motion closest to
MOVING_SPEED = 0.01  # [m/s] (in the file's units) samples slower than this are at rest
SPEED_WINDOW = 0.5  # [s] the hand's speed is its displacement over this long
UNITS = {"centimetres": 100.0, "millimetres": 1000.0}
CONFIDENCE_SIGMAS = 2.0  # the certainty bound's confidence (2 sigma ~ 95 %)
SENSE_COSINE = 0.5  # |cos| between motion and palm normal (or vertical) that decides a sense


class UnitError(DemoError):
    """The demonstration's positions are not in metres; `suspected_unit` names the likely one."""

    def __init__(self, message: str, suspected_unit: str | None) -> None:
        super().__init__(message)
        self.suspected_unit = suspected_unit


class UncertainEstimateError(CapError, ValueError):
    """The estimates are too uncertain to execute with this grasp; the message says which."""


def _extent_and_speed(t: FloatArray, pos: FloatArray) -> tuple[float, float]:
    """(extent [file units], median speed while moving [units/s]); the speed is taken over
    SPEED_WINDOW so that tracking noise, differentiated sample by sample, does not pass for
    motion (3 cm of noise at 30 Hz would read as 2 m/s)."""
    extent = float(np.linalg.norm(pos.max(axis=0) - pos.min(axis=0)))
    span = float(t[-1] - t[0])
    lag = max(1, round(len(t) * min(SPEED_WINDOW, span / 2) / max(span, 1e-12)))
    speed = np.linalg.norm(pos[lag:] - pos[:-lag], axis=1) / (t[lag:] - t[:-lag])
    moving = speed[speed > MOVING_SPEED]
    return extent, float(np.median(moving)) if moving.size else 0.0


def check_units(demo: Demonstration) -> None:
    """Raise UnitError when the path is implausible in metres (see the module docstring)."""
    extent, speed = _extent_and_speed(demo.t, demo.position)
    if extent <= MAX_EXTENT and speed <= MAX_HAND_SPEED:
        return
    fits = {
        name: abs(math.log(max(speed / f, 1e-9) / TYPICAL_HAND_SPEED))
        for name, f in UNITS.items()
        if extent / f <= MAX_EXTENT and speed / f <= MAX_HAND_SPEED
    }
    unit = min(fits, key=fits.__getitem__) if fits else None
    what = (
        f"the path spans {extent:.3g} m and the hand moves at {speed:.3g} m/s while moving "
        f"(plausible: at most {MAX_EXTENT:.0f} m and {MAX_HAND_SPEED:.0f} m/s)"
    )
    if unit is None:
        raise UnitError(f"positions are not plausible in metres: {what}", None)
    f = UNITS[unit]
    raise UnitError(
        f"positions look like {unit}, not metres: {what}; in {unit} they span "
        f"{extent / f:.2f} m at {speed / f:.2f} m/s. Convert them to metres (divide by "
        f"{f:.0f}).",
        unit,
    )


def motion_sense_warning(
    demo: Demonstration, direction: FloatArray, chord: FloatArray, constraint: str
) -> str | None:
    """A warning when the motion's sense contradicts the verb (open vs close), else None.

    direction (3,): the initial direction of motion; chord (3,) [m]: from the resting start to
    the resting end. The motion's sense: with hand orientations, pulling against the palm
    normal (hand z, which points at the object) opens and pushing along it closes; without
    them, or when the palm is across the motion (a pressed plate, a crank), a mostly vertical
    chord (lids, windows) opens upward and closes downward; otherwise the sense is not known
    and nothing is said.
    """
    wanted = verb_sense(demo.instruction)
    if wanted is None or constraint not in ("prismatic", "revolute"):
        return None
    d = np.asarray(direction, dtype=float)
    moved: str | None = None
    why = ""
    if demo.orientation is not None:
        from scipy.spatial.transform import Rotation

        w, x, y, z = demo.orientation[0]
        palm = Rotation.from_quat([x, y, z, w]).apply([0.0, 0.0, 1.0])
        c = float(d @ palm)
        if abs(c) > SENSE_COSINE:
            moved = "close" if c > 0 else "open"
            why = "pushes along the palm normal" if c > 0 else "pulls against the palm normal"
    if moved is None:
        norm = float(np.linalg.norm(chord))
        c = float(chord[2]) / norm if norm > 0 else 0.0
        if abs(c) > SENSE_COSINE:
            moved = "open" if c > 0 else "close"
            why = "moves upward" if c > 0 else "moves downward"
    if moved is None or moved == wanted:
        return None
    return (
        f"the instruction says {wanted} ('{demo.instruction}') but the demonstrated motion "
        f"{why}, which {'opens' if moved == 'open' else 'closes'}: check the demonstration"
    )


def check_certainty(
    constraint: str, normal_std_deg: float | None, path_length: float, slip_limit: float
) -> None:
    """Raise UncertainEstimateError when the workplane is too uncertain for the grasp (module
    docstring): 2 sigma of the normal over the path must stay within `slip_limit` [m]."""
    if constraint not in ("prismatic", "revolute"):
        raise UncertainEstimateError(
            f"constraint {constraint!r}: neither the words nor the geometry decided prismatic "
            "or revolute; nothing to execute"
        )
    if normal_std_deg is None or not math.isfinite(normal_std_deg):
        raise UncertainEstimateError("the workplane normal has no uncertainty estimate")
    drift = path_length * math.sin(math.radians(min(CONFIDENCE_SIGMAS * normal_std_deg, 90.0)))
    if drift > slip_limit:
        raise UncertainEstimateError(
            f"estimates too uncertain for the grasp: the workplane normal is known to "
            f"+-{normal_std_deg:.2f} deg (1 sigma), so over the {path_length:.2f} m path the "
            f"hand may leave the true plane by {drift * 100:.1f} cm ({CONFIDENCE_SIGMAS:.0f} "
            f"sigma), more than the grasp's {slip_limit * 100:.0f} cm slip limit. Demonstrate "
            "again with less tracking noise or a longer, steadier motion."
        )
