"""report.md from results.json. Every number printed here is a value of results.json."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from constraint_aware.bench.ablation import FULL, AblationCell, AblationSection, beyond_noise
from constraint_aware.bench.analysis import CellSummary, PolicySection
from constraint_aware.bench.endtoend import report_lines as end_to_end_report_lines
from constraint_aware.bench.placement import report_lines as placement_report_lines


def _f(x: float | None, digits: int = 1) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "n/a"
    return f"{x:.{digits}f}"


def _signed(x: float) -> str:
    return f"{x:+.0f}"


def _progress(summary: dict[str, Any]) -> str:
    if summary["constraint_type"] == "revolute":
        return f"{_f(summary['progress_deg'], 0)} deg"
    return f"{_f(summary['progress_cm'], 1)} cm"


def _outcome_row(name: str, s: dict[str, Any]) -> str:
    below = s.get("first_step_below_5_deg")
    return (
        f"| {s['task']} | {s['controller']} | {_signed(s['offset_deg'])} | **{s['outcome']}** | "
        f"{_progress(s)} | {s['steps']} | {_f(s['peak_force_N'])} | {_f(s['mean_force_N'])} | "
        f"{_f(s['final_angle_deg'])} | {below if below is not None else 'never'} |"
    )


def _count(x: int | None) -> str:
    return "n/a" if x is None else f"{x:,}"


def _policy_and_robot(meta: dict[str, Any]) -> str:
    """The header's policy and robot line (absent from results written before they were
    recorded: then nothing)."""
    pol = meta.get("policy")
    if not pol:
        return ""
    robot = meta.get("robot", "hook-hand")
    return (
        f"Policy: `{pol['name']}` "
        + ("(shipped; " if pol["shipped"] else f"from `{pol['source']}` (")
        + f"observation `{pol['observation']}`; "
        f"card sha256 `{pol['card_sha256'][:16]}`, weights sha256 "
        f"`{pol['weights_sha256'][:16]}`), in every run of the policy controller except the "
        "policy section's named comparison and the paper-policy appendix run. Robot: "
        f"`{robot}` for the paper's experiments, the randomized suite, the offset map and the "
        "sensitivity; the embodiment section compares its own robots and the placement, policy "
        "and fault sections run on the hook hand.\n"
    )


def write_report(out: Path, results: dict[str, Any], figures: dict[str, str]) -> Path:
    meta = results["meta"]
    figs = meta["paper_figures"]
    lines: list[str] = []
    add = lines.append
    add("# cap bench: the constraint-aware policy, reproduced and stress-tested\n")
    mode = "quick" if meta["quick"] else "full"
    add(
        f"Mode: **{mode}**; {meta['n_tasks']} tasks, {meta['n_controllers']} controllers; "
        f"wall time {_f(meta['wall_time_s'], 0)} s on {meta['workers']} worker processes. "
        "Every number below is read from `results.json` in this folder; every figure is "
        "redrawn from it by `cap bench --replot DIR`.\n"
    )
    header = _policy_and_robot(meta)
    if header:
        add(header)
    for line in results.get("skipped", {}).values():  # sections `cap bench` could not run here
        add(f"**Skipped**: {line}.\n")

    # 1. learning
    le = results["learning"]
    fa = le["final_angle_deg"]
    add(f"## Training: the bench's policy (`{le['policy']}`)\n")
    add(f"![learning curve]({figures['learning']})\n")
    if not le.get("has_log", True):
        add("No training log was found beside the policy file: the curve shows none.\n")
    add(
        f"Preset `{le['preset']}`, {_count(le['total_timesteps'])} env steps (best checkpoint at "
        f"{_count(le['best_timesteps'])}), {_f(le['wall_time_s'], 0)} s. Mean angle between d "
        f"and the joint axis after the 5th action, over {_count(le['episodes'])} evaluation "
        "episodes:\n"
    )
    add("| controller | mean [deg] | p95 [deg] |\n|---|---|---|")
    for name, value in fa.items():
        add(f"| {name} | {_f(value, 2)} | {_f(le['p95_final_angle_deg'][name], 2)} |")
    add(
        "\n`mu_agnostic` is the friction-aware correction for the median friction: a policy "
        "that sees only (F/|F|, d) cannot separate the direction error from the friction tilt, "
        "so this is about the best such a policy can do; `oracle` knows the friction.\n"
    )

    study = le.get("observation_study")
    if study:
        add("### Why this observation (the observation study, recorded in the policy's card)\n")
        add(
            "| observation | standard mean [deg] | with resistance mean [deg] | "
            "probe worst [deg] | closed loop successes | median peak [N] | mean F [N] |\n"
            + "|---" * 7
            + "|"
        )
        for row in study["rows"]:
            add(
                f"| {row['observation']} | {_f(row['standard_mean_deg'], 2)} | "
                f"{_f(row['resistance_mean_deg'], 2)} | {_f(row['probe_worst_deg'], 1)} | "
                f"{row['closed_loop_successes']}/{row['closed_loop_runs']} | "
                f"{_f(row['closed_loop_median_peak_N'])} | {_f(row['closed_loop_mean_force_N'])} |"
            )
        add(f"\nChosen: `{study['chosen']}`. {study['reason']}\n")

    # 2. fig 6
    paper = results["paper"]
    add(f"## Drawer-opening with direction errors (paper fig. {figs['drawer']})\n")
    add(f"![drawer]({figures['fig6']})\n")
    header = (
        "| task | controller | offset [deg] | outcome | progress | steps | peak F [N] | "
        "mean F [N] | final angle [deg] | first step < 5 deg |\n" + "|---" * 10 + "|"
    )
    add(header)
    for name in ("fig6_drawer_+30_policy", "fig6_drawer_-30_policy"):
        add(_outcome_row(name, paper[name]))
    add("")

    # 3. figs 7-8
    add(
        f"## Classical vs constraint-aware on three prismatic tasks (paper figs. "
        f"{figs['comparison'][0]}-{figs['comparison'][1]})\n"
    )
    add(f"![comparison]({figures['fig78']})\n")
    add(header)
    for name, s in paper.items():
        if name.startswith("fig78_"):
            add(_outcome_row(name, s))
    add(
        "\nThe classical controller's gains were tuned on drawer-opening only "
        "(`benchmarks/tune_classical.py`) and used unchanged everywhere.\n"
    )

    # 4. fig 9 + appendix
    add(f"## Revolute joints and the torque policy (paper fig. {figs['revolute']}, appendix)\n")
    add(f"![revolute]({figures['fig9']})\n")
    add(header)
    for name, s in paper.items():
        if name.startswith(("fig9_", "appendix_")):
            label = dict(s)
            if name.startswith("appendix_handle_paper_policy"):
                label["controller"] = "paper policy without torque policy"
            elif name.startswith("appendix_"):
                label["controller"] = "policy without torque policy"
            add(_outcome_row(name, label))
    add("")

    # 5. figs 11-12
    add(
        f"## Force over time and the door's trajectory (paper figs. {figs['force']}, "
        f"{figs['trajectory']}, in simulation)\n"
    )
    add(f"![force]({figures['fig11']})\n\n![trajectory]({figures['fig12']})\n")

    # headline
    head = results["headline"]
    add("## Headline: randomized suite\n")
    add(
        f"On `{meta.get('robot', 'hook-hand')}`. "
        f"{head['seeds']} seeds per task and controller; friction, mass and damping scaled by "
        f"U({_f(meta['randomization']['scale'][0])}, {_f(meta['randomization']['scale'][1])}), "
        f"offsets uniform in ±{_f(meta['randomization']['prismatic_offset_deg'], 0)} deg "
        f"(prismatic) and ±{_f(meta['randomization']['revolute_offset_deg'], 0)} deg (revolute). "
        "Cells: successes / runs, median peak force [N].\n"
    )
    table = head["table"]
    ctrls = list(next(iter(table.values())))
    add("| task | " + " | ".join(ctrls) + " |")
    add("|---" * (len(ctrls) + 1) + "|")
    for task, row in table.items():
        cells = [
            f"{row[c]['successes']}/{row[c]['n']}, {_f(row[c]['peak_force_median_N'])}"
            for c in ctrls
        ]
        add(f"| {task} | " + " | ".join(cells) + " |")
    add(f"\n![peak forces]({figures['peak_forces']})\n")

    # beyond
    if "heatmap" in results:
        add("## Beyond the paper: how large an initial error each controller survives\n")
        add(f"![heat map]({figures['heatmap']})\n")
        hm = results["heatmap"]
        add("Widest symmetric offset range with every run successful:\n")
        add("| task | " + " | ".join(ctrls) + " |")
        add("|---" * (len(ctrls) + 1) + "|")
        for task in hm["success_rate"]:
            cells = []
            for c in ctrls:
                w = hm["full_success_halfwidth_deg"][task][c]
                cells.append("none" if w is None else f"±{_f(w, 0)}")
            add(f"| {task} | " + " | ".join(cells) + " |")
        add("")
    if "sensitivity" in results:
        add("## Beyond the paper: sensitivity\n")
        add(f"![sensitivity]({figures['sensitivity']})\n")
        add(
            "For each factor, the first level at which some run of that controller fails "
            "(any task at the paper's offset), or `-` when none does:\n"
        )
        sens = results["sensitivity"]
        add("| factor | levels | " + " | ".join(ctrls) + " |")
        add("|---" * (len(ctrls) + 2) + "|")
        for name, entry in sens.items():
            levels = ", ".join(_fmt_level(v) for v in entry["levels"])
            cells = []
            for c in ctrls:
                lv = entry["first_failure"][c]
                cells.append(
                    "-" if lv is None else f"{_fmt_level(lv)} ({entry['first_failure_task'][c]})"
                )
            add(f"| {name} [{entry['unit']}] | {levels} | " + " | ".join(cells) + " |")
        add("")
    if "embodiment" in results:
        lines += _embodiment_section(results["embodiment"], results["learning"]["policy"])
    if "placement" in results:
        lines.extend(placement_report_lines(results["placement"]))
    if "end_to_end" in results:
        lines.extend(end_to_end_report_lines(results["end_to_end"]))
    if results.get("worst_cases"):
        add("## Worst cases of the constraint-aware policy\n")
        add(
            "| task | offset [deg] | seed | outcome | peak F [N] | conditions |\n"
            + "|---" * 6
            + "|"
        )
        for w in results["worst_cases"]:
            cond = ", ".join(f"{k}={_fmt_level(v)}" for k, v in w["overrides"]) or "preset"
            if w["randomized"]:
                cond = "randomized " + cond
            if any(w["sensor_bias_N"]):
                cond += f", bias {_f(w['sensor_bias_magnitude_N'], 2)} N"
            cond += f", noise {_f(w['sensor_noise_N'], 2)} N"
            if w.get("robot", "hook-hand") != "hook-hand":
                cond += f", robot `{w['robot']}`"
            add(
                f"| {w['task']} | {_f(w['offset_deg'], 1)} | {w['seed']} | {w['outcome']} | "
                f"{_f(w['peak_force_N'])} | {cond} |"
            )
        add("")
    if "policy_section" in results:
        lines.extend(policy_section_lines(PolicySection.from_dict(results["policy_section"])))
    if "ablation" in results:
        lines.extend(ablation_lines(AblationSection.from_dict(results["ablation"]), figures))
    if results.get("faults"):
        _faults_section(add, results["faults"], results["learning"]["policy"])
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _cell(c: CellSummary) -> str:
    return f"{c.successes}/{c.n}, {_f(c.median_peak_force_N)}, {_f(c.mean_force_N)}"


def _table(cells: list[CellSummary], first: str, key: Any) -> list[str]:
    ctrls = list(dict.fromkeys(c.controller for c in cells))
    rows: dict[Any, dict[str, CellSummary]] = {}
    for c in cells:
        rows.setdefault(key(c), {})[c.controller] = c
    n_keys = first.count("|") + 1
    out = [f"| {first} | " + " | ".join(ctrls) + " |", "|---" * (len(ctrls) + n_keys) + "|"]
    for k, row in rows.items():
        label = " | ".join(str(x) for x in k) if isinstance(k, tuple) else str(k)
        out.append(
            f"| {label} | " + " | ".join(_cell(row[c]) if c in row else "" for c in ctrls) + " |"
        )
    return out


def policy_section_lines(sec: PolicySection) -> list[str]:
    """The policy section: the default policy as run (controller "policy"), after a setup
    probe, and alone ("policy-raw"), the paper's policy as published, classical, projection."""
    lines = [
        "## Policies: default vs default + probe vs default (raw) vs paper vs classical vs "
        "projection\n"
    ]
    lines.append(
        f"Every controller runs with the dead band derived from the sensor noise "
        f"({_f(sec.sensor_noise_N, 1)} N per axis: {_f(sec.threshold_N, 1)} N), not a hand-set "
        "one. `default` is the default policy as controller `policy` runs it: its action "
        "averaged with its mirror image about the workplane normal, inside SteadyDirection "
        "(docs/design/default-controller.md): the start's reading scaled from the hand's "
        "travel, the part of the last reading a reading still carries removed, overshoot "
        "damping and, on revolute joints, the rotation rate v / r the classical controller is "
        "also given. The hand turns at that rate from the first move; d turns with the path "
        "once a reading has located it (a force across d above the dead band). "
        "`default + probe` is the same after a setup probe on a twin of the task (`cap run "
        "--probe`, control.probe): the arm stiffness the wrist sees and the grasp's play, "
        "which `policy` adds back on its first reading across d. "
        "`default (raw)` and `paper` are the policies alone (controller `policy-raw`, paper "
        "3.3's d + pi(s)). Cells: successes / runs, median peak |F| [N], mean |F| [N].\n"
    )
    if sec.suite:
        lines.append("### Randomized suite\n")
        lines.extend(_table(sec.suite, "task", lambda c: c.task))
        lines.append("")
    lines.append("### The paper's offsets\n")
    lines.extend(_table(sec.paper_offsets, "task", lambda c: c.task))
    lines.append("\n### Resistance map (paper offsets)\n")
    lines.extend(
        _table(
            sec.resistance, "factor | level | task", lambda c: (c.axis, _fmt_level(c.level), c.task)
        )
    )
    lines.append("")
    return lines


