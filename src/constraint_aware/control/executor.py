"""The closed loop of paper 3.4 and 5.1, for any robot implementing `Robot` (no MuJoCo here).

Each control step: read the wrench, subtract the offset F_d recorded before moving, check
safety, ask the controller for d_{t+1}, project it on the known workplane (assumption 4),
rotate the hand (revolute constraints: by the rotation taking d_t to d_{t+1}, paper 3.4.1; or,
for fixed-orientation grasps, by the torque policy's w), command a 1 cm move, advance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.controllers import ControlInput, DirectionController, project_on_plane
from constraint_aware.control.record import RunRecord, StepRecord
from constraint_aware.control.robot import Robot, TaskMonitor
from constraint_aware.control.torque_policy import TorquePolicy
from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray, angle_deg, as_vector, unit
from constraint_aware.spatial import Pose, Wrench

ConstraintType = Literal["prismatic", "revolute"]
CommandFrom = Literal["measured", "target"]


@dataclass(frozen=True)
class ExecutorConfig:
    """How the loop runs. Units in brackets."""

    constraint_type: ConstraintType = "prismatic"  # decides whether the hand rotates
    workplane_normal: tuple[float, float, float] | None = (0.0, 0.0, 1.0)  # None: 3-D motion;
    # for revolute constraints oriented so that the motion turns positively about it
    step_length: float = 0.01  # [m] per control step (paper: 1 cm)
    threshold: float = 3.0  # [N] |F| below this is no force (paper 3.3.2, 6.2.2): near
    # alignment the joint's own resistance dominates F and its direction misleads; 3 N is 15 %
    # of this hand's 1 cm step force (2000 N/m), chosen from a sweep over 1, 2, 3 N (README)
    force_limit: float = 60.0  # [N] stop: the object's damage limit
    max_steps: int = 60  # stop: timeout
    contact_force: float = 1.0  # [N] without hand contact sensing: |F| above this once means
    lost_contact_force: float = 0.25  # contact was made, and |F| below this means none
    lost_contact_steps: int = 5  # stop after this many steps without contact
    offset_samples: int = 10  # wrench readings averaged into F_d before moving
    ramp_up_steps: int = 0  # >0: the first steps move 1/(n+1), 2/(n+1)... of step_length: an
    # acceleration limit that keeps the object's inertial force small (assumption 2)
    torque_policy: bool = False  # fixed-orientation grasp: rotate by the torque policy's w
    rotation_radius: float | None = None  # [m] r for the torque policy's initial w
    torque_alpha: float = 0.1  # [N m] torque policy dead-band
    torque_beta_deg: float = 1.0  # [deg] torque policy adjustment
    command_from: CommandFrom = "measured"  # "measured": re-anchor the target across d at
    # the measured pose each step; "target": accumulate targets like a stiff position robot

    def __post_init__(self) -> None:
        if self.constraint_type not in ("prismatic", "revolute"):
            raise InvalidInputError(
                f"constraint_type {self.constraint_type!r}; valid names: prismatic, revolute"
            )
        if self.torque_policy and (self.rotation_radius is None or self.rotation_radius <= 0):
            raise InvalidInputError("the torque policy needs a positive rotation_radius [m]")
        if self.command_from not in ("measured", "target"):
            raise InvalidInputError(
                f"command_from {self.command_from!r}; valid names: measured, target"
            )


@dataclass
class Executor:
    """Runs one controller on one robot until success, a safety stop or the timeout."""

    robot: Robot
    controller: DirectionController
    config: ExecutorConfig = field(default_factory=ExecutorConfig)
    monitor: TaskMonitor | None = None

    def run(
        self, initial_direction: FloatArray, label: dict[str, object] | None = None
    ) -> RunRecord:
        cfg = self.config
        d = unit(as_vector(initial_direction, "initial_direction"))
        normal = None
        if cfg.workplane_normal is not None:
            normal = unit(as_vector(cfg.workplane_normal, "workplane_normal"))
            d = project_on_plane(d, normal)
        self.controller.reset(d)
        torque_policy = None
        if cfg.torque_policy:
            assert cfg.rotation_radius is not None
            if normal is None:
                raise InvalidInputError("the torque policy needs a workplane normal")
            torque_policy = TorquePolicy(
                cfg.rotation_radius,
                cfg.step_length,
                cfg.torque_alpha,
                math.radians(cfg.torque_beta_deg),
            )

        # F_d, tau_d: after grasping, before moving; averaged so that one noisy sample does not
        # become a bias for the whole run
        samples = [self.robot.read_wrench() for _ in range(cfg.offset_samples)]
        offset = Wrench(
            np.mean([w.force for w in samples], axis=0),
            np.mean([w.torque for w in samples], axis=0),
        )
        if not (np.all(np.isfinite(offset.force)) and np.all(np.isfinite(offset.torque))):
            return RunRecord.stopped(label, "nan: sensor returned NaN before moving", offset)
        record = RunRecord.start(label, offset.force, offset.torque)
        stiffness = getattr(self.robot, "translational_stiffness", None)
        step_force = None if stiffness is None else float(stiffness) * cfg.step_length
        target = self.robot.commanded_pose()
        contact = False
        quiet = 0
        for step in range(cfg.max_steps):
            wrench = self.robot.read_wrench()
            force = wrench.force - offset.force
            torque = wrench.torque - offset.torque
            pose = self.robot.read_pose()
            if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque))):
                record.finish("nan", "sensor returned NaN", self.monitor)
                return record
            magnitude = float(np.linalg.norm(force))
            record.steps.append(
                self._step_record(step, d, force, magnitude, torque, pose.position, torque_policy)
            )
            if self.monitor is not None and self.monitor.succeeded():
                record.finish("success", "", self.monitor)
                return record
            if magnitude > cfg.force_limit:
                record.finish(
                    "force_limit",
                    f"|F| = {magnitude:.1f} N > {cfg.force_limit:.0f} N",
                    self.monitor,
                )
                return record
            if self.monitor is not None and (reason := self.monitor.grasp_failure()):
                record.finish("grasp_lost", reason, self.monitor)
                return record
            touching = self.robot.grasp_contact()
            if touching is None:  # no contact sensing in the hand: judge from the wrist force
                contact = contact or magnitude > cfg.contact_force
                touching = not (contact and magnitude < cfg.lost_contact_force)
            quiet = 0 if touching else quiet + 1
            if quiet >= cfg.lost_contact_steps:
                record.finish(
                    "contact_lost", f"no hand-object contact for {quiet} steps", self.monitor
                )
                return record

            inp = ControlInput(
                force, torque, d, self.robot.control_period, cfg.threshold, normal, step_force
            )
            d_next = project_on_plane(unit(self.controller.next_direction(inp)), normal)
            rotation = self._hand_rotation(d, d_next, torque, normal, torque_policy, step)
            length = self.controller.step_length(cfg.step_length)
            if step < cfg.ramp_up_steps:
                length *= (step + 1) / (cfg.ramp_up_steps + 1)
            target = self._next_target(target, pose.position, d_next * length, normal)
            target = Pose(target.position, rotation * target.orientation)
            self.robot.command_pose(target)
            self.robot.advance()
            d = d_next
        record.finish("timeout", f"not done after {cfg.max_steps} steps", self.monitor)
        return record

    # --- pieces of the loop -----------------------------------------------------------------
    def _hand_rotation(
        self,
        d: FloatArray,
        d_next: FloatArray,
        torque: FloatArray,
        normal: FloatArray | None,
        torque_policy: TorquePolicy | None,
        step: int,
    ) -> Rotation:
        if self.config.constraint_type != "revolute":
            return Rotation.identity()
        own = self.controller.hand_rotation()
        if own is not None:
            return own
        if torque_policy is not None and normal is not None:
            if step > 0:  # the torque read now results from the previous step's rotation
                torque_policy.update(torque, normal)
            return Rotation.from_rotvec(torque_policy.w * normal)
        # paper 3.4.1: the rotation about d_t x d_{t+1} by the angle between them
        axis = np.cross(d, d_next)
        s = float(np.linalg.norm(axis))
        if s < 1e-12:
            return Rotation.identity()
        angle = math.atan2(s, float(d @ d_next))
        return Rotation.from_rotvec(axis / s * angle)

    def _next_target(
        self, target: Pose, measured: FloatArray, move: FloatArray, normal: FloatArray | None
    ) -> Pose:
        if self.config.command_from == "target":
            return target.moved(move)
        # Release the tracking error across the new direction (where the constraint stopped
        # the hand) but keep it along the direction and out of the workplane: the target stays
        # smooth along the motion and a press keeps its depth, while each step's constraint
        # force comes from that step's move alone, as in the training environment.
        err = measured - target.position
        if normal is not None:
            err = err - float(err @ normal) * normal
        d = unit(move)
        err = err - float(err @ d) * d
        return Pose(target.position + err + move, target.orientation)

    def _step_record(
        self,
        step: int,
        d: FloatArray,
        force: FloatArray,
        force_norm: float,
        torque: FloatArray,
        hand: FloatArray,
        torque_policy: TorquePolicy | None,
    ) -> StepRecord:
        m = self.monitor
        truth = m.admissible_direction() if m is not None else None
        slip = m.slip() if m is not None else (math.nan, math.nan)
        return StepRecord(
            step=step,
            direction=d.tolist(),
            force=force.tolist(),
            force_norm=force_norm,
            torque=torque.tolist(),
            hand_position=hand.tolist(),
            handle_position=m.handle_position().tolist() if m is not None else None,
            admissible_direction=truth.tolist() if truth is not None else None,
            angle_deg=float(angle_deg(d, truth)) if truth is not None else math.nan,
            progress=m.progress() if m is not None else math.nan,
            slip_m=slip[0],
            slip_deg=slip[1],
            rotation_rate=torque_policy.w if torque_policy is not None else None,
        )
