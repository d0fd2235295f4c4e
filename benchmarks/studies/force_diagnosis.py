"""Where the policy's contact force comes from, and what steadies it: the force study's runs.

Typed from end to end: `run_variant` runs one controller variant on one `analysis.Condition`
and returns a `RunDiagnosis` (the run's outcome and forces, split into the start transient and
the steady part, and the steady direction error: its signed mean is the tracking lag, the
step-to-step turn is the zig-zag); `summarize` groups them by their own keys into
`VariantSummary`s. `benchmarks/studies/forces.py` runs the study and writes JSON.

Variants (`VARIANTS`): the default policy alone (controller "policy-raw"), the classical
controller (unchanged gains), the projection controller, the default controller "policy"
(the policy inside `SteadyDirection`) whole and with each stage off, `SteadyDirection` around
the projection controller (it is not specific to the policy); and two candidates that lost,
kept for their numbers: a curvature feed-forward estimated from d's own recent turns, and
two policy sub-steps per control step.

References (`REFERENCES`), which read the simulator's admissible direction and so are not
controllers a robot can run: d turned onto it (or short of it, or past it) from the first
reading on. With `settled=True` any label runs with the hand at rest before each reading
(`SETTLED_PERIOD`). Both locate where a force gap comes from: the estimate of the path, the
size of the turn, or the hand's motion between readings.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware import deadband
from constraint_aware.bench.analysis import CellKey, Condition, group_cells, prepare_condition
from constraint_aware.control.classical import ClassicalGains
from constraint_aware.control.controllers import (
    POLICY_STAGES,
    ControlInput,
    DirectionController,
    PolicyController,
    ProjectionController,
    make_controller,
)
from constraint_aware.control.executor import Executor
from constraint_aware.control.record import RunRecord, StepRecord
from constraint_aware.control.robot import reported_stiffness
from constraint_aware.control.simulate import RunSpec, probed_config
from constraint_aware.control.steady import HAND_SMOOTHING, SteadyDirection
from constraint_aware.errors import UnknownNameError
from constraint_aware.figio import new_figure, save_figure
from constraint_aware.geometry import FloatArray, turn_vector, unit
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.robot_adapter import CONTROL_PERIOD

#: Steps counted as the start transient (the initial offset's correction) ...
TRANSIENT_STEPS = 5
#: ... and the first step counted as steady (the transient has settled by then in every run).
STEADY_FROM = 10
#: [deg] runs that begin at least this far off enter the main-correction medians (a smaller
#: offset is within the noise of the first readings: its turn over its error is noise too)
CORRECTION_MIN_OFFSET_DEG = 2.0

#: A variant builds its controller from (policy, rotation rate [rad/s] or None, oriented
#: workplane normal (3,)).
ControllerFactory = Callable[[ConstraintAwarePolicy, float | None, FloatArray], DirectionController]

#: References, not controllers a robot can run (they read the simulator's admissible
#: direction): label -> the share of the error d turns by each step once a reading is above
#: the dead band (1: exactly onto the path). They bound what a better estimate of the path
#: could give, and whether turning past it or short of it costs force.
REFERENCES: dict[str, float] = {
    "ground truth": 1.0,
    "ground truth x0.85": 0.85,
    "ground truth x1.25": 1.25,
}
#: [s] the settled-hand check's control period: about 4 of the hook hand's 0.076 s tracking
#: time constants, so the hand has come to rest before each reading (1 - e^-4 = 98 %).
SETTLED_PERIOD = 0.3
#: appended to a variant's label when it ran with the settled hand
SETTLED_SUFFIX = ", settled hand"


class GroundTruthDirection:
    """A reference (`REFERENCES`): d0 until the first reading above the dead band, then each
    step d turned toward the simulator's admissible direction by `gain` times the error. The
    hand rotation and step length are those of `hand` (controller "policy", run alongside on
    the same readings), so only d differs from it."""

    def __init__(
        self, truth: Callable[[], FloatArray], hand: DirectionController, gain: float
    ) -> None:
        self.truth = truth
        self.hand = hand
        self.gain = gain
        self.name = hand.name
        self.engaged = False

    def reset(self, direction: FloatArray) -> None:
        self.hand.reset(direction)
        self.engaged = False

    def next_direction(self, inp: ControlInput) -> FloatArray:
        self.hand.next_direction(inp)
        self.engaged = self.engaged or float(np.linalg.norm(inp.force)) > inp.threshold
        d = np.asarray(inp.direction, dtype=float)
        if not self.engaged:
            return d
        turn = turn_vector(d, unit(np.asarray(self.truth(), dtype=float)))
        return np.asarray(unit(Rotation.from_rotvec(self.gain * turn).apply(d)))

    def step_length(self, nominal: float) -> float:
        return self.hand.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return self.hand.hand_rotation()


def _steady_projection(
    policy: ConstraintAwarePolicy, rate: float | None, normal: FloatArray
) -> DirectionController:
    """The projection rule inside the same steadying (it is not specific to the policy)."""
    return SteadyDirection(ProjectionController(), rate)


def _without(stage: str) -> ControllerFactory:
    def build(
        policy: ConstraintAwarePolicy, rate: float | None, normal: FloatArray
    ) -> DirectionController:
        return make_controller("policy", policy, rate, normal, {stage: 0.0})

    return build


def _named(name: str) -> ControllerFactory:
    def build(
        policy: ConstraintAwarePolicy, rate: float | None, normal: FloatArray
    ) -> DirectionController:
        return make_controller(name, policy, rate, normal)

    return build


class EstimatedCurvature:
    """Candidate (a), kept in the study only: d also turns by an exponential average
    (HAND_SMOOTHING) of its own applied turns, a curvature feed-forward estimated from the
    robot's recent motion with no geometry given; the hand follows paper 3.4.1 (the executor's
    rule). Measured worse than the known rate: the initial offset's correction winds the
    estimate up."""

    def __init__(self, inner: DirectionController) -> None:
        self.inner = inner
        self.name = inner.name
        self._estimate = np.zeros(3)

    def reset(self, direction: FloatArray) -> None:
        self.inner.reset(direction)
        self._estimate = np.zeros(3)

    def next_direction(self, inp: ControlInput) -> FloatArray:
        d = np.asarray(inp.direction, dtype=float)
        proposed = np.asarray(self.inner.next_direction(inp), dtype=float)
        turn = turn_vector(d, unit(proposed)) + self._estimate
        self._estimate = self._estimate + HAND_SMOOTHING * (turn - self._estimate)
        return np.asarray(unit(Rotation.from_rotvec(turn).apply(d)))

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return None


class PolicySubSteps:
    """Candidate (d), kept in the study only: the policy applied `n` times per control step on
    the same force reading (each from the direction the last one gave). The diagnosis shows
    the policy over-corrects small errors, so more correction per step is measured, not
    expected to help."""

    def __init__(self, inner: DirectionController, n: int = 2) -> None:
        self.inner = inner
        self.name = inner.name
        self.n = n

    def reset(self, direction: FloatArray) -> None:
        self.inner.reset(direction)

    def next_direction(self, inp: ControlInput) -> FloatArray:
        d = np.asarray(inp.direction, dtype=float)
        for _ in range(self.n):
            d = np.asarray(self.inner.next_direction(dataclasses.replace(inp, direction=d)))
        return d

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return None


def _wrapped(kind: str) -> ControllerFactory:
    def build(
        policy: ConstraintAwarePolicy, rate: float | None, normal: FloatArray
    ) -> DirectionController:
        inner = PolicyController(policy)
        if kind == "curvature":
            return EstimatedCurvature(inner)
        return PolicySubSteps(inner, 2)

    return build


#: The variant that probes a twin of its condition at setup and runs with what the probe
#: measured (control.simulate.probed_config), as `cap run --probe` does.
PROBED = "steady + probe"


def without(stage: str) -> str:
    """The label of controller "policy" with one stage off (`POLICY_STAGES`)."""
    return f"steady without {stage}"


#: label -> controller factory. "default" is the default policy alone (controller
#: "policy-raw"), "steady" the full controller "policy" (the mirror-averaged action inside
#: `SteadyDirection`), "steady without STAGE" the same with one stage off.
VARIANTS: dict[str, ControllerFactory] = {
    "default": _named("policy-raw"),  # the default policy alone (paper 3.3's rule)
    "classical": _named("classical"),
    "steady": _named("policy"),
    **{without(stage): _without(stage) for stage in POLICY_STAGES},
    "estimated curvature": _wrapped("curvature"),
    "policy sub-steps x2": _wrapped("substeps"),
    "projection": _named("projection"),
    "projection + steady": _steady_projection,
    # controller "policy" after a setup probe on a twin (`cap run --probe`): the measured arm
    # stiffness and grasp play (run_variant)
    PROBED: _named("policy"),
}


@dataclass(frozen=True)
class RunDiagnosis:
    """One run, measured from its step records. Forces [N], angles [deg]."""

    condition: Condition
    variant: str
    seed: int
    success: bool
    outcome: str
    n_steps: int
    peak_force_N: float
    peak_step: int
    mean_force_N: float
    transient_mean_force_N: float  # steps < TRANSIENT_STEPS
    steady_mean_force_N: float  # steps >= STEADY_FROM (nan if the run is shorter)
    steady_along_force_N: float  # mean of -F.d there: the object's resistance to the move
    steady_across_force_N: float  # mean |F| across d in the workplane there
    steady_lag_deg: float  # mean signed angle(truth -> d) about the workplane normal there
    steady_error_deg: float  # median |angle(d, truth)| there
    turn_rms_deg: float  # RMS of d's step-to-step turn there (the zig-zag)
    path_turn_deg: float  # the object's turn per step, delta / r (revolute; 0 prismatic)
    median_slip_deg: float  # hand-handle rotation drift, median over the run
    # The main correction: the biggest turn of d decided in the first TRANSIENT_STEPS steps.
    correction_error_deg: float  # |angle(d, truth)| of the move whose reading decided it
    correction_turn_deg: float  # the turn, signed: + toward the truth
    correction_reading_share: float  # that reading's |F| across d in the workplane over the
    # quasi-static k delta sin(error) of a settled, rigidly guided hand (nan without k delta)
    correction_across_N: float  # that reading's |F| across d in the workplane
    # The first reading after the first move (step 1: the object starts from rest)
    first_along_N: float  # F.d: negative is resistance to the move
    first_across_N: float  # |F| across d in the workplane


def _signed_deg(a: FloatArray, b: FloatArray, normal: FloatArray) -> float:
    return math.degrees(math.atan2(float(np.cross(a, b) @ normal), float(a @ b)))


def _split(step: StepRecord, normal: FloatArray) -> tuple[float, float]:
    """(F.d, |F across d in the workplane|) [N] of a step's reading."""
    d, f = np.asarray(step.direction), np.asarray(step.force)
    return float(f @ d), abs(float(f @ np.cross(normal, d)))


