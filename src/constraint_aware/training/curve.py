"""Learning-curve figure: reads a training log CSV (and reference levels), writes a PNG."""

from __future__ import annotations

import csv
from pathlib import Path

from constraint_aware.figio import new_figure, save_figure


def read_log(path: str | Path) -> dict[str, list[float]]:
    """Columns of a training log CSV as float lists."""
    with Path(path).open() as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return {}
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def plot_learning_curve(
    log_csv: str | Path,
    out_png: str | Path,
    reference_angles_deg: dict[str, float] | None = None,
    title: str = "Constraint-aware policy: learning curve",
) -> Path:
    """Mean final angle and return over timesteps, with reference controllers as lines."""
    log = read_log(log_csv)
    fig = new_figure(figsize=(11, 4))
    ax_a, ax_r = fig.subplots(1, 2)
    if log:
        steps = [t / 1e6 for t in log["timesteps"]]
        ax_a.plot(steps, log["eval_mean_final_angle_deg"], "o-", ms=3, label="policy (eval mean)")
        ax_a.plot(steps, log["eval_p95_final_angle_deg"], "--", lw=1, label="policy (eval p95)")
        ax_r.plot(steps, log["eval_mean_return"], "o-", ms=3, label="eval")
        ax_r.plot(steps, log["train_mean_return"], lw=1, alpha=0.7, label="training (stochastic)")
    colors = {"noop": "grey", "projection": "tab:red", "mu_agnostic": "tab:purple"}
    for name, level in (reference_angles_deg or {}).items():
        ax_a.axhline(level, ls=":", color=colors.get(name, "tab:green"), label=f"{name}")
    ax_a.set_yscale("log")
    ax_a.set_xlabel("env steps [millions]")
    ax_a.set_ylabel("angle(d, u) after 5 actions [deg]")
    ax_a.legend(fontsize=8)
    ax_a.grid(True, which="both", alpha=0.3)
    ax_r.set_xlabel("env steps [millions]")
    ax_r.set_ylabel("episode return  (sum of -|F|/(k step))")
    ax_r.legend(fontsize=8)
    ax_r.grid(True, alpha=0.3)
    fig.suptitle(title)
    return save_figure(fig, out_png)
