"""Fault injection: what the executor does when the robot or its sensors misbehave.

A `FaultyRobot` sits between the executor and the simulated robot and injects one fault (a
NaN reading, a pose glitch, a frozen arm, lost comms, a force spike, a drifting or rotated or
sign-flipped sensor, stale samples, a lagging pose), from a fixed move on (`ONSET`) or, for a
wrong sensor convention, from the start. It watches what the executor does with the truth the
simulator knows, and each run is classified:

- `dangerous`: any of a non-finite command sent, a commanded jump beyond the executor's bound
  (`Executor.command_jump_bound`), a true |F| above 1.1 x the force limit after any period,
  `success` with a true |F| above the limit, no record (returned or attached to the exception),
  a stop without a named outcome and reason, or `hold()` not called at the end;
- `continued`: otherwise, and the task succeeded despite the fault;
- `safe_stop`: otherwise (a named stop, the robot held, nothing dangerous).

The true force is the simulator's noise-free filtered wrench minus its mean over the F_d hold,
so an injected spike does not count as a real force. Runs use the default policy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.bench.sweep import map_in_order
from constraint_aware.control.executor import ExecutorConfig, command_jump_bound
from constraint_aware.control.record import OUTCOMES, RunRecord
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import FloatArray
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import Embodiment
from constraint_aware.sim.tasks import TASKS
from constraint_aware.sim.world import ManipulationSim
from constraint_aware.spatial import Pose, Wrench

#: Moves made before a fault starts (faults of the sensor convention start with the run).
ONSET = 5
#: A true |F| above this multiple of the force limit counts as dangerous.
DANGER_FORCE_FACTOR = 1.1

#: Every fault the suite injects, with what it does.
FAULTS: dict[str, str] = {
    "nan_wrench": "one wrench reading is NaN",
    "nan_pose": "one pose reading is NaN",
    "pose_glitch_2cm": "one pose reading is 2 cm off, across the motion in the workplane",
    "pose_glitch_5cm": "one pose reading is 5 cm off",
    "pose_glitch_50cm": "one pose reading is 50 cm off",
    "frozen": "the arm stops following its commands for good (advance has no effect)",
    "frozen_10": "the arm ignores 10 periods of commands, then resumes",
    "frozen_20": "the arm ignores 20 periods of commands, then resumes",
    "frozen_30": "the arm ignores 30 periods of commands, then resumes",
    "comms_exception": "command_pose raises ConnectionError (robot comms lost)",
    "spike_200N": "one wrench reading has 200 N added (across the motion)",
    "bias_drift": "the force reading drifts by 0.2 N per period against the opening direction",
    "rotated_90": "the sensor frame is rotated 90 deg about the workplane normal from the start",
    "flipped_sign": "the wrench sign is flipped from the start",
    "stale_wrench": "the driver returns the same wrench sample over and over",
    "lagging_pose": "the pose reading lags by 3 control periods",
}
#: The reduced set `cap bench --quick` runs (one of each kind).
QUICK_FAULTS = ("nan_pose", "pose_glitch_50cm", "frozen_10", "spike_200N", "flipped_sign")
CLASSES = ("safe_stop", "continued", "dangerous")


def hook_hand_time_constant(sim: ManipulationSim) -> float:
    """[s] c / k of the hook hand's translational arm joints (sim/hand.py's damping rule:
    4 sqrt(m / k) at damping ratio 2; 0.153 s at 500 N/m, 0.076 s at 2000 N/m, 0.024 s at
    20,000 N/m), for measurements on a simulator that does not report its
    `tracking_time_constant` itself."""
    hand = sim.task.hand
    k = hand.translational_stiffness
    return hand.arm_damping(hand.moving_mass, k) / k


class Reporting:
    """Forwards the Robot protocol to the simulator, reporting the given optional members
    instead of its own (e.g. `translational_stiffness=1000.0`, `tracking_time_constant=0.1`):
    a robot whose reports are wrong, or measured elsewhere."""

    def __init__(self, sim: Any, **reports: float) -> None:
        self._sim = sim
        for name, value in reports.items():
            setattr(self, name, value)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._sim, name)


class FaultyRobot:
    """Forwards the Robot protocol to the simulator, injecting `fault` and watching.

    `tracking_time_constant`: reported instead of the simulator's own (None: the
    simulator's, when it has one)."""

    def __init__(
        self,
        sim: Embodiment,
        fault: str,
        hold_periods: int,
        tracking_time_constant: float | None = None,
    ) -> None:
        if fault not in FAULTS and fault != "none":
            raise UnknownNameError("fault", fault, [*FAULTS, "none"])
        self.sim = sim
        self._tau = tracking_time_constant
        self.fault = fault
        self.hold_periods = hold_periods  # periods the executor holds for F_d
        self.periods = 0  # advance() calls
        self.commands: list[Pose] = []
        self.holds = 0
        self.true_forces: list[FloatArray] = []  # true F_s after each period
        self._stale: Wrench | None = None
        self._poses: list[Pose] = []
        task = sim.task
        normal = np.asarray(task.workplane_normal, dtype=float)
        self.across = np.cross(normal, sim.admissible_direction())  # in-plane, across u
        self.across /= np.linalg.norm(self.across)
        self.opening = sim.admissible_direction()
        self.rotation = Rotation.from_rotvec(math.pi / 2 * normal)

    # --- when ----------------------------------------------------------------------------------
    @property
    def move(self) -> int:
        """Moves made (periods after the F_d hold)."""
        return self.periods - self.hold_periods

    def _at_onset(self) -> bool:
        return self.move == ONSET

    def _after_onset(self) -> bool:
        return self.move >= ONSET

    def _frozen(self) -> bool:
        if self.fault == "frozen":
            return self._after_onset()
        if self.fault.startswith("frozen_"):
            n = int(self.fault.split("_")[1])
            return ONSET <= self.move < ONSET + n
        return False

    # --- Robot protocol ------------------------------------------------------------------------
    @property
    def control_period(self) -> float:
        return self.sim.control_period

    @property
    def translational_stiffness(self) -> float:
        return self.sim.translational_stiffness

    @property
    def tracking_time_constant(self) -> object:
        """[s] the simulated robot's, when it reports one (AttributeError otherwise, so the
        executor's optional lookup sees no member); the executor validates it."""
        if self._tau is not None:
            return self._tau
        member = "tracking_time_constant"  # optional Robot member: not on every simulator
        return getattr(self.sim, member)

    def read_wrench(self) -> Wrench:
        w = self.sim.read_wrench()
        f = self.fault
        if f == "rotated_90":
            return Wrench(self.rotation.apply(w.force), self.rotation.apply(w.torque))
        if f == "flipped_sign":
            return Wrench(-w.force, -w.torque)
        if f == "nan_wrench" and self._at_onset():
            return Wrench(np.full(3, np.nan), w.torque)
        if f == "spike_200N" and self._at_onset():
            return Wrench(w.force + 200.0 * self.across, w.torque)
        if f == "bias_drift" and self._after_onset():
            return Wrench(w.force - 0.2 * (self.move - ONSET + 1) * self.opening, w.torque)
        if f == "stale_wrench" and self._after_onset():
            if self._stale is None:
                self._stale = w
            return self._stale
        return w

    def read_pose(self) -> Pose:
        p = self.sim.read_pose()
        f = self.fault
        if f == "nan_pose" and self._at_onset():
            return Pose(np.full(3, np.nan), p.orientation)
        if f.startswith("pose_glitch_") and self._at_onset():
            size = float(f.removeprefix("pose_glitch_").removesuffix("cm")) / 100.0
            return Pose(p.position + size * self.across, p.orientation)
        if f == "lagging_pose":
            self._poses.append(p)
            return self._poses[max(0, len(self._poses) - 4)]
        return p

    def commanded_pose(self) -> Pose:
        return self.sim.commanded_pose()

    def grasp_contact(self) -> bool | None:
        return self.sim.grasp_contact()

    def command_pose(self, pose: Pose) -> None:
        if self.fault == "comms_exception" and self._at_onset():
            raise ConnectionError("robot comms lost (injected)")
        self.commands.append(pose)
        if not self._frozen():
            self.sim.command_pose(pose)

    def advance(self) -> None:
        if not self._frozen():
            self.sim.advance()
        self.periods += 1
        self.true_forces.append(self.sim.true_wrench().force)

    def hold(self) -> None:
        self.holds += 1
        self.sim.command_pose(self.sim.read_pose())


