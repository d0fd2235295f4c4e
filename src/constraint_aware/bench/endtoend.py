"""End to end: the execution sequence from home on randomly placed objects of every kind,
from demonstrations that locate the object only roughly.

Each run: an object of one kind at a random placement (lfo.synthetic.random_placement, as the
placement benchmark draws them), a demonstration whose tracked point is offset from the handle
(lfo.synthetic.HandOffset: up to 5 cm plus 1 cm) with 5 mm tracking noise, the skill inferred
from it, and the whole sequence (lfo/sequence.py) on the true object: perceive with the head
camera, reach, approach, grasp, manipulate, release, retreat, return home. Nothing of the
simulated object reaches the pipeline; the task monitor scores afterwards (the object's
progress at the end of the manipulation, the recognizer's error against the true contact
point). Beside it, on the same placement, today's run with the hand placed at the grasp
(`lfo.execute.execute`) from the placement benchmark's demonstration (no offset), for the
peak-force comparison, and the run placed at the grasp with the skill the sequence's
manipulation used: the same estimates, so that the start alone differs.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from constraint_aware.errors import CapError, UnknownNameError
from constraint_aware.geometry import angle_deg, norm
from constraint_aware.lfo.execute import execute
from constraint_aware.lfo.infer import infer_skill
from constraint_aware.lfo.synthetic import (
    HandOffset,
    Placement,
    TrackingNoise,
    demo_of_object,
    random_placement,
)
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.recognizer import Recognition, Recognizer, make_recognizer
from constraint_aware.sim.tasks import KINDS

NOISE = 0.005  # [m] tracking noise, as the placement benchmark's
FULL_PER_KIND = 15  # placements per kind and robot of benchmarks/placement.py --end-to-end
ROBOTS = ("hook-hand", "jaco")


@dataclass(frozen=True)
class SequenceRun:
    """One placement end to end and its teleported twin. Units: m, N, mm, deg."""

    kind: str
    robot: str
    index: int
    success: bool
    failed_phase: str | None
    outcome: str  # "success" or the failed phase's outcome
    reason: str
    manipulation_peak_N: float | None  # the executor's peak |F - F_d|
    sequence_peak_N: float  # the largest |F| of any phase
    true_goal: float  # [m] or [rad]
    progress: float  # [m] or [rad] the object's position at the end of the manipulation
    demo_offset_mm: float  # the demonstrated point's distance from the contact point
    contact_error_mm: float | None  # the recognizer's, of the grasp it went to
    approach_error_deg: float | None
    periods: int
    teleported_success: bool | None = None
    teleported_peak_N: float | None = None
    teleported_outcome: str | None = None
    wall_time_s: float = math.nan
    # the true force between hand and object (`object_force`: independent of what the hand
    # carried when F_d was read), peak over the manipulation's periods (its F_d hold included)
    object_force_peak_N: float | None = None
    teleported_object_force_peak_N: float | None = None
    # the head camera's recognition alone (before the wrist camera's second look)
    first_contact_error_mm: float | None = None
    # the teleported run with the skill the sequence's manipulation ran with (its own
    # demonstration, corrected by what it recognized): the start alone differs
    own_teleported_success: bool | None = None
    own_teleported_peak_N: float | None = None
    own_teleported_object_force_peak_N: float | None = None


@dataclass
class EndToEndResult:
    per_kind: int
    seed: int
    robots: list[str]
    kinds: list[str]
    recognizer: str
    runs: list[SequenceRun] = field(default_factory=list)
    summary: list[dict[str, Any]] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _demo_skill(place: Placement, rng: np.random.Generator, offset: HandOffset | None) -> Any:
    demo = demo_of_object(
        place.task, place.goal, rng, TrackingNoise(noise=NOISE),
        point_offset=None if offset is None else offset.draw(rng),
    )  # fmt: skip
    return infer_skill(demo)


def one_sequence(
    place: Placement,
    index: int,
    robot: str,
    skill: Any,
    policy: ConstraintAwarePolicy | None,
    recognizer: Recognizer,
    seed: int,
) -> tuple[SequenceRun, Any]:
    """The sequence on `place` from `skill`, scored afterwards against the truth, and the
    skill its manipulation ran with (corrected by the recognized contact point; None when
    nothing was recognized)."""
    from constraint_aware.lfo.grasp_data import contact_label
    from constraint_aware.lfo.perception import corrected_skill
    from constraint_aware.lfo.sequence import run_in_simulation

    task = place.task
    seen: dict[str, float] = {}
    done: list[str] = []  # the phases finished so far

    rest: dict[str, np.ndarray] = {}

    def on_phase(name: str, sim: Any) -> None:
        done.append(name)
        if name == "perceive":  # where the handle rests as the camera sees it (a lid on its stop)
            rest["handle"] = np.asarray(type(sim).handle_position(sim), dtype=float)
        if name == "manipulate":
            seen["progress"] = float(type(sim).progress(sim))

    def on_period(sim: Any) -> None:
        if done and done[-1] == "grasp":  # the manipulation runs after the grasp
            peak = max(seen.get("object_force", 0.0), norm(sim.object_force()))
            seen["object_force"] = peak

    start = time.perf_counter()
    offset = float("nan")
    try:
        result = run_in_simulation(
            skill, task, robot, policy=policy, seed=seed, recognizer=recognizer,
            on_phase=on_phase, on_period=on_period,
        )  # fmt: skip
    except CapError as exc:  # refused before moving (the station, an estimate)
        refused = SequenceRun(
            place.kind, robot, index, False, "station", "refused", str(exc), None, 0.0,
            place.goal, 0.0, offset, None, None, 0, wall_time_s=time.perf_counter() - start,
        )  # fmt: skip
        return refused, None
    record = result.record
    sim = result.sim
    progress = seen.get("progress", float(type(sim).progress(sim)))
    perceive = record.phase("perceive").details
    look = record.phase("look").details
    final = look if "contact_point" in look else perceive  # what the hand went to
    contact_err = approach_err = first_err = None
    used = None
    if "contact_point" in final:
        seen_at = Recognition(
            np.asarray(final["contact_point"]), np.asarray(final["approach"]), final["method"]
        )
        used = corrected_skill(skill, seen_at)
    if "contact_point" in perceive:
        truth, approach = contact_label(task, perceive["shape"], np.asarray(skill.start_position))
        # the label of the configured object, moved to where its handle rested
        truth = (
            truth + rest.get("handle", task.object.handle_position) - task.object.handle_position
        )
        first_err = 1000.0 * float(np.linalg.norm(np.asarray(perceive["contact_point"]) - truth))
        contact_err = 1000.0 * float(np.linalg.norm(np.asarray(final["contact_point"]) - truth))
        approach_err = float(angle_deg(np.asarray(final["approach"]), approach))
        offset = 1000.0 * float(np.linalg.norm(np.asarray(skill.start_position) - truth))
    failed = record.phase(record.failed_phase) if record.failed_phase else None
    manipulation = record.manipulation
    scored = SequenceRun(
        place.kind, robot, index, record.success, record.failed_phase,
        "success" if record.success else (failed.outcome if failed else "error"),
        record.reason, None if manipulation is None else manipulation.peak_force,
        record.peak_force, place.goal, progress, offset, contact_err, approach_err,
        record.periods, wall_time_s=time.perf_counter() - start,
        object_force_peak_N=seen.get("object_force"), first_contact_error_mm=first_err,
    )  # fmt: skip
    return scored, used


def run_end_to_end(
    per_kind: int,
    robots: tuple[str, ...] = ROBOTS,
    seed: int = 0,
    kinds: tuple[str, ...] = KINDS,
    policy: ConstraintAwarePolicy | None = None,
    recognizer: str = "cnn",
    teleported: bool = True,
    progress: Any = None,
) -> EndToEndResult:
    """`per_kind` placements of each kind on each robot (placement i of kind k: the
    placement benchmark's draw np.random.default_rng([seed, k, i]), k the kind's index in
    `sim.tasks.KINDS`, so that a subset of `kinds` draws the same placements), end to end from
    an offset demonstration, and, when `teleported`, today's run placed at the grasp from the
    placement benchmark's demonstration of the same placement."""
    for kind in kinds:
        if kind not in KINDS:
            raise UnknownNameError("kind", kind, KINDS)
    policy = policy or ConstraintAwarePolicy.load()
    found = make_recognizer(recognizer)
    result = EndToEndResult(per_kind, seed, list(robots), list(kinds), recognizer)
    # one after the other in the calling process, never on a pool forked from a process that
    # has rendered: the sequences' offscreen depth rendering (EGL) hangs there (`cap bench`
    # runs this section in a process of its own)
    for robot in robots:
        for kind in kinds:
            k = KINDS.index(kind)
            for i in range(per_kind):
                place = random_placement(kind, np.random.default_rng([seed, k, i]))
                skill = _demo_skill(place, np.random.default_rng([seed, k, i, 2]), HandOffset())
                run, used = one_sequence(place, i, robot, skill, policy, found, i)
                if teleported:
                    run = _with_teleported(run, place, robot, policy, seed, k, i, used)
                result.runs.append(run)
                if progress is not None:
                    progress(run)
    result.summary = summarize(result.runs)
    return result


