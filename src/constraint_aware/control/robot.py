"""What the executor needs from a robot (real or simulated), and what only a simulator knows.

A real arm implements `Robot`: read the wrist wrench, read the hand pose, command a hand pose
to its compliant (impedance) controller, and advance one control period. `TaskMonitor` is the
ground truth a simulator can add (true admissible direction, progress, slip); the executor
records it when present and never needs it to act.
"""

from __future__ import annotations

from typing import Protocol

from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose, Wrench

__all__ = ["Pose", "Robot", "TaskMonitor", "Wrench"]


class Robot(Protocol):
    """A hand with a wrist force/torque sensor on a compliant arm.

    Optional members, looked up with getattr by the executor:
    - `grasp_contact() -> bool | None` (below);
    - `translational_stiffness: float` [N/m], the arm's Cartesian impedance stiffness along the
      motion; with the step length it gives the step force k*delta a policy may use;
    - `hold() -> None`: stop moving and hold the current measured pose (called on every stop).
    """

    @property
    def control_period(self) -> float:
        """[s] time advanced by `advance`."""
        ...

    def read_wrench(self) -> Wrench: ...

    def read_pose(self) -> Pose: ...

    def commanded_pose(self) -> Pose:
        """The compliant controller's current setpoint (differs from `read_pose` under load,
        e.g. while pressing on an object)."""
        ...

    def grasp_contact(self) -> bool | None:
        """Whether the hand still touches the object, from the hand's own sensing (finger
        torques, tactile pads); None when the hand cannot tell."""
        ...

    def command_pose(self, pose: Pose) -> None:
        """Set the compliant controller's target, reached over the next control period."""
        ...

    def advance(self) -> None:
        """Let one control period pass."""
        ...


class TaskMonitor(Protocol):
    """Simulation ground truth for records and success; optional for the executor."""

    def admissible_direction(self) -> FloatArray:
        """(3,) unit: the guide axis, or the arc's tangent at the hand (opening sense)."""
        ...

    def progress(self) -> float:
        """Opening so far: [m] prismatic, [rad] revolute."""
        ...

    def succeeded(self) -> bool: ...

    def grasp_failure(self) -> str | None:
        """A reason when the grasp is lost (separation or slip beyond the limit), else None."""
        ...

    def slip(self) -> tuple[float, float]:
        """Drift of the hand relative to the handle since the grasp: ([m], [deg])."""
        ...

    def handle_position(self) -> FloatArray: ...
