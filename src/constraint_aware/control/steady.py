"""The default controller's steadying of a direction controller's turns (controller "policy").

Each stage is one small function with its rule; `SteadyDirection.next_direction` runs them in
order. What each stage buys, measured, is in docs/design/default-controller.md.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, fields, replace

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.interface import ControlInput, DirectionController
from constraint_aware.errors import check_number
from constraint_aware.geometry import FloatArray, turn_vector, unit

#: Overshoot damping, Rprop's step factors (Riedmiller & Braun, ICNN 1993, eta- and eta+).
OVERSHOOT_FACTOR = 0.5
RECOVERY_FACTOR = 1.2
#: The smallest gain: a tenth of the proposed turn still corrects a persistent error.
MIN_TURN_GAIN = 0.1
#: Without a known rotation rate the hand turns by an exponential average of the applied
#: turns with this weight on the newest (about the last three steps).
HAND_SMOOTHING = 0.3
#: The travel scaling leaves a reading alone when the hand travelled less than this share of
#: its first move: it has not started (a frozen or clamped arm), and dividing would amplify noise.
MIN_TRAVEL_SHARE = 0.1


@dataclass(frozen=True)
class SteadyConfig:
    """Which stages of `SteadyDirection` act, and the overshoot damping's factors.

    Attributes:
        confidence_ramp: scale each turn by clip((|F| - threshold) / threshold, 0, 1).
        overshoot_damping: a proposal that reverses the last one scales the turn gain by
            `overshoot_factor`, one that keeps its sense by `recovery_factor` (gain in
            [min_gain, 1]).
        rotation_feedforward: on a revolute joint with a known rotation rate w [rad/s], turn d
            by w dt between moves and the hand by w dt every step.
        play_compensation: add the force the grasp's play hides [N] across d on the first
            reading that locates the path; take its extra turn back if the next one reverses.
        wait_for_location: feed the rotation into d only once a reading has located the path.
        reversals_once_located: count reversals only from the first located reading on.
        travel_scaling: scale the force across d of the first reading after the first move
            from the hand's travel to the commanded move.
        carry_removal: remove from a reading the share exp(-dt / tau) of the last one's force
            across d that it still carries, when both have the same sign.
        overshoot_factor: gain factor on a reversal, in (0, 1].
        recovery_factor: gain factor otherwise, >= 1.
        min_gain: the smallest gain, in (0, 1].
        hand_smoothing: weight of the newest applied turn in the hand's turn without a known
            rate, in (0, 1].
    """

    confidence_ramp: bool = True
    overshoot_damping: bool = True
    rotation_feedforward: bool = True
    play_compensation: bool = True
    wait_for_location: bool = True
    reversals_once_located: bool = True
    travel_scaling: bool = True
    carry_removal: bool = True
    overshoot_factor: float = OVERSHOOT_FACTOR
    recovery_factor: float = RECOVERY_FACTOR
    min_gain: float = MIN_TURN_GAIN
    hand_smoothing: float = HAND_SMOOTHING

    def __post_init__(self) -> None:
        n = "SteadyConfig."
        check_number(n + "overshoot_factor", self.overshoot_factor, low=0, low_open=True, high=1)
        check_number(n + "recovery_factor", self.recovery_factor, low=1)
        check_number(n + "min_gain", self.min_gain, low=0, low_open=True, high=1)
        check_number(n + "hand_smoothing", self.hand_smoothing, low=0, low_open=True, high=1)


#: The stages `SteadyConfig` switches (its boolean fields).
STEADY_STAGES = tuple(f.name for f in fields(SteadyConfig) if f.type in (bool, "bool"))


# --- the stages' rules, one function each -----------------------------------------------------
def across_force(inp: ControlInput) -> tuple[float, FloatArray] | None:
    """The reading's force across d in the workplane [N], signed along m = unit(n x d), and m
    (3,); None without a known workplane normal n."""
    if inp.workplane_normal is None:
        return None
    m = unit(np.cross(inp.workplane_normal, inp.direction))
    return float(np.asarray(inp.force, dtype=float) @ m), m


def _with_across(inp: ControlInput, across: tuple[float, FloatArray], value: float) -> ControlInput:
    """The reading with its force across d set to `value` [N], the rest as read."""
    force = np.asarray(inp.force, dtype=float)
    return replace(inp, force=force + (value - across[0]) * across[1])


def travel_scaled(inp: ControlInput, across: tuple[float, FloatArray]) -> ControlInput:
    """Travel scaling: the force across d times l / (x (1 + tau / dt)), capped at k l [N].

    l [m] the commanded move, x [m] the hand's travel since, tau [s] the robot's tracking
    time constant, k [N/m] its stiffness. From rest the hand has travelled part of the move
    when the reading is taken, and the arm's damping adds the lag tau v (v = x / dt), while
    the policy was trained on the settled k l sin(e). The reading is left as read when any of
    these is unknown, x < MIN_TRAVEL_SHARE l, x (1 + tau / dt) >= l, F.d > 0 (a passive
    object holds the hand back: a push along d is a wrong wrench convention), or k x <= -F.d
    (the object still holds the hand: the force across d is its resistance at an angle).
    """
    k, move, x, tau = inp.stiffness, inp.last_move, inp.hand_travel, inp.tracking_time_constant
    if k is None or move is None or x is None or tau is None:
        return inp
    if not all(math.isfinite(v) and v > 0 for v in (k, move, tau, inp.dt)):
        return inp
    if not math.isfinite(x) or x < MIN_TRAVEL_SHARE * move:
        return inp
    along = float(np.asarray(inp.force, dtype=float) @ np.asarray(inp.direction, dtype=float))
    travelled = x * (1.0 + tau / inp.dt)
    if along > 0 or k * x + along <= 0 or travelled >= move:
        return inp
    scaled = min(abs(across[0]) * move / travelled, k * move)
    return _with_across(inp, across, math.copysign(scaled, across[0]))


def carry_removed(
    inp: ControlInput, across: tuple[float, FloatArray], last: FloatArray
) -> ControlInput:
    """Carry removal: a force across d [N] with the same sign as the last reading's `last`
    (3,) [N] has there loses lam |last across d| (never past zero), lam = exp(-dt / tau) with
    the robot's tracking time constant tau [s]: the grasp and the arm still carry that share
    of the last reading. A reading that reverses, or a robot without a finite tau > 0, is left
    as read (nothing is amplified)."""
    tau = inp.tracking_time_constant
    if tau is None or not (math.isfinite(tau) and tau > 0 and math.isfinite(inp.dt) and inp.dt > 0):
        return inp
    last_across = float(np.asarray(last, dtype=float) @ across[1])
    if across[0] * last_across <= 0:
        return inp
    lam = math.exp(-inp.dt / tau)
    kept = max(0.0, abs(across[0]) - lam * abs(last_across))
    return _with_across(inp, across, math.copysign(kept, across[0]))


def play_added(inp: ControlInput, across: tuple[float, FloatArray]) -> ControlInput | None:
    """Play compensation: the reading with the play's force k p [N] added across d on the side
    the force across d points to; None without a play force above the dead band (within it,
    it is not told apart from noise)."""
    if not inp.play_force or inp.play_force <= inp.threshold:
        return None
    return _with_across(inp, across, across[0] + math.copysign(inp.play_force, across[0]))


def confidence(force_norm: float, threshold: float) -> float:
    """Confidence ramp: clip((|F| - threshold) / threshold, 0, 1), forces [N]; with no dead
    band 1 for any force. A force just above the 4-sigma band is mostly noise."""
    if threshold <= 0:
        return 1.0 if force_norm > 0 else 0.0
    return min(1.0, max(0.0, (force_norm - threshold) / threshold))


def _finite(v: FloatArray) -> bool:
    return v.shape == (3,) and bool(np.all(np.isfinite(v)))


class SteadyDirection:
    """A direction controller's turns steadied; controller "policy" is the learned policy
    (its action mirror-averaged) inside it.

    Each step, d_t -> d_{t+1}:
    1. condition the reading: the first one after the first move has its force across d
       scaled from the hand's travel (`travel_scaled`); from the first reading that locates
       the path (a force across d above the dead band) on, the share of the last reading a
       reading carries is removed (`carry_removed`); the first located reading gets the
       grasp's play force added (`play_added`);
    2. ask the inner controller: proposal d';
    3. scale the turn d -> d' (a rotation vector) by the confidence ramp and the overshoot
       gain (Rprop: halved on a reversal, regrown by 1.2 otherwise; reversals counted from the
       first located reading on); a reversal right after the play compensation takes its
       extra turn back instead of halving the gain;
    4. feed the known rotation forward: on a revolute joint with known rate w [rad/s], d also
       turns by w dt about the workplane normal between moves, once the path is located;
    5. turn the hand: by w dt each step when w is known, else by the smoothed applied turn;
       none on a fixed-orientation grasp (the executor's torque policy turns it).
    A non-finite proposal is passed on for the executor to stop on ("bad_command").
    Inputs: the force, the dead band, the workplane normal and, when known, the rotation rate
    and what the executor reports of the robot (its stiffness, tau, the last move, the hand's
    travel, the play force). Why each stage, measured: docs/design/default-controller.md.
    """

    def __init__(
        self,
        inner: DirectionController,
        rotation_rate: float | None = None,
        config: SteadyConfig | None = None,
        name: str = "steady",
    ) -> None:
        self.inner = inner
        if rotation_rate is not None:
            rotation_rate = check_number("rotation_rate", rotation_rate, unit="rad/s")
        self.rotation_rate = rotation_rate  # [rad/s] w, or None
        self.config = config or SteadyConfig()
        self.name = name
        self.reset(np.array([1.0, 0.0, 0.0]))

    def reset(self, direction: FloatArray) -> None:
        self.inner.reset(direction)
        self._readings = 0  # readings this run; the first is at rest, before any move
        self._located = False  # a reading has located the path
        self._last_force = np.zeros(3)  # [N] the last reading, as read
        self._gain = 1.0  # the overshoot damping's gain
        self._last_turn = np.zeros(3)  # [rad] the last tracked proposal (rotation vector)
        self._play_turn: FloatArray | None = None  # [rad] the play compensation's applied turn
        self._play_used = False
        self._smoothed = np.zeros(3)  # [rad] exponential average of the applied turns
        self._rotation: Rotation | None = None

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return self._rotation

    def next_direction(self, inp: ControlInput) -> FloatArray:
        self._readings += 1
        d = np.asarray(inp.direction, dtype=float)
        across = across_force(inp)
        locates = across is not None and abs(across[0]) > inp.threshold
        reading = self._condition(inp, across, locates)
        self._located = self._located or locates
        proposed, play_turn = self._ask(reading, across, locates)
        if not _finite(proposed):
            return proposed
        turn = self._scale(inp, turn_vector(d, unit(proposed)), play_turn, across)
        turn = turn + self._feed_forward(inp)
        self._turn_hand(inp, turn)
        return np.asarray(unit(Rotation.from_rotvec(turn).apply(d)))

    def _condition(
        self, inp: ControlInput, across: tuple[float, FloatArray] | None, locates: bool
    ) -> ControlInput:
        """Step 1: the reading as the inner controller is asked it (before the play)."""
        if across is None:
            return inp
        last, self._last_force = self._last_force, np.asarray(inp.force, dtype=float)
        cfg = self.config
        if self._readings == 2:  # the first reading after the first move, from rest
            if cfg.travel_scaling and locates and self._translated(inp):
                return travel_scaled(inp, across)
            return inp  # the reading before it was at rest: it carries nothing
        if cfg.carry_removal and (self._located or locates) and self._readings > 2:
            return carry_removed(inp, across, last)
        return inp

    def _translated(self, inp: ControlInput) -> bool:
        """Whether the first move only translated the hand (the travel model's case): not with
        a known rotation's turn, nor on a fixed-orientation grasp (the torque policy's)."""
        if inp.fixed_orientation:
            return False
        return self._rotation is None or self._rotation.magnitude() < 1e-12

    def _ask(
        self, reading: ControlInput, across: tuple[float, FloatArray] | None, locates: bool
    ) -> tuple[FloatArray, FloatArray | None]:
        """Step 2: the inner controller's proposal d' (3,) and, on the play-compensated
        reading, the turn [rad] the play's force added to it (else None)."""
        played = None
        if self.config.play_compensation and not self._play_used and locates:
            assert across is not None  # a located reading has a workplane
            played = play_added(reading, across)
        if played is None:
            return np.asarray(self.inner.next_direction(reading), dtype=float), None
        # the reading as read goes to a copy, so that the inner controller's own state (a
        # history policy's previous step) advances once, with the reading that drives the move
        plain = np.asarray(copy.deepcopy(self.inner).next_direction(reading), dtype=float)
        proposed = np.asarray(self.inner.next_direction(played), dtype=float)
        if not _finite(plain):
            return plain, None
        if not _finite(proposed):
            return proposed, None
        self._play_used = True
        return proposed, turn_vector(unit(plain), unit(proposed))

    def _scale(
        self,
        inp: ControlInput,
        turn: FloatArray,
        play_turn: FloatArray | None,
        across: tuple[float, FloatArray] | None,
    ) -> FloatArray:
        """Step 3: the proposed turn [rad] times the confidence ramp and the overshoot gain."""
        cfg = self.config
        size = float(np.linalg.norm(turn))
        pending, self._play_turn = self._play_turn, None
        take_back = pending is not None and size > 1e-9 and float(turn @ pending) < 0
        tracked = self._located or across is None or not cfg.reversals_once_located
        if cfg.overshoot_damping and size > 1e-9 and tracked:
            if float(turn @ self._last_turn) < 0 and not take_back:
                self._gain = max(self._gain * cfg.overshoot_factor, cfg.min_gain)
            else:
                self._gain = min(self._gain * cfg.recovery_factor, 1.0)
            self._last_turn = turn
        gain = self._gain if cfg.overshoot_damping else 1.0
        ramp = 1.0
        if cfg.confidence_ramp:
            ramp = confidence(float(np.linalg.norm(inp.force)), inp.threshold)
        if play_turn is not None:
            self._play_turn = gain * ramp * play_turn
        scaled = gain * ramp * turn
        if take_back:  # as far as this reading is trusted
            assert pending is not None
            scaled = scaled - ramp * pending
        return np.asarray(scaled)

    def _known_rotation(self, inp: ControlInput) -> FloatArray | None:
        """The known rotation w dt n [rad] (3,) per step, or None."""
        normal = inp.workplane_normal
        if not self.config.rotation_feedforward or self.rotation_rate is None or normal is None:
            return None
        return np.asarray(self.rotation_rate * inp.dt * np.asarray(normal, dtype=float))

    def _feed_forward(self, inp: ControlInput) -> FloatArray:
        """Step 4: d's extra turn [rad] with the path: w dt n between moves (not before the
        first), once a reading has located the path."""
        per_step = self._known_rotation(inp)
        waiting = self.config.wait_for_location and not self._located
        if per_step is None or self._readings < 2 or waiting:
            return np.zeros(3)
        return per_step

    def _turn_hand(self, inp: ControlInput, turn: FloatArray) -> None:
        """Step 5: this step's hand rotation (`hand_rotation`)."""
        self._smoothed = self._smoothed + self.config.hand_smoothing * (turn - self._smoothed)
        per_step = self._known_rotation(inp)
        if inp.fixed_orientation:
            self._rotation = None
        else:
            self._rotation = Rotation.from_rotvec(self._smoothed if per_step is None else per_step)

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """For each stage acting on this constraint type ("prismatic" or "revolute"), the
        run inputs (`interface.INPUT_NAMES`) it needs: the inner controller's, then this
        wrapper's."""
        own = getattr(self.inner, "stage_inputs", None)
        stages: dict[str, tuple[str, ...]] = dict(own(constraint_type)) if own else {}
        cfg = self.config
        revolute = constraint_type == "revolute"
        needs = {
            "confidence_ramp": (),
            "overshoot_damping": (),
            "reversals_once_located": ("workplane_normal",),
            "rotation_feedforward": ("rotation_rate", "workplane_normal"),
            "wait_for_location": ("workplane_normal",),
            "play_compensation": ("play_force", "workplane_normal"),
            "travel_scaling": ("step_force", "tracking_time_constant", "workplane_normal"),
            "carry_removal": ("tracking_time_constant", "workplane_normal"),
        }
        for stage, names in needs.items():
            if stage in ("rotation_feedforward", "wait_for_location") and not revolute:
                continue
            if getattr(cfg, stage):
                stages[stage] = names
        return stages
