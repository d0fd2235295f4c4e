"""The record of one run: per-step measurements and the outcome, saved as JSON."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.control.robot import TaskMonitor
from constraint_aware.spatial import Wrench

OUTCOMES = ("success", "force_limit", "grasp_lost", "contact_lost", "nan", "timeout")


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


@dataclass
class RunRecord:
    label: dict[str, Any]
    force_offset: list[float]  # F_d (3,) [N]
    torque_offset: list[float]  # tau_d (3,) [N m]
    steps: list[StepRecord] = field(default_factory=list)
    outcome: str = "running"
    reason: str = ""
    success: bool = False
    progress: float = math.nan  # final, [m] or [rad]
    slip_m: float = math.nan
    slip_deg: float = math.nan

    @classmethod
    def start(
        cls, label: dict[str, Any] | None, force: np.ndarray, torque: np.ndarray
    ) -> RunRecord:
        return cls(dict(label or {}), force.tolist(), torque.tolist())

    @classmethod
    def stopped(cls, label: dict[str, Any] | None, reason: str, offset: Wrench) -> RunRecord:
        rec = cls(dict(label or {}), offset.force.tolist(), offset.torque.tolist())
        rec.outcome, rec.reason = "nan", reason
        return rec

    def finish(self, outcome: str, reason: str, monitor: TaskMonitor | None) -> None:
        self.outcome, self.reason = outcome, reason
        self.success = outcome == "success"
        if monitor is not None:
            self.progress = monitor.progress()
            self.slip_m, self.slip_deg = monitor.slip()

    # --- summaries ------------------------------------------------------------------------
    @property
    def n_steps(self) -> int:
        return max(len(self.steps) - 1, 0)  # the last entry is the measurement that ended it

    @property
    def peak_force(self) -> float:
        return max((s.force_norm for s in self.steps), default=0.0)

    @property
    def mean_force(self) -> float:
        return float(np.mean([s.force_norm for s in self.steps])) if self.steps else 0.0

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
        return {"summary": self.summary(), **asdict(self)}

    def save(self, path: str | Path) -> Path:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(self.to_dict(), indent=1, allow_nan=True) + "\n")
        return out

    @classmethod
    def load(cls, path: str | Path) -> RunRecord:
        data = json.loads(Path(path).read_text())
        data.pop("summary", None)
        steps = [StepRecord(**s) for s in data.pop("steps")]
        return cls(steps=steps, **data)
