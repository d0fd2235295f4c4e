"""The closed loop of paper 3.4 and 5.1, for any robot implementing `Robot` (no MuJoCo here).

Before moving, the executor holds the hand for `timing.offset_samples` control periods and
averages one wrench reading per period into the offset F_d (and derives the dead band from
their spread when `threshold` is None). Each control step then: read the wrench and the pose,
check them (control.guards: finite, plausible, fresh), subtract F_d, stop on the force limit,
a lost grasp or contact, a failed start-of-run self-check (control.self_check), then on
success (the executor's own goal from the robot's poses, or the simulator's task monitor);
otherwise ask the controller for d_{t+1}, project it on the known workplane (assumption 4),
rotate the hand (revolute constraints: by the rotation taking d_t to d_{t+1}, paper 3.4.1; or,
for fixed-orientation grasps, by the torque policy's w), shorten the move if its predicted
force would pass the limit, bound the target (control.motion), and command it.

Two ways to drive it:
- `run(d0)` for a `Robot` whose `advance()` blocks for one control period;
- `start(d0)` then `step(wrench, pose) -> Pose | RunRecord` once per control period, for
  callback-driven stacks (a ROS 2 timer, a ros2_control controller): send the returned pose;
  a `RunRecord` means the run has finished. `run()` is exactly this loop. A second `start()`
  while a run is in progress ends that run with outcome "aborted" (the robot told to hold)
  and starts the new one.

`start` and `step` check their arguments' types and shapes (InvalidInputError naming the
argument: a list instead of a Wrench, a force of shape (2,), complex values, a NaN in d0); a
non-finite reading is a sensor fault, which the guards turn into a named stop.

At `start` the record lists the run's inputs (control.run_inputs: each value and its source:
the configuration, the robot `profile` from a calibration, the robot's reports) and the
controller's stages, and a warning names each missing input that switches a stage off (with
`ExecutorConfig.strict_inputs` the run is refused instead: MissingInputError). A dead or
frozen force sensor stops the run `sensor_dead` (control.sensor_health).

Safety invariants (each tested by injecting the fault, tests/test_faults.py): no non-finite or
oversized command is ever returned or sent; a reading above the force limit is never a
success; every stop has a named outcome (record.OUTCOMES) and a reason; the robot's optional
`hold()` is called on every stop and on any exception; on an exception (KeyboardInterrupt
included) the record is finished with outcome "error" and attached to it as `run_record`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.controllers import ControlInput, DirectionController, project_on_plane
from constraint_aware.control.executor_config import ExecutorConfig, max_grasp_play
from constraint_aware.control.guards import (
    Stop,
    arm_force,
    arm_force_stop,
    command_jump_bound,
    command_stop,
    direction_stop,
    force_limit_stop,
    step_length_stop,
)
from constraint_aware.control.motion import next_target, orient_normal, paper_turn
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.record import OUTCOMES, RunRecord, measured_step
from constraint_aware.control.robot import (
    Robot,
    TaskMonitor,
    checked_pose,
    checked_wrench,
    request_hold,
)
from constraint_aware.control.run_inputs import INPUT_NAMES, RunInput
from constraint_aware.control.run_state import RunState, begin_run, goal_reached, sample_offset
from constraint_aware.errors import InvalidInputError, check_choice
from constraint_aware.geometry import FloatArray, all_finite, in_plane, norm, unit
from constraint_aware.spatial import Pose, Wrench, turned

__all__ = [
    "INPUT_NAMES",
    "Executor",
    "ExecutorConfig",
    "command_jump_bound",
    "max_grasp_play",
    "orient_normal",
]


@dataclass
class Executor:
    """Runs one controller on one robot until success, a safety stop or the timeout."""

    robot: Robot
    controller: DirectionController
    config: ExecutorConfig = field(default_factory=ExecutorConfig)
    monitor: TaskMonitor | None = None
    profile: RobotProfile | None = None  # the robot's calibration (control.calibrate)
    _record: RunRecord | None = field(default=None, init=False, repr=False)
    _run: RunState | None = field(default=None, init=False, repr=False)

    # --- the two ways to drive it -----------------------------------------------------------
    def run(
        self, initial_direction: FloatArray, label: Mapping[str, object] | None = None
    ) -> RunRecord:
        """The whole run on a robot whose `advance()` lets one control period pass.

        Returns the finished record. On any exception the robot is told to hold, the record is
        finished with outcome "error" and attached to the exception as `run_record`."""
        try:
            self.start(initial_direction, label)
            while True:
                out = self.step(self.robot.read_wrench(), self.robot.read_pose())
                if isinstance(out, RunRecord):
                    return out
                self.robot.command_pose(out)
                self.robot.advance()
        except BaseException as exc:
            self._fail(exc)
            raise

    def start(
        self, initial_direction: FloatArray, label: Mapping[str, object] | None = None
    ) -> RunRecord:
        """Begin a run from d0 (3,), finite and non-zero; returns the record that `step` fills
        (already finished when the robot's commanded pose is not finite: nothing to hold).

        The first `timing.offset_samples` calls of `step` hold the hand (they return the
        commanded pose unchanged) and sample F_d; the moves start after them. A run still in
        progress is first ended with outcome "aborted" and the robot told to hold."""
        previous = self._record
        if previous is not None and not previous.finished:
            self._finish(previous, "aborted", "start() was called again before this run ended")
        record = RunRecord({}, [math.nan] * 3, [math.nan] * 3)
        self._record, self._run = record, None
        try:
            if label is not None and not isinstance(label, Mapping):
                raise InvalidInputError(f"label: expected a dict or None, got {label!r}")
            record.label.update(label or {})
            begun = begin_run(
                self.config, self.robot, self.controller, record, initial_direction, self.profile
            )
            if isinstance(begun, Stop):
                self._finish(record, begun.outcome, begun.reason)
            else:
                self._run = begun
        except BaseException as exc:
            self._fail(exc)
            raise
        return record

    def stop(self, outcome: str, reason: str) -> RunRecord:
        """End the started run now with a named `outcome` (one of record.OUTCOMES other than
        "success") and a `reason`; the robot is told to hold. For whatever supervises the
        run: an operator's stop, or a setup check that failed (control.probe)."""
        record = self._record
        if record is None:
            raise InvalidInputError("Executor.stop: call start() first")
        if record.finished:
            return record
        check_choice("outcome", outcome, [o for o in OUTCOMES if o != "success"])
        if not reason:
            raise InvalidInputError("Executor.stop: reason: a stop needs a reason")
        return self._finish(record, outcome, reason)

    def step(self, wrench: Wrench, pose: Pose) -> Pose | RunRecord:
        """One control period: the latest `wrench` and `pose` in, the pose to command out, or
        the finished record when the run has ended (the robot has then been told to hold).
        Raises InvalidInputError naming the argument when it is not a Wrench / Pose of real
        (3,) vectors (the record is then finished with outcome "error")."""
        record = self._record
        if record is None:
            raise InvalidInputError("Executor.step: call start() first")
        if record.finished or self._run is None:
            return record
        try:
            return self._step(self._run, checked_wrench(wrench), checked_pose(pose))
        except BaseException as exc:
            self._fail(exc)
            raise

    @property
    def record(self) -> RunRecord | None:
        """The current (or last) run's record."""
        return self._record

    @property
    def command_jump_bound(self) -> float:
        """[m] the largest change of the commanded position between two steps."""
        return command_jump_bound(self.config)

    # --- one step -----------------------------------------------------------------------------
    def _step(self, st: RunState, wrench: Wrench, pose: Pose) -> Pose | RunRecord:
        cfg = self.config
        pose_ok, pose_why = st.pose.check(pose)
        if st.offset is None:
            sampling = sample_offset(st, cfg, wrench)
            if isinstance(sampling, Stop):
                return self._end(st, sampling)
            if sampling:
                return st.target
        st.lag.note_motion(pose.position if pose_ok else None, float(self.robot.control_period))
        assert st.offset is not None
        force = wrench.force - st.offset.force
        torque = wrench.torque - st.offset.torque
        finite = all_finite(force) and all_finite(torque)
        magnitude = norm(force) if finite else math.nan
        hand = pose.position if pose_ok else np.full(3, math.nan)
        rate = st.torque_policy.w if st.torque_policy is not None else None
        st.record.steps.append(
            measured_step(
                st.moves, st.direction, force, magnitude, torque, hand, self.monitor, rate
            )
        )
        if not finite:
            return self._end(st, Stop("nan", "sensor returned a non-finite wrench"))
        if stop := st.pose.count(pose_ok, pose_why):
            return self._end(st, stop)
        if stop := st.stale.check(wrench) or st.health.check_reading(wrench.force):
            return self._end(st, stop)
        # the force limit and the faults come before success: a run above the limit is never
        # a success, whatever the monitor or the goal say
        limit = cfg.limits.force_limit
        if stop := force_limit_stop(magnitude, limit):
            return self._end(st, stop)
        st.arm_force = 0.0
        if pose_ok:
            st.arm_force = arm_force(
                st.lag, st.stiffness, cfg.step_length, pose.position, st.target.position
            )
        stop = arm_force_stop(st.arm_force, magnitude, st.stiffness, cfg.step_length, limit)
        travel = self._hand_travel(st, pose) if pose_ok else None
        if stop := st.health.classify(stop, magnitude, st.threshold, travel, cfg.step_length):
            return self._end(st, stop)
        deflected = (st.lag, pose.position, st.target.position, magnitude, st.threshold, travel)
        if pose_ok and (stop := st.health.check_deflection(*deflected, cfg.step_length)):
            return self._end(st, stop)
        if self.monitor is not None and (reason := self.monitor.grasp_failure()):
            return self._finish(st.record, "grasp_lost", reason)
        grasp_contact = getattr(self.robot, "grasp_contact", None)
        touching = grasp_contact() if grasp_contact is not None else None
        if stop := st.contact.check(magnitude, touching):
            return self._end(st, stop)
        if pose_ok and (
            why := st.self_check.check(
                st.moves,
                force,
                pose.position,
                st.target.position,
                st.direction,
                st.threshold,
                st.record.notes,
            )
        ):
            return self._finish(st.record, "sensor_convention", why)
        if stop := st.health.check_quiet(force, travel, cfg.step_length):
            return self._end(st, stop)
        if pose_ok and (reached := goal_reached(st, cfg.goal, pose)):
            return self._finish(st.record, "success", reached)
        if self.monitor is not None and self.monitor.succeeded():
            return self._finish(st.record, "success", "")
        if st.moves >= cfg.limits.max_steps:
            return self._finish(
                st.record, "timeout", f"not done after {cfg.limits.max_steps} steps"
            )
        if not pose_ok:  # an untrusted pose is not acted on: hold the last target this period
            return self._held(st, force)
        return self._move(st, force, torque, pose, travel)

    def _move(
        self,
        st: RunState,
        force: FloatArray,
        torque: FloatArray,
        pose: Pose,
        travel: float | None,
    ) -> Pose | RunRecord:
        cfg = self.config
        inp = ControlInput(
            force,
            torque,
            st.direction,
            self.robot.control_period,
            st.threshold,
            st.normal,
            _value(st.inputs["step_force"]),
            fixed_orientation=st.torque_policy is not None,
            play_force=_value(st.inputs["play_force"]) or None,  # None: no play to add
            tracking_time_constant=st.lag.tracking_time_constant,
            stiffness=st.stiffness,
            last_move=st.prediction.last_length if st.moves > 0 else None,
            hand_travel=travel,
        )
        raw = np.asarray(self.controller.next_direction(inp), dtype=float)
        if stop := direction_stop(raw):
            return self._end(st, stop)
        d_next = project_on_plane(unit(raw), st.normal)
        orientation = self._turned_hand(st, d_next, torque)
        length = float(self.controller.step_length(cfg.step_length))
        if stop := step_length_stop(length, cfg.step_length):
            return self._end(st, stop)
        if cfg.guards.predictive_force and length > 0:
            shortest = cfg.guards.min_step_fraction * cfg.step_length
            length, stop = st.prediction.limit(force, st.arm_force, length, shortest)
            if stop:
                return self._end(st, stop)
        reanchor = cfg.command_from == "measured"
        target = next_target(
            st.target, pose.position, d_next * length, st.normal, cfg.step_length, reanchor
        )
        if orientation is not None:
            target = Pose(target.position, orientation)
        # a robot not following its setpoint (frozen, e-stopped, clamped): do not let the
        # target run away, or the robot lunges when it resumes
        held, stop = st.lead.check(norm(target.position - pose.position))
        if stop:
            return self._end(st, stop)
        if held:
            return self._held(st, force)
        if stop := command_stop(target, st.target, self.command_jump_bound):
            return self._end(st, stop)
        st.prediction.note(force, length)
        st.self_check.note_move(length)
        st.command_position = pose.position.copy()
        st.pose.commanded(norm(target.position - st.target.position))
        st.target = target
        st.direction = d_next
        st.moves += 1
        return target

    def _held(self, st: RunState, force: FloatArray) -> Pose:
        """Hold the last target this period (no command change), noted as a zero move."""
        st.prediction.note(force, 0.0)
        st.self_check.note_move(0.0)
        return st.target

    def _turned_hand(self, st: RunState, d_next: FloatArray, torque: FloatArray) -> Rotation | None:
        """The target's orientation after this step's hand rotation (world frame, applied to
        the last target's); None on a prismatic constraint (the hand keeps its orientation).

        A controller's own rotation comes first: its `hand_turn()` rotation vector [rad] when
        it has one (composed without building a Rotation for it, `spatial.turned`), else its
        `hand_rotation()`; then the torque policy's w about n; else paper 3.4.1's turn."""
        if self.config.constraint_type != "revolute":
            return None
        orientation = st.target.orientation
        hand_turn = getattr(self.controller, "hand_turn", None)
        own_turn = hand_turn() if hand_turn is not None else None
        if own_turn is not None:
            return turned(own_turn, orientation)
        own = self.controller.hand_rotation()
        if own is not None:
            return own * orientation
        tp, normal = st.torque_policy, st.normal
        if tp is not None and normal is not None:
            if st.moves > 0:  # the torque read now results from the previous step's rotation
                tp.update(torque, normal)
            return turned(tp.w * normal, orientation)
        return turned(paper_turn(st.direction, d_next), orientation)

    @staticmethod
    def _hand_travel(st: RunState, pose: Pose) -> float | None:
        """[m] the hand's travel from the pose at the last move to `pose` (trusted), in the
        workplane when it is known; None before the first move."""
        if st.command_position is None:
            return None
        return norm(in_plane(pose.position - st.command_position, st.normal))

    # --- ending ------------------------------------------------------------------------------
    def _end(self, st: RunState, stop: Stop) -> RunRecord:
        return self._finish(st.record, stop.outcome, stop.reason)

    def _finish(self, record: RunRecord, outcome: str, reason: str) -> RunRecord:
        record.finish(outcome, reason, self.monitor)
        self._hold(record)
        return record

    def _hold(self, record: RunRecord) -> None:
        request_hold(self.robot, record.notes)

    def _fail(self, exc: BaseException) -> None:
        """Finish the record with outcome "error", hold, and attach the record to `exc`."""
        record = self._record
        if record is None:
            return
        if not record.finished:
            text = str(exc) or type(exc).__name__
            record.finish("error", f"{type(exc).__name__}: {text}", None)
            self._hold(record)
        try:
            exc.run_record = record  # type: ignore[attr-defined]
        except AttributeError:  # an exception type with __slots__: say so in the record
            record.notes.append("could not attach the record to the exception")


def _value(item: RunInput) -> float | None:
    """A scalar run input's value (None when missing)."""
    return item.value if isinstance(item.value, float) else None