def _main_correction(
    steps: list[StepRecord], normal: FloatArray, step_force: float | None
) -> tuple[float, float, float, float]:
    """(error, signed turn, reading share, across force) of the biggest turn d_i -> d_i+1
    decided from the readings of steps 1 .. TRANSIENT_STEPS - 1 (step 0 reads before any
    move)."""
    best: tuple[float, float, float, float] = (math.nan, math.nan, math.nan, math.nan)
    size = 0.0
    for s, nxt in itertools.pairwise(steps[1 : TRANSIENT_STEPS + 1]):
        if s.admissible_direction is None:
            continue
        d, truth = np.asarray(s.direction), np.asarray(s.admissible_direction)
        turn = _signed_deg(d, np.asarray(nxt.direction), normal)
        if abs(turn) <= size:
            continue
        size = abs(turn)
        to_truth = _signed_deg(d, truth, normal)
        error = abs(to_truth)
        across = _split(s, normal)[1]
        quasi_static = step_force * math.sin(math.radians(error)) if step_force else 0.0
        share = across / quasi_static if quasi_static > 0 else math.nan
        best = (error, math.copysign(abs(turn), turn * to_truth), share, across)
    return best


def diagnose(
    record: RunRecord, condition: Condition, variant: str, seed: int, normal: FloatArray,
    path_turn_deg: float, step_force: float | None = None,
) -> RunDiagnosis:  # fmt: skip
    """The run's forces and direction errors from its step records; step_force [N]: the
    robot's k delta (for the main correction's reading share)."""
    steps = [s for s in record.steps if math.isfinite(s.force_norm)]
    forces = np.array([s.force_norm for s in steps])
    steady = steps[STEADY_FROM:]
    along, across, lag, err, turns = [], [], [], [], []
    prev = None
    for s in steady:
        d = np.asarray(s.direction)
        f_along, f_across = _split(s, normal)
        along.append(-f_along)
        across.append(f_across)
        if s.admissible_direction is not None:
            lag.append(_signed_deg(np.asarray(s.admissible_direction), d, normal))
            err.append(abs(s.angle_deg))
        if prev is not None:
            turns.append(_signed_deg(prev, d, normal))
        prev = d

    def mean(v: list[float]) -> float:
        return float(np.mean(v)) if v else math.nan

    slips = [s.slip_deg for s in steps if math.isfinite(s.slip_deg)]
    error, turn, share, across_n = _main_correction(steps, normal, step_force)
    first_along, first_across = _split(steps[1], normal) if len(steps) > 1 else (math.nan,) * 2
    return RunDiagnosis(
        condition=condition,
        variant=variant,
        seed=seed,
        success=record.success,
        outcome=record.outcome,
        n_steps=record.n_steps,
        peak_force_N=float(forces.max()) if forces.size else 0.0,
        peak_step=int(forces.argmax()) if forces.size else 0,
        mean_force_N=float(forces.mean()) if forces.size else 0.0,
        transient_mean_force_N=float(forces[:TRANSIENT_STEPS].mean()) if forces.size else 0.0,
        steady_mean_force_N=float(forces[STEADY_FROM:].mean()) if steady else math.nan,
        steady_along_force_N=mean(along),
        steady_across_force_N=mean(across),
        steady_lag_deg=mean(lag),
        steady_error_deg=float(np.median(err)) if err else math.nan,
        turn_rms_deg=float(np.sqrt(np.mean(np.square(turns)))) if turns else math.nan,
        path_turn_deg=path_turn_deg,
        median_slip_deg=float(np.median(slips)) if slips else math.nan,
        correction_error_deg=error,
        correction_turn_deg=turn,
        correction_reading_share=share,
        correction_across_N=across_n,
        first_along_N=first_along,
        first_across_N=first_across,
    )