def _with_teleported(
    run: SequenceRun, place: Placement, robot: str, policy: ConstraintAwarePolicy,
    seed: int, k: int, i: int, used: Any,
) -> SequenceRun:  # fmt: skip
    """`run` with today's teleported run of the same placement (the placement benchmark's
    demonstration and seed) and, given the skill the sequence's manipulation `used`, the
    teleported run of that skill: the same estimates, the start alone differs."""
    today = _teleported(
        _demo_skill(place, np.random.default_rng([seed, k, i, 1]), None), place, robot, policy, i
    )
    mine = _Teleported(None, None) if used is None else _teleported(used, place, robot, policy, i)
    return dataclasses.replace(
        run,
        teleported_success=today.success,
        teleported_peak_N=today.peak_N,
        teleported_outcome=today.outcome,
        teleported_object_force_peak_N=today.object_force_peak_N,
        own_teleported_success=mine.success,
        own_teleported_peak_N=mine.peak_N,
        own_teleported_object_force_peak_N=mine.object_force_peak_N,
    )


@dataclass(frozen=True)
class _Teleported:
    success: bool | None  # None: not run
    outcome: str | None
    peak_N: float | None = None  # the executor's peak |F - F_d|
    object_force_peak_N: float | None = None  # the true hand-object force's peak


