"""Plausibility of a demonstration and its estimates, checked before anything moves.

- Consistency over time: a tracker's gross glitches (a sample, or a run of at most
  MAX_GLITCH_RUN, that jumps far off the path and back) are removed and named. A jump that
  does not come back is refused: a change of scale by a unit's factor is named as mixed
  units; anything else as the tracker losing the hand.
- Units: positions must be metres. The demonstration is read in each of UNITS; a reading is
  plausible when the path spans at most MAX_EXTENT and the hand moves at most MAX_HAND_SPEED,
  and, for another unit to be suggested, when it also yields a usable demonstration (a path of
  at least MIN_PATH, a hand that moves) whose size fits the words' object
  (lexicon.NOUN_SIZES: a drawer's travel, a door's radius). A conversion is suggested only when
  exactly one unit is plausible; when several are (centimetres and inches differ by 2.54 only),
  the error lists them and says the demonstration does not tell.
- Opening vs closing: the verb's sense against the motion's (a warning, never a refusal); when
  the motion does not show its sense, the warning says so.
- Certainty: an execution is refused when the estimates are too uncertain for the grasp.
  The workplane is the one estimate the executor never corrects (it projects every command on
  it, assumption 4): a normal off by e moves the hand out of the true plane by about
  path x sin(e), which the grasp absorbs only up to the task's slip limit (3 cm) before it
  counts as lost. Refused when that drift at two sigma (95 %) of the fitted normal, over the
  demonstrated path, exceeds the slip limit.
"""

from __future__ import annotations

import itertools
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray
from constraint_aware.lfo.demo import DemoError, Demonstration
from constraint_aware.lfo.fitting import FitError, fit_circle, fit_line, outlier_mask
from constraint_aware.lfo.lexicon import NOUN_SIZES, constraint_from_words, verb_sense

MAX_EXTENT = 3.0  # [m] a robot's and a person's workspace: no one manipulation spans more
MAX_HAND_SPEED = 2.0  # [m/s] median hand speed while moving: opening drawers and doors takes
# 0.1-0.5 m/s; even fast reaches peak near 2 m/s
MIN_PATH = 0.03  # [m] shorter demonstrations say nothing about the constraint
MOVING_SPEED = 0.01  # [m/s] samples slower than this are at rest
SPEED_WINDOW = 0.5  # [s] the hand's speed is its displacement over this long
#: The units a tracker reports positions in: name -> units per metre.
UNITS = {"metres": 1.0, "centimetres": 100.0, "millimetres": 1000.0, "inches": 1.0 / 0.0254}
#: A step between samples longer than this many times the typical step around it is a jump
#: (the typical step: the larger of the median steps over JUMP_WINDOW samples before and after).
JUMP_RATIO = 20.0
JUMP_WINDOW = 10
#: At most this many consecutive samples off the path and back are a tracker glitch.
MAX_GLITCH_RUN = 5
#: Two parts of a path whose scales differ by a unit's factor within this share are in
#: different units.
SCALE_TOLERANCE = 0.15
CONFIDENCE_SIGMAS = 2.0  # the certainty bound's confidence (2 sigma ~ 95 %)
SENSE_COSINE = 0.5  # |cos| between motion and palm normal (or vertical) that decides a sense


class UnitError(DemoError):
    """The demonstration's positions are not in metres, or not in one unit throughout.

    `candidates`: the units whose reading is plausible (one: `suspected_unit` names it; none or
    several: `suspected_unit` is None, as it is for mixed units)."""

    def __init__(
        self, message: str, suspected_unit: str | None, candidates: tuple[str, ...] = ()
    ) -> None:
        super().__init__(message)
        self.suspected_unit = suspected_unit
        self.candidates = candidates


class UncertainEstimateError(CapError, ValueError):
    """The estimates are too uncertain to execute with this grasp; the message says which."""


@dataclass(frozen=True)
class UnitReading:
    """The demonstration read in one unit: its size and speed in metres, and what is
    implausible about it (`problems` empty and `size_problem` None: plausible)."""

    unit: str
    extent_m: float  # [m] the path's bounding-box diagonal (small glitches removed)
    speed_m_s: float  # [m/s] median hand speed while moving (0: never moving)
    size: tuple[str, float] | None  # ("travel" or "radius", [m]) of the words' object
    problems: tuple[str, ...]  # beyond any manipulation (MAX_EXTENT, MAX_HAND_SPEED)
    size_problem: str | None  # the size outside the words' object's (lexicon.NOUN_SIZES)

    def describe(self, noun: str | None) -> str:
        text = f"spans {self.extent_m:.3g} m at {self.speed_m_s:.3g} m/s"
        if self.size is not None and noun is not None:
            text += f", a {noun}'s {self.size[0]} of {self.size[1]:.3g} m"
        return text


