"""The executor's guards: what stops a run, or holds the hand, before harm is done.

Each guard catches one fault between the policy and the arm, and ends the run with a named
outcome (control.record.OUTCOMES) and a reason, or holds the last target for a period:

- pose plausibility (`PoseGuard`): a pose reading that is not finite, or that jumped further
  than the commands since the last trusted pose allow, is not acted on (the hand holds);
  `pose_fault_steps` such readings in a row stop `bad_pose`. A glitch must never become a
  command.
- stale wrench (`StaleWrenchGuard`): a driver that keeps returning one cached sample blinds
  every force check; `stale_steps` identical samples stop `stale_wrench`.
- force limit (`force_limit_stop`): |F| above the object's limit stops `force_limit`, checked
  before success, so a run above the limit is never a success.
- arm force (`arm_force`, `arm_force_stop`): on an arm with a known stiffness, the deflection
  (control.lag) is a lower bound on |F|. When it says much more than the sensor, the arm is
  not following (frozen, e-stopped, clamped) or the sensor reads low: stop `not_following`;
  above the force limit: stop `force_limit`.
- lead bound (`LeadGuard`): a target running ahead of a hand that does not move would make
  the hand lunge when it resumes; beyond `max_lead` the target is held, and after
  `follow_patience` such steps the run stops `not_following`.
- predictive force (`ForcePrediction`): the next move, fully blocked, adds k l to the force;
  a move predicted past the limit is shortened, or refused (stop `force_limit`) when it would
  be shorter than `min_step_fraction` of a step.
- contact (`ContactGuard`): a hand that no longer touches the object pushes nothing; without
  contact for `lost_contact_steps` steps the run stops `contact_lost`.
- command (`direction_stop`, `step_length_stop`, `command_stop`): a controller's non-finite
  direction or out-of-range step, and a non-finite command or one that jumps beyond the
  bound, stop `bad_command`: the command is never sent.

The constants below are the rules; how each was measured, and the commands that reproduce
the measurements: docs/design/executor-guards.md.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from constraint_aware.control.executor_config import ExecutorConfig
from constraint_aware.control.lag import LagModel
from constraint_aware.geometry import FloatArray, all_finite, norm
from constraint_aware.spatial import Pose, Wrench

#: [m] without a known stiffness, the lead of the target over the measured pose beyond which
#: the robot counts as not following (5 paper steps).
DEFAULT_MAX_LEAD = 0.05
#: The re-anchoring across d (`command_from="measured"`) releases at most this many step
#: lengths per step, so a pose glitch can never turn into a larger command.
REANCHOR_LIMIT_STEPS = 2.0
#: Without a known stiffness, the force change per metre of the last moves (its maximum over
#: this many moves, times FORCE_RATE_SAFETY) predicts the next move's force.
FORCE_RATE_WINDOW = 3
FORCE_RATE_SAFETY = 1.5
#: The arm's force estimate subtracts this many step forces (k x step length) for the hand's
#: lag behind a moving target, which reads as deflection but is no force: without a reported
#: tracking_time_constant (the whole lag) ...
ARM_FORCE_LAG_STEPS = 0.75
#: ... and with one (what the lag model leaves unexplained; kept at the quasi-static value so
#: that a frozen arm is caught as fast).
ARM_FORCE_MODEL_STEPS = 0.75
#: The arm's force estimate above the sensor's |F| by more than this many step forces: the
#: arm and the sensor disagree (stop `not_following`).
ARM_FORCE_DISAGREEMENT_STEPS = 0.5
#: [m] a command shorter than this is a hold: the hand stops.
HOLD_LENGTH = 1e-4


class Stop(NamedTuple):
    """A guard's verdict: end the run with `outcome` (record.OUTCOMES) and `reason`."""

    outcome: str
    reason: str


def command_jump_bound(config: ExecutorConfig) -> float:
    """[m] the largest change of the commanded position between two steps: one step length
    plus the largest re-anchoring (REANCHOR_LIMIT_STEPS step lengths). Never exceeded."""
    return config.step_length * (1.0 + REANCHOR_LIMIT_STEPS) * (1 + 1e-9)