def _teleported(
    skill: Any, place: Placement, robot: str, policy: ConstraintAwarePolicy, i: int
) -> _Teleported:
    """The run of `skill` with the hand placed at the grasp of `place`'s object (seed `i`)."""
    peak = [0.0]

    def on_period(sim: Any) -> None:
        peak[0] = max(peak[0], norm(sim.object_force()))

    try:
        record, _ = execute(
            skill, "policy", seed=i, task=place.task, policy=policy, robot=robot,
            on_period=on_period,
        )  # fmt: skip
    except CapError as exc:
        return _Teleported(False, f"refused: {exc}"[:120])
    return _Teleported(record.success, record.outcome, record.peak_force, peak[0])


def _median(values: list[float]) -> float | None:
    return float(np.median(values)) if values else None


def _paired(
    runs: list[SequenceRun],
    mine: str,
    theirs: str,
    ran: tuple[str, str] = ("success", "own_teleported_success"),
) -> list[tuple[float, float]]:
    """(`mine`, `theirs`) (SequenceRun fields) over the runs where both runs named in `ran`
    (their success fields) succeeded and both values were measured."""
    out = []
    for r in runs:
        a, b = getattr(r, mine), getattr(r, theirs)
        if all(getattr(r, name) for name in ran) and a is not None and b is not None:
            out.append((float(a), float(b)))
    return out


def _differences(
    runs: list[SequenceRun],
    mine: str,
    theirs: str,
    ran: tuple[str, str] = ("success", "own_teleported_success"),
) -> list[float]:
    """`mine` - `theirs` over the pairs of `_paired`."""
    return [a - b for a, b in _paired(runs, mine, theirs, ran)]