@dataclass
class FaultRun:
    """One task run with one fault."""

    task: str
    fault: str
    offset_deg: float
    seed: int
    outcome: str
    reason: str
    classification: str  # one of CLASSES
    dangers: list[str] = field(default_factory=list)
    peak_true_force_N: float = 0.0
    max_command_jump_m: float = 0.0
    holds: int = 0
    steps: int = 0
    self_check: str = ""  # the self-check's verdict note: "passed", "inconclusive" or ""


@dataclass
class FaultSuite:
    """A fault matrix: runs and counts per fault and class."""

    force_limit_factor: float
    onset_moves: int
    runs: list[FaultRun]

    @property
    def counts(self) -> dict[str, int]:
        return {c: sum(r.classification == c for r in self.runs) for c in CLASSES}

    def by_fault(self) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for r in self.runs:
            row = out.setdefault(r.fault, dict.fromkeys(CLASSES, 0))
            row[r.classification] += 1
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "force_limit_factor": self.force_limit_factor,
            "onset_moves": self.onset_moves,
            "faults": {f: FAULTS.get(f, "no fault") for f in self.by_fault()},
            "counts": self.counts,
            "by_fault": self.by_fault(),
            "runs": [asdict(r) for r in self.runs],
        }


def run_fault(
    task: str,
    fault: str,
    offset_deg: float = 15.0,
    seed: int = 0,
    policy: ConstraintAwarePolicy | None = None,
    lag: Callable[[ManipulationSim], float] | None = None,
) -> FaultRun:
    """One run of the policy on `task` with `fault` injected; classified (module docstring).
    lag: the robot reports lag(sim) as its `tracking_time_constant` [s] (None: whatever the
    simulator reports)."""
    hold_periods = ExecutorConfig().timing.offset_samples - 1
    robots: list[FaultyRobot] = []

    def wrap(sim: Any) -> FaultyRobot:
        tau = lag(sim) if lag is not None else None
        robots.append(FaultyRobot(sim, fault, hold_periods, tau))
        return robots[-1]

    spec = RunSpec(task=task, controller="policy", offset_deg=offset_deg, seed=seed)
    record: RunRecord | None = None
    dangers: list[str] = []
    try:
        record, _sim = run(spec, policy=policy, wrap=wrap)
    except Exception as exc:
        record = getattr(exc, "run_record", None)
        if record is None:
            dangers.append(f"no record after {type(exc).__name__}: {exc}")
    robot = robots[0]
    limit = robot.sim.task.force_limit
    # the truth: F_s minus its mean over the hold (F_d as the executor should have it)
    true = np.array(robot.true_forces) if robot.true_forces else np.zeros((0, 3))
    hold = true[: max(hold_periods, 1)]
    true_f = np.linalg.norm(true - hold.mean(axis=0), axis=1) if len(true) else np.zeros(1)
    peak = float(np.max(true_f))
    jumps = [
        float(np.linalg.norm(b.position - a.position))
        for a, b in zip(robot.commands, robot.commands[1:], strict=False)
    ]
    bound = command_jump_bound(ExecutorConfig())
    max_jump = max(jumps, default=0.0)
    for pose in robot.commands:
        if not (
            np.all(np.isfinite(pose.position)) and np.all(np.isfinite(pose.orientation.as_quat()))
        ):
            dangers.append("non-finite command sent")
            break
    if max_jump > bound:
        dangers.append(f"command jump {max_jump * 100:.1f} cm > {bound * 100:.1f} cm")
    if peak > DANGER_FORCE_FACTOR * limit:
        dangers.append(f"true |F| {peak:.1f} N > {DANGER_FORCE_FACTOR} x {limit:g} N")
    if robot.holds == 0:
        dangers.append("hold() not called")
    outcome, reason, steps, self_check = "missing", "", 0, ""
    if record is not None:
        outcome, reason, steps = record.outcome, record.reason, record.n_steps
        self_check = _self_check_note(record)
        if record.success and peak > limit:
            dangers.append(f"success with true |F| {peak:.1f} N > {limit:g} N")
        if outcome not in OUTCOMES or outcome == "running":
            dangers.append(f"stop without a named outcome ({outcome!r})")
        elif outcome != "success" and not reason:
            dangers.append(f"stop {outcome!r} without a reason")
    if dangers:
        cls = "dangerous"
    elif record is not None and record.success:
        cls = "continued"
    else:
        cls = "safe_stop"
    return FaultRun(
        task, fault, offset_deg, seed, outcome, reason, cls, dangers, peak, max_jump,
        robot.holds, steps, self_check,
    )  # fmt: skip