def run_variant(
    cond: Condition,
    variant: str,
    seed: int,
    policy: ConstraintAwarePolicy | None = None,
    sensor_noise: float = 0.1,
    settled: bool = False,
) -> RunDiagnosis:
    """One closed-loop run of a `VARIANTS` or `REFERENCES` label on `cond`, as
    bench.analysis.run_condition runs the policy section (dead band derived from the noise,
    the preload robot when asked), with the revolute workplane normal oriented from the hinge
    for every controller.

    settled: the hook hand at the control period `SETTLED_PERIOD` instead of its 0.1 s, with
    the same 1 cm steps, so that each reading is taken at rest; the label gets
    `SETTLED_SUFFIX`. The classical controller's adaptation rate gamma_t is scaled by the
    periods' ratio there, so that it adapts t^ by the same amount per step as tuned (its
    force feedback sets only the direction of a capped step, which the period does not
    change)."""
    if variant not in VARIANTS and variant not in REFERENCES:
        raise UnknownNameError("force-study variant", variant, [*VARIANTS, *REFERENCES])
    policy = policy or ConstraintAwarePolicy.load()
    spec = RunSpec(
        cond.task, "policy", cond.offset_deg, seed=seed, randomize=cond.randomize,
        sensor_noise=sensor_noise, overrides=cond.overrides,
    )  # fmt: skip
    threshold = deadband.threshold_from_noise(sensor_noise)
    prep = prepare_condition(cond, spec, threshold, SETTLED_PERIOD if settled else None)
    sim, cfg, normal, d0, rate = prep.sim, prep.config, prep.normal, prep.d0, prep.rotation_rate
    if variant == PROBED:
        if settled:
            raise ValueError(f"{PROBED!r} runs at the robot's own control period only")
        cfg = probed_config(spec, cfg)
    radius = cfg.rotation_radius if rate is not None else None
    path_turn = math.degrees(cfg.step_length / radius) if radius else 0.0
    ctrl: DirectionController
    if variant in REFERENCES:
        hand = make_controller("policy", policy, rate, normal)
        ctrl = GroundTruthDirection(sim.admissible_direction, hand, REFERENCES[variant])
    elif settled and variant == "classical":
        gamma_t = ClassicalGains().gamma_t * CONTROL_PERIOD / SETTLED_PERIOD
        ctrl = make_controller("classical", policy, rate, normal, {"gamma_t": gamma_t})
    else:
        ctrl = VARIANTS[variant](policy, rate, normal)
    record = Executor(sim, ctrl, cfg, monitor=sim).run(d0, {"task": cond.task})
    stiffness, _ = reported_stiffness(sim)  # as the executor takes it
    if cfg.robot.stiffness is not None:  # measured by the probe
        stiffness = cfg.robot.stiffness
    step_force = None if stiffness is None else stiffness * cfg.step_length
    label = variant + SETTLED_SUFFIX if settled else variant
    return diagnose(record, cond, label, seed, normal, path_turn, step_force)