def summarize(runs: list[SequenceRun]) -> list[dict[str, Any]]:
    """Per robot and kind (and per robot over all kinds): successes, failures by phase, peak
    |F| medians end to end and teleported and their median paired difference where both
    succeeded, the same for the true hand-object force; the same two differences against the
    teleported run of the sequence's own skill, and that run's true peak against today's (the
    demonstration's share of the first difference); the recognizer's errors, the true
    shortfall."""
    out: list[dict[str, Any]] = []
    robots = list(dict.fromkeys(r.robot for r in runs))
    kinds = list(dict.fromkeys(r.kind for r in runs))
    for robot in robots:
        for kind in [*kinds, "all"]:
            mine = [r for r in runs if r.robot == robot and (kind == "all" or r.kind == kind)]
            if not mine:
                continue
            failures: dict[str, int] = {}
            for r in mine:
                if not r.success:
                    key = f"{r.failed_phase}: {r.outcome}"
                    failures[key] = failures.get(key, 0) + 1
            today = ("success", "teleported_success")
            pairs = _differences(mine, "manipulation_peak_N", "teleported_peak_N", today)
            true_pairs = _paired(
                mine, "object_force_peak_N", "teleported_object_force_peak_N", today
            )
            # the sequence against the teleported start of the same skill, and the teleported
            # start's own change with the demonstration (today's against the sequence's skill)
            own = _differences(mine, "manipulation_peak_N", "own_teleported_peak_N")
            own_true = _differences(
                mine, "object_force_peak_N", "own_teleported_object_force_peak_N"
            )
            demo_true = _differences(
                mine,
                "teleported_object_force_peak_N",
                "own_teleported_object_force_peak_N",
                ("teleported_success", "own_teleported_success"),
            )
            contact = [r.contact_error_mm for r in mine if r.contact_error_mm is not None]
            first = [r.first_contact_error_mm for r in mine if r.first_contact_error_mm is not None]
            scale = 100.0 if kind in ("drawer", "plate", "pole", "window") else math.degrees(1)
            short = [(r.true_goal - r.progress) * scale for r in mine if r.success]
            out.append(
                {
                    "robot": robot,
                    "kind": kind,
                    "n": len(mine),
                    "successes": sum(r.success for r in mine),
                    "success_rate": sum(r.success for r in mine) / len(mine),
                    "failures": failures,
                    "peak_N_median": _median(
                        [
                            r.manipulation_peak_N
                            for r in mine
                            if r.success and r.manipulation_peak_N is not None
                        ]
                    ),
                    "teleported_successes": sum(bool(r.teleported_success) for r in mine),
                    "teleported_peak_N_median": _median(
                        [
                            r.teleported_peak_N
                            for r in mine
                            if r.teleported_success and r.teleported_peak_N is not None
                        ]
                    ),
                    "paired": len(pairs),
                    "peak_difference_N_median": _median(pairs),
                    "object_force_peak_N_median": _median([a for a, _ in true_pairs]),
                    "teleported_object_force_peak_N_median": _median([b for _, b in true_pairs]),
                    "object_force_difference_N_median": _median([a - b for a, b in true_pairs]),
                    "own_teleported_successes": sum(bool(r.own_teleported_success) for r in mine),
                    "own_paired": len(own),
                    "own_peak_difference_N_median": _median(own),
                    "own_object_force_difference_N_median": _median(own_true),
                    "demonstration_object_force_difference_N_median": _median(demo_true),
                    "contact_error_mm_median": _median(contact),
                    "contact_error_mm_p95": (
                        float(np.percentile(contact, 95)) if contact else None
                    ),
                    "first_contact_error_mm_median": _median(first),
                    "first_contact_error_mm_p95": (
                        float(np.percentile(first, 95)) if first else None
                    ),
                    "shortfall_median": None if kind == "all" else _median(short),
                    "wall_time_s_median": _median([r.wall_time_s for r in mine]),
                }
            )
    return out


#: `cap bench`'s reduced set: placements per kind and robot, robots and kinds (full, quick).
BENCH_PER_KIND = {False: 1, True: 1}
BENCH_ROBOTS = {False: ROBOTS, True: ("hook-hand",)}
BENCH_KINDS = {False: KINDS, True: ("drawer",)}


