"""One executor run's state, and what is settled before the hand moves.

`begin_run` turns the configuration, the robot's optional reports and the controller into a
run: d0 in the workplane, the normal oriented from the hinge, the stiffness in use (an
override from the configuration replaces the robot's report, with a note), the run's inputs
and the controller's stages (control.run_inputs), and the guards' state. `sample_offset`
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
    InputSource,
    RunInput,
    gather_inputs,
    stage_states,
    warn_missing,
)
from constraint_aware.control.self_check import SensorSelfCheck
from constraint_aware.control.torque_policy import TorquePolicy
from constraint_aware.deadband import noise_std, threshold_from_noise
from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray, unit
from constraint_aware.spatial import Pose, Wrench


@dataclass
class RunState:
    """The state of one run between `Executor.start` and its end."""

    record: RunRecord
    direction: FloatArray  # d_t (3,) unit
    normal: FloatArray | None  # (3,) unit workplane normal, oriented; None: 3-D motion
    target: Pose  # the last commanded pose (the hold pose before moving)
    torque_policy: TorquePolicy | None
    stiffness: float | None  # [N/m] the arm's stiffness in use (robot's report or config)
    inputs: dict[str, RunInput]  # control.run_inputs
    lag: LagModel
    pose: PoseGuard
    stale: StaleWrenchGuard
    contact: ContactGuard
    lead: LeadGuard
    prediction: ForcePrediction
    self_check: SensorSelfCheck
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
) -> RunState | Stop:
    """The run from d0 `initial_direction` (3,), finite and non-zero (InvalidInputError
    otherwise), or a stop when the robot's commanded pose is not finite (nothing to hold).
    Fills the record's notes, goal, inputs and stages, warns of missing inputs and resets the
    controller."""
    cfg = config
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
    stiffness, source = _stiffness(cfg, robot, record)
    play = cfg.robot.grasp_play
    if play is not None and play > 0:
        record.notes.append(
            f"grasp play {play * 1000:.2f} mm from the configuration"
            + ("" if stiffness is not None else ": unused without a stiffness")
        )
    tau, ignored = reported_time_constant(robot)
    if ignored:
        record.notes.append(ignored)
    if cfg.goal.travel is not None:
        record.goal = {"kind": "travel", "value": cfg.goal.travel, "unit": "m"}
    elif cfg.goal.rotation is not None:
        record.goal = {"kind": "rotation", "value": cfg.goal.rotation, "unit": "rad"}
    controller.reset(d)
    inputs = gather_inputs(
        stiffness=stiffness,
        stiffness_source=source,
        step_length=cfg.step_length,
        tracking_time_constant=tau,
        normal=normal,
        grasp_play=play,
        controller=controller,
    )
    record.inputs = {name: inputs[name].to_record() for name in INPUT_NAMES}
    record.stages, warnings = stage_states(controller, cfg.constraint_type, inputs)
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
        self_check=SensorSelfCheck(cfg.self_check.steps, stiffness, normal, lag),
    )


def _stiffness(
    cfg: ExecutorConfig, robot: Robot, record: RunRecord
) -> tuple[float | None, InputSource]:
    """[N/m] the stiffness in use and its source: the configuration's override (noted with
    the robot's report), else the robot's valid report (an invalid one is noted)."""
    stiffness, ignored = reported_stiffness(robot)
    if ignored:
        record.notes.append(ignored)
    if cfg.robot.stiffness is None:
        return stiffness, "robot"
    reported = "none" if stiffness is None else f"{stiffness:g} N/m"
    record.notes.append(
        f"stiffness {cfg.robot.stiffness:.0f} N/m from the configuration (robot reports {reported})"
    )
    return cfg.robot.stiffness, "config"


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
    limit = config.limits.force_limit
    if config.threshold is None:
        sigma = noise_std(forces)
        st.threshold = threshold_from_noise(sigma)
        st.record.notes.append(
            f"dead band {st.threshold:.3g} N derived from F_d noise {sigma:.3g} N"
        )
        if st.threshold >= limit:
            return Stop(
                "sensor_noise", f"derived dead band {st.threshold:.1f} N >= force limit {limit:g} N"
            )
    else:
        st.threshold = config.threshold
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
        travel = float(np.linalg.norm(pose.position - st.start_pose.position))
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
