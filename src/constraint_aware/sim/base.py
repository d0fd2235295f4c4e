"""What every embodiment is: the Robot adapter and the ground-truth monitor on one model.

The embodiments (sim/world.py: the hook hand, sim/jaco.py: the Jaco arm) derive from
`Embodiment`; the registry of them by name is sim/embodiment.py, which imports them (and not
the other way round).
"""

from __future__ import annotations

import copy

import mujoco

from constraint_aware.sim.grasp import grasp
from constraint_aware.sim.monitor import GroundTruthMonitor
from constraint_aware.sim.robot_adapter import SimulatedRobot

#: [control periods] held after the contacts go off (`Embodiment.in_free_space`).
FREE_SPACE_SETTLE_PERIODS = 20


class Embodiment(GroundTruthMonitor, SimulatedRobot):
    """What every embodiment is: the Robot adapter and the ground-truth monitor on one model."""

    def in_free_space(self, settle_periods: int = FREE_SPACE_SETTLE_PERIODS) -> Embodiment:
        """This robot with its contacts off, on a copy of its model (the cached model other
        runs share stays as it is): the hand in free space at its grasp posture, holding its
        setpoint for `settle_periods` control periods so that it lets go of the object's
        contact forces and comes to rest (a free-space calibration starts at rest). Returns
        self."""
        model = copy.copy(self.model)
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
        self.model = model
        for _ in range(settle_periods):
            self.command_pose(self.commanded_pose())
            self.advance()
        return self

    def reset(self) -> None:
        """Grasp the handle and settle (sim/grasp.py): F_d may be read after."""
        grasp(self)
        # the tracking time constant at the grasp configuration, fixed for the episode
        self._tracking_time_constant = self._free_space_time_constant()