@dataclass
class PoseGuard:
    """Pose plausibility: finite, and no further from the last trusted pose than the change of
    the command since then plus `margin` [m]; `fault_steps` untrusted poses in a row stop."""

    margin: float  # [m]
    fault_steps: int
    trusted: Pose | None = None  # the last pose that passed
    since_trusted: float = 0.0  # [m] the command changes since that pose
    faults: int = 0  # untrusted poses in a row

    def check(self, pose: Pose) -> tuple[bool, str]:
        """Whether `pose` can be trusted (it then becomes the reference), and why not."""
        position = np.asarray(pose.position, dtype=float)
        quat = pose.orientation.as_quat()
        if not (all_finite(position) and all_finite(quat)):
            return False, "non-finite pose"
        ref = self.trusted
        if ref is not None:
            allowed = self.since_trusted + self.margin
            jump = norm(position - ref.position)
            if jump > allowed:
                return False, (
                    f"pose jumped {jump * 100:.1f} cm > commanded {allowed * 100:.1f} cm "
                    f"(incl. margin)"
                )
        self.trusted = pose
        self.since_trusted = 0.0
        return True, ""

    def count(self, ok: bool, why: str) -> Stop | None:
        """Count an untrusted pose (once moving); stop after `fault_steps` in a row."""
        self.faults = 0 if ok else self.faults + 1
        if self.faults >= self.fault_steps:
            return Stop("bad_pose", f"{why} ({self.faults} in a row)")
        return None

    def commanded(self, jump: float) -> None:
        """The command moved by `jump` [m]: the hand may move that much further."""
        self.since_trusted += jump


@dataclass
class StaleWrenchGuard:
    """`steps` identical wrench samples in a row: the driver is returning a cached reading."""

    steps: int
    last: tuple[float, ...] | None = None
    repeats: int = 0  # readings equal to the one before, in a row

    def check(self, wrench: Wrench) -> Stop | None:
        sample = (*np.asarray(wrench.force).tolist(), *np.asarray(wrench.torque).tolist())
        self.repeats = self.repeats + 1 if sample == self.last else 0
        self.last = sample
        if self.repeats + 1 >= self.steps:
            return Stop("stale_wrench", f"the same wrench sample was read {self.repeats + 1} times")
        return None


def force_limit_stop(magnitude: float, limit: float) -> Stop | None:
    """|F| = `magnitude` [N] above `limit` [N]."""
    if magnitude > limit:
        return Stop("force_limit", f"|F| = {magnitude:.1f} N > {limit:g} N")
    return None


def arm_force(
    lag: LagModel,
    stiffness: float | None,
    step_length: float,
    position: FloatArray,
    target: FloatArray,
) -> float:
    """[N] a lower bound on |F| from the arm alone: `stiffness` [N/m] x the deflection of the
    hand at `position` (3,) [m] from its `target` (3,) [m] (`LagModel.lagged_deflection`), less
    an allowance for the hand's dynamics of ARM_FORCE_LAG_STEPS step forces (quasi-static) or
    ARM_FORCE_MODEL_STEPS (with a reported tracking_time_constant); 0 without a stiffness."""
    if stiffness is None or lag.deflection0 is None:
        return 0.0
    quasi_static = lag.tracking_time_constant is None
    steps = ARM_FORCE_LAG_STEPS if quasi_static else ARM_FORCE_MODEL_STEPS
    allowance = steps * stiffness * step_length
    deflection = lag.lagged_deflection(position, target)
    return max(0.0, stiffness * norm(deflection) - allowance)


def arm_force_stop(
    estimate: float, magnitude: float, stiffness: float | None, step_length: float, limit: float
) -> Stop | None:
    """The arm's force `estimate` [N] against the sensor's `magnitude` [N]: a disagreement of
    more than ARM_FORCE_DISAGREEMENT_STEPS step forces (`stiffness` [N/m] x `step_length`
    [m]) stops `not_following`; an estimate above `limit` [N] stops `force_limit`."""
    if stiffness is not None and estimate > magnitude + ARM_FORCE_DISAGREEMENT_STEPS * (
        stiffness * step_length
    ):
        return Stop(
            "not_following",
            f"the arm's deflection implies |F| >= {estimate:.1f} N but the sensor reads "
            f"{magnitude:.1f} N: the arm is not following its target (frozen, e-stopped, "
            f"clamped, or its pose lags) or the sensor reads low",
        )
    if estimate > limit:
        return Stop(
            "force_limit",
            f"the arm's deflection implies |F| >= {estimate:.1f} N > {limit:g} N (the sensor "
            f"reads {magnitude:.1f} N)",
        )
    return None


@dataclass
class LeadGuard:
    """The target may lead the measured pose by at most `max_lead` [m]; held at the bound for
    `patience` steps, the run stops `not_following`."""

    max_lead: float  # [m]
    patience: int
    held: int = 0  # steps held at the bound in a row

    @classmethod
    def for_run(cls, config: ExecutorConfig, stiffness: float | None) -> LeadGuard:
        """The configured `guards.max_lead`, else the force limit's deflection plus two steps
        when the `stiffness` [N/m] is known, else DEFAULT_MAX_LEAD."""
        g = config.guards
        if g.max_lead is not None:
            lead = g.max_lead
        elif stiffness is not None:
            lead = config.limits.force_limit / stiffness + 2 * config.step_length
        else:
            lead = DEFAULT_MAX_LEAD
        return cls(lead, g.follow_patience)

    def check(self, lead: float) -> tuple[bool, Stop | None]:
        """For a new target leading the measured pose by `lead` [m]: (hold the last target,
        stop)."""
        if lead <= self.max_lead:
            self.held = 0
            return False, None
        self.held += 1
        if self.held >= self.patience:
            return True, Stop(
                "not_following",
                f"target led the measured pose by {lead * 100:.1f} cm > "
                f"{self.max_lead * 100:.1f} cm for {self.held} steps",
            )
        return True, None