def ablation_lines(sec: AblationSection, figures: dict[str, str] | None = None) -> list[str]:
    """The ablation section: per set, one row per stage of controller "policy" switched off
    (everything else on) beside the full controller and the paper's rule alone."""
    b = sec.benchmark_seeds
    lines = [
        "## The default controller's stages, each switched off\n",
        "Controller `policy` with one stage off and every other stage on (`policy without "
        "STAGE`), beside the full controller and `policy-raw` (the paper's rule alone; "
        "docs/design/default-controller.md says what each stage does). Sensor noise "
        f"{_f(sec.sensor_noise_N, 1)} N per axis, the dead band derived from it. This bench "
        "runs "
        + "; ".join(f"{name}: {what}" for name, what in sec.seeds.items())
        + f". The full sets ({b['suite']} suite seeds per task on each robot, {b['noise']} "
        f"noise seeds per paper offset, {b['map']} seeds per resistance-map condition) are "
        "`benchmarks/ablation.py`'s; the run that decided which stages stay is "
        "`benchmarks/results/ablation_every_stage.json`. Cells: successes / "
        "runs, median peak |F| [N], median of the runs' mean |F| [N]; **bold**: beyond noise "
        f"({_f(sec.noise_percent, 0)} % or {_f(sec.noise_floor_N, 1)} N, whichever is larger, "
        "or any change in successes) against the full controller; `-`: not run, the "
        "stage cannot act there (the known rotation on a prismatic joint; the play "
        "compensation, which needs the play a setup probe measures, has its numbers in the "
        "benchmark's results).\n",
    ]
    if figures and "ablation" in figures:
        lines.append(f"![ablation]({figures['ablation']})\n")
    for set_name in dict.fromkeys(c.set for c in sec.cells):
        cells = [c for c in sec.cells if c.set == set_name]
        tasks = list(dict.fromkeys(c.task for c in cells))
        by = {(c.row, c.task): c for c in cells}
        lines.append(f"### {set_name}\n")
        lines.append("| row | " + " | ".join(tasks) + " |")
        lines.append("|---" * (len(tasks) + 1) + "|")
        for row in sec.rows:
            entries = [
                _ablation_cell(by[(row, t)], by.get((FULL, t))) if (row, t) in by else "-"
                for t in tasks
            ]
            if any(e != "-" for e in entries):
                lines.append(f"| {row} | " + " | ".join(entries) + " |")
        lines.append("")
    return lines


