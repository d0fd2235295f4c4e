"""The bench's policy section: default, default (raw), paper, classical, projection.

Typed from end to end: experiments produce `RunResult`s, `summarize` groups them by their own
keys (never by the order runs were generated) into `CellSummary`s, and the report reads those.

Every controller runs with the same dead band, derived from the simulated sensor's noise
(`deadband.threshold_from_noise`), not the executor's hand-set 3 N.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np

from constraint_aware import deadband
from constraint_aware.bench.sweep import PAPER_OFFSETS, map_in_order, suite_specs
from constraint_aware.control.controllers import make_controller
from constraint_aware.control.executor import Executor, ExecutorConfig
from constraint_aware.control.simulate import (
    NoisySensorSim,
    RunSpec,
    build_task,
    controller_geometry,
    executor_config,
    probed_config,
)
from constraint_aware.geometry import FloatArray, rotate_about
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.tasks import TASKS, task_config
from constraint_aware.spatial import Wrench

#: The section's controllers: label -> (executor controller name, shipped policy name or None).
POLICY_SECTION_CONTROLLERS: dict[str, tuple[str, str | None]] = {
    # the default policy as the library runs it (controller "policy": inside SteadyDirection)
    "default": ("policy", "default"),
    # the same after a setup probe on a twin of the task (`cap run --probe`): the arm stiffness
    # the wrist sees and the grasp's play (PROBED_LABELS)
    "default + probe": ("policy", "default"),
    # the same policy alone, and the paper's as published: the paper's rule d + pi(s)
    "default (raw)": ("policy-raw", "default"),
    "paper": ("policy-raw", "paper"),
    "classical": ("classical", None),
    "projection": ("projection", None),
}
#: [m] the object has "moved" (the grasp preload released) beyond this progress.
PRELOAD_RELEASE_PROGRESS = 0.002


#: The labels whose runs probe a twin of the task at setup first and run with what it
#: measured (control.simulate.probed_config).
PROBED_LABELS = ("default + probe",)


@dataclass(frozen=True)
class Condition:
    """One cell of an experiment: a task at an offset with parameter overrides."""

    axis: str  # e.g. "joint friction x", "suite"
    level: float  # the axis value (multiplier, [m], [N/m] or [N]); seed for the suite
    task: str
    offset_deg: float
    overrides: tuple[tuple[str, object], ...] = ()
    randomize: bool = False
    preload_N: float = 0.0  # grasp preload in F_d that vanishes once the object moves


@dataclass(frozen=True)
class RunResult:
    condition: Condition
    controller: str  # a POLICY_SECTION_CONTROLLERS label
    seed: int
    threshold_N: float
    success: bool
    outcome: str
    peak_force_N: float
    mean_force_N: float
    final_angle_deg: float


@dataclass(frozen=True)
class CellSummary:
    axis: str
    level: float
    task: str
    controller: str
    n: int
    successes: int
    median_peak_force_N: float
    mean_force_N: float  # mean over runs of each run's mean |F|
    median_final_angle_deg: float


class PreloadSim(NoisySensorSim):
    """The simulated robot with a grasp preload along the motion in the wrench reading that
    vanishes once the object has moved (so F_d keeps it and F = F_s - F_d shows -preload)."""

    def __init__(self, *args: Any, preload: np.ndarray, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.preload = preload

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        if self.progress() > PRELOAD_RELEASE_PROGRESS:
            return w
        return Wrench(force=w.force + self.preload, torque=w.torque)


@dataclass
class PreparedRun:
    """A condition's simulator, reset, with the executor config and the run's inputs.

    d0: (3,) the initial direction, the admissible one turned by the condition's offset;
    normal, rotation_rate: the controllers' geometry (`control.simulate.controller_geometry`:
    the normal oriented from the hinge, w_d = v / r on revolute joints, else None)."""

    sim: NoisySensorSim
    config: ExecutorConfig
    normal: FloatArray
    d0: FloatArray
    rotation_rate: float | None


def prepare_condition(
    cond: Condition, spec: RunSpec, threshold: float, control_period: float | None = None
) -> PreparedRun:
    """The shared set-up of one policy-section run (and of the force study's): the task from
    `spec`, the preload robot when `cond.preload_N` > 0, the dead band `threshold` [N];
    control_period [s]: the robot's period when not None (the force study's settled hand)."""
    task = build_task(spec)
    rng = np.random.default_rng(spec.seed + 7919)
    sensor_noise = spec.sensor_noise
    if cond.preload_N > 0:
        sim: NoisySensorSim = PreloadSim(task, rng, sensor_noise, preload=np.zeros(3))
    else:
        sim = NoisySensorSim(task, rng, sensor_noise)
    if control_period is not None:
        sim.control_period_s = control_period  # validated: whole simulation substeps
    sim.reset()
    cfg = dataclasses.replace(executor_config(task), threshold=threshold)
    assert cfg.workplane_normal is not None
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    u = sim.admissible_direction()
    if isinstance(sim, PreloadSim):
        sim.preload = cond.preload_N * u
    d0 = rotate_about(u, normal, math.radians(spec.offset_deg))
    normal, rate = controller_geometry(cfg, sim, d0)
    return PreparedRun(sim, cfg, normal, d0, rate)


@functools.cache
def _shipped_policy(name: str) -> ConstraintAwarePolicy:
    """A shipped policy by name, loaded once per process: runs only read a policy (each
    controller keeps its own session)."""
    return ConstraintAwarePolicy.load(name)


def run_condition(
    cond: Condition,
    controller: str,
    seed: int,
    threshold: float,
    sensor_noise: float = 0.1,
    policy: ConstraintAwarePolicy | None = None,
    policy_controller: str = "policy",
) -> RunResult:
    """One closed-loop run of `controller` on `cond` (the simulate.run steps, with the preload
    robot when `cond.preload_N` > 0). `controller` is a POLICY_SECTION_CONTROLLERS label, or
    any label when `policy` is given: then `policy_controller` ("policy" or "policy-raw")
    with that policy."""
    if policy is not None:
        name, policy_name = policy_controller, None
    else:
        name, policy_name = POLICY_SECTION_CONTROLLERS[controller]
    spec = RunSpec(
        cond.task,
        name,
        cond.offset_deg,
        seed=seed,
        randomize=cond.randomize,
        sensor_noise=sensor_noise,
        overrides=cond.overrides,
    )
    if policy_name is not None:
        policy = _shipped_policy(policy_name)
    prep = prepare_condition(cond, spec, threshold)
    sim, cfg, normal, d0, rate = prep.sim, prep.config, prep.normal, prep.d0, prep.rotation_rate
    if controller in PROBED_LABELS:
        cfg = probed_config(spec, cfg)
    ctrl = make_controller(name, policy, rate, normal)
    record = Executor(sim, ctrl, cfg, monitor=sim).run(d0, {"task": cond.task})
    return RunResult(
        condition=cond,
        controller=controller,
        seed=seed,
        threshold_N=threshold,
        success=record.success,
        outcome=record.outcome,
        peak_force_N=float(record.peak_force),
        mean_force_N=float(record.mean_force),
        final_angle_deg=float(record.final_angle),
    )


def run_all(
    conditions: Sequence[Condition],
    seeds: Iterable[int],
    controllers: Sequence[str] = tuple(POLICY_SECTION_CONTROLLERS),
    sensor_noise: float = 0.1,
    policies: dict[str, ConstraintAwarePolicy] | None = None,
    threshold: float | None = None,
    policy_controller: str = "policy",
) -> list[RunResult]:
    """Every condition x seed x controller (labels; `policies` adds policy objects by label,
    run by `policy_controller`), with the dead band derived from the noise unless
    `threshold` [N] is given."""
    thr = deadband.threshold_from_noise(sensor_noise) if threshold is None else threshold
    policies = policies or {}
    labels = list(controllers) + [k for k in policies if k not in controllers]
    seeds = list(seeds)
    jobs = [
        (c, ctrl, s, thr, sensor_noise, policies.get(ctrl), policy_controller)
        for c in conditions
        for s in seeds
        for ctrl in labels
    ]
    return map_in_order(_run_condition_job, jobs, label="policy section")


def _run_condition_job(
    args: tuple[Condition, str, int, float, float, ConstraintAwarePolicy | None, str],
) -> RunResult:
    """`run_condition` on one job of `run_all` (a sweep's worker calls it)."""
    return run_condition(*args)


def closed_loop_cases() -> list[Condition]:
    """The named resistance cases (door hinge friction 2x/4x/8x, radius 0.08 m and
    0.35 m, drawer rail friction 4 and 8 N, drawer mass 8 kg, pole friction 4 N)."""
    conds = []
    for f in (1.0, 2.0, 4.0):
        conds.append(
            Condition(
                "door hinge friction N m", f, "door-opening", 15.0, (("object__frictionloss", f),)
            )
        )
    for r in (0.08, 0.35):
        conds.append(Condition("door radius m", r, "door-opening", 15.0, (("object__radius", r),)))
    for f in (4.0, 8.0):
        for off in (30.0, -30.0):
            conds.append(
                Condition(
                    "drawer rail friction N",
                    f,
                    "drawer-opening",
                    off,
                    (("object__frictionloss", f),),
                )
            )
    conds.append(
        Condition("drawer mass kg", 8.0, "drawer-opening", -30.0, (("object__mass", 8.0),))
    )
    conds.append(
        Condition(
            "pole joint friction N", 4.0, "pole-pulling", -30.0, (("object__frictionloss", 4.0),)
        )
    )
    for p in (3.0, 6.0):
        conds.append(Condition("preload release N", p, "drawer-opening", 30.0, preload_N=p))
    return conds


class _SeededRun(Protocol):
    """What `group_cells` reads of a run (RunResult, forces.RunDiagnosis)."""

    @property
    def seed(self) -> int: ...

    @property
    def condition(self) -> Condition: ...


R = TypeVar("R", bound=_SeededRun)
#: A cell: (axis, level, task, controller or variant label).
CellKey = tuple[str, float, str, str]


def group_cells(
    runs: Iterable[R], key: Callable[[R], CellKey], labels: Sequence[str]
) -> list[tuple[CellKey, list[R]]]:
    """Runs grouped into cells by `key`, in a fixed order: axis, task, level, then the label's
    place in `labels` (others last); inside a cell by seed, offset and condition, so that
    float sums never depend on the order the runs were generated in."""
    groups: dict[CellKey, list[R]] = {}
    for r in runs:
        groups.setdefault(key(r), []).append(r)
    order = {name: i for i, name in enumerate(labels)}
    return [
        (k, sorted(groups[k], key=lambda r: (r.seed, r.condition.offset_deg, repr(r.condition))))
        for k in sorted(groups, key=lambda k: (k[0], k[2], k[1], order.get(k[3], 99)))
    ]


def summarize(results: Iterable[RunResult]) -> list[CellSummary]:
    """One summary per (axis, level, task, controller), sorted by those keys."""
    out = []
    for key, rows in group_cells(
        results,
        lambda r: (r.condition.axis, r.condition.level, r.condition.task, r.controller),
        tuple(POLICY_SECTION_CONTROLLERS),
    ):
        out.append(
            CellSummary(
                axis=key[0],
                level=key[1],
                task=key[2],
                controller=key[3],
                n=len(rows),
                successes=sum(r.success for r in rows),
                median_peak_force_N=float(np.median([r.peak_force_N for r in rows])),
                mean_force_N=float(np.mean([r.mean_force_N for r in rows])),
                median_final_angle_deg=float(np.nanmedian([r.final_angle_deg for r in rows]))
                if any(math.isfinite(r.final_angle_deg) for r in rows)
                else math.nan,
            )
        )
    return out


# --- the experiments ------------------------------------------------------------------------
def _preset(task: str, field: str) -> float:
    return float(getattr(task_config(task).object, field))


def resistance_map(quick: bool = False) -> list[Condition]:
    """The resistance map: joint dry friction 0.25x-8x preset, damping up to 8x, mass
    0.5x-8x, door radius 0.06-0.8 m, wrist stiffness 500-8000 N/m, a released grasp preload;
    every task at its paper offset (both signs for the drawer)."""
    conds: list[Condition] = []

    def add(
        axis: str, level: float, task: str, over: tuple[tuple[str, object], ...], **kw: Any
    ) -> None:
        for off in PAPER_OFFSETS[task]:
            conds.append(Condition(axis, level, task, off, over, **kw))

    if quick:
        add("joint friction x", 8.0, "door-opening", (("object__frictionloss", 4.0),))
        return conds
    for task in TASKS:
        for x in (0.25, 1.0, 2.0, 4.0, 8.0):
            add(
                "joint friction x",
                x,
                task,
                (("object__frictionloss", x * _preset(task, "frictionloss")),),
            )
        for x in (4.0, 8.0):
            add("joint damping x", x, task, (("object__damping", x * _preset(task, "damping")),))
        for x in (0.5, 2.0, 8.0):
            add("object mass x", x, task, (("object__mass", x * _preset(task, "mass")),))
        for k in (500.0, 8000.0):
            add("wrist stiffness", k, task, (("hand__translational_stiffness", k),))
        for p in (3.0, 6.0):
            add("preload release", p, task, (), preload_N=p)
    for r in (0.06, 0.08, 0.2, 0.35, 0.8):
        add("hinge radius", r, "door-opening", (("object__radius", r),))
    # the named cases beyond the preset multiples
    for f in (4.0, 8.0):
        add("drawer rail friction N", f, "drawer-opening", (("object__frictionloss", f),))
    add("drawer mass kg", 8.0, "drawer-opening", (("object__mass", 8.0),))
    add("pole joint friction N", 4.0, "pole-pulling", (("object__frictionloss", 4.0),))
    return conds


def suite_conditions(n_seeds: int) -> list[tuple[Condition, int]]:
    """The randomized suite (bench.sweep.suite_specs): one condition per task and seed."""
    out = []
    for spec in suite_specs(n_seeds, ("classical",)):
        cond = Condition("suite", 0.0, spec.task, spec.offset_deg, randomize=True)
        out.append((cond, spec.seed))
    return out


def paper_offset_conditions(quick: bool = False) -> list[Condition]:
    """Every task at the paper's offsets (quick: the drawer at +30 deg and the door)."""
    if quick:
        return [
            Condition("paper offsets", 30.0, "drawer-opening", 30.0),
            Condition("paper offsets", 15.0, "door-opening", 15.0),
        ]
    return [Condition("paper offsets", off, t, off) for t in TASKS for off in PAPER_OFFSETS[t]]


@dataclass(frozen=True)
class PolicySection:
    """Everything the report's policy section shows."""

    threshold_N: float
    sensor_noise_N: float
    suite: list[CellSummary]
    paper_offsets: list[CellSummary]
    resistance: list[CellSummary]

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PolicySection:
        def cells(rows: list[dict[str, Any]]) -> list[CellSummary]:
            return [CellSummary(**r) for r in rows]

        return cls(
            threshold_N=data["threshold_N"],
            sensor_noise_N=data["sensor_noise_N"],
            suite=cells(data["suite"]),
            paper_offsets=cells(data["paper_offsets"]),
            resistance=cells(data["resistance"]),
        )


def policy_section(
    quick: bool = False, suite_seeds: int = 20, sensor_noise: float = 0.1, map_seeds: int = 2
) -> PolicySection:
    """Run the section: the randomized suite (aggregated per task), the paper's offsets and the
    resistance map. Quick: no suite, the drawer and door at a paper offset, the 8x door."""
    threshold = deadband.threshold_from_noise(sensor_noise)
    suite_jobs = [
        (cond, ctrl, seed, threshold, sensor_noise, None, "policy")
        for cond, seed in suite_conditions(0 if quick else suite_seeds)
        for ctrl in POLICY_SECTION_CONTROLLERS
    ]
    suite_runs = map_in_order(_run_condition_job, suite_jobs, label="policy section suite")
    paper = run_all(paper_offset_conditions(quick), [0], sensor_noise=sensor_noise)
    res = run_all(
        resistance_map(quick), range(1 if quick else map_seeds), sensor_noise=sensor_noise
    )
    # the paper offsets aggregate over both drawer signs: one cell per task
    paper_cells = summarize(
        dataclasses.replace(r, condition=dataclasses.replace(r.condition, level=0.0)) for r in paper
    )
    return PolicySection(
        threshold, sensor_noise, summarize(suite_runs), paper_cells, summarize(res)
    )
