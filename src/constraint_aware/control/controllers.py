"""Direction controllers behind one interface: given the offset force and d_t, return d_{t+1}."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, fields, replace
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import UnknownNameError, check_number
from constraint_aware.geometry import (
    FloatArray,
    normalize_force,
    turn_vector,
    unit,
    update_direction_rule,
)
from constraint_aware.policy import ConstraintAwarePolicy


@dataclass(frozen=True)
class ControlInput:
    """What a controller sees each control step.

    force: (3,) [N] F = F_s - F_d, world frame (raw: not thresholded, not normalized);
    torque: (3,) [N m] about the tool point, offset removed; direction: (3,) unit d_t;
    dt: [s] control period; threshold: [N] below which |F| counts as no force;
    workplane_normal: (3,) unit, when the workplane is known (assumption 4);
    step_force: [N] k*delta, the robot's translational impedance stiffness times the step
    length (the force of one fully blocked step), when the robot reports its stiffness;
    fixed_orientation: the executor turns the hand by the torque policy (a fixed-orientation
    grasp, paper appendix): a controller's own hand rotation would override it.
    play_force: [N] the force the grasp's play hides, k*p (`ExecutorConfig.grasp_play`, measured
    by control.probe), when known and non-zero.
    tracking_time_constant: [s] tau, how the robot's tool lags a commanded pose (the Robot
    protocol's optional member), when the robot reports it.
    stiffness: [N/m] k, the robot's reported translational stiffness, when it reports it.
    last_move: [m] the length of the move commanded before this reading (0 for a hold); None
    before the first move.
    hand_travel: [m] how far the hand travelled, in the workplane when it is known, from the
    trusted pose at the last command to this reading's pose (after the executor's own holds,
    which send no command, that spans their periods too); None before the first move.
    """

    force: FloatArray
    torque: FloatArray
    direction: FloatArray
    dt: float
    threshold: float
    workplane_normal: FloatArray | None = None
    step_force: float | None = None
    fixed_orientation: bool = False
    play_force: float | None = None
    tracking_time_constant: float | None = None
    stiffness: float | None = None
    last_move: float | None = None
    hand_travel: float | None = None


class DirectionController(Protocol):
    name: str

    def reset(self, direction: FloatArray) -> None:
        """Start of a run with the initial direction d0 (3,)."""
        ...

    def next_direction(self, inp: ControlInput) -> FloatArray:
        """d_{t+1}: (3,) unit vector."""
        ...

    def step_length(self, nominal: float) -> float:
        """[m] translation this step, in [0, nominal]; most controllers always move the
        nominal 1 cm. 0 is a hold: with the executor's default `command_from="measured"` the
        target is re-anchored at the measured pose in the workplane (up to the re-anchoring
        limit), so the arm lets go of its in-plane stretch; the self-check compares the reading
        after a hold and the one after the next move with the arm's deflection only
        (SELF_CHECK_SETTLE_MOVES)."""
        ...

    def hand_rotation(self) -> Rotation | None:
        """This step's hand rotation if the controller decides it; None: the executor's rule
        (paper 3.4.1 on revolute constraints, or the torque policy)."""
        ...


class _Base:
    name = "base"

    def reset(self, direction: FloatArray) -> None:
        pass

    def step_length(self, nominal: float) -> float:
        return nominal

    def hand_rotation(self) -> Rotation | None:
        return None


class FixedDirection(_Base):
    """No correction: keep d0 (the baseline that shows what the correction buys)."""

    name = "fixed"

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return inp.direction


class ProjectionController(_Base):
    """d <- d - (d.F^)F^, renormalized: exact for a frictionless guide."""

    name = "projection"

    def next_direction(self, inp: ControlInput) -> FloatArray:
        f_hat = normalize_force(inp.force, inp.threshold)
        a = -float(inp.direction @ f_hat) * f_hat
        return np.asarray(update_direction_rule(inp.direction, a))


class PolicyController(_Base):
    """The constraint-aware policy alone (paper 3.3): d <- (d + pi(s)) / |d + pi(s)|.

    s is the policy card's observation: (F^, d), plus the previous step's for history
    policies (a fresh session per run) or |F|/(k*delta) from the robot's step force. This is
    controller "policy-raw" (the paper's rule as published); controller "policy" runs it
    inside `SteadyDirection`.
    """

    name = "policy-raw"

    def __init__(self, policy: ConstraintAwarePolicy | None = None, mirror: bool = False) -> None:
        self.policy = policy or ConstraintAwarePolicy.load()
        self.session = self.policy.session()
        # mirror: the action averaged with its mirror image about the workplane normal, when
        # the workplane is known (policy.mirror_average); off for the paper's rule as published
        self.mirror = mirror
        if mirror:
            self.name = "policy-mirrored"

    def reset(self, direction: FloatArray) -> None:
        self.session.reset()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        return self.session.update_direction(
            inp.force,
            inp.direction,
            threshold=inp.threshold,
            step_force=inp.step_force,
            workplane_normal=inp.workplane_normal if self.mirror else None,
        )


#: Overshoot damping, Rprop's step factors (Riedmiller & Braun, ICNN 1993, eta- and eta+):
#: a proposed turn that reverses the last one halves the gain on the turns, one that keeps its
#: sense lets the gain grow back by 1.2 (up to 1).
OVERSHOOT_FACTOR = 0.5
RECOVERY_FACTOR = 1.2
#: The smallest gain: a tenth of the proposed turn still corrects a persistent error.
MIN_TURN_GAIN = 0.1
#: Without a known rotation rate, the hand turns by an exponential average of the applied
#: turns with this weight on the newest (about the last three steps).
HAND_SMOOTHING = 0.3
#: The start's travel scaling (SteadyConfig.travel_scaling) leaves a reading alone when the
#: hand travelled less than this share of its first move: it has not started to move (a
#: frozen or clamped arm), and dividing by its travel would multiply noise.
MIN_TRAVEL_SHARE = 0.1


@dataclass(frozen=True)
class SteadyConfig:
    """Which parts of `SteadyDirection` act (each measured on its own in bench/forces.py).

    confidence_ramp: the turn is scaled by clip((|F| - threshold) / threshold, 0, 1): a force
    just above the dead band is mostly noise (the band is 4 sigma of it), its direction is not
    trusted, from twice the band on it is fully. overshoot_damping: Rprop's gain on the turns
    (OVERSHOOT_FACTOR, RECOVERY_FACTOR, MIN_TURN_GAIN); any reversal of the last tracked
    proposal counts (reversals_once_located: tracked from the first located reading on).
    strict_reversal (off; measured and rejected, docs/forces.md): only a reversal no
    bigger than the last proposal counts (a turn g*p that overshot the error e leaves
    |e'| = g|p| - |e| <= |p|). Measured before reversals_once_located, which now covers
    that door case: it let the hook hand's door correct in full after a 0.4 deg
    first proposal, but on the Jaco, whose lag makes the proposals of an oscillation grow, it
    stopped damping them: drawer mean |F| 1.17 -> 1.47 N. rotation_feedforward: with a known
    rotation rate w [rad/s] (revolute, w = v / r, what the classical controller is given), d
    also turns by w dt between consecutive moves and the hand turns by w dt each step; without
    it the hand turns by the smoothed applied turn (HAND_SMOOTHING) instead of each step's.
    play_compensation: with the force the grasp's play hides (ControlInput.play_force, k*p),
    the first reading with a force across d above the dead band gets k*p added across d, on
    the side it points to: the hand crossed the play before the constraint pushed back, so
    the reading understates the error. One reading cannot tell a constraint's push from the
    object's resistance seen at an angle (its across part points away from the path): when
    the next proposal reverses, the compensation's extra turn is taken back at once and the
    reversal is not counted as an overshoot (docs/forces.md, stop 22).
    wait_for_location: the known rotation is fed forward into d only once a reading has
    located the path, i.e. carried a force across d above the dead band. Until then d is the
    start estimate, checked by nothing, and is left as it is (the classical controller's t^
    is too): turning it with the path keeps an unknown error as large as it was. Measured on
    the hook hand's door at the paper's offset (docs/forces.md, stop 23): peak 5.08 -> 4.73 N
    at +15 deg, 4.77 -> 4.80 N at -15 deg. With no dead band (threshold 0) any force across d
    locates the path, so d follows the rotation from the second reading on, as before.
    reversals_once_located: the overshoot damping tracks the proposals only from the first
    reading that has located the path on (the test of wait_for_location). An earlier reading
    has its force along d, the object breaking away or resisting, with nothing across d
    above the dead band; the turn it proposes is small and carries no direction (under 3 deg
    for pure resistance, issue 9). When the first located reading reverses it, that is not
    an overshoot, as there was no path yet to pass, and halving the gain there left half of
    the first real correction for later steps. Measured on the hook hand's door at the
    paper's offset (docs/forces.md, stop 25): a 0.4 deg proposal from the breakaway reading
    (4.6 N against d, 0.1 N across) halved the next reading's 12 deg correction. Without a
    known workplane nothing is told across d, and every proposal is tracked. Without the
    known rotation rate five of the forces study's door cells peak 0.07-1.5 N higher at the
    same mean |F| (the full first correction lands past the path; docs/forces.md, stop 25).
    lag_inversion (off; measured and rejected, docs/forces.md, stop 27): with the robot's
    tracking_time_constant tau, the force across d that the inner controller sees is a
    first-order lag undone, F_across' = (F_across - lam F_across,prev) / (1 - lam),
    lam = exp(-dt / tau), from the reading that first locates the path on (the along-d part
    as read; a constant force unchanged). A reading does carry part of the last one across d:
    fitted on the hook hand's drawer suite (classical controller, against the simulator's
    path), 0.32 of it at 2000 N/m, where exp(-dt / tau) = 0.27, and there it puts the
    drawer below the classical controller (suite mean |F| 0.892 against 0.907 N). But that
    share is the grasp's and the arm's together, not the free-space tau's: 0.29 at 500 N/m
    (exp(-dt / tau) = 0.52), 0.64 at 8000 N/m (0.07), 0.18 with 10x stiffer fingers. With tau
    the inversion overshoots where tau overstates it: on the Jaco the door's paper-offset
    peak rises from 19.3 to 33.4 N, on the hook hand at 500 N/m the pole's mean |F| from 0.78
    to 0.85 N.
    travel_scaling: the first reading after the first move from rest, the one the start's
    correction is made on, has its force across d scaled by l / (x (1 + tau / dt)): l the
    move, x the hand's travel since it was commanded (ControlInput.last_move, hand_travel)
    and tau the robot's tracking_time_constant. On a rigid grasp the arm's stretch after a
    command lies along d (the executor re-anchors across d), so the force across d is
    k x' sin(e), e the error and x' the hand's travel along the path plus the lag tau v the
    arm's damping adds (v = x / dt, the executor's lag model); the policy was trained on the
    settled reading k l sin(e). From rest the hand has travelled a third of the move when the
    reading is taken (x = 0.33-0.41 l on the hook hand), so that reading understates the
    error. Only while the hand has travelled farther than the force along d (k x > -F.d):
    until then the object still holds the hand, and the reading's force across d is its
    resistance seen at an angle (on the hook hand's drawer, plate and pole, suite, paper
    offsets and resistance map: all 153 first readings that pass that test point toward the
    path, 29 of the 49 that fail it; docs/forces.md, stop 29). Not on a push along d (F.d > 0:
    a passive object starting from rest holds the hand back, so that is a wrong wrench
    convention the self-check has not judged yet), nor after a travel under MIN_TRAVEL_SHARE
    of the move; the scaled force never exceeds k l, the model's largest. Not together with
    lag_inversion, which undoes the lag on that reading already. Only after a first move that
    translated the hand:
    a hand turned with it (the known rotation rate's w dt on a revolute joint, or the torque
    policy's turn) adds the twist's force, which the model does not describe (on the Jaco's
    wrap grasp 1.2-1.5 N across d, away from the path at the door's +15 deg). Needs the
    robot's stiffness and tau (a robot that does not report tau gets its readings as they
    are); no dead band or gain of its own.
    carry_removal: a reading taken while the hand is still moving carries part of the last one
    across d (the grasp and the arm settle after each re-anchoring; fitted on the hook hand's
    drawer suite, 0.32 of it). After the main correction that carried part keeps pushing d the
    way the last reading did, past the path: on the hook hand's drawer suite the next step turns
    d on the same way by 2.1-8.4 deg in 13 of 20 runs (16 of 20 end it on the path's far side),
    and the overshoot damping, which reacts to reversals only, then halves the gain for the way
    back (docs/forces.md, stop 30). So from the first located reading on, a reading whose force
    across d has the same sign as the last reading's loses lam times the last one's, never past
    zero; lam = exp(-dt / tau) from the robot's tracking_time_constant. This is lag_inversion
    made one-sided: nothing is amplified (no division by 1 - lam) and a reading that reverses is
    passed as read, so where exp(-dt / tau) overstates the share (the Jaco, a soft wrist: stop
    27) the cost is a slower correction, not the inversion's overshoot. Not on the first reading
    after the first move (the reading before it is at rest, and carries no motion), nor together
    with lag_inversion, which undoes the carried share already. Needs tau; no dead band or gain
    of its own.
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


class SteadyDirection(_Base):
    """Any direction controller with its turns steadied (issue 9's door and drawer forces);
    controller "policy" is the learned policy inside it.

    Measured cause (bench/forces.py): the default policy turns d by 5-12 deg for any force
    just above the dead band, so on the door it settles into a +-10 deg zig-zag from step to
    step instead of a lag, and paper 3.4.1's hand rotation (the hand turns with every change
    of d) rocks the hand on the handle with it: median peak 11 N where the classical
    controller, whose hand turns at the known w = v / r, has 3.6 N. On the drawer the same
    kicks, one step and its reversal, double the mean |F|.

    Each step: the inner controller proposes d' (3,) (on the reading after the first move, with
    its force across d scaled from the hand's travel to the move: SteadyConfig.travel_scaling;
    on later readings, once one has located the path, with the part of the last reading they
    still carry removed: SteadyConfig.carry_removal); the turn d -> d' (a rotation vector, any
    axis) is scaled by the confidence ramp and the overshoot gain (which tracks the proposals
    once a reading has located the path), plus the feed-forward
    turn about the workplane normal when the rotation rate is known and a reading has located
    the path (SteadyConfig.wait_for_location); d_{t+1} is d turned by
    it. The hand rotation (revolute, asked by the executor) is the known rate's, or the
    smoothed turn; None on a fixed-orientation grasp (the executor's torque policy).
    Nothing depends on a policy file or a task: the inputs are the force, the dead band, the
    workplane normal and, when given, the rotation rate and what the executor reports of the
    robot (its stiffness, tau, the last move and the hand's travel).
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
        self.rotation_rate = rotation_rate  # [rad/s] w_d, or None
        self.config = config or SteadyConfig()
        self.name = name
        self.reset(np.array([1.0, 0.0, 0.0]))

    def reset(self, direction: FloatArray) -> None:
        self.inner.reset(direction)
        self.gain = 1.0
        self._last_turn = np.zeros(3)  # the last non-zero proposed turn (rotation vector)
        self._smoothed = np.zeros(3)  # [rad] exponential average of the applied turns
        self._rotation: Rotation | None = None
        self._play_used = False  # the play has been compensated in this run
        self._located = False  # a reading has carried a force across d above the dead band
        self._pending_extra: FloatArray | None = None  # last step's applied play turn
        self._previous_force: FloatArray | None = None  # [N] (3,) the last raw reading
        # readings seen in this run, this one included: the first is at rest, before any
        # move; from the second on the hand has moved
        self._readings = 0

    def step_length(self, nominal: float) -> float:
        return self.inner.step_length(nominal)

    def hand_rotation(self) -> Rotation | None:
        return self._rotation

    def next_direction(self, inp: ControlInput) -> FloatArray:
        cfg = self.config
        self._readings += 1
        d = np.asarray(inp.direction, dtype=float)
        extra = None  # the play compensation's part of this step's proposed turn
        across = _across(inp)  # (force [N], direction (3,)) across d, or None
        # the reading locates the path: a force across d above the dead band (the one test
        # behind wait_for_location, reversals_once_located and the play compensation)
        locates = across is not None and abs(across[0]) > inp.threshold
        # what the inner controller is asked: the reading with the arm's lag undone across d
        # (SteadyConfig.lag_inversion), or its carried part removed (carry_removal), from the
        # first located reading on
        asked = self._lag_undone(inp, across, self._located or locates)
        # (not with lag_inversion, which already undoes the lag on this reading)
        scale = cfg.travel_scaling and self._readings == 2
        if scale and locates and self._translated(inp):
            asked = _travel_scaled(asked, across)
        compensate = cfg.play_compensation and not self._play_used and locates
        played = self._play_input(asked, across) if compensate else None
        if played is None:
            proposed = np.asarray(self.inner.next_direction(asked), dtype=float)
        else:
            # the reading as it is is asked of a copy, so that the inner controller's own state
            # (a history policy's previous step, an integrator) advances once, with the
            # reading that drives the move
            raw = np.asarray(copy.deepcopy(self.inner).next_direction(asked), dtype=float)
            proposed = np.asarray(self.inner.next_direction(played), dtype=float)
            if not _finite_direction(raw):
                return raw  # the executor stops on it ("bad_command"), naming it
            if _finite_direction(proposed):
                extra = turn_vector(unit(raw), unit(proposed))
                self._play_used = True
        if not _finite_direction(proposed):
            return proposed  # the executor stops on it ("bad_command"), naming it
        turn = turn_vector(d, unit(proposed))
        size = float(np.linalg.norm(turn))
        pending, self._pending_extra = self._pending_extra, None
        take_back = pending is not None and size > 1e-9 and float(turn @ pending) < 0
        self._located = self._located or locates
        tracked = self._located or across is None or not cfg.reversals_once_located
        if cfg.overshoot_damping and size > 1e-9 and tracked:
            # a reversal of the last proposal, unless it reverses the play compensation
            overshot = float(turn @ self._last_turn) < 0 and not take_back
            if overshot:
                self.gain = max(self.gain * cfg.overshoot_factor, cfg.min_gain)
            else:
                self.gain = min(self.gain * cfg.recovery_factor, 1.0)
            self._last_turn = turn
        gain = self.gain if cfg.overshoot_damping else 1.0
        ramp = 1.0
        if cfg.confidence_ramp:
            ramp = _confidence(float(np.linalg.norm(inp.force)), inp.threshold)
        turn = gain * turn * ramp  # this order: the same floats as the gain, then the ramp
        if extra is not None:  # as applied
            self._pending_extra = gain * ramp * extra
        if take_back:  # as far as this reading is trusted (a reading near the band is noise)
            assert pending is not None
            turn = turn - ramp * pending
        normal = inp.workplane_normal
        known = cfg.rotation_feedforward and self.rotation_rate is not None and normal is not None
        per_step = np.zeros(3)
        if known:
            assert self.rotation_rate is not None and normal is not None
            per_step = self.rotation_rate * inp.dt * np.asarray(normal, dtype=float)
            # the path turns between consecutive moves (not before the first); d follows it
            # once a reading has located the path (SteadyConfig.wait_for_location)
            if self._readings > 1 and (self._located or not cfg.wait_for_location):
                turn = turn + per_step
        self._smoothed = self._smoothed + cfg.hand_smoothing * (turn - self._smoothed)
        if inp.fixed_orientation:
            self._rotation = None
        else:
            self._rotation = Rotation.from_rotvec(per_step if known else self._smoothed)
        return np.asarray(unit(Rotation.from_rotvec(turn).apply(d)))

    def _translated(self, inp: ControlInput) -> bool:
        """Whether the last move only translated the hand. The travel model describes a
        translating hand: after a move that also turned it (this wrapper's hand rotation, or
        the torque policy's on a fixed-orientation grasp) the reading carries the twist too."""
        if inp.fixed_orientation:
            return False
        return self._rotation is None or self._rotation.magnitude() < 1e-12

    def _lag_undone(
        self, inp: ControlInput, across: tuple[float, FloatArray] | None, located: bool
    ) -> ControlInput:
        """The reading with the arm's first-order lag undone across d once the path is
        located: inverted (SteadyConfig.lag_inversion), or its carried part removed from a
        reading that keeps the last one's sign (carry_removal); else the reading as it is.
        Remembers the raw reading for the next step. across: this reading's `_across`."""
        cfg = self.config
        force = np.asarray(inp.force, dtype=float)
        previous, self._previous_force = self._previous_force, force.copy()
        if not (cfg.carry_removal and located and across is not None):
            return inp
        tau = inp.tracking_time_constant
        if previous is None or tau is None or not (math.isfinite(tau) and tau > 0):
            return inp
        if not (math.isfinite(inp.dt) and inp.dt > 0):
            return inp
        lam = math.exp(-inp.dt / tau)  # the share of the last reading a reading still carries
        across_force, across_dir = across
        last = float(previous @ across_dir)
        # the last reading was taken at rest (before the first move): nothing carried
        if self._readings <= 2 or across_force * last <= 0:
            return inp  # ... or this one reverses it: as read (never amplified)
        restored = math.copysign(max(0.0, abs(across_force) - lam * abs(last)), across_force)
        return replace(inp, force=force + (restored - across_force) * across_dir)

    def _play_input(
        self, inp: ControlInput, across: tuple[float, FloatArray] | None
    ) -> ControlInput | None:
        """The reading with the play's force added across d, on the side the force across d
        points to (SteadyConfig.play_compensation), or None when no play force above the dead
        band is known. Asked only of a reading that locates the path (a force across d above
        the dead band, which needs a known workplane). across: this reading's `_across`."""
        # a play force within the dead band is not told apart from the sensor's noise: adding
        # it only perturbs (the Jaco's 0.05 mm, 0.09 N against a 0.55 N band)
        if not inp.play_force or inp.play_force <= inp.threshold:
            return None
        assert across is not None  # a located reading has a workplane
        across_force, across_dir = across
        added = math.copysign(inp.play_force, across_force) * across_dir
        return replace(inp, force=np.asarray(inp.force, dtype=float) + added)


def _travel_scaled(inp: ControlInput, across: tuple[float, FloatArray] | None) -> ControlInput:
    """The reading with its force across d scaled from the hand's travel to the move
    (SteadyConfig.travel_scaling), or the reading as it is when the robot does not report
    what that needs, the hand has hardly moved, or the object still holds the hand."""
    k, move, x, tau = inp.stiffness, inp.last_move, inp.hand_travel, inp.tracking_time_constant
    if across is None or k is None or move is None or x is None or tau is None:
        return inp
    if not all(math.isfinite(v) and v > 0 for v in (k, move, tau, inp.dt)):
        return inp
    if not math.isfinite(x) or x < MIN_TRAVEL_SHARE * move:
        return inp
    force = np.asarray(inp.force, dtype=float)
    along = float(force @ np.asarray(inp.direction, dtype=float))
    # a passive object starting from rest holds the hand back (F.d <= 0): a push along d is
    # not this model's (a wrong wrench convention, which the self-check has not judged yet)
    if along > 0 or k * x + along <= 0:
        return inp  # ... or the force along d exceeds the travel's: the object holds the hand
    travelled = x * (1.0 + tau / inp.dt)  # the travel plus the lag the arm's damping adds
    if travelled >= move:
        return inp
    across_force, across_dir = across
    # never more than the model's largest force across d, k l sin(e) <= k l
    scaled = math.copysign(min(abs(across_force) * move / travelled, k * move), across_force)
    return replace(inp, force=force + (scaled - across_force) * across_dir)


def _across(inp: ControlInput) -> tuple[float, FloatArray] | None:
    """The reading's force across d in the workplane [N], signed along n x d, and that unit
    direction n x d (3,); None without a known workplane."""
    if inp.workplane_normal is None:
        return None
    across_dir = unit(np.cross(inp.workplane_normal, inp.direction))
    return float(np.asarray(inp.force, dtype=float) @ across_dir), across_dir


def _finite_direction(v: FloatArray) -> bool:
    return v.shape == (3,) and bool(np.all(np.isfinite(v)))


def _confidence(force_norm: float, threshold: float) -> float:
    """clip((|F| - threshold) / threshold, 0, 1); 1 for any force with no dead band."""
    if threshold <= 0:
        return 1.0 if force_norm > 0 else 0.0
    return min(1.0, max(0.0, (force_norm - threshold) / threshold))


def make_controller(
    name: str,
    policy: ConstraintAwarePolicy | None = None,
    rotation_rate: float | None = None,
    rotation_axis: FloatArray | None = None,
    params: dict[str, float] | None = None,
) -> DirectionController:
    """A controller by name: policy, policy-raw, fixed, projection or classical.

    "policy" is the learned policy as this library runs it: its action mirror-averaged about
    the known workplane normal (`policy.mirror_average`) and inside `SteadyDirection`, which
    it measured better than the policy alone on every task and both robots
    (docs/forces.md); "policy-raw" is the paper's rule d <- (d + pi(s)) / |...| alone, the
    faithful reproduction. rotation_rate [rad/s] and rotation_axis (3,) give the classical
    controller its rotational part (revolute tasks), and "policy" its feed-forward; the
    other controllers leave hand rotation to the executor. params: the classical
    controller's gains (ClassicalGains fields).
    """
    if name == "policy":
        switches = dict(params or {})
        mirror = bool(switches.pop("mirror_average", True))
        known = [f.name for f in fields(SteadyConfig) if f.type in (bool, "bool")]
        for key in switches:
            if key not in known:
                raise UnknownNameError("policy stage", key, ["mirror_average", *known])
        config = SteadyConfig(**{k: bool(v) for k, v in switches.items()})
        inner = PolicyController(policy, mirror=mirror)
        return SteadyDirection(inner, rotation_rate, config, name="policy")
    if name == "policy-raw":
        return PolicyController(policy)
    if name == "fixed":
        return FixedDirection()
    if name == "projection":
        return ProjectionController()
    if name == "classical":
        from constraint_aware.control.classical import ClassicalController, ClassicalGains

        gains = ClassicalGains(**(params or {}))
        return ClassicalController(gains, w_d=rotation_rate, axis=rotation_axis)
    raise UnknownNameError("controller", name, list(CONTROLLERS))


CONTROLLERS = ("policy", "policy-raw", "fixed", "projection", "classical")
#: The stages of controller "policy" that `make_controller`'s params can switch off.
POLICY_STAGES = (
    "mirror_average",
    *(f.name for f in fields(SteadyConfig) if f.type in (bool, "bool")),
)
#: The controllers a learned policy drives (the ones `--policy` applies to).
POLICY_CONTROLLERS = ("policy", "policy-raw")


def driving_policy(controller: object) -> ConstraintAwarePolicy | None:
    """The learned policy behind a controller ("policy", "policy-raw"), or None."""
    while isinstance(controller, SteadyDirection):
        controller = controller.inner
    return controller.policy if isinstance(controller, PolicyController) else None


def project_on_plane(direction: FloatArray, normal: FloatArray | None) -> FloatArray:
    """d with its component along the workplane normal removed (assumption 4), renormalized.

    Keeps d when it is (nearly) parallel to the normal, rather than returning a zero vector.
    """
    if normal is None:
        return direction
    p = direction - float(direction @ normal) * normal
    return unit(p) if np.linalg.norm(p) > 1e-6 else direction
