"""The default controller's steadying of a direction controller's turns (controller "policy").

Each stage is one small function stating its rule; `SteadyDirection.next_direction` runs them
in order. What each stage buys, measured stage by stage, is in
docs/design/default-controller.md (`benchmarks/ablation.py`).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, fields

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.interface import ControlInput, DirectionController
from constraint_aware.errors import check_number
from constraint_aware.geometry import (
    FloatArray,
    all_finite,
    cross3,
    norm,
    rotate_about,
    turn_vector,
    unit,
)

#: Overshoot damping, Rprop's step factors (Riedmiller & Braun, ICNN 1993, eta- and eta+).
OVERSHOOT_FACTOR = 0.5
RECOVERY_FACTOR = 1.2
#: The smallest turn gain: a tenth of the proposed turn still corrects a persistent error.
MIN_TURN_GAIN = 0.1
#: Without a known rotation rate the hand turns by an exponential average of the applied
#: turns with this weight on the newest (about the last three steps).
HAND_SMOOTHING = 0.3
#: The travel scaling leaves a reading alone when the hand travelled less than this share of
#: its first move: it has not started (a frozen or clamped arm), and dividing would amplify noise.
MIN_TRAVEL_SHARE = 0.1


@dataclass(frozen=True)
class SteadyConfig:
    """Which stages of `SteadyDirection` act (all by default).

    Attributes:
        overshoot_damping: halve the turn gain on a proposal that reverses the last one.
        rotation_feedforward: turn d and the hand with a revolute joint's known rotation rate.
        wait_for_location: feed that rotation into d only once a reading has located the path.
        travel_scaling: scale the start's reading from the hand's travel to the commanded move.
        carry_removal: remove from a reading the share of the last one it still carries.
        play_compensation: add the force the grasp's play hides to the first located reading.
    """

    overshoot_damping: bool = True
    rotation_feedforward: bool = True
    wait_for_location: bool = True
    travel_scaling: bool = True
    carry_removal: bool = True
    play_compensation: bool = True


#: The stages `SteadyConfig` switches, in its order.
STEADY_STAGES = tuple(f.name for f in fields(SteadyConfig))


# --- the stages' rules ------------------------------------------------------------------------
def across_force(inp: ControlInput) -> tuple[float, FloatArray] | None:
    """The reading's force across d in the workplane [N], signed along m = unit(n x d), and m
    (3,); None without a known workplane normal n. A reading locates the path when this force
    is above the dead band."""
    if inp.workplane_normal is None:
        return None
    # unit(n x d) and F.m in Python floats, in numpy's order (geometry.cross3, geometry.unit)
    c0, c1, c2 = cross3(
        np.asarray(inp.workplane_normal, dtype=float).tolist(),
        np.asarray(inp.direction, dtype=float).tolist(),
    )
    size = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    m0, m1, m2 = (c0 / size, c1 / size, c2 / size) if size > 1e-12 else (0.0, 0.0, 0.0)
    f0, f1, f2 = np.asarray(inp.force, dtype=float).tolist()
    return f0 * m0 + f1 * m1 + f2 * m2, np.array([m0, m1, m2])


def _with_across(inp: ControlInput, across: tuple[float, FloatArray], value: float) -> ControlInput:
    """The reading with its force across d set to `value` [N], the rest as read."""
    force = np.asarray(inp.force, dtype=float)
    return _with_force(inp, force + (value - across[0]) * across[1])


def _with_force(inp: ControlInput, force: FloatArray) -> ControlInput:
    """`dataclasses.replace(inp, force=force)` for the frozen ControlInput (no __post_init__,
    no slots): its fields copied as they are, where `replace` would re-run __init__ over every
    field (several times the cost, once per control period)."""
    out = object.__new__(ControlInput)
    out.__dict__.update(inp.__dict__, force=force)
    return out


def travel_scaled(inp: ControlInput, across: tuple[float, FloatArray]) -> ControlInput:
    """Travel scaling: the force across d [N] times l / (x (1 + tau / dt)), at most k l.

    l [m] the commanded move, x [m] the hand's travel since, tau [s] the robot's tracking
    time constant, dt [s] the control period, k [N/m] the stiffness. Taken from rest, the
    reading sees k x sin(e) plus the lag tau v the arm's damping adds (v = x / dt), where the
    policy was trained on the settled k l sin(e). Left as read when any of these is unknown,
    x < MIN_TRAVEL_SHARE l, x (1 + tau / dt) >= l, F.d > 0 (a passive object holds the hand
    back: a push along d is a wrong wrench convention) or k x <= -F.d (the object still holds
    the hand: the force across d is its resistance seen at an angle).
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
    """Carry removal: a force across d [N] with the same sign as the last reading `last` (3,)
    [N] has across this d loses lam times that, never past zero; lam = exp(-dt / tau), the
    share of the last reading the grasp and the arm still carry (tau [s] the robot's tracking
    time constant, dt [s] the period). A reading that reverses, or a robot without a finite
    tau > 0, is left as read: nothing is amplified."""
    tau = inp.tracking_time_constant
    if tau is None or not (math.isfinite(tau) and tau > 0 and math.isfinite(inp.dt) and inp.dt > 0):
        return inp
    last_across = float(np.asarray(last, dtype=float) @ across[1])
    if across[0] * last_across <= 0:
        return inp
    kept = max(0.0, abs(across[0]) - math.exp(-inp.dt / tau) * abs(last_across))
    return _with_across(inp, across, math.copysign(kept, across[0]))


