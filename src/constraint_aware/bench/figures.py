"""The bench's figures. They read results.json and the run records; they never run anything."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.image import imread

from constraint_aware.bench.ablation import FULL, AblationSection, without
from constraint_aware.bench.experiments import FIG6, FIG11, FIG12
from constraint_aware.control.plots import plot_trajectory
from constraint_aware.control.record import RunRecord
from constraint_aware.figio import save_figure
from constraint_aware.training.curve import plot_learning_curve

COLORS = {
    "policy": "tab:blue",
    "classical": "tab:orange",
    "projection": "tab:green",
    "fixed": "tab:gray",
    "policy, no torque policy": "tab:purple",
}


def _record(out: Path, results: dict[str, Any], name: str) -> RunRecord:
    return RunRecord.load(out / results["paper"][name]["record"])


def _curves(ax_a: Any, ax_f: Any, rec: RunRecord, label: str) -> None:
    steps = [s.step for s in rec.steps]
    color = COLORS.get(label)
    ax_a.plot(steps, rec.angles, "o-", ms=2.5, label=label, color=color)
    ax_f.plot(steps, [s.force_norm for s in rec.steps], "o-", ms=2.5, label=label, color=color)


def _finish(fig: Any, path: Path) -> str:
    return save_figure(fig, path, dpi=100).name


def fig_learning(out: Path, results: dict[str, Any]) -> str:
    refs = {k: v for k, v in results["learning"]["final_angle_deg"].items() if k != "policy"}
    path = out / "fig_learning_curve.png"
    plot_learning_curve(out / results["learning"]["log_file"], path, refs)
    return path.name


def fig6(out: Path, results: dict[str, Any]) -> str:
    fig = Figure(figsize=(10, 7))
    for i, name in enumerate(FIG6):
        info = results["paper"][name]
        ax = fig.add_subplot(2, 2, i + 1)
        snap = info.get("snapshot")
        if snap and (out / snap).is_file():
            ax.imshow(imread(out / snap))
        ax.axis("off")
        ax.set_title(f"offset {info['offset_deg']:+.0f} deg: {info['outcome']}", fontsize=10)
        ax2 = fig.add_subplot(2, 2, i + 3)
        rec = _record(out, results, name)
        ax2.plot([s.step for s in rec.steps], rec.angles, "o-", ms=3)
        ax2.axhline(0, color="grey", lw=0.8)
        ax2.set_xlabel("control step (100 ms)")
        ax2.set_ylabel("angle(d, admissible) [deg]")
        ax2.grid(True, alpha=0.3)
    fig.suptitle("Drawer-opening with the constraint-aware policy (paper fig. 6)")
    return _finish(fig, out / "fig6_drawer.png")


def fig78(out: Path, results: dict[str, Any]) -> str:
    tasks = ("drawer", "plate", "pole")
    fig = Figure(figsize=(12, 6))
    axes = fig.subplots(2, 3, sharex=True)
    for j, task in enumerate(tasks):
        for ctrl in ("classical", "policy"):
            _curves(axes[0, j], axes[1, j], _record(out, results, f"fig78_{task}_{ctrl}"), ctrl)
        axes[0, j].set_title(f"{task}, offset -30 deg")
        axes[1, j].set_xlabel("control step (100 ms)")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("angle(d, admissible) [deg]")
    axes[1, 0].set_ylabel("|F - F_d| [N]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Classical (tuned on the drawer) vs constraint-aware (paper figs. 7-8)")
    return _finish(fig, out / "fig78_classical_vs_policy.png")


def fig9(out: Path, results: dict[str, Any]) -> str:
    fig = Figure(figsize=(10, 6))
    axes = fig.subplots(2, 2, sharex="col")
    for j, task in enumerate(("door", "handle")):
        for ctrl in ("classical", "policy"):
            _curves(axes[0, j], axes[1, j], _record(out, results, f"fig9_{task}_{ctrl}"), ctrl)
        if task == "handle":
            rec = _record(out, results, "appendix_handle_policy_without_torque_policy")
            _curves(axes[0, j], axes[1, j], rec, "policy, no torque policy")
        axes[0, j].set_title(f"{task}, offset +15 deg")
        axes[1, j].set_xlabel("control step (100 ms)")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
        axes[0, j].legend(fontsize=8)
    axes[0, 0].set_ylabel("angle(d, arc tangent) [deg]")
    axes[1, 0].set_ylabel("|F - F_d| [N]")
    fig.suptitle("Revolute joints (paper fig. 9) and the torque policy (appendix)")
    return _finish(fig, out / "fig9_revolute.png")


def fig11(out: Path, results: dict[str, Any]) -> str:
    rec = _record(out, results, FIG11)
    fig = Figure(figsize=(6.4, 5))
    ax_a, ax_f = fig.subplots(2, 1, sharex=True)
    t = [0.1 * s.step for s in rec.steps]
    ax_a.plot(t, rec.angles, "o-", ms=3)
    ax_a.set_ylabel("angle to (1, 0, 0) [deg]")
    ax_f.plot(t, [s.force_norm for s in rec.steps], "o-", ms=3, color="tab:red")
    ax_f.set_ylabel("|F - F_d| [N]")
    ax_f.set_xlabel("time [s]")
    for ax in (ax_a, ax_f):
        ax.grid(True, alpha=0.3)
    fig.suptitle("Drawer-opening: angle and wrist force over time (paper fig. 11, simulated)")
    return _finish(fig, out / "fig11_drawer_force.png")


def fig12(out: Path, results: dict[str, Any]) -> str:
    rec = _record(out, results, FIG12)
    path = out / "fig12_door_trajectory.png"
    plot_trajectory(rec, path, "Door-opening: tool point, d (blue), F (red) (paper fig. 12)")
    return path.name


def fig_heatmap(out: Path, results: dict[str, Any]) -> str:
    hm = results["heatmap"]
    ctrls = list(next(iter(hm["success_rate"].values())))
    tasks = list(hm["success_rate"])
    fig = Figure(figsize=(4 * len(ctrls), 3.6))
    axes = fig.subplots(1, len(ctrls), sharey=True)
    for ax, ctrl in zip(np.atleast_1d(axes), ctrls, strict=True):
        grid = np.array([hm["success_rate"][t][ctrl] for t in tasks])
        im = ax.imshow(grid, vmin=0, vmax=1, cmap="RdYlGn", aspect="auto")
        ax.set_xticks(
            range(len(hm["offsets_deg"])),
            [f"{o:+.0f}" for o in hm["offsets_deg"]],
            fontsize=7,
            rotation=90,
        )
        ax.set_yticks(range(len(tasks)), tasks, fontsize=8)
        ax.set_title(ctrl)
        ax.set_xlabel("initial offset [deg]")
    fig.colorbar(im, ax=axes, shrink=0.8, label="success rate")
    fig.suptitle(f"Success over the initial direction error ({hm['seeds']} seeds per cell)")
    fig.savefig(out / "fig_heatmap_offsets.png", dpi=100, bbox_inches="tight")
    return "fig_heatmap_offsets.png"


def fig_sensitivity(out: Path, results: dict[str, Any]) -> str:
    sens = results["sensitivity"]
    names = list(sens)
    fig = Figure(figsize=(3.3 * len(names), 5.6))
    axes = fig.subplots(2, len(names))
    for j, name in enumerate(names):
        entry = sens[name]
        levels = entry["levels"]
        per_ctrl: dict[str, list[list[float]]] = {}
        per_peak: dict[str, list[list[float]]] = {}
        for task_data in entry["tasks"].values():
            for ctrl, v in task_data.items():
                per_ctrl.setdefault(ctrl, []).append(v["success_rate"])
                per_peak.setdefault(ctrl, []).append(v["peak_force_median_N"])
        for ctrl in per_ctrl:
            c = COLORS.get(ctrl)
            axes[0, j].plot(
                levels, np.mean(per_ctrl[ctrl], axis=0), "o-", ms=3, label=ctrl, color=c
            )
            axes[1, j].plot(levels, np.median(per_peak[ctrl], axis=0), "o-", ms=3, color=c)
        axes[0, j].set_title(f"{name} [{entry['unit']}]", fontsize=9)
        axes[0, j].set_ylim(-0.05, 1.05)
        axes[1, j].set_xlabel(entry["unit"])
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
            if name in ("joint friction x", "wrist stiffness"):
                ax.set_xscale("log")
                ax.minorticks_off()
                ax.set_xticks(levels, [f"{v:g}" for v in levels], fontsize=7)
    axes[0, 0].set_ylabel("success rate (mean over tasks)")
    axes[1, 0].set_ylabel("peak |F| [N] (median over tasks)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Sensitivity at the paper's offsets")
    return _finish(fig, out / "fig_sensitivity.png")


def fig_peak_forces(out: Path, results: dict[str, Any]) -> str:
    samples = results["headline"]["peak_force_samples"]
    tasks = list(samples)
    ctrls = list(next(iter(samples.values())))
    fig = Figure(figsize=(11, 4))
    ax = fig.subplots()
    width = 0.8 / len(ctrls)
    for k, ctrl in enumerate(ctrls):
        data = [samples[t][ctrl] for t in tasks]
        pos = np.arange(len(tasks)) + (k - (len(ctrls) - 1) / 2) * width
        bp = ax.boxplot(
            data,
            positions=pos,
            widths=width * 0.9,
            patch_artist=True,
            showfliers=True,
            flierprops={"markersize": 2},
        )
        for patch in bp["boxes"]:
            patch.set_facecolor(COLORS.get(ctrl, "white"))
            patch.set_alpha(0.6)
        ax.plot([], [], "s", color=COLORS.get(ctrl), label=ctrl)
    limit = results["meta"]["force_limit_N"]
    ax.axhline(limit, ls="--", color="tab:red", lw=0.8, label="damage limit")
    ax.set_xticks(range(len(tasks)), tasks)
    ax.set_ylabel("peak |F - F_d| [N]")
    ax.legend(fontsize=8, ncol=5)
    ax.grid(True, axis="y", alpha=0.3)
    ax.set_title("Peak force over the randomized suite")
    return _finish(fig, out / "fig_peak_forces.png")


def fig_ablation(out: Path, results: dict[str, Any]) -> str:
    """Per set, the change of each stage-off row's median mean |F| against the full
    controller's [N] (task columns); a change in successes is written in the cell."""
    sec = AblationSection.from_dict(results["ablation"])
    sets = list(dict.fromkeys(c.set for c in sec.cells))
    stage_rows = [r for r in sec.rows if r.startswith(without(""))]
    fig = Figure(figsize=(max(6.0, 4.2 * len(sets)), 0.42 * len(stage_rows) + 1.8))
    axes = np.atleast_1d(fig.subplots(1, len(sets), sharey=True))
    for ax, name in zip(axes, sets, strict=True):
        by = {(c.row, c.task): c for c in sec.cells if c.set == name}
        tasks = list(dict.fromkeys(c.task for c in sec.cells if c.set == name))
        grid = np.full((len(stage_rows), len(tasks)), np.nan)
        for i, row in enumerate(stage_rows):
            for j, task in enumerate(tasks):
                cell, full = by.get((row, task)), by.get((FULL, task))
                if cell is None or full is None:
                    continue
                grid[i, j] = cell.median_mean_force_N - full.median_mean_force_N
                if cell.successes != full.successes:
                    ax.text(j, i, f"{cell.successes - full.successes:+d}", ha="center",
                            va="center", fontsize=7)  # fmt: skip
        span = max(float(np.nanmax(np.abs(grid))) if np.any(np.isfinite(grid)) else 0.0, 0.2)
        im = ax.imshow(grid, cmap="RdBu_r", vmin=-span, vmax=span, aspect="auto")
        ax.set_xticks(range(len(tasks)), [t.split("-")[0] for t in tasks], fontsize=7)
        ax.set_title(name, fontsize=9)
        fig.colorbar(im, ax=ax, fraction=0.05)
    axes[0].set_yticks(
        range(len(stage_rows)), [r.removeprefix(without("")) for r in stage_rows], fontsize=7
    )
    fig.suptitle("Stage off minus full: median mean |F| [N] (red: higher without it)", fontsize=10)
    return _finish(fig, out / "fig_ablation.png")


def draw_all(
    out: Path, results: dict[str, Any], executor: Executor | None = None
) -> dict[str, str]:
    """Every figure the results allow, each drawn by its own call on `executor` (None: one
    after the other here); returns {figure key: file name}."""
    drawers: dict[str, Callable[[Path, dict[str, Any]], str]] = {
        "learning": fig_learning,
        "fig6": fig6,
        "fig78": fig78,
        "fig9": fig9,
        "fig11": fig11,
        "fig12": fig12,
        "peak_forces": fig_peak_forces,
    }
    if "heatmap" in results:
        drawers["heatmap"] = fig_heatmap
    if "sensitivity" in results:
        drawers["sensitivity"] = fig_sensitivity
    if "ablation" in results:
        drawers["ablation"] = fig_ablation
    if executor is None:
        return {key: draw(out, results) for key, draw in drawers.items()}
    futures = {key: executor.submit(draw, out, results) for key, draw in drawers.items()}
    return {key: future.result() for key, future in futures.items()}