@dataclass(frozen=True)
class UnitCheck:
    """What `check_units` found: the samples kept (gross glitches removed), a note per removed
    glitch, and the metres reading's notes (its size against the words' object)."""

    keep: NDArray[np.bool_]  # (N,)
    notes: list[str] = field(default_factory=list)
    glitches: int = 0  # samples removed as gross glitches


def _speed(t: FloatArray, pos: FloatArray) -> float:
    """[units/s] median speed while moving, over SPEED_WINDOW so that tracking noise,
    differentiated sample by sample, does not pass for motion (3 cm of noise at 30 Hz would
    read as 2 m/s); `pos` in metres."""
    span = float(t[-1] - t[0])
    lag = max(1, round(len(t) * min(SPEED_WINDOW, span / 2) / max(span, 1e-12)))
    if lag >= len(t):
        return 0.0
    speed = np.linalg.norm(pos[lag:] - pos[:-lag], axis=1) / (t[lag:] - t[:-lag])
    moving = speed[speed > MOVING_SPEED]
    return float(np.median(moving)) if moving.size else 0.0


def _typical_steps(steps: FloatArray) -> FloatArray:
    """(N-1,) per step: the larger of the median steps over JUMP_WINDOW before and after it."""
    n = len(steps)
    pad = np.full(JUMP_WINDOW, np.nan)
    padded = np.concatenate([pad, steps, pad])
    windows = np.lib.stride_tricks.sliding_window_view(padded, JUMP_WINDOW)
    with warnings.catch_warnings():  # an all-padding window at either end is expected
        warnings.simplefilter("ignore", RuntimeWarning)
        before = np.nanmedian(windows[:n], axis=1)
        after = np.nanmedian(windows[JUMP_WINDOW + 1 : JUMP_WINDOW + 1 + n], axis=1)
    typical = np.fmax(before, after)
    return np.where(np.isnan(typical), 0.0, typical)


def _segments(pos: FloatArray) -> tuple[list[tuple[int, int]], FloatArray, FloatArray]:
    """The path cut at its jumps: [(first, stop)] sample ranges, the steps between samples
    and the typical step around each."""
    steps = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    typical = _typical_steps(steps)
    spread = np.percentile(pos, 95, axis=0) - np.percentile(pos, 5, axis=0)
    floor = 1e-3 * float(np.linalg.norm(spread)) + 1e-12
    jumps = np.flatnonzero(steps > JUMP_RATIO * np.maximum(typical, floor))
    bounds = [0, *(int(j) + 1 for j in jumps), len(pos)]
    return [(a, b) for a, b in itertools.pairwise(bounds)], steps, typical


def _unit_pair(ratio: float) -> tuple[str, str] | None:
    """The two units (smaller factor first) whose factors differ by `ratio` (> 1), if any."""
    for small, f_small in UNITS.items():
        for large, f_large in UNITS.items():
            if f_large > f_small and abs(ratio / (f_large / f_small) - 1.0) < SCALE_TOLERANCE:
                return small, large
    return None