@dataclass
class ForcePrediction:
    """The force of the next move, predicted whatever its direction (a wrong sensor frame must
    not fool it): the force so far plus k l, the move of length l fully blocked, with k the
    larger of the known `stiffness` [N/m] and FORCE_RATE_SAFETY x the largest force change per
    metre of the last FORCE_RATE_WINDOW moves (without a stiffness: no prediction before the
    second move)."""

    stiffness: float | None  # [N/m]
    force_limit: float  # [N]
    rates: deque[float] = field(default_factory=lambda: deque(maxlen=FORCE_RATE_WINDOW))
    last_force: FloatArray | None = None  # [N] (3,) at the last move or hold
    last_length: float = 0.0  # [m] of the last move (0 for a hold)

    def note(self, force: FloatArray, length: float) -> None:
        """The `force` (3,) [N] read before a move of `length` [m] (0: a hold)."""
        if self.last_force is not None and self.last_length > HOLD_LENGTH:
            self.rates.append(norm(force - self.last_force) / self.last_length)
        self.last_force = force
        self.last_length = length

    def bounded_length(
        self, force: FloatArray, estimate: float, length: float
    ) -> tuple[float, float]:
        """The longest move (<= `length` [m]) whose predicted force stays at the limit, and
        the force [N] predicted for the full length (NaN without a prediction). The force so
        far is max(|F|, the arm's force `estimate` [N])."""
        rates = [FORCE_RATE_SAFETY * r for r in self.rates]
        known = [self.stiffness] if self.stiffness is not None else []
        k = max([*rates, *known], default=None)
        if k is None or k <= 0:
            return length, math.nan
        now = max(norm(force), estimate)
        predicted = now + k * length
        if predicted <= self.force_limit:
            return length, predicted
        return max(0.0, (self.force_limit - now) / k), predicted

    def limit(
        self, force: FloatArray, estimate: float, length: float, min_length: float
    ) -> tuple[float, Stop | None]:
        """The move's length [m] after the prediction, or a stop when the prediction would
        shorten it below `min_length` [m]."""
        allowed, predicted = self.bounded_length(force, estimate, length)
        if allowed >= length:
            return length, None
        if allowed < min_length:
            return 0.0, Stop(
                "force_limit",
                f"next step refused: predicted |F| = {predicted:.1f} N > {self.force_limit:g} N",
            )
        return allowed, None


@dataclass
class ContactGuard:
    """Hand-object contact: from the hand's own sensing when it has it, else from |F| (above
    `contact_force` [N] once: contact made; then below `lost_force` [N]: none). `lost_steps`
    steps without contact stop `contact_lost`."""

    contact_force: float  # [N]
    lost_force: float  # [N]
    lost_steps: int
    made: bool = False  # |F| has been above contact_force
    quiet: int = 0  # steps without contact in a row

    def check(self, magnitude: float, touching: bool | None) -> Stop | None:
        """`magnitude` [N] |F| this step; `touching`: the hand's own sensing, or None."""
        if touching is None:  # no contact sensing in the hand: judge from the wrist force
            self.made = self.made or magnitude > self.contact_force
            touching = not (self.made and magnitude < self.lost_force)
        self.quiet = 0 if touching else self.quiet + 1
        if self.quiet >= self.lost_steps:
            return Stop("contact_lost", f"no hand-object contact for {self.quiet} steps")
        return None


def direction_stop(raw: FloatArray) -> Stop | None:
    """A controller's direction that is not a finite non-zero (3,) vector."""
    if raw.shape != (3,) or not all_finite(raw) or norm(raw) < 1e-9:
        return Stop("bad_command", f"controller returned direction {raw!r}")
    return None


def step_length_stop(length: float, nominal: float) -> Stop | None:
    """A controller's step `length` [m] outside [0, `nominal`]."""
    if not (math.isfinite(length) and 0.0 <= length <= nominal * (1 + 1e-9)):
        return Stop("bad_command", f"controller step length {length!r} outside [0, step_length]")
    return None


def command_stop(target: Pose, previous: Pose, bound: float) -> Stop | None:
    """A command that is not finite, or whose position jumps from the `previous` command by
    more than `bound` [m]: not sent."""
    # the previous command's orientation object was checked when it was sent (or held)
    same = target.orientation is previous.orientation
    quat = None if same else target.orientation.as_quat()
    if not (all_finite(target.position) and (quat is None or all_finite(quat))):
        return Stop("bad_command", "non-finite command (not sent)")
    jump = norm(target.position - previous.position)
    if jump > bound:
        return Stop(
            "bad_command", f"command jump {jump * 100:.1f} cm > {bound * 100:.1f} cm (not sent)"
        )
    return None