#: every label a run can carry, in the order tables list them
LABELS = (
    *VARIANTS,
    *REFERENCES,
    *(v + SETTLED_SUFFIX for v in VARIANTS),
    *(v + SETTLED_SUFFIX for v in REFERENCES),
)


@dataclass(frozen=True)
class VariantSummary:
    """One (experiment axis, level, task, variant) cell: medians and means over its runs."""

    axis: str
    level: float
    task: str
    variant: str
    n: int
    successes: int
    outcomes: dict[str, int]
    median_peak_force_N: float
    mean_force_N: float  # mean over runs of each run's mean |F|
    transient_mean_force_N: float
    steady_mean_force_N: float
    steady_along_force_N: float
    steady_lag_deg: float
    steady_error_deg: float
    turn_rms_deg: float
    median_peak_step: float
    median_slip_deg: float
    path_turn_deg: float
    # the main corrections of runs that began >= 2 deg off (medians; nan if none):
    median_correction_error_deg: float  # the error its reading saw
    median_correction_turn_share: float  # the turn toward the truth over that error
    median_correction_reading_share: float  # the reading's across force over k delta sin(error)
    median_correction_turn_per_N: float  # [deg/N] the turn toward the truth over that force
    median_first_along_N: float  # the first reading's F.d (step 1, from rest)
    median_first_across_N: float  # the first reading's |F| across d