def remove_gross_glitches(demo: Demonstration) -> UnitCheck:
    """Samples kept after removing gross glitches (module docstring); raises UnitError for
    mixed units and DemoError for a jump that does not come back."""
    t, pos = demo.t, demo.position
    segments, steps, typical = _segments(pos)
    long = [(a, b) for a, b in segments if b - a > MAX_GLITCH_RUN]
    if not long:
        raise DemoError(
            f"the positions jump every few samples ({len(segments)} jumps in {len(t)} samples): "
            "no continuous motion to learn from"
        )
    keep = np.zeros(len(t), dtype=bool)
    for a, b in long:
        keep[a:b] = True
    for (a0, b0), (a1, _b1) in itertools.pairwise(long):
        # the path's ends on either side, as medians: robust to a glitch at a segment's edge
        before_end = np.median(pos[max(a0, b0 - MAX_GLITCH_RUN) : b0], axis=0)
        after_start = np.median(pos[a1 : a1 + MAX_GLITCH_RUN], axis=0)
        gap = float(np.linalg.norm(after_start - before_end))
        near = max(float(typical[b0 - 2]) if b0 >= 2 else 0.0, float(typical[a1]))
        if gap <= JUMP_RATIO * max(near, 1e-12) * (a1 - b0 + 1):
            continue  # back on the path: what lay between was a glitch
        before = float(np.median(np.linalg.norm(pos[a0:b0], axis=1)))
        after = float(np.median(np.linalg.norm(pos[a1:_b1], axis=1)))
        ratio = max(before, after) / max(min(before, after), 1e-12)
        pair = _unit_pair(ratio)
        # a change of unit scales the motion too: the steps grow with the positions (a tracker
        # that jumps to another place keeps its step size)
        step_ratio = float(np.median(steps[a1 : _b1 - 1]) + 1e-12) / float(
            np.median(steps[a0 : b0 - 1]) + 1e-12
        )
        if pair is not None and (step_ratio if after > before else 1 / step_ratio) < math.sqrt(
            UNITS[pair[1]] / UNITS[pair[0]]
        ):
            pair = None
        where = f"samples {a0}-{b0 - 1} and {a1}-{_b1 - 1}"
        if pair is not None:
            raise UnitError(
                f"mixed units: the positions change scale by x{ratio:.3g} between sample "
                f"{b0 - 1} and sample {a1} (median distance from the origin {before:.3g} in "
                f"samples {a0}-{b0 - 1}, {after:.3g} in {a1}-{_b1 - 1}), the factor between "
                f"{pair[0]} and {pair[1]}; convert every sample to metres",
                None,
            )
        raise DemoError(
            f"the positions jump by {gap:.3g} (file units) between sample {b0 - 1} and sample "
            f"{a1} and do not come back ({where} lie apart): a tracker that lost the hand or "
            "changed its frame; fix or remove those samples"
        )
    dropped = np.flatnonzero(~keep)
    notes: list[str] = []
    if dropped.size:
        runs = np.split(dropped, np.flatnonzero(np.diff(dropped) > 1) + 1)
        worst = max(
            float(np.max(np.linalg.norm(pos[r] - pos[_nearest_kept(keep, int(r[0]))], axis=1)))
            for r in runs
        )
        listed = ", ".join(
            str(int(r[0])) if len(r) == 1 else f"{int(r[0])}-{int(r[-1])}" for r in runs[:5]
        ) + (", ..." if len(runs) > 5 else "")
        notes.append(
            f"{dropped.size} tracker glitch sample{'s' if dropped.size > 1 else ''} removed "
            f"(sample {listed}; up to {worst:.3g} m off the path and back)"
        )
    return UnitCheck(keep=keep, notes=notes, glitches=int(dropped.size))


def _nearest_kept(keep: NDArray[np.bool_], index: int) -> int:
    kept = np.flatnonzero(keep)
    return int(kept[np.argmin(np.abs(kept - index))])


def read_in(unit: str, t: FloatArray, pos: FloatArray, noun: str | None) -> UnitReading:
    """The demonstration (`pos` in the file's units, gross glitches removed) read in `unit`."""
    q = pos / UNITS[unit]
    small = outlier_mask(q) if len(q) > MAX_GLITCH_RUN else np.zeros(len(q), dtype=bool)
    clean = q[~small] if np.count_nonzero(~small) >= len(q) // 2 else q
    extent = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))
    speed = _speed(t, q)
    problems: list[str] = []
    if extent > MAX_EXTENT:
        problems.append(f"the path spans {extent:.3g} m, more than {MAX_EXTENT:g} m")
    if speed > MAX_HAND_SPEED:
        problems.append(f"the hand moves at {speed:.3g} m/s, faster than {MAX_HAND_SPEED:g} m/s")
    size: tuple[str, float] | None = None
    size_problem: str | None = None
    if noun in NOUN_SIZES:
        what, low, high = NOUN_SIZES[noun]
        value: float | None = None
        try:
            value = fit_line(clean).length if what == "travel" else fit_circle(clean).radius
        except FitError:
            value = None  # the geometry says nothing about this size (the words may be wrong)
        if value is not None and math.isfinite(value):
            size = (what, value)
            if not low <= value <= high:
                size_problem = f"a {noun}'s {what} of {value:.3g} m, outside {low:g}-{high:g} m"
    return UnitReading(unit, extent, speed, size, tuple(problems), size_problem)


def _usable(reading: UnitReading) -> bool:
    """Plausible and enough to learn from: what a suggested conversion must yield."""
    return (
        not reading.problems
        and reading.size_problem is None
        and reading.extent_m >= MIN_PATH
        and reading.speed_m_s > 0
    )


