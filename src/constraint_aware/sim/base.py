"""What every embodiment is: the Robot adapter and the ground-truth monitor on one model.

The embodiments (sim/world.py: the hook hand, sim/jaco.py: the Jaco arm) derive from
`Embodiment`; the registry of them by name is sim/embodiment.py, which imports them (and not
the other way round).
"""

from __future__ import annotations

from constraint_aware.sim.grasp import grasp
from constraint_aware.sim.monitor import GroundTruthMonitor
from constraint_aware.sim.robot_adapter import SimulatedRobot


class Embodiment(GroundTruthMonitor, SimulatedRobot):
    """What every embodiment is: the Robot adapter and the ground-truth monitor on one model."""

    def reset(self) -> None:
        """Grasp the handle and settle (sim/grasp.py): F_d may be read after."""
        grasp(self)
        # the tracking time constant at the grasp configuration, fixed for the episode
        self._tracking_time_constant = self._free_space_time_constant()
