"""Grasp choreography shared by every embodiment: place, close, press, settle, re-target.

The order matters physically (physics notes): closing the fingers pre-loads the wrist, so the
wrist setpoint is reset to the measured pose and the hand settles again before F_d is read.
"""

from __future__ import annotations

from typing import Protocol

import mujoco

from constraint_aware.sim.robot_adapter import TIMESTEP
from constraint_aware.sim.tasks import TaskConfig
from constraint_aware.spatial import Pose


class GraspingRobot(Protocol):
    """An embodiment: the Robot adapter (sim/robot_adapter.py) and the ground-truth monitor
    (sim/monitor.py) on one model."""

    model: mujoco.MjModel
    data: mujoco.MjData
    task: TaskConfig
    settle_time: float

    def grasp_pose(self) -> Pose: ...
    def _place(self, pose: Pose) -> None: ...
    def _apply_setpoint(self, pose: Pose) -> None: ...
    def _rest_at_measured(self) -> None: ...
    def _step(self, n: int) -> None: ...
    def _settle_filter(self) -> None: ...
    def _record_grasp(self) -> None: ...


def grasp(robot: GraspingRobot) -> None:
    """Place the hand at the grasp, close the fingers, press if the grasp presses, settle,
    then re-target the wrist at its measured pose and settle again (F_d is read after)."""
    m, d = robot.model, robot.data
    mujoco.mj_resetData(m, d)
    pose = robot.grasp_pose()
    robot._place(pose)
    press = robot.task.press_depth
    robot._apply_setpoint(pose.moved(pose.orientation.apply([0.0, 0.0, press])))
    mujoco.mj_forward(m, d)
    settle = round(robot.settle_time / TIMESTEP)
    robot._step(settle)
    if press == 0.0:
        # no press: let the wrist rest where it settled (notes: closing pre-loads it)
        robot._rest_at_measured()
        robot._step(settle)
    robot._settle_filter()
    robot._record_grasp()