def _ablation_cell(c: AblationCell, full: AblationCell | None) -> str:
    text = f"{c.successes}/{c.n}, {_f(c.median_peak_force_N, 2)}, {_f(c.median_mean_force_N, 2)}"
    if full is None or c.row == FULL:
        return text
    differs = (
        c.successes != full.successes
        or beyond_noise(c.median_peak_force_N, full.median_peak_force_N)
        or beyond_noise(c.median_mean_force_N, full.median_mean_force_N)
    )
    return f"**{text}**" if differs else text


def _fmt_level(v: float) -> str:
    return f"{v:g}"


def _embodiment_cells(rows: list[dict[str, Any]], robots: list[str], ctrls: list[str]) -> list[str]:
    """Rows per task and controller, a column per robot: successes / runs, median peak and
    median mean |F| [N]."""
    index = {(r["task"], r["controller"], r["robot"]): r for r in rows}
    out = ["| task | controller | " + " | ".join(robots) + " |", "|---" * (len(robots) + 2) + "|"]
    for task in dict.fromkeys(r["task"] for r in rows):
        for c in ctrls:
            cells = []
            for robot in robots:
                r = index.get((task, c, robot))
                cells.append(
                    "-"
                    if r is None
                    else f"{r['successes']}/{r['n']}, {_f(r['peak_force_median_N'])}, "
                    f"{_f(r['mean_force_median_N'])}"
                )
            out.append(f"| {task} | {c} | " + " | ".join(cells) + " |")
    return out