def play_added(inp: ControlInput, across: tuple[float, FloatArray]) -> ControlInput | None:
    """Play compensation: the reading with the play's force k p [N] added across d on the side
    the force across d points to (the hand crossed the play before the constraint pushed
    back); None without a play force above the dead band (within it, it is noise)."""
    if not inp.play_force or inp.play_force <= inp.threshold:
        return None
    return _with_across(inp, across, across[0] + math.copysign(inp.play_force, across[0]))


def overshoot_gain(gain: float, reversed_: bool) -> float:
    """Overshoot damping (Rprop): the turn gain times OVERSHOOT_FACTOR after a proposal that
    reverses the last one (the last turn went past the path), else times RECOVERY_FACTOR;
    kept in [MIN_TURN_GAIN, 1]."""
    if reversed_:
        return max(gain * OVERSHOOT_FACTOR, MIN_TURN_GAIN)
    return min(gain * RECOVERY_FACTOR, 1.0)


def _finite(v: FloatArray) -> bool:
    return v.shape == (3,) and all_finite(v)


class SteadyDirection:
    """A direction controller's turns steadied; controller "policy" is the learned policy
    (its action mirror-averaged about the workplane normal) inside it.

    Each step, d_t -> d_{t+1}:
    1. condition the reading: the first one after the first move has its force across d
       scaled from the hand's travel (`travel_scaled`); later ones, once a reading has
       located the path (a force across d above the dead band), lose the part of the last
       reading they still carry (`carry_removed`); the first located reading gets the grasp's
       play force added (`play_added`);
    2. ask the inner controller for d';
    3. scale the turn d -> d' (a rotation vector) by the overshoot gain (`overshoot_gain`); a
       reversal right after the play compensation takes its extra turn back instead;
    4. feed the known rotation forward: on a revolute joint with known rate w [rad/s], d also
       turns by w dt about the workplane normal between moves, once the path is located;
    5. turn the hand: by w dt each step when w is known, else by the smoothed applied turn
       (HAND_SMOOTHING); left to the executor's torque policy on a fixed-orientation grasp.
    A non-finite proposal is passed on for the executor to stop on ("bad_command").

    It depends on no policy file and no task: the inputs are the reading, the dead band, the
    workplane normal and, when known, the rotation rate and what the executor reports of the
    robot (stiffness, tau, the last move, the hand's travel, the play force). Every stage
    off (`SteadyConfig`) leaves the inner controller's turn as it is, the hand turned by the
    smoothed turn. Why each stage, with its measured effect: docs/design/default-controller.md.
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
        self._gain = 1.0  # the overshoot damping's turn gain
        self._last_turn = np.zeros(3)  # [rad] the last proposed turn (rotation vector)
        self._play_used = False
        self._play_turn: FloatArray | None = None  # [rad] the play's applied extra turn
        self._smoothed = np.zeros(3)  # [rad] exponential average of the applied turns
        self._rotation: FloatArray | None = None  # [rad] rotation vector of this step's turn

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return None if self._rotation is None else Rotation.from_rotvec(self._rotation)

    def hand_turn(self) -> FloatArray | None:
        """This step's hand rotation as a rotation vector (3,) [rad] (`hand_rotation`'s), or
        None; the executor composes it with the hand's orientation (`spatial.turned`)."""
        return self._rotation

    def next_direction(self, inp: ControlInput) -> FloatArray:
        self._readings += 1
        d = np.asarray(inp.direction, dtype=float)
        across = across_force(inp)
        locates = across is not None and abs(across[0]) > inp.threshold
        self._located = self._located or locates
        reading = self._conditioned(inp, across, locates)
        proposed, play_turn = self._asked(reading, across, locates)
        if not _finite(proposed):
            return proposed
        turn = self._scaled(turn_vector(d, unit(proposed)), play_turn)
        turn = turn + self._fed_forward(inp)
        self._turn_hand(inp, turn)
        angle = norm(turn)
        if angle < 1e-15:
            return np.asarray(unit(d))
        return np.asarray(unit(rotate_about(d, turn / angle, angle)))

    def _conditioned(
        self, inp: ControlInput, across: tuple[float, FloatArray] | None, locates: bool
    ) -> ControlInput:
        """Step 1 (before the play): the start's reading travel-scaled, later located ones
        with the carried part removed."""
        if across is None:
            return inp
        last, self._last_force = self._last_force, np.asarray(inp.force, dtype=float)
        cfg = self.config
        if self._readings == 2:  # after the first move; the reading before was at rest
            if cfg.travel_scaling and locates and self._translated(inp):
                return travel_scaled(inp, across)
            return inp
        if cfg.carry_removal and self._located and self._readings > 2:
            return carry_removed(inp, across, last)
        return inp

    def _translated(self, inp: ControlInput) -> bool:
        """Whether the first move only translated the hand (the travel model's case): not
        with the known rotation's turn, nor on a fixed-orientation grasp (the torque policy's
        turn): a twist adds a force the model does not describe."""
        if inp.fixed_orientation:
            return False
        return self._rotation is None or norm(self._rotation) < 1e-12

    def _asked(
        self, reading: ControlInput, across: tuple[float, FloatArray] | None, locates: bool
    ) -> tuple[FloatArray, FloatArray | None]:
        """Step 2: the inner controller's proposal d' (3,), with the play's force on the first
        located reading, and the extra turn [rad] the play gave (None otherwise)."""
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

    def _scaled(self, turn: FloatArray, play_turn: FloatArray | None) -> FloatArray:
        """Step 3: the proposed turn [rad] times the overshoot gain; a proposal that reverses
        the play's extra turn takes it back at once and is not counted as an overshoot (one
        reading cannot tell the constraint's push from a resisting object's seen at an angle)."""
        pending, self._play_turn = self._play_turn, None
        moves = norm(turn) > 1e-9
        take_back = pending is not None and moves and float(turn @ pending) < 0
        gain = 1.0
        if self.config.overshoot_damping:
            if moves:
                reversed_ = float(turn @ self._last_turn) < 0 and not take_back
                self._gain = overshoot_gain(self._gain, reversed_)
                self._last_turn = turn
            gain = self._gain
        if play_turn is not None:
            self._play_turn = gain * play_turn
        if take_back:
            assert pending is not None
            return np.asarray(gain * turn - pending)
        return np.asarray(gain * turn)

    def _known_rotation(self, inp: ControlInput) -> FloatArray | None:
        """The known rotation per step, w dt n [rad] (3,), or None."""
        normal = inp.workplane_normal
        if not self.config.rotation_feedforward or self.rotation_rate is None or normal is None:
            return None
        return np.asarray(self.rotation_rate * inp.dt * np.asarray(normal, dtype=float))

    def _fed_forward(self, inp: ControlInput) -> FloatArray:
        """Step 4: d's turn with the path [rad]: w dt n between moves (not before the first),
        once a reading has located the path (until then d is an unchecked start estimate, and
        turning it keeps its error)."""
        per_step = self._known_rotation(inp)
        waiting = self.config.wait_for_location and not self._located
        if per_step is None or self._readings < 2 or waiting:
            return np.zeros(3)
        return per_step

    def _turn_hand(self, inp: ControlInput, turn: FloatArray) -> None:
        """Step 5: this step's hand rotation (`hand_rotation`)."""
        self._smoothed = self._smoothed + HAND_SMOOTHING * (turn - self._smoothed)
        per_step = self._known_rotation(inp)
        if inp.fixed_orientation:
            self._rotation = None
        else:
            self._rotation = self._smoothed if per_step is None else per_step

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """For each stage acting on this constraint type ("prismatic" or "revolute"), the run
        inputs (`interface.INPUT_NAMES`) it needs: the inner controller's, then this one's."""
        own = getattr(self.inner, "stage_inputs", None)
        stages: dict[str, tuple[str, ...]] = dict(own(constraint_type)) if own else {}
        revolute_only = ("rotation_feedforward", "wait_for_location")
        needs = {
            "overshoot_damping": (),
            "rotation_feedforward": ("rotation_rate", "workplane_normal"),
            "wait_for_location": ("rotation_rate", "workplane_normal"),
            "travel_scaling": ("step_force", "tracking_time_constant", "workplane_normal"),
            "carry_removal": ("tracking_time_constant", "workplane_normal"),
            "play_compensation": ("play_force", "workplane_normal"),
        }
        for stage, names in needs.items():
            if getattr(self.config, stage) and (
                constraint_type == "revolute" or stage not in revolute_only
            ):
                stages[stage] = names
        return stages
