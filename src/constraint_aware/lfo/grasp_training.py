"""Training the contact-points recognizer end to end (`cap train-grasp`) and scoring recognizers.

`train_grasp`: training and validation crops from the scene builders (lfo/grasp_data.py, two
seeds: disjoint placements, sizes and offsets), the CNN trained on them (training/grasp.py,
torch), both methods scored per kind on the validation crops (`score`), the weights written
with a card that holds those scores. `score` is what benchmarks/recognizer.py reports too.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import angle_deg
from constraint_aware.lfo.grasp_data import GraspDataset, generate
from constraint_aware.recognizer import (
    HANDLE_SHAPES,
    ContactPointRecognizer,
    GeometricRecognizer,
    GraspFrame,
    RecognitionError,
    Recognizer,
)

#: The crop frame of a dataset's labels: crops are scored in their own frame.
_IDENTITY = GraspFrame(np.zeros(3), np.eye(3))


@dataclass(frozen=True)
class Scores:
    """Per-crop errors of one recognizer: contact point [m] and approach [deg] (inf where it
    gave no answer), with the crops' kinds and robots."""

    method: str
    position: np.ndarray
    approach: np.ndarray
    kinds: np.ndarray
    robots: np.ndarray

    def table(self) -> dict[str, dict[str, float | None]]:
        """Per kind (and "all"): n, contact-point error median and 95th percentile [mm],
        approach error 95th percentile [deg], and the share with no answer. A percentile is
        the crop's at or above its rank, not interpolated: the crops of one scene share its
        demonstration, and interpolating would dilute one scene's error (8 crops of 160 at
        39 deg, the rest below 7 deg: 39 deg, where interpolation gives 8 deg). A crop without
        an answer counts as an infinite error: a percentile it reaches is None."""
        out: dict[str, dict[str, float | None]] = {}
        for kind in [*dict.fromkeys(self.kinds.tolist()), "all"]:
            mask = np.ones(len(self.kinds), bool) if kind == "all" else self.kinds == kind
            pos, app = self.position[mask] * 1000.0, self.approach[mask]
            out[kind] = {
                "n": float(mask.sum()),
                "median_mm": _finite(np.percentile(pos, 50, method="lower")),
                "p95_mm": _finite(np.percentile(pos, 95, method="higher")),
                "approach_p95_deg": _finite(np.percentile(app, 95, method="higher")),
                "no_answer": float(np.mean(~np.isfinite(pos))),
            }
        return out

    def subset(self, mask: np.ndarray) -> Scores:
        """These scores on the crops where `mask` (N,) bool is True."""
        return Scores(
            self.method,
            self.position[mask],
            self.approach[mask],
            self.kinds[mask],
            self.robots[mask],
        )


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


#: The name `demonstration_scores` gives what the recognizer starts from.
DEMONSTRATION = "demonstration"


def demonstration_scores(data: GraspDataset) -> Scores:
    """What a recognizer starts from, scored as if it were one: the demonstrated point as the
    contact point (its distance from the truth, `data.offsets`) and the nominal approach
    (its error, `data.nominal_errors`). Its table is the methods' (`Scores.table`), so a
    method that keeps the nominal approach (recognizer.NOMINAL_APPROACH) shows the same
    approach percentiles as this."""
    return Scores(
        DEMONSTRATION,
        np.asarray(data.offsets, dtype=float),
        np.asarray(data.nominal_errors, dtype=float),
        data.kinds,
        data.robots,
    )


def score(recognizer: Recognizer, data: GraspDataset) -> Scores:
    """`recognizer` on every crop of `data` (each in its own frame, as labelled)."""
    position = np.full(len(data), np.inf)
    approach = np.full(len(data), np.inf)
    if isinstance(recognizer, ContactPointRecognizer):
        names = [HANDLE_SHAPES[int(i)] for i in data.shapes]
        for i in range(0, len(data), 256):
            p, a = recognizer.predict(data.heights[i : i + 256], names[i : i + 256])
            position[i : i + 256] = np.linalg.norm(p - data.points[i : i + 256], axis=1)
            approach[i : i + 256] = angle_deg(a, data.approaches[i : i + 256])
    else:
        for i in range(len(data)):
            try:
                r = recognizer.recognize(
                    data.heights[i].astype(float), _IDENTITY, HANDLE_SHAPES[int(data.shapes[i])]
                )
            except RecognitionError:
                continue
            position[i] = float(np.linalg.norm(r.contact_point - data.points[i]))
            approach[i] = float(angle_deg(r.approach, data.approaches[i]))
    return Scores(recognizer.name, position, approach, data.kinds, data.robots)


