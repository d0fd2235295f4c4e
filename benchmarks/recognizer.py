"""The contact-points recognizers on held-out placements and sizes, per kind. Writes JSON,
prints a table.

    nice -n 10 python benchmarks/recognizer.py [--scenes 40] [--seed 7] [--data FILE.npz]
        [--kinds drawer,...] [--per-crop] [--no-distractors] [--noiseless]
        [--out benchmarks/results/recognizer.json]

Held-out crops (lfo/grasp_data.py with a seed `cap train-grasp` does not use: other
placements, sizes, distractors and demonstration offsets), from both robots' head cameras;
per kind and method (the shipped CNN, the geometric baseline): the contact-point error's
median and 95th percentile [mm], the approach error's 95th percentile [deg], and the share of
crops without an answer; the same again ("handle seen") on the crops whose camera sees at
least half of the handle around the contact point (lfo.grasp_data's SEEN_SHARE within
CONTACT_RADIUS; the truth, used in scoring only): a distractor standing in front of the
contact point hides it from any single view.
The execution sequence looks twice: the CNN's answer for a head crop aims the wrist camera
(lfo.perception.WRIST_CAMERAS) from its look pose, and the head and wrist images together are
recognized again (lfo.grasp_data.second_look_rows; the hand itself is not in these scenes).
The `cnn, second look` rows score that second answer, one per head crop: the grasp the
sequence goes to; `geometric, second look` the baseline's own pipeline (its second looks
aimed by its first answers; a crop it does not answer for gets none).
Also, as a further row per kind in the same table (`demonstration`), what the recognizers
start from: the demonstrated point's own distance from the contact point and the nominal
approach's error. `--kinds`: those kinds' scenes only (the same scenes as in the full set);
`--per-crop`: also every crop's errors, its scene (8 crops each: 4 per robot's camera), the
share of its cells without a depth return and the shares of the handle and of its
surroundings of the contact point its camera sees unoccluded. `--no-distractors` (the same
placements and demonstrations, other crop offsets) and `--noiseless` (sim.camera.NO_NOISE)
take the distractors or the sensor's noise away, to tell what hides a handle.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from constraint_aware.bench.provenance import write_results
from constraint_aware.lfo.grasp_data import (
    HEAD,
    SECOND_LOOK,
    SEEN_SHARE,
    GraspDataset,
    LookFrom,
    generate,
)
from constraint_aware.lfo.grasp_training import (
    DEMONSTRATION,
    Scores,
    demonstration_scores,
    score,
)
from constraint_aware.recognizer import (
    ContactPointRecognizer,
    GeometricRecognizer,
    GraspFrame,
    RecognitionError,
    Recognizer,
)
from constraint_aware.sim.camera import NO_NOISE
from constraint_aware.sim.tasks import KINDS

HERE = Path(__file__).parent
TARGETS = {"median_mm": 5.0, "p95_mm": 15.0, "approach_p95_deg": 10.0}
CROPS_PER_SCENE = 8  # lfo.grasp_data.generate's default: 4 crops per view, 2 robots' cameras
SECOND_LOOK_METHOD = "cnn, second look"
BASELINE_SECOND_LOOK = "geometric, second look"


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def _per_crop(data: GraspDataset, scores: dict[str, Scores]) -> list[dict[str, object]]:
    """Every crop: kind, scene (its index among the kind's scenes), robot, the demonstrated
    point's offset [mm], the share of cells without a return, the share of the handle its
    camera sees unoccluded (lfo.grasp_data.handle_visibility), each method's contact-point
    error [mm] (None: no answer)."""
    out: list[dict[str, object]] = []
    seen: dict[str, int] = {}
    for i in range(len(data)):
        kind = str(data.kinds[i])
        n = seen.get(kind, 0)
        seen[kind] = n + 1
        row: dict[str, object] = {
            "kind": kind,
            "scene": n // CROPS_PER_SCENE,
            "robot": str(data.robots[i]),
            "offset_mm": 1000.0 * float(data.offsets[i]),
            "no_return": float(np.isnan(data.heights[i]).mean()),
            "handle_visible": float(data.visible[i]),
            "contact_visible": float(data.contact_visible[i]),
        }
        for name, s in scores.items():
            e = float(s.position[i])
            row[f"{name}_mm"] = 1000.0 * e if np.isfinite(e) else None
        out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=40, help="held-out scenes per kind")
    parser.add_argument("--seed", type=int, default=7, help="of the held-out scenes")
    parser.add_argument("--data", help="score these crops (a GraspDataset .npz) instead")
    parser.add_argument("--kinds", default=",".join(KINDS), help="object kinds, comma-separated")
    parser.add_argument("--per-crop", action="store_true", help="every crop's errors too")
    parser.add_argument(
        "--no-distractors", action="store_true", help="the same placements without distractors"
    )
    parser.add_argument(
        "--noiseless", action="store_true", help="the rendered depth without the sensor's noise"
    )
    parser.add_argument("--out", default=str(HERE / "results" / "recognizer.json"))
    args = parser.parse_args()
    start = time.perf_counter()
    kinds_asked = tuple(k for k in args.kinds.split(",") if k)
    cnn = ContactPointRecognizer.load()
    baseline = GeometricRecognizer()

    def aimed_by(found: Recognizer) -> LookFrom:
        """Second looks where `found` answers for each head crop, as the sequence aims."""

        def look_from(
            robot: str, frame: GraspFrame, height: np.ndarray, shape: str
        ) -> tuple[np.ndarray, np.ndarray] | None:
            try:
                r = found.recognize(np.asarray(height, dtype=float), frame, shape)
            except RecognitionError:
                return None  # the sequence stops before it looks again
            return r.contact_point, r.approach

        return look_from

    def rendered(aim: Recognizer) -> GraspDataset:
        return generate(
            args.scenes,
            seed=args.seed,
            kinds=kinds_asked,
            distractors=not args.no_distractors,
            noise=NO_NOISE if args.noiseless else None,
            look_from=aimed_by(aim),
        )

    everything = GraspDataset.load(args.data) if args.data else rendered(cnn)
    generated = time.perf_counter() - start
    data = everything.select(everything.views == HEAD)
    looked = everything.select(everything.views == SECOND_LOOK)
    scores = {found.name: score(found, data) for found in (cnn, baseline)}
    tables = {name: s.table() for name, s in scores.items()}
    if len(looked):
        tables[SECOND_LOOK_METHOD] = score(cnn, looked).table()
        # the baseline's own pipeline: its second looks where its first answers aim (the
        # same scenes and head crops: the head crops are drawn before any second look)
        again = rendered(baseline)
        tables[BASELINE_SECOND_LOOK] = score(
            baseline, again.select(again.views == SECOND_LOOK)
        ).table()
    seen = np.asarray(data.contact_visible) >= SEEN_SHARE  # the truth, for scoring only
    seen_tables = {f"{name}, handle seen": s.subset(seen).table() for name, s in scores.items()}
    kinds = list(dict.fromkeys(data.kinds.tolist()))
    seen_share = {kind: float(seen[data.kinds == kind].mean()) for kind in kinds}
    # what the methods start from, in the methods' table (the same percentiles)
    start_from = demonstration_scores(data).table()
    results = {
        "scenes_per_kind": args.scenes,
        "seed": args.seed,
        "distractors": not args.no_distractors,
        "sensor_noise": not args.noiseless,
        "crops": len(data),
        "robots": sorted(set(data.robots.tolist())),
        "targets": TARGETS,
        "methods": tables,
        "demonstration": start_from,
        "handle_seen": {"min_visible": SEEN_SHARE, "share": seen_share, "methods": seen_tables},
        "generation_s": generated,
    }
    if args.per_crop:
        results["per_crop"] = _per_crop(data, scores)
    out = write_results(args.out, results)
    print("| kind | method | median [mm] | p95 [mm] | approach p95 [deg] | no answer |")
    print("|---" * 6 + "|")
    for kind in [*kinds, "all"]:
        rows = [*tables.items(), *seen_tables.items(), (DEMONSTRATION, start_from)]
        for method, table in rows:
            r = table[kind]
            cells = [_f(r["median_mm"]), _f(r["p95_mm"]), _f(r["approach_p95_deg"])]
            no_answer = 100.0 * (r["no_answer"] or 0.0)
            print(f"| {kind} | {method} | " + " | ".join(cells) + f" | {no_answer:.0f} % |")
    print(f"wrote {out} ({len(data)} crops)")


if __name__ == "__main__":
    main()
