"""Figures of one run record (reads records only; never runs anything)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from constraint_aware.control.probe import ProbeResult
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


def plot_probe(result: ProbeResult, out_png: str | Path, title: str | None = None) -> Path:
    """A setup probe (control.probe): left, each push direction in the workplane with the force
    change it met (green: judged and opposed to the stretch, red: judged otherwise, grey: not
    judged); right, each push's stiffness against the robot's report."""
    dirs = np.array([p.direction for p in result.pushes]).reshape(-1, 3)
    forces = np.array([p.force_change for p in result.pushes]).reshape(-1, 3)
    if result.workplane_normal is not None and len(dirs):
        n = np.asarray(result.workplane_normal, dtype=float)
        e1 = dirs[0] - float(dirs[0] @ n) * n
        e1 = e1 / max(float(np.linalg.norm(e1)), 1e-12)
        basis = np.stack([e1, np.cross(n, e1)])  # (2, 3): in-plane axes
        axes = ("along push 1", "n x push 1")
    else:
        basis, axes = np.eye(3)[:2], ("x", "y")
    d2, f2 = dirs @ basis.T, forces @ basis.T
    fmax = max(float(np.max(np.linalg.norm(f2, axis=1), initial=0.0)), 1e-9)
    fig = new_figure(figsize=(10.0, 4.6))
    ax_p, ax_k = fig.subplots(1, 2)
    for push, tip, df in zip(result.pushes, d2, f2, strict=True):
        color = "grey"
        if push.judged and push.cos is not None:
            color = "tab:green" if push.cos <= -0.5 else "tab:red"
        ax_p.plot([0, tip[0]], [0, tip[1]], color="lightgrey", lw=1)
        ax_p.annotate("", xy=tip + 0.6 * df / fmax, xytext=tip,
                      arrowprops={"arrowstyle": "->", "color": color, "lw": 1.6})  # fmt: skip
        ax_p.text(*(tip * 1.05), f"{np.linalg.norm(df):.1f} N", fontsize=7, ha="center")
    ax_p.set_aspect("equal")
    ax_p.set_xlim(-1.8, 1.8)
    ax_p.set_ylim(-1.8, 1.8)
    ax_p.set_xlabel(axes[0])
    ax_p.set_ylabel(axes[1])
    ax_p.set_title(f"pushes and the force change dF (longest {fmax:.1f} N)", fontsize=9)
    angles = np.degrees(np.arctan2(d2[:, 1], d2[:, 0])) if len(d2) else np.zeros(0)
    push_k = [p.push_stiffness for p in result.pushes]
    arm_k = [np.nan if p.arm_stiffness is None else p.arm_stiffness for p in result.pushes]
    ax_k.bar(angles - 6, push_k, width=12, color="lightgrey", label="push: -dF.u / amplitude")
    ax_k.bar(angles + 6, arm_k, width=12, color="tab:blue", label="arm: |dF| / |stretch| (judged)")
    if result.reported_stiffness is not None:
        ax_k.axhline(result.reported_stiffness, ls="--", color="black", lw=1,
                     label=f"reported {result.reported_stiffness:.0f} N/m")  # fmt: skip
    ax_k.set_xlabel("push direction [deg from push 1]")
    ax_k.set_ylabel("stiffness [N/m]")
    ax_k.legend(fontsize=7)
    ax_k.grid(True, alpha=0.3)
    fig.suptitle(title or f"probe: {result.verdict} ({result.reason})", fontsize=9)
    return save_figure(fig, out_png)
