"""The record of one run: per-step measurements and the outcome, saved as JSON."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.control.robot import TaskMonitor
from constraint_aware.geometry import angle_deg

#: Every way a run ends, with what it means. Safety stops come before `success` each step: a
#: run whose reading is above the force limit or whose sensors fail is never a success.
OUTCOME_MEANINGS: dict[str, str] = {
    "success": "the goal (ExecutorConfig.goal.travel / goal.rotation) or the task monitor's "
    "success was reached",
    "force_limit": "|F| read above the force limit, or the next step was refused because its "
    "predicted force would pass it",
    "grasp_lost": "the task monitor saw the hand slip off or separate (simulation)",
    "contact_lost": "no hand-object contact for guards.lost_contact_steps steps",
    "nan": "the wrench reading (or F_d) was not finite",
    "bad_pose": "the pose reading was not finite or jumped further than the hand can move, "
    "for guards.pose_fault_steps steps in a row; or the robot's commanded pose was not finite "
    "at the start (nothing to hold)",
    "bad_command": "the command would have been non-finite or jumped beyond the bound (not sent)",
    "not_following": "the target led the measured pose by more than guards.max_lead for "
    "guards.follow_patience steps, or the arm's deflection (less the lag the robot reports as its "
    "tracking_time_constant) implies much more force than the sensor reads (robot frozen, "
    "e-stopped or its setpoint clamped; or a sensor reading low)",
    "stale_wrench": "the same wrench sample was read guards.stale_steps times in a row",
    "sensor_dead": "the force reading stayed within the dead band while the moving hand's "
    "deflection implied a larger force, read only noise around zero while the hand moved, or "
    "froze (its spread far below the sensor's noise sigma; control.sensor_health)",
    "sensor_noise": "the F_d samples were so noisy that the derived dead band reached the "
    "force limit",
    "sensor_convention": "the first moves contradict the wrench convention (flipped sign or "
    "rotated sensor frame), or a setup probe found it wrong (control.probe; no move made)",
    "timeout": "limits.max_steps moves made without success",
    "aborted": "start() was called again before the run ended: this run was ended, the robot "
    "told to hold, and the new run started",
    "error": "an exception ended the run (the reason holds its text); the record is attached "
    "to the exception as `run_record`",
}
OUTCOMES = tuple(OUTCOME_MEANINGS)


@dataclass
class StepRecord:
    """One control step, measured before the move of that step. Units: m, N, N m, deg."""

    step: int
    direction: list[float]  # d_t (3,)
    force: list[float]  # F = F_s - F_d (3,) [N], world frame
    force_norm: float  # |F| [N]
    torque: list[float]  # tau - tau_d (3,) [N m] about the tool point
    hand_position: list[float]  # tool point (3,) [m]
    handle_position: list[float] | None  # (3,) [m] (simulation only)
    admissible_direction: list[float] | None  # (3,) unit (simulation only)
    angle_deg: float  # angle(d_t, admissible direction) [deg] (simulation only)
    progress: float  # [m] or [rad] (simulation only)
    slip_m: float  # hand-handle drift since the grasp [m] (simulation only)
    slip_deg: float  # hand-handle rotation drift [deg] (simulation only)
    rotation_rate: float | None  # torque policy's w [rad/step]


def measured_step(
    step: int,
    direction: np.ndarray,
    force: np.ndarray,
    force_norm: float,
    torque: np.ndarray,
    hand: np.ndarray,
    monitor: TaskMonitor | None,
    rotation_rate: float | None,
) -> StepRecord:
    """The record of one step: d_t (3,), F (3,) [N] and |F| [N], the torque (3,) [N m], the
    hand's position (3,) [m] (NaN when untrusted), the torque policy's w [rad/step], and what
    the task `monitor` knows (simulation ground truth; NaN/None without one)."""
    truth = monitor.admissible_direction() if monitor is not None else None
    slip = monitor.slip() if monitor is not None else (math.nan, math.nan)
    return StepRecord(
        step=step,
        direction=direction.tolist(),
        force=force.tolist(),
        force_norm=force_norm,
        torque=torque.tolist(),
        hand_position=hand.tolist(),
        handle_position=monitor.handle_position().tolist() if monitor is not None else None,
        admissible_direction=truth.tolist() if truth is not None else None,
        angle_deg=float(angle_deg(direction, truth)) if truth is not None else math.nan,
        progress=monitor.progress() if monitor is not None else math.nan,
        slip_m=slip[0],
        slip_deg=slip[1],
        rotation_rate=rotation_rate,
    )


@dataclass
class RunRecord:
    """One run. `outcome` is "running" until finished, then one of OUTCOMES."""

    label: dict[str, Any]
    force_offset: list[float]  # F_d (3,) [N]
    torque_offset: list[float]  # tau_d (3,) [N m]
    steps: list[StepRecord] = field(default_factory=list)
    outcome: str = "running"
    reason: str = ""
    success: bool = False
    progress: float = math.nan  # final, [m] or [rad] (task monitor)
    slip_m: float = math.nan
    slip_deg: float = math.nan
    threshold: float = math.nan  # [N] the dead band used (configured or derived from F_d)
    goal: dict[str, Any] | None = None  # the executor's own goal: kind, value, reached
    notes: list[str] = field(default_factory=list)  # what the executor decided on its own
    # each run input (control.run_inputs.INPUT_NAMES): {"value": ..., "source": ...}
    inputs: dict[str, dict[str, Any]] = field(default_factory=dict)
    # each stage the controller declares: "active" or "off: missing <input>[, <input>]"
    stages: dict[str, str] = field(default_factory=dict)

    @classmethod
    def start(
        cls, label: dict[str, Any] | None, force: np.ndarray, torque: np.ndarray
    ) -> RunRecord:
        return cls(dict(label or {}), force.tolist(), torque.tolist())

    @property
    def finished(self) -> bool:
        return self.outcome != "running"

    def finish(self, outcome: str, reason: str, monitor: TaskMonitor | None) -> None:
        if outcome not in OUTCOMES:
            raise ValueError(f"outcome {outcome!r}; valid names: {', '.join(OUTCOMES)}")
        self.outcome, self.reason = outcome, reason
        self.success = outcome == "success"
        if monitor is not None:
            try:
                self.progress = monitor.progress()
                self.slip_m, self.slip_deg = monitor.slip()
            except Exception as exc:  # the record must survive a failing monitor too
                self.notes.append(f"task monitor failed at finish: {exc!r}")

    # --- summaries ------------------------------------------------------------------------
    @property
    def n_steps(self) -> int:
        return max(len(self.steps) - 1, 0)  # the last entry is the measurement that ended it

    def _finite_forces(self) -> list[float]:
        """|F| of the steps with a finite reading (a run may end on a non-finite one)."""
        return [s.force_norm for s in self.steps if math.isfinite(s.force_norm)]

    @property
    def peak_force(self) -> float:
        return max(self._finite_forces(), default=0.0)

    @property
    def mean_force(self) -> float:
        forces = self._finite_forces()
        return float(np.mean(forces)) if forces else 0.0

    @property
    def angles(self) -> list[float]:
        return [s.angle_deg for s in self.steps]

    @property
    def final_angle(self) -> float:
        return self.steps[-1].angle_deg if self.steps else math.nan

    def summary(self) -> dict[str, Any]:
        return {
            **self.label,
            "outcome": self.outcome,
            "success": self.success,
            "reason": self.reason,
            "steps": self.n_steps,
            "progress": self.progress,
            "peak_force_N": self.peak_force,
            "mean_force_N": self.mean_force,
            "final_angle_deg": self.final_angle,
            "slip_m": self.slip_m,
            "slip_deg": self.slip_deg,
        }

    def to_dict(self) -> dict[str, Any]:
        """Strict-JSON-ready: NaN and inf become None (null), numpy scalars plain numbers."""
        out: dict[str, Any] = _strict({"summary": self.summary(), **asdict(self)})
        return out

    def save(self, path: str | Path) -> Path:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=False) + "\n")
        return out

    @classmethod
    def load(cls, path: str | Path) -> RunRecord:
        data = json.loads(Path(path).read_text())
        data.pop("summary", None)
        steps = [StepRecord(**_nan_for_none(s, _STEP_FLOATS)) for s in data.pop("steps")]
        return cls(steps=steps, **_nan_for_none(data, _RUN_FLOATS))


_STEP_FLOATS = ("force_norm", "angle_deg", "progress", "slip_m", "slip_deg")
_RUN_FLOATS = ("progress", "slip_m", "slip_deg", "threshold")


def _nan_for_none(data: dict[str, Any], names: tuple[str, ...]) -> dict[str, Any]:
    """JSON null back to NaN for the float fields that may be unknown."""
    return {k: (math.nan if k in names and v is None else v) for k, v in data.items()}


def _strict(value: Any) -> Any:
    """A copy of nested dicts/lists with non-finite floats as None (strict JSON)."""
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_strict(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
