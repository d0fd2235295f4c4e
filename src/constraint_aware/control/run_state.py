"""One executor run's state, and what is settled before the hand moves.

`begin_run` turns the configuration, the robot's optional reports and the controller into a
run: d0 in the workplane, the normal oriented from the hinge, what is known about the robot
and where from (the configuration, a robot profile, the robot's reports: control.run_inputs,
with a note for each report replaced), the run's inputs and the controller's stages, and the
guards' state. `sample_offset`
collects the wrench offset F_d over the hold before moving and derives the dead band from its
spread. `goal_reached` is the executor's own success, judged on the robot's poses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from constraint_aware.control.controllers import DirectionController, project_on_plane
from constraint_aware.control.executor_config import ExecutorConfig, GoalConfig
from constraint_aware.control.guards import (
    ContactGuard,
    ForcePrediction,
    LeadGuard,
    PoseGuard,
    StaleWrenchGuard,
    Stop,
)
from constraint_aware.control.lag import LagModel
from constraint_aware.control.motion import orient_normal
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.record import RunRecord
from constraint_aware.control.robot import (
    Robot,
    checked_pose,
    checked_vector,
    reported_stiffness,
    reported_time_constant,
)
from constraint_aware.control.run_inputs import (
    INPUT_NAMES,
    SOURCE_WORDS,
    RunInput,
    check_profile_period,
    gather_inputs,
    measured_dead_band,
    refuse_missing,
    resolve_robot_values,
    stage_states,
    warn_missing,
)
from constraint_aware.control.self_check import SensorSelfCheck
from constraint_aware.control.sensor_health import SensorHealth
from constraint_aware.control.torque_policy import TorquePolicy
from constraint_aware.deadband import noise_std, threshold_from_noise
from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray, norm, unit
from constraint_aware.spatial import Pose, Wrench


@dataclass
class RunState:
    """The state of one run between `Executor.start` and its end."""

    record: RunRecord
    direction: FloatArray  # d_t (3,) unit
    normal: FloatArray | None  # (3,) unit workplane normal, oriented; None: 3-D motion
    target: Pose  # the last commanded pose (the hold pose before moving)
    torque_policy: TorquePolicy | None
    stiffness: float | None  # [N/m] the arm's stiffness in use (config, profile or robot)
    inputs: dict[str, RunInput]  # control.run_inputs
    lag: LagModel
    pose: PoseGuard
    stale: StaleWrenchGuard
    contact: ContactGuard
    lead: LeadGuard
    prediction: ForcePrediction
    self_check: SensorSelfCheck
    health: SensorHealth
    dead_band: float | None  # [N] the configured or profile dead band; None: derived from F_d
    samples: list[Wrench] = field(default_factory=list)  # F_d samples, one per period
    offset: Wrench | None = None  # F_d, tau_d once sampled
    threshold: float = math.nan  # [N] dead band in use
    start_pose: Pose | None = None  # the trusted pose when moving began
    moves: int = 0  # control steps taken (commands sent after F_d)
    arm_force: float = 0.0  # [N] |F| implied by the arm's deflection (lower bound)
    command_position: FloatArray | None = None  # [m] (3,) the trusted pose at the last move


def begin_run(
    config: ExecutorConfig,
    robot: Robot,
    controller: DirectionController,
    record: RunRecord,
    initial_direction: object,
    profile: RobotProfile | None = None,
) -> RunState | Stop:
    """The run from d0 `initial_direction` (3,), finite and non-zero (InvalidInputError
    otherwise), or a stop when the robot's commanded pose is not finite (nothing to hold).
    Fills the record's notes, goal, inputs and stages, warns of missing inputs (with
    `strict_inputs`: raises MissingInputError instead) and resets the controller. `profile`:
    the robot's calibration (control.profile), which must be at the robot's control period
    (ProfileFileError otherwise)."""
    cfg = config
    if profile is not None:
        check_profile_period(profile, float(robot.control_period))
    d = unit(checked_vector(initial_direction, "initial_direction", finite=True))
    if not np.linalg.norm(d) > 0.5:
        raise InvalidInputError("initial_direction: must be a non-zero vector")
    hold = checked_pose(robot.commanded_pose(), "robot.commanded_pose()")
    quat = hold.orientation.as_quat()
    if not (np.all(np.isfinite(hold.position)) and np.all(np.isfinite(quat))):
        return Stop("bad_pose", "the robot's commanded pose is not finite: nothing to hold")
    normal = None
    if cfg.workplane_normal is not None:
        normal = np.asarray(cfg.workplane_normal, dtype=float)
        if cfg.constraint_type == "revolute" and cfg.hinge_point is not None:
            oriented = orient_normal(normal, d, hold.position, cfg.hinge_point)
            if float(oriented @ normal) < 0:
                record.notes.append("workplane_normal flipped: d0 turns negatively about it")
            normal = oriented
        d = project_on_plane(d, normal)
    torque_policy = None
    if cfg.torque_policy.enabled and cfg.rotation_radius is not None:
        tp = cfg.torque_policy
        beta = math.radians(tp.beta_deg)
        torque_policy = TorquePolicy(cfg.rotation_radius, cfg.step_length, tp.alpha, beta)
    reported_k, ignored_k = reported_stiffness(robot)
    reported_tau, ignored_tau = reported_time_constant(robot)
    record.notes.extend(note for note in (ignored_k, ignored_tau) if note)
    if profile is not None:
        record.notes.append(
            f"robot profile {profile.robot!r} measured {profile.measured_at} ({profile.outcome})"
        )
    values = resolve_robot_values(
        stiffness_override=cfg.robot.stiffness,
        grasp_play_override=cfg.robot.grasp_play,
        threshold=cfg.threshold,
        reported_stiffness=reported_k,
        reported_time_constant=reported_tau,
        profile=profile,
        notes=record.notes,
    )
    stiffness, tau, play = values.stiffness, values.tracking_time_constant, values.grasp_play
    if play is not None and play > 0:
        record.notes.append(
            f"grasp play {play * 1000:.2f} mm from the {SOURCE_WORDS[values.grasp_play_source]}"
            + ("" if stiffness is not None else ": unused without a stiffness")
        )
    if cfg.goal.travel is not None:
        record.goal = {"kind": "travel", "value": cfg.goal.travel, "unit": "m"}
    elif cfg.goal.rotation is not None:
        record.goal = {"kind": "rotation", "value": cfg.goal.rotation, "unit": "rad"}
    controller.reset(d)
    inputs = gather_inputs(
        values=values, step_length=cfg.step_length, normal=normal, controller=controller
    )
    record.inputs = {name: inputs[name].to_record() for name in INPUT_NAMES}
    record.stages, warnings = stage_states(controller, cfg.constraint_type, inputs)
    if cfg.strict_inputs:
        refuse_missing(warnings)
    warn_missing(warnings)
    lag = LagModel(tau)
    g = cfg.guards
    return RunState(
        record=record,
        direction=d,
        normal=normal,
        target=hold,
        torque_policy=torque_policy,
        stiffness=stiffness,
        inputs=inputs,
        lag=lag,
        pose=PoseGuard(g.pose_jump_margin, g.pose_fault_steps),
        stale=StaleWrenchGuard(g.stale_steps),
        contact=ContactGuard(g.contact_force, g.lost_contact_force, g.lost_contact_steps),
        lead=LeadGuard.for_run(cfg, stiffness),
        prediction=ForcePrediction(stiffness, cfg.limits.force_limit),
        self_check=SensorSelfCheck(
            cfg.self_check.steps, stiffness, normal, lag, values.deflection_model
        ),
        health=SensorHealth.for_run(values.force_noise, values.deflection_model),
        dead_band=values.dead_band,
    )


def sample_offset(st: RunState, config: ExecutorConfig, wrench: Wrench) -> bool | Stop:
    """Collect one F_d sample: True while sampling (the hand holds), False once F_d and the
    dead band are set (the last sample is also the first control step's reading: before
    moving nothing has changed), a stop when the samples are unusable."""
    st.samples.append(wrench)
    if len(st.samples) < config.timing.offset_samples:
        return True  # hold: one fresh reading per control period
    forces = np.array([w.force for w in st.samples])
    torques = np.array([w.torque for w in st.samples])
    st.offset = Wrench(forces.mean(axis=0), torques.mean(axis=0))
    st.record.force_offset = st.offset.force.tolist()
    st.record.torque_offset = st.offset.torque.tolist()
    if not (np.all(np.isfinite(forces)) and np.all(np.isfinite(torques))):
        return Stop("nan", "sensor returned NaN before moving")
    trusted = st.pose.trusted
    if trusted is None:
        return Stop("bad_pose", "no finite pose before moving")
    if stop := st.health.offset_sampled(forces):
        return stop
    limit = config.limits.force_limit
    if st.dead_band is None:
        sigma = noise_std(forces)
        st.threshold = threshold_from_noise(sigma)
        st.record.notes.append(
            f"dead band {st.threshold:.3g} N derived from F_d noise {sigma:.3g} N"
        )
        st.inputs["dead_band"] = measured_dead_band(st.threshold)
        st.record.inputs["dead_band"] = st.inputs["dead_band"].to_record()
    else:
        st.threshold = st.dead_band
    if st.threshold >= limit:
        return Stop("sensor_noise", f"dead band {st.threshold:.1f} N >= force limit {limit:g} N")
    st.record.threshold = st.threshold
    st.start_pose = trusted
    st.lag.begin(trusted.position, st.target.position)
    return False


def goal_reached(st: RunState, goal: GoalConfig, pose: Pose) -> str:
    """A reason when the `goal` is reached by the hand at `pose` (the robot's own poses:
    travel from the start pose, or rotation about the workplane normal); its progress goes to
    the record's goal."""
    if st.start_pose is None or st.record.goal is None:
        return ""
    if goal.travel is not None:
        travel = norm(pose.position - st.start_pose.position)
        st.record.goal["reached"] = travel
        if travel >= goal.travel:
            return f"goal: travel {travel * 100:.1f} cm >= {goal.travel * 100:.1f} cm"
    elif goal.rotation is not None and st.normal is not None:
        turn = (pose.orientation * st.start_pose.orientation.inv()).as_rotvec()
        angle = float(turn @ st.normal)
        st.record.goal["reached"] = angle
        if angle >= goal.rotation:
            return (
                f"goal: rotation {math.degrees(angle):.1f} deg >= "
                f"{math.degrees(goal.rotation):.1f} deg"
            )
    return ""