def _why_not(reading: UnitReading) -> str:
    """Why `reading` is not usable, in a few words."""
    reasons = [*reading.problems, *([reading.size_problem] if reading.size_problem else [])]
    if reading.extent_m < MIN_PATH:
        reasons.append(f"the path spans {reading.extent_m:.2g} m, less than {MIN_PATH:g} m")
    elif reading.speed_m_s <= 0:
        reasons.append(f"the hand never moves faster than {MOVING_SPEED * 100:g} cm/s")
    return ", ".join(reasons)


def check_units(demo: Demonstration) -> UnitCheck:
    """The samples to use (gross glitches removed) when the positions are plausible in metres;
    raises UnitError (module docstring) when they are not, or not in one unit throughout."""
    found = remove_gross_glitches(demo)
    t, pos = demo.t[found.keep], demo.position[found.keep]
    noun = constraint_from_words(demo.instruction, demo.object).noun
    metres = read_in("metres", t, pos, noun)
    if not metres.problems:
        notes = list(found.notes)
        if metres.size_problem:  # plausible, but not for the words' object: say so
            notes.append(f"in metres the demonstration is {metres.size_problem}: check its unit")
        return UnitCheck(keep=found.keep, notes=notes, glitches=found.glitches)
    readings = {u: read_in(u, t, pos, noun) for u in UNITS if u != "metres"}
    usable = tuple(u for u, r in readings.items() if _usable(r))
    what = (
        f"in metres the path {metres.describe(None)} (plausible: at most {MAX_EXTENT:g} m "
        f"and {MAX_HAND_SPEED:g} m/s)"
    )
    if len(usable) == 1:
        unit = usable[0]
        f = UNITS[unit]
        others = "; ".join(f"in {u}: {_why_not(r)}" for u, r in readings.items() if u != unit)
        raise UnitError(
            f"positions look like {unit}, not metres: {what}; in {unit} it "
            f"{readings[unit].describe(noun)} (no other unit fits: {others}). Convert them "
            f"to metres (divide by {f:.4g}).",
            unit,
            usable,
        )
    if usable:
        listed = "; ".join(f"in {u} it {readings[u].describe(noun)}" for u in usable)
        divide = ", ".join(f"by {UNITS[u]:.4g} for {u}" for u in usable)
        raise UnitError(
            f"positions are not metres: {what}. They fit several units and the demonstration "
            f"does not tell which: {listed}. Convert them to metres with the tracker's unit "
            f"(divide {divide}).",
            None,
            usable,
        )
    raise UnitError(
        f"positions are not plausible in any unit ({', '.join(UNITS)}): {what}; "
        + "; ".join(f"in {u}: {_why_not(r)}" for u, r in readings.items()),
        None,
    )


def motion_sense_warning(
    demo: Demonstration,
    direction: FloatArray,
    chord: FloatArray,
    constraint: str,
    start_orientation: FloatArray | None = None,
) -> str | None:
    """A warning when the motion's sense contradicts the verb (open vs close) or cannot be
    told from the demonstration, else None.

    direction (3,): the initial direction of motion; chord (3,) [m]: from the resting start to
    the resting end; start_orientation (4,): the hand's quaternion (w, x, y, z) at the start
    (default: the demonstration's first). The motion's sense: with a hand orientation, pulling
    against the palm normal (hand z, which points at the object) opens and pushing along it
    closes; without one, or when the palm is across the motion (a pressed plate, a crank), a
    mostly vertical chord (lids, windows) opens upward and closes downward. Otherwise (a
    horizontal motion without hand orientations, whatever the workplane) the positions alone do
    not show whether the object opened or closed, and the warning says so.
    """
    wanted = verb_sense(demo.instruction)
    if wanted is None or constraint not in ("prismatic", "revolute"):
        return None
    d = np.asarray(direction, dtype=float)
    moved: str | None = None
    why = ""
    quat = start_orientation
    if quat is None and demo.orientation is not None:
        quat = demo.orientation[0]
    if quat is not None:
        from scipy.spatial.transform import Rotation

        w, x, y, z = quat
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
    if moved is None:
        lacking = "no hand orientations" if quat is None else "the palm across the motion"
        return (
            f"the instruction says {wanted} ('{demo.instruction}'), but a motion that is not "
            f"vertical, with {lacking}, does not show which way the object moved: check that "
            f"the demonstration starts {'closed' if wanted == 'open' else 'open'}"
        )
    if moved == wanted:
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
