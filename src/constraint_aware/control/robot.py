"""What the executor needs from a robot (real or simulated), and what only a simulator knows.

A real arm implements `Robot`: read the wrist wrench, read the hand pose, command a hand pose
to its compliant (impedance) controller, and advance one control period. `TaskMonitor` is the
ground truth a simulator can add (true admissible direction, progress, slip); the executor
records it when present and never needs it to act.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import FloatArray
from constraint_aware.spatial import Pose, Wrench

__all__ = [
    "Pose",
    "Robot",
    "TaskMonitor",
    "Wrench",
    "checked_pose",
    "checked_vector",
    "checked_wrench",
    "reported_stiffness",
    "reported_time_constant",
    "request_hold",
]


class Robot(Protocol):
    """A hand with a wrist force/torque sensor on a compliant arm.

    Conventions (the executor relies on them; `Wrench.from_sensor` converts a raw reading):
    - Frames: every vector is in one fixed world (robot base) frame; positions in [m].
    - Wrench sign: the action of everything outside the hand on the hand (the object's force
      plus the hand's weight), i.e. the raw F_s of paper 3.4.2. Pulling a drawer, the drawer
      resists: F points against the motion. Many sensors and MuJoCo report the opposite (the
      mount's action on the tool side): use `sign=-1` in `Wrench.from_sensor`. A start-of-run
      self-check stops with `sensor_convention` when the first moves contradict this.
    - Torque reference point: the tool point (TCP), the point whose pose `read_pose` returns.
    - Samples: each `read_wrench` returns a fresh sample (or a filtered one, e.g. the mean over
      the last 20 ms) taken during the last control period, never a cached copy: the executor
      stops with `stale_wrench` on identical samples and estimates the sensor noise from the
      spread of the samples it averages into F_d, one per control period.
    - The hand's weight: F_d, sampled while holding after the grasp, holds the hand's weight
      (and any grasp preload) and is subtracted from every reading. That is exact while the
      hand keeps its orientation relative to gravity (rotations about the vertical); otherwise
      compensate the weight in `Wrench.from_sensor(..., hand_mass=..., hand_com=...)`.

    Optional members, looked up with getattr by the executor:
    - `grasp_contact() -> bool | None` (below); without it contact is judged from |F|;
    - `translational_stiffness: float` [N/m], the arm's Cartesian impedance stiffness along the
      motion; with the step length it gives the step force k*delta a policy may use, the
      force predicted for the next step and the bound on the target's lead. What matters is
      the stiffness the wrist sensor sees, which an arm's joint-friction feed-forward can
      raise above its controller's setting (the simulated Jaco: 1.7-2.6 x its 1000 N/m);
      `control.probe.probe_sensor` measures it, and `ExecutorConfig.stiffness` overrides the
      report with it;
    - `tracking_time_constant: float` [s], tau: how the tool lags a commanded pose in free
      space, as a first-order response (an impedance with damping c on the tool's velocity:
      tau = c / k). A tool following a setpoint that moves at velocity v trails it by tau v,
      and settles onto a step with time constant tau. The executor's guards that compare the
      wrench with the arm's deflection (measured - commanded pose: the `not_following`
      arm-force check and the `sensor_convention` self-check) credit tau x the hand's
      measured velocity to the lag instead of to a force. Without it they assume a
      quasi-static arm (settled within one control period): true of the hook hand at 2000 N/m
      (tau 0.076 s at a 0.1 s period), not at 500 N/m (0.153 s), where they stopped 10 of 12
      correct runs. For a controller that damps the velocity error (feed-forward of the
      setpoint's velocity, as the Jaco arm's) the lag behind a moving setpoint is shorter
      than the settle time onto a step -- measured on the Jaco, lag / speed 0.11-0.16 s
      against c / k = 0.36-0.69 s; the executor takes either: its arm-force check credits no
      more lag than the hand shows.
      Reported 0.5x-1.5x of c / k, the hook hand's runs at 500-8000 N/m still pass but for
      2 of 60 (benchmarks/guard_lag.py: the self-check); the arm-force check credits no more
      lag than is there, and an over-report up to 2x does not hide a flipped or rotated
      sensor (tests/test_lag_guards.py). Ignored with a note unless finite and > 0;
    - `hold() -> None`: stop moving and hold the current measured pose (called on every stop
      and on any exception).
    """

    @property
    def control_period(self) -> float:
        """[s] time advanced by `advance`."""
        ...

    def read_wrench(self) -> Wrench:
        """The latest wrist wrench: force [N], torque [N m] about the tool point, world frame,
        sign as above; a fresh or filtered sample of the last control period."""
        ...

    def read_pose(self) -> Pose:
        """The measured tool-point pose (world frame), from the arm's own state."""
        ...

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


def request_hold(robot: object, notes: list[str]) -> None:
    """Tell the robot to hold (its optional `hold()`); a failure is appended to `notes` as a
    note naming it, not raised (a stop must still return its record)."""
    hold = getattr(robot, "hold", None)
    if hold is None:
        return
    try:
        hold()
    except Exception as exc:
        notes.append(f"robot.hold() failed: {exc!r}")


def reported_time_constant(robot: object) -> tuple[float | None, str]:
    """The robot's optional `tracking_time_constant` [s]: the value if it is a finite number
    > 0, else None; with a note naming a report that was ignored ("" when the robot reports
    none or a valid one)."""
    return _positive_report(robot, "tracking_time_constant", "[s]")


def reported_stiffness(robot: object) -> tuple[float | None, str]:
    """The robot's optional `translational_stiffness` [N/m] as the executor uses it: the value
    if it is a finite number > 0, else None; with a note naming a report that was ignored
    ("" when the robot reports none or a valid one)."""
    return _positive_report(robot, "translational_stiffness", "[N/m]")


def _positive_report(robot: object, name: str, unit: str) -> tuple[float | None, str]:
    raw = getattr(robot, name, None)
    if raw is None:
        return None, ""
    try:
        value = float(raw)
    except (TypeError, ValueError):
        value = math.nan  # not a number: ignored like a NaN
    if math.isfinite(value) and value > 0:
        return value, ""
    return None, f"ignored {name} {raw!r} (valid: finite, > 0 {unit})"


# --- readings handed to the executor: types and shapes are checked, values are not ----------
# A non-finite value is a sensor fault, which the executor's guards handle (a named stop); a
# wrong type or shape is an integration error, which raises InvalidInputError naming it.


def checked_vector(value: object, name: str, *, finite: bool = False) -> FloatArray:
    """`value` as a real float64 array of shape (3,); InvalidInputError naming `name` for any
    other type, shape or dtype (complex, bool, text, objects), and with `finite` for NaN/inf."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (3,):
        # a robot's own reading, every control period: a copy (the robot may reuse its buffer)
        if finite and not all(map(math.isfinite, value.tolist())):
            raise InvalidInputError(f"{name}: contains NaN or inf: {value!r}")
        return value.copy()
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:  # e.g. ragged nested sequences
        raise InvalidInputError(f"{name}: not a numeric array ({exc})") from exc
    if arr.dtype.kind not in "iuf":
        what = "complex" if arr.dtype.kind == "c" else f"of dtype {arr.dtype}"
        raise InvalidInputError(f"{name}: expected 3 real numbers, got values {what}: {value!r}")
    if arr.shape != (3,):
        raise InvalidInputError(f"{name}: expected shape (3,), got {arr.shape}")
    out = arr.astype(np.float64)
    if finite and not np.all(np.isfinite(out)):
        raise InvalidInputError(f"{name}: contains NaN or inf: {value!r}")
    return out


def checked_wrench(value: object, name: str = "wrench") -> Wrench:
    """`value` as a Wrench of real (3,) float arrays; InvalidInputError naming `name` (or
    `name.force`, `name.torque`) otherwise. Non-finite values pass (a sensor fault)."""
    if not isinstance(value, Wrench):
        raise InvalidInputError(
            f"{name}: expected a Wrench (force (3,) [N], torque (3,) [N m]), got "
            f"{type(value).__name__}"
        )
    force = checked_vector(value.force, f"{name}.force")
    torque = checked_vector(value.torque, f"{name}.torque")
    return Wrench(force, torque)


def checked_pose(value: object, name: str = "pose") -> Pose:
    """`value` as a Pose with a real (3,) float position and a single scipy Rotation;
    InvalidInputError naming `name` (or `name.position`, `name.orientation`) otherwise.
    Non-finite values pass (a sensor fault)."""
    if not isinstance(value, Pose):
        raise InvalidInputError(
            f"{name}: expected a Pose (position (3,) [m], orientation: a scipy Rotation), got "
            f"{type(value).__name__}"
        )
    position = checked_vector(value.position, f"{name}.position")
    orientation = value.orientation
    if not isinstance(orientation, Rotation) or not orientation.single:
        raise InvalidInputError(
            f"{name}.orientation: expected a single scipy Rotation, got {orientation!r}"
        )
    return Pose(position, orientation)