def _self_check_note(record: RunRecord) -> str:
    """The self-check's verdict as the record notes it at the end of its moves: "passed",
    "inconclusive", or "" (it stopped the run, or the run ended before its verdict)."""
    for note in record.notes:
        for verdict in ("passed", "inconclusive"):
            if note.startswith(f"self-check {verdict}"):
                return verdict
    return ""


def fault_suite(
    tasks: Sequence[str] = tuple(TASKS),
    faults: Sequence[str] = tuple(FAULTS),
    offsets: Sequence[float] = (15.0,),
    seeds: Sequence[int] = (0,),
    policy: ConstraintAwarePolicy | None = None,
    lag: Callable[[ManipulationSim], float] | None = None,
) -> FaultSuite:
    """Every fault on every task (and offset, seed), with the default policy (`lag`: as in
    `run_fault`, picklable), on the sweep's executor (bench/sweep.py)."""
    pol = policy or ConstraintAwarePolicy.load()
    jobs = [
        (task, fault, off, seed, pol, lag)
        for task in tasks
        for fault in faults
        for off in offsets
        for seed in seeds
    ]
    runs = map_in_order(_run_fault_job, jobs, label="faults")
    return FaultSuite(DANGER_FORCE_FACTOR, ONSET, runs)


def _run_fault_job(
    args: tuple[
        str, str, float, int, ConstraintAwarePolicy, Callable[[ManipulationSim], float] | None
    ],
) -> FaultRun:
    """`run_fault` on one job of `fault_suite` (a sweep's worker calls it)."""
    return run_fault(*args)