def _nanmean(values: Iterable[float]) -> float:
    v = [x for x in values if math.isfinite(x)]
    return float(np.mean(v)) if v else math.nan


def _nanmedian(values: Iterable[float]) -> float:
    v = [x for x in values if math.isfinite(x)]
    return float(np.median(v)) if v else math.nan


def summarize(runs: Iterable[RunDiagnosis], aggregate_levels: bool = False) -> list[VariantSummary]:
    """One summary per (axis, level, task, variant), sorted by those keys (never by the order
    the runs came in); aggregate_levels: one cell per (axis, task, variant), level 0."""

    def cell_of(r: RunDiagnosis) -> CellKey:
        level = 0.0 if aggregate_levels else r.condition.level
        return (r.condition.axis, level, r.condition.task, r.variant)

    out = []
    for cell, rows in group_cells(runs, cell_of, LABELS):
        outcomes: dict[str, int] = {}
        for r in rows:
            outcomes[r.outcome] = outcomes.get(r.outcome, 0) + 1
        big = [r for r in rows if abs(r.condition.offset_deg) >= CORRECTION_MIN_OFFSET_DEG]
        out.append(
            VariantSummary(
                axis=cell[0],
                level=cell[1],
                task=cell[2],
                variant=cell[3],
                n=len(rows),
                successes=sum(r.success for r in rows),
                outcomes=dict(sorted(outcomes.items())),
                median_peak_force_N=float(np.median([r.peak_force_N for r in rows])),
                mean_force_N=float(np.mean([r.mean_force_N for r in rows])),
                transient_mean_force_N=_nanmean(r.transient_mean_force_N for r in rows),
                steady_mean_force_N=_nanmean(r.steady_mean_force_N for r in rows),
                steady_along_force_N=_nanmean(r.steady_along_force_N for r in rows),
                steady_lag_deg=_nanmean(r.steady_lag_deg for r in rows),
                steady_error_deg=_nanmedian(r.steady_error_deg for r in rows),
                turn_rms_deg=_nanmean(r.turn_rms_deg for r in rows),
                median_peak_step=float(np.median([r.peak_step for r in rows])),
                median_slip_deg=_nanmedian(r.median_slip_deg for r in rows),
                path_turn_deg=rows[0].path_turn_deg,
                median_correction_error_deg=_nanmedian(r.correction_error_deg for r in big),
                median_correction_turn_share=_nanmedian(
                    r.correction_turn_deg / r.correction_error_deg for r in big
                ),
                median_correction_reading_share=_nanmedian(r.correction_reading_share for r in big),
                median_correction_turn_per_N=_nanmedian(
                    r.correction_turn_deg / r.correction_across_N
                    for r in big
                    if r.correction_across_N > 0
                ),
                median_first_along_N=_nanmedian(r.first_along_N for r in rows),
                median_first_across_N=_nanmedian(r.first_across_N for r in rows),
            )
        )
    return out


