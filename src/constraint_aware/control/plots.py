"""Figures of one run record (reads records only; never runs anything)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from constraint_aware.control.record import RunRecord
from constraint_aware.figio import new_figure, save_figure


def plot_run(record: RunRecord, out_png: str | Path, title: str | None = None) -> Path:
    """Angle to the admissible direction and |F| over the control steps (paper figs. 6, 11)."""
    steps = [s.step for s in record.steps]
    fig = new_figure(figsize=(6.4, 5.2))
    ax_a, ax_f = fig.subplots(2, 1, sharex=True)
    ax_a.plot(steps, record.angles, "o-", ms=3, color="tab:blue")
    ax_a.axhline(0.0, color="grey", lw=0.8)
    ax_a.set_ylabel("angle(d, admissible) [deg]")
    ax_a.grid(True, alpha=0.3)
    forces = [s.force_norm for s in record.steps]
    ax_f.plot(steps, forces, "o-", ms=3, color="tab:red")
    limit = record.label.get("force_limit_N")
    if isinstance(limit, int | float):
        ax_f.axhline(float(limit), ls="--", color="tab:red", lw=0.8, label="damage limit")
        ax_f.legend(fontsize=8)
    ax_f.set_xlabel("control step (100 ms)")
    ax_f.set_ylabel("|F - F_d| [N]")
    ax_f.grid(True, alpha=0.3)
    lab = record.label
    default = (
        f"{lab.get('task')} / {lab.get('controller')} / offset {lab.get('offset_deg', 0):+.0f} deg"
        f": {record.outcome}"
    )
    fig.suptitle(title or default, fontsize=10)
    return save_figure(fig, out_png)


def plot_trajectory(
    record: RunRecord, out_png: str | Path, title: str | None = None, every: int = 3
) -> Path:
    """Top view of the tool point with motion-direction and force arrows (paper fig. 12)."""
    hand = np.array([s.hand_position for s in record.steps])
    dirs = np.array([s.direction for s in record.steps])
    forces = np.array([s.force for s in record.steps])
    origin = hand[0]
    xy = (hand - origin)[:, :2]
    fig = new_figure(figsize=(5.6, 5.0))
    ax = fig.subplots()
    ax.plot(xy[:, 0], xy[:, 1], "o", ms=3, color="black", label="tool point")
    idx = np.arange(0, len(xy), every)
    scale = 0.04  # [m] arrow length on the plot
    fmax = max(float(np.max(np.linalg.norm(forces[:, :2], axis=1))), 1e-9)
    for vectors, color, label in (
        (dirs[idx, :2] * scale, "tab:blue", "motion direction d"),
        (forces[idx, :2] / fmax * scale, "tab:red", "force F (scaled)"),
    ):
        ax.quiver(*xy[idx].T, *vectors.T, color=color, angles="xy", scale_units="xy", scale=1,
                  width=0.004, label=label)  # fmt: skip
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (from the start)")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(title or f"{record.label.get('task')}: tool point, d and F", fontsize=10)
    return save_figure(fig, out_png)
