"""The start-of-run sensor self-check: is the wrench convention the one the executor assumes?

Guarded against: a wrist sensor whose sign is flipped or whose frame is rotated (a driver's
convention, a mounting error). Such a reading drives every force-based decision the wrong
way: a policy follows the wrong direction and the force checks judge the wrong force. The
self-check judges the reading against physics over the first `self_check.steps` moves and
stops `sensor_convention` with a reason naming the likely fault.

Two tests, on the workplane's components only (nothing commands the normal axis, and a press
force along it need not be the wrist spring's):

- cosine with the deflection: on a compliant arm F = k x the deflection (control.lag), so F
  points along the hand's deflection. A median cos(F, deflection) near -1 means a flipped
  sign, below 0 a frame rotated by more than 90 deg.
- F along the move: a passive object does not push the hand along its commanded move, so
  F.d <= 0 up to friction and noise; a consistent positive F.d/|F| means a flipped sign or a
  rotated frame. The wrench is read as the hand decelerates at the end of a period, when the
  hand's and the object's inertia do push along the move, so this test is not applied once
  the arm confirms the convention: cos(F, deflection) agrees both with the reported lag and
  with a share of it (CONFIRM_LAG_SHARE), which no wrong convention does; nor once a judged
  move read F well against the move (AGAINST): the object held the hand back there, which a
  flipped sign does not read against a passive object.

The reading after a hold and the one after the hand starts again are transients the lag
model does not describe: they enter the cosine test only (SETTLE_MOVES). Moves with too little
in-plane force or deflection are not judged, nor, on a robot whose profile measured the
deflection model's error (control.sensor_health.DeflectionModel), moves whose deflection implies
no more force than that error, a + b |v|: there the lag credit tau v, large at speed, leaves a
remainder whose direction the model does not know (a joint-impedance arm's Cartesian stiffness
is not one k along every direction); with too few judged moves the check records
"inconclusive" and lets the run go on. The constants' measured origins:
docs/design/executor-guards.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.guards import HOLD_LENGTH
from constraint_aware.control.lag import LagModel
from constraint_aware.control.sensor_health import DeflectionModel
from constraint_aware.geometry import FloatArray, in_plane, norm

#: [N] only moves whose in-plane |F| is above the dead band and this are judged.
MIN_FORCE = 2.0
#: [m] the cosine test needs an in-plane deflection above this (less on a stiff arm) ...
MIN_DEFLECTION = 0.002
#: [m] ... but never below this floor against pose noise.
DEFLECTION_FLOOR = 0.0002
#: Judged moves a verdict needs; with fewer the check is inconclusive.
MIN_SAMPLES = 3
#: The median F.d/|F| above which the object "pushes the hand along its move".
MAX_ALONG = 0.1
#: A settled move whose F.d/|F| is below this read the object holding the hand back, which a
#: flipped sign cannot read against a passive object: the F.d test then gives no verdict.
AGAINST = -0.5
#: The median cos(F, deflection) from which the arm confirms the wrench convention.
CONFIRM_COS = 0.5
#: The confirmation must also hold with this share of the reported tracking_time_constant, so
#: that an over-reported lag cannot confirm a rotated frame.
CONFIRM_LAG_SHARE = 0.5
#: After a hold, the F.d test and the confirmation take readings again from this many moves on.
SETTLE_MOVES = 2


def _agree(cosines: list[float]) -> bool:
    """Whether the moves agree with the arm: median cosine at least CONFIRM_COS."""
    return bool(cosines) and float(np.median(cosines)) >= CONFIRM_COS


def min_check_deflection(stiffness: float | None) -> float:
    """[m] the smallest deflection the cosine test compares with F: MIN_DEFLECTION, or on an
    arm of known `stiffness` [N/m] the deflection of MIN_FORCE if smaller, never below
    DEFLECTION_FLOOR."""
    if stiffness is None:
        return MIN_DEFLECTION
    by_force = max(MIN_FORCE / stiffness, DEFLECTION_FLOOR)
    return min(MIN_DEFLECTION, by_force)


@dataclass
class SensorSelfCheck:
    """The self-check's state over one run's first `steps` moves.

    steps: moves judged (0: off); stiffness: [N/m] the arm's, or None; normal: (3,) unit
    workplane normal, or None (3-D: the whole vectors are judged); lag: the run's lag model;
    model: the robot profile's deflection model with its measured error, or None.
    """

    steps: int
    stiffness: float | None
    normal: FloatArray | None
    lag: LagModel
    model: DeflectionModel | None = None
    along: list[float] = field(default_factory=list)  # F.d / |F| per settled move
    cosines: list[float] = field(default_factory=list)  # cos(F, deflection) per move
    confirm: list[float] = field(default_factory=list)  # the same with CONFIRM_LAG_SHARE of tau
    within_error: int = 0  # moves the cosine test left alone: within the model's error
    moves_since_hold: int = SETTLE_MOVES  # commands since the last hold (HOLD_LENGTH)

    def note_move(self, length: float) -> None:
        """A command of `length` [m] was sent (or the last target held: 0)."""
        self.moves_since_hold = 0 if length < HOLD_LENGTH else self.moves_since_hold + 1

    def arm_confirms(self) -> bool:
        """Whether the arm has confirmed the convention: over at least MIN_SAMPLES moves the
        median cos(F, deflection) is at least CONFIRM_COS, both with the reported lag and with
        CONFIRM_LAG_SHARE of it (a flipped sign gives about -1, a frame rotated by 90 deg about
        0; an over-reported lag adds deflection along the motion that a rotated frame can
        match, which the smaller share does not)."""
        if min(len(self.cosines), len(self.confirm)) < MIN_SAMPLES:
            return False
        return _agree(self.cosines) and _agree(self.confirm)

    def check(
        self,
        moves: int,
        force: FloatArray,
        position: FloatArray,
        target: FloatArray,
        direction: FloatArray,
        threshold: float,
        notes: list[str],
    ) -> str:
        """After `moves` moves: judge `force` (3,) [N] at the hand's `position` (3,) [m] with
        its `target` (3,) [m], the move along `direction` (3,) unit and the dead band
        `threshold` [N]; a reason when the convention is wrong, else "". At the last judged
        move a note (passed or inconclusive) goes to `notes`."""
        if moves == 0 or moves > self.steps:
            return ""
        why = self._verdict(force, position, target, direction, threshold)
        if not why and moves == self.steps:
            notes.append(self._summary(threshold))
        return why

    def _summary(self, threshold: float) -> str:
        along = float(np.median(self.along)) if self.along else math.nan
        cos = float(np.median(self.cosines)) if self.cosines else math.nan
        lag = "" if self.lag.tracking_time_constant is None else " with the lag model"
        confirms = self.arm_confirms()
        skipped = " (not applied: the arm confirms)" if confirms else ""
        counts = (
            f"median F.d/|F| {along:.2f} ({len(self.along)} moves){skipped}, "
            f"cos(F, deflection) {cos:.2f} ({len(self.cosines)} moves){lag}"
        )
        if self.within_error:
            counts += (
                f", {self.within_error} more moves' deflection within the calibrated model's "
                f"error (not judged)"
            )
        # a test that judged fewer than MIN_SAMPLES moves has said nothing
        judged = len(self.cosines) >= MIN_SAMPLES or (
            len(self.along) >= MIN_SAMPLES and not confirms
        )
        if judged:
            return f"self-check passed: {counts}"
        return (
            f"self-check inconclusive: too few of the first {self.steps} moves had an in-plane "
            f"force of {max(threshold, MIN_FORCE):.1f} N or more ({MIN_SAMPLES} needed): "
            f"{counts}"
        )

    def _within_model_error(self, deflection: float) -> bool:
        """Whether an in-plane `deflection` [m] implies no more force than the deflection
        model's measured error at the hand's speed (never, without a model); counted."""
        m = self.model
        if m is None:
            return False
        within = m.stiffness * deflection <= m.error_at(self.lag.velocity)
        self.within_error += within
        return within

    def _verdict(
        self,
        force: FloatArray,
        position: FloatArray,
        target: FloatArray,
        direction: FloatArray,
        threshold: float,
    ) -> str:
        # a hand stopping or starting again: compared with the deflection only
        settled = self.moves_since_hold >= SETTLE_MOVES
        force = in_plane(force, self.normal)
        magnitude = norm(force)
        if magnitude < max(threshold, MIN_FORCE):
            return ""
        if settled:
            self.along.append(float(force @ direction) / magnitude)
        deflection = in_plane(self.lag.deflection(position, target), self.normal)
        size = norm(deflection)
        if size > min_check_deflection(self.stiffness) and not self._within_model_error(size):
            self.cosines.append(float(force @ deflection) / (magnitude * size))
            if settled:
                half = in_plane(
                    self.lag.deflection(position, target, CONFIRM_LAG_SHARE), self.normal
                )
                half_size = max(norm(half), 1e-12)
                self.confirm.append(float(force @ half) / (magnitude * half_size))
        # With a share of the lag credited F agrees with the deflection: the full credit is
        # what disagrees (it over-states the lag against a steady resistance), not the
        # convention. A flipped sign or a frame rotated by 90 deg disagrees at either share.
        if len(self.cosines) >= MIN_SAMPLES and not _agree(self.confirm):
            c = float(np.median(self.cosines))
            n = len(self.cosines)
            if c < -0.5:
                return (
                    f"wrench sign flipped (or frame rotated)? F points against the hand's "
                    f"deflection (median cos {c:.2f} over {n} moves)"
                )
            if c < 0.0:
                return (
                    f"sensor frame rotated ~{math.degrees(math.acos(c)):.0f} deg? F is not along "
                    f"the hand's deflection (median cos {c:.2f} over {n} moves)"
                )
        if len(self.along) >= MIN_SAMPLES and not self.arm_confirms():
            a = float(np.median(self.along))
            if a > MAX_ALONG and min(self.along) >= AGAINST:
                return (
                    f"wrench sign flipped or frame rotated? the object pushes the hand along "
                    f"its commanded move (median F.d/|F| = {a:.2f} over {len(self.along)} moves)"
                )
        return ""