def summary_from_dict(data: dict[str, object]) -> VariantSummary:
    """A `VariantSummary` back from its JSON form (dataclasses.asdict)."""
    return VariantSummary(**data)  # type: ignore[arg-type]


#: bootstrap resamples of a paired difference's confidence interval
BOOTSTRAP_RESAMPLES = 10_000


@dataclass(frozen=True)
class PairedDifference:
    """One (axis, task) cell: `variant` minus `baseline`, run by run on the same condition and
    seed, in each run's mean |F| [N]. ci_*: the 95 % bootstrap interval of the mean
    difference (percentiles, `BOOTSTRAP_RESAMPLES` resamples of the pairs, a fixed seed)."""

    axis: str
    task: str
    variant: str
    baseline: str
    n: int
    mean_difference_N: float
    median_difference_N: float
    ci_low_N: float
    ci_high_N: float
    variant_lower: int  # pairs where the variant's run mean is below the baseline's
    differences_N: tuple[float, ...] = ()  # each pair's difference, in the pairs' sorted order


def paired_from_dict(data: dict[str, Any]) -> PairedDifference:
    """A `PairedDifference` back from its JSON form (dataclasses.asdict)."""
    return PairedDifference(**{**data, "differences_N": tuple(data.get("differences_N", ()))})


def plot_paired_differences(pairs: Iterable[PairedDifference], path: str | Path) -> Path:
    """One row per cell: every pair's difference [N] (grey dots), the mean with its 95 %
    interval (blue: below 0, red: above, purple: either), and zero (at or below the
    baseline). Returns the written path."""
    pairs = list(pairs)
    fig = new_figure(figsize=(9.0, 0.42 * len(pairs) + 1.4))
    ax = fig.add_subplot(1, 1, 1)
    jitter = np.random.default_rng(0)  # fixed: the same figure from the same results
    for row, p in enumerate(pairs):
        y = len(pairs) - 1 - row
        diffs = np.asarray(p.differences_N, dtype=float)
        ax.scatter(diffs, y + jitter.uniform(-0.15, 0.15, diffs.size), s=9, alpha=0.5, c="gray")
        if p.ci_high_N < 0:
            color = "tab:blue"
        elif p.ci_low_N > 0:
            color = "tab:red"
        else:
            color = "tab:purple"
        xerr = [[p.mean_difference_N - p.ci_low_N], [p.ci_high_N - p.mean_difference_N]]
        ax.errorbar(p.mean_difference_N, y, xerr=xerr, fmt="o", color=color, capsize=3)
    ax.axvline(0.0, color="black", lw=0.8)
    ax.set_yticks(range(len(pairs)))
    several = len({p.variant.removesuffix(SETTLED_SUFFIX) for p in pairs}) > 1
    labels = [  # the compared variant named when the figure holds more than one
        (f"{p.variant.removesuffix(SETTLED_SUFFIX)}:\n" if several else "")
        + f"{p.axis}: {p.task}"
        + (SETTLED_SUFFIX if p.variant.endswith(SETTLED_SUFFIX) else "")
        for p in reversed(pairs)
    ]
    ax.set_yticklabels(labels, fontsize=7)
    names = sorted({(p.variant, p.baseline) for p in pairs if p.variant in VARIANTS})
    names = names or sorted({(p.variant, p.baseline) for p in pairs})
    title = "; ".join(f"{a} minus {b}" for a, b in names)
    ax.set_title(f"Run by run, {title}: mean and 95 % interval", fontsize=9)
    ax.set_xlabel("difference of the runs' mean |F| [N] (below 0: the first is lower)")
    return save_figure(fig, path)