@dataclass
class GraspTraining:
    """What `train_grasp` made: the recognizer, where it was written, the scores per method
    and kind, and the wall times [s]."""

    recognizer: ContactPointRecognizer
    path: Path
    scores: dict[str, dict[str, dict[str, float | None]]]
    times: dict[str, float] = field(default_factory=dict)


def train_grasp(
    out: str | Path,
    scenes_per_kind: int = 200,
    validation_scenes: int = 30,
    crops_per_view: int = 4,
    seed: int = 0,
    config: Any = None,
    data: str | Path | None = None,
    on_scene: Callable[[str, int, int], None] | None = None,
    on_epoch: Callable[[int, dict[str, float]], None] | None = None,
    looks_per_view: int = 4,
) -> GraspTraining:
    """Generate the crops (or read the training set from `data`, a GraspDataset .npz), with
    `looks_per_view` second-look crops per robot and scene (lfo.grasp_data.scene_samples),
    train the CNN (`config`: training.grasp.GraspTrainConfig), score it and the geometric
    baseline per kind on validation crops of other scenes, write OUT/recognizer.npz + .json
    and the datasets. on_scene(stage, done, total) and on_epoch(epoch, row) report progress."""
    from constraint_aware.training.grasp import GraspTrainConfig, train_recognizer

    if scenes_per_kind < 1 or validation_scenes < 1:
        raise InvalidInputError(
            f"scenes per kind {scenes_per_kind}, validation scenes {validation_scenes}: "
            "valid: >= 1 each"
        )
    cfg = config or GraspTrainConfig(seed=seed)
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    times: dict[str, float] = {}
    start = time.perf_counter()
    if data is not None:
        train = GraspDataset.load(data)
    else:
        train = generate(
            scenes_per_kind, seed=2 * seed + 1, crops_per_view=crops_per_view,
            progress=None if on_scene is None else (lambda d, t: on_scene("training", d, t)),
            looks_per_view=looks_per_view,
        )  # fmt: skip
        train.save(out_dir / "grasp_train.npz")
    valid = generate(
        validation_scenes, seed=2 * seed + 2, crops_per_view=crops_per_view,
        progress=None if on_scene is None else (lambda d, t: on_scene("validation", d, t)),
        looks_per_view=looks_per_view,
    )  # fmt: skip
    valid.save(out_dir / "grasp_validation.npz")
    times["data_s"] = time.perf_counter() - start
    start = time.perf_counter()
    result = train_recognizer(
        train.heights, train.shapes, train.points, train.approaches, cfg,
        validation=(valid.heights, valid.shapes, valid.points, valid.approaches),
        progress=on_epoch,
        card={"data": {"scenes_per_kind": scenes_per_kind, "crops_per_view": crops_per_view,
                       "looks_per_view": looks_per_view, "seed": seed,
                       "train_crops": len(train), "validation_crops": len(valid)}},
    )  # fmt: skip
    times["training_s"] = result.wall_time_s
    scores = {
        method.name: score(method, valid).table()
        for method in (result.recognizer, GeometricRecognizer())
    }
    recognizer = ContactPointRecognizer(
        result.recognizer.weights, {**result.recognizer.card, "validation": scores}
    )
    path = recognizer.save(out_dir / "recognizer.npz")
    times["total_s"] = times["data_s"] + time.perf_counter() - start
    return GraspTraining(recognizer, path, scores, times)


__all__ = [
    "DEMONSTRATION",
    "GraspTraining",
    "Scores",
    "demonstration_scores",
    "score",
    "train_grasp",
]