def _embodiment_section(emb: dict[str, Any], policy: str = "default") -> list[str]:
    robots, ctrls = emb["robots"], emb["controllers"]
    out = [
        "## Embodiments: the same controllers on the hook hand and on a Kinova Jaco arm\n",
        "Embodiment 1 is the hook hand on virtual Cartesian joints; embodiment 2 the Kinova Jaco "
        "arm and 3-finger hand (dm-control's models) under an operational-space impedance "
        f"controller. The policy is the bench's (`{policy}`) and the classical gains are those "
        "tuned on embodiment 1's drawer; nothing is retuned. Cells: successes / runs, median "
        "peak |F|, median mean |F| [N].\n",
    ]
    if emb["transfer"]:
        out.append(f"Randomized suite, {emb['seeds']} seeds per task and controller:\n")
        out += _embodiment_cells(emb["transfer"], robots, ctrls)
        out.append("")
    shown: list[list[str]] = []
    for level in dict.fromkeys(r["level"] for r in emb["paper"]):
        band = "the executor's default dead band" if level is None else f"a {level:g} N dead band"
        cells = _embodiment_cells([r for r in emb["paper"] if r["level"] == level], robots, ctrls)
        if cells in shown:  # the default dead band is derived from the noise: often the same
            out.append(f"The paper's conditions with {band}: the same cells as above.\n")
            continue
        shown.append(cells)
        out.append(f"The paper's conditions (seed 0, paper offsets), {band}:\n")
        out += cells
        out.append("")
    if emb["variants"]:
        periods = emb["simulated_period_s"]
        out.append(
            "Variants on the paper's conditions (all tasks pooled): successes / runs, the median "
            "over tasks of the median peak |F| [N]. Simulated period per nominal period: "
            + ", ".join(f"{k} s -> {_f(v, 3)} s" for k, v in periods.items())
            + ".\n"
        )
        vctrls = list(dict.fromkeys(r["controller"] for r in emb["variants"]))
        cols = [f"{rb} {c}" for rb in robots for c in vctrls]
        out.append("| variant | level | " + " | ".join(cols) + " |")
        out.append("|---" * (len(cols) + 2) + "|")
        keys = dict.fromkeys((r["variant"], r["level"]) for r in emb["variants"])
        for variant, level in keys:
            cells = []
            for rb in robots:
                for c in vctrls:
                    rows = [
                        r
                        for r in emb["variants"]
                        if (r["variant"], r["level"], r["robot"], r["controller"])
                        == (variant, level, rb, c)
                    ]
                    n = sum(r["n"] for r in rows)
                    ok = sum(r["successes"] for r in rows)
                    peaks = sorted(r["peak_force_median_N"] for r in rows)
                    cells.append(f"{ok}/{n}, {_f(peaks[len(peaks) // 2])}" if rows else "-")
            out.append(f"| {variant} | {_fmt_level(level)} | " + " | ".join(cells) + " |")
        out.append("")
    return out


def _faults_section(add: Any, faults: dict[str, Any], policy: str) -> None:
    """Fault injection (bench/faults.py): counts per fault and class."""
    c = faults["counts"]
    add("## Fault injection: the executor under robot and sensor faults\n")
    add(
        f"The bench's policy (`{policy}`) on each task (hook hand) with one fault injected after "
        f"{faults['onset_moves']} moves (sensor conventions: from the start). Dangerous: a "
        f"non-finite or oversized command, a true |F| above {faults['force_limit_factor']} x "
        "the limit, success above the limit, no record, a stop without a reason, no hold "
        "(the faults: `constraint_aware.bench.faults.FAULTS`). "
        f"Totals: **{c['dangerous']} dangerous**, {c['safe_stop']} safe stops, "
        f"{c['continued']} correct continuations.\n"
    )
    add("| fault | safe stop | continued | dangerous |\n|---|---|---|---|")
    for name, row in faults["by_fault"].items():
        add(f"| `{name}` | {row['safe_stop']} | {row['continued']} | {row['dangerous']} |")
    add("")