def paired_differences(
    runs: Iterable[RunDiagnosis], variant: str, baseline: str, seed: int = 0
) -> list[PairedDifference]:
    """Each (axis, task) cell's paired comparison of `variant` against `baseline`, sorted by
    (axis, task). Runs pair on their whole condition (levels, offsets, overrides, ...) and
    seed; a run without a partner, or a pair with a non-finite mean, is left out. Each cell
    resamples with its own generator, seeded from `seed` and the cell, so its interval depends
    neither on the order of the runs nor on the other cells. Raises ValueError on two runs of
    one label on the same condition and seed."""
    by: dict[tuple[str, str], dict[str, dict[str, float]]] = {}
    for r in runs:
        if r.variant not in (variant, baseline):
            continue
        c = r.condition
        pair = by.setdefault((c.axis, c.task), {}).setdefault(repr((c, r.seed)), {})
        if r.variant in pair:
            raise ValueError(f"two {r.variant!r} runs on {c} with seed {r.seed}")
        pair[r.variant] = r.mean_force_N
    out = []
    for (axis, task), pairs in sorted(by.items()):
        ordered = (pairs[k] for k in sorted(pairs))  # not the order the runs came in
        diff = np.array([p[variant] - p[baseline] for p in ordered if len(p) == 2])
        diff = diff[np.isfinite(diff)]
        if diff.size == 0:
            continue
        cell = zlib.crc32(f"{axis}|{task}|{variant}|{baseline}".encode())
        rng = np.random.default_rng([seed, cell])
        means = diff[rng.integers(0, diff.size, (BOOTSTRAP_RESAMPLES, diff.size))].mean(axis=1)
        low, high = np.percentile(means, [2.5, 97.5])
        out.append(
            PairedDifference(
                axis=axis,
                task=task,
                variant=variant,
                baseline=baseline,
                n=int(diff.size),
                mean_difference_N=float(diff.mean()),
                median_difference_N=float(np.median(diff)),
                ci_low_N=float(low),
                ci_high_N=float(high),
                variant_lower=int((diff < 0).sum()),
                differences_N=tuple(float(x) for x in diff),
            )
        )
    return out


def table_lines(cells: list[VariantSummary], variants: Iterable[str]) -> list[str]:
    """A markdown table: one row per (axis, level, task), a column per variant with
    "successes/n, median peak |F|, mean |F|"."""
    variants = list(variants)
    rows: dict[tuple[str, float, str], dict[str, VariantSummary]] = {}
    for c in cells:
        rows.setdefault((c.axis, c.level, c.task), {})[c.variant] = c
    lines = [
        "| axis | level | task | " + " | ".join(variants) + " |",
        "|---|---|---|" + "---|" * len(variants),
    ]
    for (axis, level, task), by in rows.items():
        cols = []
        for v in variants:
            cell = by.get(v)
            cols.append(
                "" if cell is None else
                f"{cell.successes}/{cell.n}, {cell.median_peak_force_N:.2f}, "
                f"{cell.mean_force_N:.2f}"
            )  # fmt: skip
        lines.append(f"| {axis} | {level:g} | {task} | " + " | ".join(cols) + " |")
    return lines


#: The probe's forces [N]: along -d (the object's resistance) and across d (the constraint
#: force of a misaligned move), the scale of the door's and drawer's steady forces.
PROBE_ALONG_N = (0.0, -0.5, -1.0, -2.0)
PROBE_ACROSS_N = (0.0, 0.2, 0.5, 1.0, 1.5, 2.0, 3.0, 5.0, 8.0)


@dataclass(frozen=True)
class TurnProbe:
    """The policy's one-step turn [deg] of d for F = along * d + across * (n x d)."""

    along_N: float
    across_N: float
    turn_deg: float
    implied_error_deg: float  # asin(across / step_force): the error a quasi-static blocked
    # step would need to produce that force across d
    mirrored_turn_deg: float  # the same with the mirror-averaged action (controller "policy")


def probe_turns(
    policy: ConstraintAwarePolicy, step_force: float = 20.0, threshold: float = 0.4
) -> list[TurnProbe]:
    """One update_direction per force from a fresh session (d = x, workplane normal z)."""
    d = np.array([1.0, 0.0, 0.0])
    normal = np.array([0.0, 0.0, 1.0])

    def turn(force: FloatArray, mirror: bool) -> float:
        nxt = policy.session().update_direction(
            force,
            d,
            threshold=threshold,
            step_force=step_force,
            workplane_normal=normal if mirror else None,
        )
        return _signed_deg(d, nxt, normal)

    out = []
    for along in PROBE_ALONG_N:
        for across in PROBE_ACROSS_N:
            force = np.array([along, across, 0.0])
            out.append(
                TurnProbe(
                    along,
                    across,
                    turn(force, False),
                    math.degrees(math.asin(min(1.0, across / step_force))),
                    turn(force, True),
                )
            )
    return out
