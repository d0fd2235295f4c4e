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
import io
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from constraint_aware.errors import CapError
from constraint_aware.geometry import FloatArray

FORMAT = "cap-demo/1"
MIN_SAMPLES = 10
#: At most this many samples (over 2 h at 60 Hz) and bytes per file: a demonstration file is
#: read as untrusted input, so its size is bounded before it is parsed.
MAX_SAMPLES = 500_000
MAX_FILE_BYTES = 64 * 2**20
MAX_TEXT = 1000  # characters of the instruction and the object's name
QUAT_COLUMNS = ("qw", "qx", "qy", "qz")
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
        for name in ("instruction", "object"):
            if not isinstance(getattr(self, name), str):
                raise DemoError(f"{name}: must be text, got {type(getattr(self, name)).__name__}")
        if not isinstance(self.meta, dict):
            raise DemoError(f"meta: must be a dict, got {type(self.meta).__name__}")
        for name in ("t", "position", "orientation"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _float_array(value, name))
        validate(self.t, self.position, self.orientation)
        if self.grasp_hint is not None and self.grasp_hint not in GRASP_TYPES:
            raise DemoError(
                f"grasp_hint {_shown(self.grasp_hint)}; valid names: {', '.join(GRASP_TYPES)}"
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


def _float_array(value: ArrayLike, name: str) -> FloatArray:
    """`value` as a real float array; DemoError naming `name` otherwise (complex included)."""
    if np.iscomplexobj(value):
        raise DemoError(f"{name}: complex values; expected real numbers")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise DemoError(f"{name}: not a numeric array ({exc})") from exc


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


def _read_text(path: Path, what: str) -> str:
    """The UTF-8 text of a regular file of at most MAX_FILE_BYTES (a BOM is skipped)."""
    if not path.is_file():
        raise DemoError(f"{what} not found (or not a regular file): {path}")
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise DemoError(
                f"{path}: {size:,} bytes; a {what} may have at most {MAX_FILE_BYTES:,} bytes"
            )
        raw = path.read_bytes()
    except OSError as exc:
        raise DemoError(f"{path}: cannot read ({exc.strerror or exc})") from exc
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DemoError(
            f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason}); save the {what} as UTF-8"
        ) from exc


def _read_csv(path: Path) -> tuple[FloatArray, FloatArray, FloatArray | None]:
    text = _read_text(path, "trajectory CSV")
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        fields = [str(f) for f in reader.fieldnames or []]
        rows = list(itertools.islice(reader, MAX_SAMPLES + 1))
    except csv.Error as exc:
        raise DemoError(f"{path}: not a readable CSV ({exc})") from exc
    need = ["t", "x", "y", "z"]
    if any(k not in fields for k in need):
        shown = ",".join(fields)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise DemoError(f"{path}: the CSV header must contain t,x,y,z (got {shown!r})")
    if len(rows) > MAX_SAMPLES:
        raise DemoError(f"{path}: more than {MAX_SAMPLES:,} samples")
    columns = [*need, *(QUAT_COLUMNS if set(QUAT_COLUMNS) <= set(fields) else ())]
    values = np.empty((len(rows), len(columns)))
    for i, row in enumerate(rows):
        for j, key in enumerate(columns):
            try:
                values[i, j] = float(row[key])
            except (TypeError, ValueError):
                raise DemoError(
                    f"{path}: data row {i + 1}, column {key!r}: {_shown(row[key])} is not a number"
                ) from None
    quat = values[:, 4:8] if len(columns) == 8 else None
    return values[:, 0], values[:, 1:4], quat


