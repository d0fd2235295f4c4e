"""One-shot demonstrations: the file format, loading and validation.

Format `cap-demo/1` (JSON):

    {
      "format": "cap-demo/1",
      "instruction": "open the drawer",          # the verbal instruction
      "object": "drawer",                        # the object's name
      "frame": "robot_base",                     # positions are in the robot base frame
      "t": [0.0, 0.033, ...],                    # [s] strictly increasing
      "position": [[x, y, z], ...],              # [m] hand position per sample
      "orientation": [[w, x, y, z], ...],        # optional unit quaternions per sample
      "grasp_hint": "lazy_closure",              # optional force-exertion type
      "trajectory_csv": "drawer_path.csv"        # optional: t,x,y,z[,qw,qx,qy,qz] instead
    }

A CSV trajectory has a header `t,x,y,z` (optionally `,qw,qx,qy,qz`), one sample per row.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from constraint_aware.errors import CapError, InvalidInputError
from constraint_aware.geometry import FloatArray

FORMAT = "cap-demo/1"
MIN_SAMPLES = 10
GRASP_TYPES = ("lazy_closure", "active_force_closure", "passive_force_closure")


class DemoError(CapError, ValueError):
    """A demonstration file or array that cannot be used, with the reason."""


@dataclass(frozen=True)
class Demonstration:
    """Hand motion and words of one demonstration. Units: s, m; robot base frame."""

    instruction: str
    object: str
    t: FloatArray  # (N,) [s], strictly increasing
    position: FloatArray  # (N, 3) [m]
    orientation: FloatArray | None = None  # (N, 4) (w, x, y, z)
    grasp_hint: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        validate(self.t, self.position, self.orientation)
        if self.grasp_hint is not None and self.grasp_hint not in GRASP_TYPES:
            raise DemoError(
                f"grasp_hint {self.grasp_hint!r}; valid names: {', '.join(GRASP_TYPES)}"
            )

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "format": FORMAT,
            "instruction": self.instruction,
            "object": self.object,
            "frame": "robot_base",
            "t": [round(float(x), 6) for x in self.t],
            "position": [[round(float(c), 6) for c in p] for p in self.position],
        }
        if self.orientation is not None:
            out["orientation"] = [[round(float(c), 6) for c in q] for q in self.orientation]
        if self.grasp_hint is not None:
            out["grasp_hint"] = self.grasp_hint
        if self.meta:
            out["meta"] = self.meta
        return out

    def save(self, path: str | Path) -> Path:
        out = Path(path)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(self.to_json(), indent=1) + "\n")
        return out


def validate(t: FloatArray, position: FloatArray, orientation: FloatArray | None = None) -> None:
    """Raise DemoError naming the problem: shapes, NaN, too few samples, time order."""
    if t.ndim != 1:
        raise DemoError(f"timestamps: expected shape (N,), got {t.shape}")
    if position.ndim != 2 or position.shape[1] != 3:
        raise DemoError(f"positions: expected shape (N, 3), got {position.shape}")
    if len(t) != len(position):
        raise DemoError(f"{len(t)} timestamps but {len(position)} positions")
    if len(t) < MIN_SAMPLES:
        raise DemoError(f"too few points: {len(t)} samples, need at least {MIN_SAMPLES}")
    if not np.all(np.isfinite(t)):
        raise DemoError("timestamps contain NaN or inf")
    if not np.all(np.isfinite(position)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(position), axis=1))[0])
        raise DemoError(f"positions contain NaN or inf (first at sample {bad})")
    steps = np.diff(t)
    if np.any(steps <= 0):
        bad = int(np.flatnonzero(steps <= 0)[0])
        raise DemoError(
            f"timestamps must be strictly increasing: t[{bad + 1}] = {t[bad + 1]} "
            f"<= t[{bad}] = {t[bad]}"
        )
    if orientation is not None:
        if orientation.shape != (len(t), 4):
            raise DemoError(f"orientations: expected shape ({len(t)}, 4), got {orientation.shape}")
        if not np.all(np.isfinite(orientation)):
            raise DemoError("orientations contain NaN or inf")
        if np.any(np.abs(np.linalg.norm(orientation, axis=1) - 1.0) > 1e-3):
            raise DemoError("orientations must be unit quaternions (w, x, y, z)")


def _read_csv(path: Path) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    try:
        with path.open(newline="") as fh:
            reader = csv.DictReader(fh)
            fields = reader.fieldnames or []
            rows = list(reader)
    except OSError as exc:
        raise DemoError(f"{path}: cannot read ({exc})") from exc
    need = ["t", "x", "y", "z"]
    if any(k not in fields for k in need):
        raise DemoError(f"{path}: CSV header must contain t,x,y,z (got {','.join(fields)})")
    try:
        t = np.array([float(r["t"]) for r in rows])
        pos = np.array([[float(r[k]) for k in "xyz"] for r in rows]).reshape(-1, 3)
        quat = None
        if all(k in fields for k in ("qw", "qx", "qy", "qz")):
            quat = np.array([[float(r[k]) for k in ("qw", "qx", "qy", "qz")] for r in rows])
    except (TypeError, ValueError) as exc:
        raise DemoError(f"{path}: non-numeric value in the trajectory ({exc})") from exc
    return t, pos, quat


def load(path: str | Path) -> Demonstration:
    """Load a demonstration (.json, or a bare .csv trajectory with no words)."""
    p = Path(path)
    if not p.is_file():
        raise DemoError(f"demonstration not found: {p}")
    if p.suffix.lower() == ".csv":
        t, pos, quat = _read_csv(p)
        return Demonstration("", "", t, pos, quat)
    try:
        data = json.loads(p.read_text())
    except json.JSONDecodeError as exc:
        raise DemoError(f"{p}: malformed JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise DemoError(f"{p}: expected a JSON object")
    if data.get("format") != FORMAT:
        raise DemoError(f"{p}: format {data.get('format')!r}; this version reads {FORMAT!r}")
    for key in ("instruction", "object"):
        if not isinstance(data.get(key), str):
            raise DemoError(f"{p}: missing or non-text field {key!r}")
    if "trajectory_csv" in data:
        t, pos, quat = _read_csv(p.parent / str(data["trajectory_csv"]))
    else:
        if "t" not in data or "position" not in data:
            raise DemoError(f"{p}: needs 't' and 'position' (or 'trajectory_csv')")
        try:
            t = np.asarray(data["t"], dtype=float)
            pos = np.asarray(data["position"], dtype=float)
            quat = np.asarray(data["orientation"], dtype=float) if "orientation" in data else None
        except (TypeError, ValueError) as exc:
            raise DemoError(f"{p}: non-numeric trajectory ({exc})") from exc
    try:
        return Demonstration(
            data["instruction"],
            data["object"],
            t,
            pos,
            quat,
            data.get("grasp_hint"),
            dict(data.get("meta", {})),
        )
    except InvalidInputError as exc:  # pragma: no cover - validate raises DemoError
        raise DemoError(str(exc)) from exc


def transformed(
    demo: Demonstration,
    matrix: FloatArray,
    about: FloatArray | None = None,
    translation: FloatArray | None = None,
    instruction: str | None = None,
    object_name: str | None = None,
) -> Demonstration:
    """The demonstration moved: positions p -> about + matrix (p - about) + translation.

    matrix (3, 3): a rotation, a mirror or a scaling (or a product). Orientations are rotated
    with a proper rotation and dropped otherwise (a mirrored hand is no rotation of the
    original one); new words replace the old ones when given.
    """
    from scipy.spatial.transform import Rotation

    m = np.asarray(matrix, dtype=float)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise DemoError(f"transform: expected a finite (3, 3) matrix, got shape {m.shape}")
    c = np.zeros(3) if about is None else np.asarray(about, dtype=float)
    shift = np.zeros(3) if translation is None else np.asarray(translation, dtype=float)
    pos = c + (demo.position - c) @ m.T + shift
    quat = None
    det = float(np.linalg.det(m))
    if demo.orientation is not None and det > 0:
        scale = det ** (1.0 / 3.0)
        rot = m / scale
        if np.allclose(rot @ rot.T, np.eye(3), atol=1e-6):
            w, x, y, z = demo.orientation.T
            turned = Rotation.from_matrix(rot) * Rotation.from_quat(np.stack([x, y, z, w], 1))
            qx, qy, qz, qw = turned.as_quat().T
            quat = np.stack([qw, qx, qy, qz], axis=1)
    return Demonstration(
        demo.instruction if instruction is None else instruction,
        demo.object if object_name is None else object_name,
        demo.t.copy(),
        pos,
        quat,
        demo.grasp_hint,
        dict(demo.meta),
    )
