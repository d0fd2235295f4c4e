"""From a demonstration to skill parameters: constraint, workplane, radius, direction, grasp.

Geometry and words are judged separately, then combined:
- geometry: a line and (if the points span a plane) a circle are fitted; the path is an arc when
  the circle explains it much better than the line (RMS ratio below GEOMETRY_RATIO) over at least
  MIN_ARC_DEG with a radius below MAX_RADIUS; it is a line when the circle explains nothing more
  (no circle, a huge radius, or ratio above LINE_RATIO) and the path is long enough that a hinge
  of radius LINE_RADIUS would have bent it by more than twice the line's RMS; anything else
  (short paths, shallow arcs within the noise) is ambiguous.
- words: `lexicon.constraint_from_words`.
- unambiguous geometry decides; ambiguous geometry defers to the words; disagreement is
  reported with the evidence; when neither knows, the type is "unknown".
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray, unit
from constraint_aware.lfo.demo import Demonstration
from constraint_aware.lfo.fitting import (
    MIN_ARC_DEG,
    CircleFit,
    FitError,
    fit_circle,
    fit_line,
    fit_plane,
    initial_direction,
    outlier_mask,
)
from constraint_aware.lfo.lexicon import constraint_from_words, grasp_for
from constraint_aware.lfo.plausibility import MIN_PATH, check_units, motion_sense_warning

GEOMETRY_RATIO = 0.35  # circle RMS / line RMS below this: an arc
LINE_RATIO = 0.7  # circle RMS / line RMS above this: the circle explains nothing more
LINE_RADIUS = 0.6  # [m] a line is conclusive when a hinge this large would visibly bend it
MAX_RADIUS = 3.0  # [m] a fitted radius beyond this is a line


class InferenceError(CapError, ValueError):
    """The demonstration cannot yield skill parameters; the message says why."""


@dataclass
class SkillParameters:
    """What the executor needs, with the evidence behind each estimate. Units: m, deg."""

    constraint_type: str  # prismatic | revolute | unknown
    workplane_normal: list[float]  # (3,) unit; revolute: the motion turns positively about it
    initial_direction: list[float]  # (3,) unit, in the workplane
    grasp: str  # force-exertion type
    fixed_orientation: bool  # the grasp fixes the hand-object orientation (torque policy)
    radius: float | None = None  # [m] revolute
    centre: list[float] | None = None  # (3,) [m] revolute
    axis: list[float] | None = None  # (3,) revolute rotation axis
    start_position: list[float] | None = None  # (3,) [m] the hand at rest before the motion
    goal: float | None = None  # demonstrated travel [m] (prismatic) or rotation [rad] (revolute)
    uncertainty: dict[str, float] = field(default_factory=dict)
    evidence: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def classify_geometry(positions: FloatArray) -> tuple[dict[str, Any], CircleFit | FitError]:
    """Line vs arc from the fits: ({'verdict', 'line_rms_m', 'circle_rms_m', ...}, the circle
    fit or the reason there is none)."""
    line = fit_line(positions)
    out: dict[str, Any] = {"line_rms_m": line.rms, "path_length_m": line.length}
    try:
        circle = fit_circle(positions)
    except FitError as exc:
        out["circle"] = f"no circle: {exc}"
        sagitta = line.length**2 / (8.0 * LINE_RADIUS)
        out["hinge_sagitta_m"] = sagitta
        out["verdict"] = "line" if sagitta > 2.0 * line.rms else "ambiguous"
        return out, exc
    out.update(circle_rms_m=circle.rms, radius_m=circle.radius, arc_deg=circle.arc_deg)
    ratio = circle.rms / max(line.rms, 1e-12)
    out["rms_ratio"] = ratio
    # how far a hinge of radius LINE_RADIUS would bend a path this long: if that would stand
    # well above the scatter, a straight path rules hinges out
    sagitta = line.length**2 / (8.0 * LINE_RADIUS)
    out["hinge_sagitta_m"] = sagitta
    conclusive = sagitta > 2.0 * line.rms
    if circle.radius <= MAX_RADIUS and ratio < GEOMETRY_RATIO and circle.arc_deg >= MIN_ARC_DEG:
        out["verdict"] = "arc"
    elif conclusive and (circle.radius > MAX_RADIUS or ratio > LINE_RATIO):
        out["verdict"] = "line"
    else:
        out["verdict"] = "ambiguous"
    return out, circle


def infer_skill(demo: Demonstration, grasp_override: str | None = None) -> SkillParameters:
    """Skill parameters of one demonstration (raises InferenceError when none can be had, and
    plausibility.UnitError when the positions are not in metres or not in one unit).

    Tracker glitches are removed before anything is fitted: gross ones (plausibility.py, named
    in the warnings) and small ones (fitting.outlier_mask, counted in the evidence)."""
    units = check_units(demo)
    kept = np.flatnonzero(units.keep)
    glitches = outlier_mask(demo.position[kept])
    used = kept[~glitches]  # indices of the samples every fit uses
    pos, times = demo.position[used], demo.t[used]
    travel = float(np.linalg.norm(pos.max(axis=0) - pos.min(axis=0)))
    if travel < MIN_PATH:
        raise InferenceError(
            f"trajectory too short: the hand moved {travel * 100:.1f} cm "
            f"(< {MIN_PATH * 100:.0f} cm)"
        )
    words = constraint_from_words(demo.instruction, demo.object)
    geometry, circle = classify_geometry(pos)
    warnings: list[str] = list(units.notes)
    verdict = {"line": "prismatic", "arc": "revolute"}.get(geometry["verdict"])
    if verdict is not None:
        constraint = verdict
        if words.constraint not in ("unknown", verdict):
            warnings.append(
                f"words suggest {words.constraint} ({words.reason}) but the hand moved along "
                f"{'an arc' if verdict == 'revolute' else 'a line'}; geometry decides: {verdict}"
            )
        elif words.constraint == "unknown":
            warnings.append(f"words unknown ({words.reason}); geometry decides: {verdict}")
    elif words.constraint != "unknown":
        constraint = words.constraint
        warnings.append(f"geometry ambiguous; words decide: {constraint} ({words.reason})")
    else:
        constraint = "unknown"
        warnings.append(f"neither words ({words.reason}) nor geometry decide the constraint")

    uncertainty: dict[str, float] = {}
    radius = centre = axis = None
    if constraint == "revolute":
        if isinstance(circle, FitError):
            raise InferenceError(f"revolute constraint but {circle}") from circle
        normal = circle.axis
        radius, centre, axis = circle.radius, circle.centre.tolist(), circle.axis.tolist()
        plane = circle.plane
        assert plane is not None  # fitted without a given normal
        uncertainty.update(
            radius_std_m=circle.radius_std,
            centre_std_m=circle.centre_std,
            circle_rms_m=circle.rms,
            normal_std_deg=plane.normal_std_deg,
            plane_rms_m=plane.rms,
            arc_deg=circle.arc_deg,
        )
    noun = words.noun
    grasp, fixed, source = grasp_for(noun, constraint)
    if demo.grasp_hint:
        grasp, source = demo.grasp_hint, "the demonstration's grasp hint"
    if grasp_override:
        grasp, source = grasp_override, "user override"
    if constraint != "revolute":
        quats = None if demo.orientation is None else demo.orientation[used]
        normal, plane_note = _prismatic_workplane(pos, grasp, quats)
        if plane_note:
            warnings.append(plane_note)
        uncertainty["line_rms_m"] = geometry["line_rms_m"]
        uncertainty["normal_std_deg"] = _line_direction_std_deg(pos)
    start = _motion_start(pos)
    stop = len(pos) - _motion_start(pos[::-1])
    rest_start = np.median(pos[: max(start, 3)], axis=0)
    rest_end = np.median(pos[min(stop, len(pos) - 3) :], axis=0)
    if constraint == "revolute":
        # the arc's tangent at the resting start position, in the sense of the motion
        assert centre is not None
        rest = np.median(pos[: max(start, 3)], axis=0)
        direction = unit(np.cross(normal, rest - np.asarray(centre)))
    else:
        line = fit_line(pos[start:])
        direction = line.direction
    direction = unit(direction - float(direction @ normal) * normal)
    if constraint == "revolute":
        assert centre is not None
        goal: float | None = _swept_angle(
            pos, np.asarray(centre), normal, max(start, 3), min(stop, len(pos) - 3)
        )
    elif constraint == "prismatic":
        goal = float((rest_end - rest_start) @ direction)
    else:
        goal = None
    uncertainty["path_length_m"] = (
        float(goal * (radius or 0.0)) if constraint == "revolute" and goal else abs(goal or 0.0)
    )
    start_dir, start_rms = initial_direction(pos, times)
    uncertainty["initial_direction_rms_m"] = start_rms
    geometry["start_segment_direction"] = start_dir.tolist()
    geometry["glitches_removed"] = int(glitches.sum()) + units.glitches

    start_quat = None if demo.orientation is None else demo.orientation[used[0]]
    sense = motion_sense_warning(demo, direction, rest_end - rest_start, constraint, start_quat)
    if sense:
        warnings.append(sense)
    return SkillParameters(
        constraint_type=constraint,
        workplane_normal=unit(normal).tolist(),
        initial_direction=direction.tolist(),
        grasp=grasp,
        fixed_orientation=fixed and constraint == "revolute",
        radius=radius,
        centre=centre,
        axis=axis,
        start_position=rest_start.tolist(),
        goal=goal,
        uncertainty=uncertainty,
        evidence={"words": asdict(words), "geometry": geometry, "grasp_source": source},
        warnings=warnings,
    )


def _motion_start(pos: FloatArray, moved: float = 0.01) -> int:
    """Index of the first sample 1 cm away from the median resting position at the start."""
    rest = np.median(pos[: max(3, len(pos) // 20)], axis=0)
    away = np.flatnonzero(np.linalg.norm(pos - rest, axis=1) > moved)
    return int(max(away[0] - 1, 0)) if away.size else 0


def _prismatic_workplane(
    pos: FloatArray, grasp: str, orientation: FloatArray | None = None
) -> tuple[FloatArray, str]:
    """A line does not fix a plane: fit one if the path spans it, else take the plane the grasp
    implies (README: LfO): a hook (lazy closure) on a bar carries force only across the bar:
    with the hand's orientations, the plane across the hand's x axis (the fingers curl in the
    hand's y-z plane, sim/hand.py, so a hooked bar runs along x); without them, the vertical
    plane through the line. A squeezed pole or a pressed plate moves in the horizontal plane
    through it. For a vertical line (a sash window) without orientations, no plane is preferred:
    the one across world y is taken, with a warning."""
    try:
        plane = fit_plane(pos)
        if plane.extent[1] > 0.2 * plane.extent[0]:
            return plane.normal, ""
    except FitError:
        pass
    line = fit_line(pos).direction
    up = np.array([0.0, 0.0, 1.0])
    bar = _hand_x(orientation) if orientation is not None else None
    if grasp == "lazy_closure" and bar is not None:
        across = bar - float(bar @ line) * line
        if np.linalg.norm(across) > 0.5:
            return unit(across), (
                "the path is a line, which fixes no plane: workplane = the plane across the "
                "hooked bar (the hand's x axis)"
            )
    if abs(float(line @ up)) > 0.9:
        normal = np.cross(line, [1.0, 0.0, 0.0])
        note = "vertical plane through it"
    elif grasp == "lazy_closure":
        normal = np.cross(line, up)
        note = "the vertical plane through it (across a hooked bar)"
    else:
        normal = np.cross(np.cross(up, line), line)  # in-plane normal closest to vertical
        normal = normal if float(normal @ up) > 0 else -normal
        note = "the horizontal plane through it (a pressed plate or a squeezed pole)"
    return unit(normal), f"the path is a line, which fixes no plane: workplane = {note}"


def _hand_x(orientation: FloatArray) -> FloatArray | None:
    """(3,) the hand's mean x axis over the demonstration (quaternions (w, x, y, z))."""
    from scipy.spatial.transform import Rotation

    w, x, y, z = np.asarray(orientation, dtype=float).T
    axes = Rotation.from_quat(np.stack([x, y, z, w], axis=1)).apply([1.0, 0.0, 0.0])
    axes = axes * np.sign(axes @ axes[0])[:, None]  # an axis: one sign
    mean = axes.mean(axis=0)
    return unit(mean) if np.linalg.norm(mean) > 0.5 else None


def _line_direction_std_deg(pos: FloatArray) -> float:
    """[deg] 1-sigma uncertainty of a fitted line's direction: the slope error of a regression,
    sigma_perp / (sqrt(N) * spread along the line)."""
    line = fit_line(pos)
    rel = pos - line.point
    along = rel @ line.direction
    perp = rel - np.outer(along, line.direction)
    sigma = float(np.sqrt(np.mean(np.sum(perp**2, axis=1)) / 2.0))  # per perpendicular axis
    spread = float(np.std(along))
    return math.degrees(math.atan2(sigma, math.sqrt(len(pos)) * max(spread, 1e-9)))


def _swept_angle(
    path: FloatArray, centre: FloatArray, normal: FloatArray, start: int, stop: int
) -> float:
    """[rad] rotation about `normal` through `centre` from the rest before the motion
    (path[:start]) to the rest after it (path[stop:]), medians against the noise, the angle
    unwrapped along the path."""
    e1 = unit(np.cross(normal, [1.0, 0.0, 0.0]))
    if np.linalg.norm(np.cross(normal, [1.0, 0.0, 0.0])) < 0.5:
        e1 = unit(np.cross(normal, [0.0, 1.0, 0.0]))
    e2 = np.cross(normal, e1)
    rel = path - centre
    ang = np.unwrap(np.arctan2(rel @ e2, rel @ e1))
    return float(np.median(ang[stop:]) - np.median(ang[:start]))


def radius_error_pct(estimate: float, truth: float) -> float:
    return abs(estimate - truth) / truth * 100.0


def angle_between_deg(a: FloatArray, b: FloatArray, unsigned_axis: bool = False) -> float:
    c = float(np.clip(unit(a) @ unit(b), -1.0, 1.0))
    if unsigned_axis:
        c = abs(c)
    return math.degrees(math.acos(c))