def _shown(value: object) -> str:
    """A short repr of a user's value for an error message."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _numbers(value: object, width: int | None, where: str) -> FloatArray:
    """`value` (parsed JSON) as floats: a list of numbers (width None, shape (N,)) or of lists
    of `width` numbers (shape (N, width)); every item a JSON number (not text, not true/false).
    DemoError names `where` and the first bad item."""
    if not isinstance(value, list):
        raise DemoError(f"{where}: expected a list, got {type(value).__name__}")
    if len(value) > MAX_SAMPLES:
        raise DemoError(f"{where}: more than {MAX_SAMPLES:,} samples")
    flat: list[object] = value
    if width is not None:
        flat = []
        for i, row in enumerate(value):
            if not isinstance(row, list) or len(row) != width:
                raise DemoError(
                    f"{where}[{i}]: expected a list of {width} numbers, got {_shown(row)}"
                )
            flat.extend(row)
    for i, x in enumerate(flat):
        if isinstance(x, bool) or not isinstance(x, int | float):
            at = f"[{i}]" if width is None else f"[{i // width}][{i % width}]"
            raise DemoError(f"{where}{at}: {_shown(x)} is not a number")
    try:
        arr = np.array(flat, dtype=float)
    except OverflowError:
        raise DemoError(f"{where}: a number out of range") from None
    return arr if width is None else arr.reshape(len(value), width)


def _trajectory_path(demo_path: Path, value: object) -> Path:
    """The demo's `trajectory_csv`, resolved and confined to the demonstration's folder: a
    demonstration file must not make the reader open files elsewhere (`load(trajectory=)` and
    `cap lfo --trajectory` take a CSV from anywhere, given by the user)."""
    if not isinstance(value, str) or not value:
        raise DemoError(f"{demo_path}: field 'trajectory_csv' must be a file name (text)")
    folder = demo_path.parent.resolve()
    target = (folder / value).resolve()
    if not target.is_relative_to(folder):
        raise DemoError(
            f"{demo_path}: field 'trajectory_csv' ({_shown(value)}) points outside the "
            f"demonstration's folder {folder}; a demonstration may only name files beside it "
            "(give another trajectory on the command line: cap lfo DEMO --trajectory CSV)"
        )
    return target


def load(path: str | Path, trajectory: str | Path | None = None) -> Demonstration:
    """Load a demonstration (.json, or a bare .csv trajectory with no words).

    Every field is checked (type, shape, finite values, at most MAX_SAMPLES samples, files of
    at most MAX_FILE_BYTES); problems raise DemoError naming the file and the field. A JSON
    demonstration's `trajectory_csv` must lie in the demonstration's folder (symbolic links
    resolved); `trajectory` [path], given by the caller, replaces it and may lie anywhere.
    """
    p = Path(path)
    if p.suffix.lower() == ".csv":
        if trajectory is not None:
            raise DemoError(f"{p}: a CSV demonstration is its own trajectory (no trajectory=)")
        t, pos, quat = _read_csv(p)
        return _demonstration(p, "", "", t, pos, quat, None, {})
    text = _read_text(p, "demonstration")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DemoError(f"{p}: malformed JSON ({exc})") from exc
    except RecursionError:
        raise DemoError(f"{p}: JSON nested too deeply (not a cap-demo/1 file)") from None
    if not isinstance(data, dict):
        raise DemoError(f"{p}: expected a JSON object, got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise DemoError(
            f"{p}: field 'format' is {_shown(data.get('format'))}; this version reads {FORMAT!r}"
        )
    for key in ("instruction", "object"):
        if not isinstance(data.get(key), str):
            raise DemoError(f"{p}: field {key!r} missing or not text")
        if len(data[key]) > MAX_TEXT:
            raise DemoError(f"{p}: field {key!r} longer than {MAX_TEXT} characters")
    hint = data.get("grasp_hint")
    if hint is not None and not isinstance(hint, str):
        raise DemoError(f"{p}: field 'grasp_hint' must be text; valid: {', '.join(GRASP_TYPES)}")
    meta = data.get("meta", {})
    if not isinstance(meta, dict):
        raise DemoError(f"{p}: field 'meta' must be a JSON object, got {type(meta).__name__}")
    if trajectory is not None or "trajectory_csv" in data:
        csv_path = Path(trajectory) if trajectory is not None else None
        if csv_path is None:
            csv_path = _trajectory_path(p, data["trajectory_csv"])
        t, pos, quat = _read_csv(csv_path)
    else:
        if "t" not in data or "position" not in data:
            raise DemoError(f"{p}: needs 't' and 'position' (or 'trajectory_csv')")
        t = _numbers(data["t"], None, f"{p}: field 't'")
        pos = _numbers(data["position"], 3, f"{p}: field 'position'")
        quat = None
        if "orientation" in data:
            quat = _numbers(data["orientation"], 4, f"{p}: field 'orientation'")
    return _demonstration(p, data["instruction"], data["object"], t, pos, quat, hint, meta)


def _demonstration(
    path: Path,
    instruction: str,
    object_name: str,
    t: FloatArray,
    pos: FloatArray,
    quat: FloatArray | None,
    hint: str | None,
    meta: dict[str, Any],
) -> Demonstration:
    """The Demonstration, its validation errors prefixed with the file they came from."""
    try:
        return Demonstration(instruction, object_name, t, pos, quat, hint, dict(meta))
    except DemoError as exc:
        raise DemoError(f"{path}: {exc}") from exc


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