def bench_section(quick: bool, policy: ConstraintAwarePolicy | None = None) -> dict[str, Any]:
    """The end-to-end experiment as `cap bench` runs it (benchmarks/placement.py
    --end-to-end runs more)."""
    out = run_end_to_end(
        BENCH_PER_KIND[quick], BENCH_ROBOTS[quick], kinds=BENCH_KINDS[quick], policy=policy
    ).to_dict()
    offset = HandOffset()
    out["full_benchmark_per_kind"] = FULL_PER_KIND
    out["noise_mm"] = NOISE * 1000.0
    out["offset_cm"] = {"max": 100.0 * offset.max_offset, "jitter": 100.0 * offset.jitter}
    return out


def _f(x: float | None, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def summary_table(summary: list[dict[str, Any]]) -> list[str]:
    """`summarize`'s rows as a Markdown table (the report's and the benchmark's)."""
    lines = [
        "| robot | kind | success | failures by phase | peak F median [N] | teleported "
        "success | teleported peak F median [N] | paired peak difference median [N] | "
        "paired true-force peak difference median [N] | same skill teleported: paired peak "
        "/ true-force difference median [N] | today's teleported - same skill's, true force "
        "[N] | contact error median / p95 [mm] | head camera alone: median / p95 [mm] |",
        "|---" * 13 + "|",
    ]
    for s in summary:
        failures = ", ".join(f"{k} x{v}" for k, v in s["failures"].items()) or "-"
        lines.append(
            f"| {s['robot']} | {s['kind']} | {s['successes']}/{s['n']} | {failures} | "
            f"{_f(s['peak_N_median'])} | {s['teleported_successes']}/{s['n']} | "
            f"{_f(s['teleported_peak_N_median'])} | {_f(s['peak_difference_N_median'], 2)} | "
            f"{_f(s.get('object_force_difference_N_median'), 2)} | "
            f"{_f(s.get('own_peak_difference_N_median'), 2)} / "
            f"{_f(s.get('own_object_force_difference_N_median'), 2)} | "
            f"{_f(s.get('demonstration_object_force_difference_N_median'), 2)} | "
            f"{_f(s['contact_error_mm_median'])} / {_f(s['contact_error_mm_p95'])} | "
            f"{_f(s.get('first_contact_error_mm_median'))} / "
            f"{_f(s.get('first_contact_error_mm_p95'))} |"
        )
    return lines


def report_lines(section: dict[str, Any]) -> list[str]:
    """The report's end-to-end section, read from results.json's "end_to_end"."""
    off = section["offset_cm"]
    return [
        "## End to end: see, reach, grasp, manipulate, release, return home\n",
        f"{section['per_kind']} random placements per kind and robot, each demonstrated once "
        f"with the tracked point up to {off['max']:g} cm (plus {off['jitter']:g} cm) from the "
        f"handle and {section['noise_mm']:g} mm tracking "
        "noise; the robot starts at home, finds the contact point with the "
        f"`{section['recognizer']}` recognizer in one depth image of its head camera and "
        "again, from beside the pre-grasp, in its wrist camera's and the head camera's "
        "together (the contact error is that second answer's; the head camera's alone beside "
        "it), and "
        "runs every phase with no access to the simulated object. Peak |F| is the "
        "manipulation's (F = F_s - F_d); teleported: the same placement started at the grasp "
        "from a demonstration without offset. F depends on what the hand carried when F_d "
        "was read (a teleported hand may already bear part of a lid's weight); the true "
        "force between hand and object (simulator, scoring only) does not. The same "
        "skill's teleported run starts at the grasp with the skill the sequence's "
        "manipulation used (its own demonstration, corrected by what it recognized): the "
        "start alone differs. The last force column is how much today's teleported run's true "
        "peak moves with its other demonstration alone (`python benchmarks/placement.py "
        f"--end-to-end` runs {section['full_benchmark_per_kind']} per kind and robot).\n",
        *summary_table(section["summary"]),
        "",
    ]
