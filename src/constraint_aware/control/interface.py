"""What a direction controller sees each control step, and what it must provide.

Every controller module imports these (and nothing of the other controllers), so the
controllers and the registry that builds them by name form no import cycle. `INPUT_NAMES`,
the run inputs a stage may need, has its home in `control.run_inputs`, where the executor
gathers and records them; it is re-exported here for the controllers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from scipy.spatial.transform import Rotation

from constraint_aware.control.run_inputs import INPUT_NAMES
from constraint_aware.geometry import FloatArray

__all__ = ["INPUT_NAMES", "ControlInput", "DirectionController", "StagedController"]


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
    """Given the offset force and d_t, return d_{t+1}.

    A controller may also provide `stage_inputs(constraint_type) -> dict[str, tuple[str,
    ...]]`: for each of its stages that applies to the constraint type ("prismatic" or
    "revolute"), the `INPUT_NAMES` it needs; the executor asks it at the start of a run (a
    controller without it is run all the same).
    """

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
        (paper 3.4.1 on revolute constraints, or the torque policy). A controller may also
        have an optional `hand_turn() -> FloatArray | None`, the same turn as a (3,) rotation
        vector [rad] in the world frame, which the executor asks first (it composes the turn
        without building a scipy Rotation: the cheaper path each control period)."""
        ...


class StagedController(DirectionController, Protocol):
    """A `DirectionController` that says what its stages need (every controller
    `make_controller` builds is one)."""

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """For each stage acting on `constraint_type` ("prismatic" or "revolute"), the
        `INPUT_NAMES` it needs ({} for a controller without stages)."""
        ...
