"""ConstraintAwarePolicy: the trained direction-update policy, run with numpy alone.

A policy file is a pair: `NAME.npz` (the MLP's weights, float32, no pickle) and `NAME.json`
(the card: observation layout, inputs it needs from the robot, training config, seed, metrics,
library versions). Two policies ship with the package (`POLICY_NAMES`): `default`, trained with
the object's own resistance along the joint, and `paper`, the faithful reproduction
of the paper's policy (trained without it, assumption 3).

Both are validated at load: every problem raises `PolicyFileError` naming the file and field.
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from constraint_aware.deadband import MIN_THRESHOLD, NOISE_SIGMAS
from constraint_aware.errors import (
    InvalidInputError,
    PolicyFileError,
    UnknownNameError,
    check_number,
)
from constraint_aware.geometry import (
    FloatArray,
    all_finite,
    as_vector,
    cross3,
    norm,
    normalize_force,
    update_direction_rule,
)

CARD_FORMAT = "constraint-aware-policy/1"
_CURRENT = (
    "force_unit_x",
    "force_unit_y",
    "force_unit_z",
    "direction_x",
    "direction_y",
    "direction_z",
)
#: The paper's observation (F/|F|, d): also the layout of cards that name no layout.
OBSERVATION_LAYOUT = _CURRENT
#: Observation layouts by name. "history" adds the previous step's (F/|F|, d) (zeros at the
#: first step); "magnitude" adds |F| / (k*delta), the force over the robot's step force (zero
#: below the dead band, and zero when the robot does not report its stiffness);
#: "magnitude_flag" adds the same ratio and a flag, 1 when the robot reports its step force and
#: 0 when not, so that "unknown" is not read as "a small force" (the ratio is 0 for both).
OBSERVATIONS: dict[str, tuple[str, ...]] = {
    "paper": _CURRENT,
    "history": _CURRENT + tuple(f"previous_{name}" for name in _CURRENT),
    "magnitude": (*_CURRENT, "force_over_step_force"),
    "magnitude_flag": (*_CURRENT, "force_over_step_force", "step_force_known"),
}
#: What each observation needs from the robot besides the force and d (the card's `inputs`).
OBSERVATION_INPUTS: dict[str, tuple[str, ...]] = {
    "paper": ("force", "direction"),
    "history": ("force", "direction"),
    "magnitude": ("force", "direction", "step_force"),
    "magnitude_flag": ("force", "direction", "step_force"),
}
#: Observations with |F| / (k*delta) (and, for magnitude_flag, the known flag after it).
MAGNITUDE_OBSERVATIONS = ("magnitude", "magnitude_flag")
#: |F| / (k*delta) is clipped to this: beyond it the arm pushes far past one blocked step.
MAGNITUDE_CLIP = 3.0
#: The shipped policies: `default` (robust to the object's resistance) and `paper`.
POLICY_NAMES = ("default", "paper")
DEFAULT_POLICY_NAME = "default"
#: [N] default dead band of `update_direction`: deadband.py's floor (the training threshold).
DEFAULT_THRESHOLD = MIN_THRESHOLD
_MAX_LAYERS = 16
_MAX_WIDTH = 4096
#: A policy's files are read as untrusted input: the card and the weights (uncompressed) are
#: bounded before they are read. The shipped networks take under 1 MB.
MAX_CARD_BYTES = 16 * 2**20
MAX_WEIGHT_BYTES = 256 * 2**20


def dead_band_card() -> dict[str, Any]:
    """The card's `dead_band` entry: deadband.py's rule, which update_direction, the executor
    and the card share (no hand-set threshold)."""
    return {
        "floor_N": MIN_THRESHOLD,
        "noise_sigmas": NOISE_SIGMAS,
        "rule": "max(floor_N, noise_sigmas * per-axis std of the F_d samples) [N]; "
        "update_direction's default is floor_N",
    }


def is_shipped(name_or_path: str | Path) -> bool:
    """Whether `ConstraintAwarePolicy.load(name_or_path)` loads a shipped policy (one of
    `POLICY_NAMES`) rather than a file; `load(None)` loads the shipped default."""
    return isinstance(name_or_path, str) and name_or_path in POLICY_NAMES


def shipped_policy_path(name: str = DEFAULT_POLICY_NAME) -> Path:
    """Path of a shipped policy's `.npz` inside the installed package (`POLICY_NAMES`)."""
    if name not in POLICY_NAMES:
        raise UnknownNameError("policy", name, POLICY_NAMES)
    return Path(str(resources.files("constraint_aware") / "data" / f"{name}.npz"))


def shipped_log_path(name: str = DEFAULT_POLICY_NAME) -> Path:
    """The training log shipped beside a policy (`cap train --ship` writes training_log.csv
    next to the default; the paper's is paper_training_log.csv)."""
    stem = "training_log" if name == DEFAULT_POLICY_NAME else f"{name}_training_log"
    return shipped_policy_path(name).parent / f"{stem}.csv"


def _layout_name(layout: tuple[str, ...]) -> str | None:
    for name, names in OBSERVATIONS.items():
        if names == layout:
            return name
    return None


class DirectionUpdater:
    """One run's direction updates: holds the previous step for history observations.

    Create one per run (`policy.session()`), call `update_direction` each control step and
    `reset()` before the next run. For policies without history it keeps no state.
    """

    def __init__(self, policy: ConstraintAwarePolicy) -> None:
        self.policy = policy
        self._previous = np.zeros(6)

    def reset(self) -> None:
        """Forget the previous step (start of a run)."""
        self._previous = np.zeros(6)

    def update_direction(
        self,
        force: ArrayLike,
        direction: ArrayLike,
        force_offset: ArrayLike | None = None,
        threshold: float | None = None,
        step_force: float | None = None,
        workplane_normal: ArrayLike | None = None,
    ) -> FloatArray:
        """The next motion direction d_{t+1} (3,) from a raw wrist force and d_t (paper 3.4.2).

        Every argument is checked: a vector that is not 3 finite real numbers, or whose norm
        overflows, and a threshold or step force that is not a finite number in range raise
        InvalidInputError naming the argument.

        force: (3,) [N] measured force F_s, world frame; force_offset: (3,) [N] F_d recorded
        after grasping (default zero); F = F_s - F_d. threshold [N]: the dead band (default
        `deadband.MIN_THRESHOLD`; a robot passes `deadband.threshold_from_noise` of its F_d
        samples): if |F| < threshold the direction is returned unchanged. step_force [N]:
        the robot's stiffness times the step length (k*delta), used by policies whose card
        lists it in `inputs`; without it they get zero there (trained for that case too).
        workplane_normal: (3,) the workplane's normal n, when known (paper assumption 4).
        Given with step_force, the action is made mirror-symmetric (`mirror_average`) for
        every reading below the step force: a misalignment of +theta and one of -theta about
        n are mirror images, so their corrections must be too, and a force straight against
        d turns d by exactly zero. A reading of at least k*delta is a blocked step, whose
        force is about -d whatever the error: it carries no side, a symmetric action would
        not turn at all, and the network's own choice of side is kept. Without n or k*delta
        (the defaults) the network's action is used as it is, as in the paper.
        """
        p = self.policy
        f = _vector(force, "force")
        d = _vector(direction, "direction")
        if force_offset is not None:
            f = _finite_norm(f - _vector(force_offset, "force_offset"), "force - force_offset")
        normal = None
        if workplane_normal is not None:
            normal = _vector(workplane_normal, "workplane_normal")
        thr = p.threshold
        if threshold is not None:
            thr = check_number("threshold", threshold, low=0, unit="N")
        if step_force is not None:
            step_force = check_number("step_force", step_force, low=0, low_open=True, unit="N")
        norm_d = norm(d)
        if norm_d < 1e-9:
            raise InvalidInputError("direction: must be a non-zero vector")
        d = d / norm_d
        f_hat = normalize_force(f, thr)
        force_norm = norm(f)
        current = np.concatenate([f_hat, d])
        # a reading within the dead band normalizes to zero: no force (Python's any() on the
        # three floats is ndarray.any's truth, without its overhead)
        has_force = any(f_hat.tolist())
        if p.observation == "history":
            obs = np.concatenate([current, self._previous])
            self._previous = current
        elif p.observation in MAGNITUDE_OBSERVATIONS:
            ratio = 0.0
            if step_force is not None and has_force:
                ratio = min(force_norm / float(step_force), MAGNITUDE_CLIP)
            extra = (
                [ratio] if p.observation == "magnitude" else [ratio, float(step_force is not None)]
            )
            obs = np.concatenate([current, extra])
        else:
            obs = current
        if not has_force:
            return d
        blocked = step_force is None or force_norm >= step_force
        # the network's action as it is (the paper's rule) without n, or for a blocked step
        a = (
            p.act_batch(obs[None, :])[0]
            if normal is None or blocked
            else _mirrored_action(p, obs, d, normal)
        )
        return np.asarray(update_direction_rule(d, p.action_scale * a))


def mirror_average(
    policy: ConstraintAwarePolicy, obs: FloatArray, direction: FloatArray, normal: FloatArray
) -> FloatArray:
    """The policy's action made exactly mirror-symmetric: (pi(s) + M pi(M s)) / 2, (3,).

    M = I - 2 m m^T reflects through the plane spanned by d and the workplane normal n
    (m = unit(n x d), the in-plane direction across d). The single-system physics is
    symmetric under M (M d = d, M n = n; a misalignment of +theta becomes -theta), so the
    ideal policy satisfies pi(M s) = M pi(s); the trained network does only approximately
    (a force straight against d turns d within the workplane by 0.8 deg at 5 N and 3.3 deg
    at 15 N with k delta = 20 N, each to a side of the network's choosing). Averaging over
    the two-element group {I, M} removes that bias exactly without retraining
    (`DirectionUpdater.update_direction` applies it below the step force only). M acts on
    every 3-vector of the observation (F/|F|, d and, for history layouts, the previous
    step's); the scalars (|F|/(k delta), the flag) are invariant. obs: (n_in,) the
    observation of `direction` (3,) unit d; normal: (3,) not parallel to d (else the plain
    action is returned). Raises InvalidInputError naming `obs` when it is not a finite
    observation of the policy's layout.
    """
    checked = policy.check_observations(np.asarray(obs)[None, :])[0]
    return _mirrored_action(policy, checked, direction, normal)


def _mirrored_action(
    policy: ConstraintAwarePolicy, obs: FloatArray, direction: FloatArray, normal: FloatArray
) -> FloatArray:
    """`mirror_average` of a checked observation `obs` (n_in,) (finite, the policy's layout):
    the network runs on it and its mirror image without checking them again."""
    # m = unit(n x d) and M = I - 2 m m^T in Python floats, each product and sum in numpy's
    # order (geometry.cross3, geometry.norm, I - 2.0 * (m m^T)), M built as one array
    c0, c1, c2 = cross3(
        np.asarray(normal, dtype=float).tolist(), np.asarray(direction, dtype=float).tolist()
    )
    size = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if size < 1e-9:  # d along n: no in-plane side to mirror
        return policy.act_batch(obs[None, :])[0]
    m0, m1, m2 = c0 / size, c1 / size, c2 / size
    mirror = np.array(
        [
            [1.0 - 2.0 * (m0 * m0), 0.0 - 2.0 * (m0 * m1), 0.0 - 2.0 * (m0 * m2)],
            [0.0 - 2.0 * (m1 * m0), 1.0 - 2.0 * (m1 * m1), 0.0 - 2.0 * (m1 * m2)],
            [0.0 - 2.0 * (m2 * m0), 0.0 - 2.0 * (m2 * m1), 1.0 - 2.0 * (m2 * m2)],
        ]
    )
    pair = np.empty((2, obs.size))
    pair[0] = pair[1] = obs
    for start in policy.vector_blocks:
        pair[1, start : start + 3] = mirror @ obs[start : start + 3]
    a, a_mirrored = policy._forward(pair)  # a finite observation has a finite mirror image
    return np.asarray(0.5 * (a + mirror @ a_mirrored))


class ConstraintAwarePolicy:
    """MLP (tanh hidden layers) mapping an observation (the card's `observation_layout`, at
    least s = (F/|F|, d) in R^6) to an action a in [-1, 1]^3.

    The direction update is d <- (d + s_a a)/|d + s_a a| with s_a the card's action scale.
    """

    def __init__(self, layers: list[tuple[FloatArray, FloatArray]], card: dict[str, Any]) -> None:
        if not layers:
            raise PolicyFileError("a policy needs at least one layer")
        layout = tuple(card.get("observation_layout", OBSERVATION_LAYOUT))
        observation = _layout_name(layout)
        if observation is None:
            raise PolicyFileError(
                f"observation_layout: {list(layout)} is none of " + ", ".join(OBSERVATIONS)
            )
        n_in = layers[0][0].shape[1]
        if n_in != len(layout) or layers[-1][0].shape[0] != 3:
            raise PolicyFileError(
                f"policy maps {n_in} -> {layers[-1][0].shape[0]}, expected {len(layout)} -> 3 "
                f"(observation {observation!r})"
            )
        self.observation = observation
        self.observation_layout = layout
        #: where each 3-vector of the observation starts (names *_x, *_y, *_z)
        self.vector_blocks = tuple(i for i, name in enumerate(layout) if name.endswith("_x"))
        # Float64 copies: the float32 training weights are reproduced to ~1e-7 while the
        # matrix products avoid float32 round-off.
        self._weights = [np.ascontiguousarray(w.T, dtype=np.float64) for w, _ in layers]
        self._biases = [np.asarray(b, dtype=np.float64) for _, b in layers]
        self.card = card
        env = card.get("env_config", {})
        self.action_scale = float(env.get("action_scale", 1.0))
        if not (math.isfinite(self.action_scale) and self.action_scale > 0):
            raise PolicyFileError(f"env_config.action_scale: must be finite and > 0, got {env}")
        self.threshold = DEFAULT_THRESHOLD
        self._session = DirectionUpdater(self)

    @property
    def inputs(self) -> tuple[str, ...]:
        """What the policy needs from the robot each step (e.g. "step_force": k*delta [N])."""
        return OBSERVATION_INPUTS[self.observation]

    @property
    def name(self) -> str:
        return str(self.card.get("name", "custom"))

    # --- loading --------------------------------------------------------------------------
    @classmethod
    def load(cls, name_or_path: str | Path | None = None) -> ConstraintAwarePolicy:
        """Load a shipped policy by name (`POLICY_NAMES`; None: "default") or a file
        (`.npz` plus its `.json` card beside it)."""
        if name_or_path is None or is_shipped(name_or_path):
            npz_path = shipped_policy_path(str(name_or_path or DEFAULT_POLICY_NAME))
        else:
            npz_path = Path(name_or_path)
            if npz_path.suffix == ".json":
                npz_path = npz_path.with_suffix(".npz")
            elif npz_path.suffix != ".npz" and not npz_path.exists():
                raise UnknownNameError("policy", str(name_or_path), POLICY_NAMES)
        return cls._load_files(npz_path)

    @classmethod
    def _load_files(cls, npz_path: Path) -> ConstraintAwarePolicy:
        card_path = npz_path.with_suffix(".json")
        if not npz_path.is_file():
            raise PolicyFileError(f"policy weights not found: {npz_path}")
        if not card_path.is_file():
            raise PolicyFileError(f"policy card not found: {card_path}")
        card = _read_card(card_path)
        layout = card["observation_layout"]
        n = card["n_layers"]
        layers: list[tuple[FloatArray, FloatArray]] = []
        try:
            with zipfile.ZipFile(npz_path) as archive:  # sizes before anything is inflated
                total = sum(info.file_size for info in archive.infolist())
            if total > MAX_WEIGHT_BYTES:
                raise PolicyFileError(
                    f"{npz_path}: {total:,} bytes of weights; at most {MAX_WEIGHT_BYTES:,}"
                )
            with np.load(npz_path, allow_pickle=False) as data:
                for i in range(n):
                    for key in (f"w{i}", f"b{i}"):
                        if key not in data.files:
                            raise PolicyFileError(f"{npz_path}: field {key!r} missing")
                    layers.append((data[f"w{i}"], data[f"b{i}"]))
        except PolicyFileError:
            raise
        except (ValueError, OSError, EOFError, KeyError, zipfile.BadZipFile) as exc:
            raise PolicyFileError(f"{npz_path}: not a readable .npz ({exc})") from exc
        width = len(layout)
        for i, (w, b) in enumerate(layers):
            for key, arr in ((f"w{i}", w), (f"b{i}", b)):
                if not np.issubdtype(arr.dtype, np.floating):
                    raise PolicyFileError(
                        f"{npz_path}: field {key!r} has dtype {arr.dtype}, expected float"
                    )
                if not np.all(np.isfinite(arr)):
                    raise PolicyFileError(f"{npz_path}: field {key!r} contains NaN or inf")
            out = 3 if i == n - 1 else w.shape[0] if w.ndim == 2 else -1
            if w.ndim != 2 or w.shape[1] != width or (i == n - 1 and w.shape[0] != 3):
                raise PolicyFileError(
                    f"{npz_path}: field 'w{i}' has shape {w.shape}, expected ({out}, {width}) "
                    f"for the card's {len(layout)} inputs ({card_path.name}: observation_layout)"
                )
            if w.shape[0] > _MAX_WIDTH:
                raise PolicyFileError(f"{npz_path}: field 'w{i}' wider than {_MAX_WIDTH}")
            if b.shape != (w.shape[0],):
                raise PolicyFileError(
                    f"{npz_path}: field 'b{i}' has shape {b.shape}, expected ({w.shape[0]},)"
                )
            width = w.shape[0]
        try:
            return cls(layers, card)
        except PolicyFileError as exc:
            raise PolicyFileError(f"{card_path}: {exc}") from exc

    def save(self, path: str | Path) -> Path:
        """Write `path` (.npz) and its card (.json). Returns the .npz path."""
        npz_path = Path(path).with_suffix(".npz")
        npz_path.parent.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {}
        for i, (w, b) in enumerate(self.layers):
            arrays[f"w{i}"] = w.astype(np.float32)
            arrays[f"b{i}"] = b.astype(np.float32)
        np.savez(npz_path, **arrays)  # type: ignore[arg-type]
        card = dict(
            self.card,
            format=CARD_FORMAT,
            observation_layout=list(self.observation_layout),
            inputs=list(self.inputs),
        )
        card["n_layers"] = len(self._weights)
        npz_path.with_suffix(".json").write_text(json.dumps(card, indent=2) + "\n")
        return npz_path

    # --- inference ------------------------------------------------------------------------
    def act_batch(self, obs: ArrayLike) -> FloatArray:
        """Deterministic actions for observations (N, n_in): (N, 3), clipped to [-1, 1].

        obs: (N, n_in) finite real numbers, n_in = len(observation_layout); anything else
        raises InvalidInputError naming `obs` (a NaN row never yields a NaN action)."""
        return self._forward(self.check_observations(obs))

    def check_observations(self, obs: ArrayLike) -> FloatArray:
        """`obs` as an (N, n_in) float array, checked: real, finite, the layout's width."""
        width = len(self.observation_layout)
        if np.iscomplexobj(obs):
            raise InvalidInputError("obs: complex values; expected real numbers")
        try:
            arr = np.asarray(obs, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"obs: not a numeric array ({exc})") from exc
        if arr.ndim != 2 or arr.shape[1] != width:
            raise InvalidInputError(
                f"obs: expected shape (N, {width}) (observation {self.observation!r}: "
                f"{', '.join(self.observation_layout)}), got {arr.shape}"
            )
        if not np.isfinite(arr).all():
            rows = np.flatnonzero(~np.all(np.isfinite(arr), axis=1))
            raise InvalidInputError(
                f"obs: NaN or inf in {rows.size} row(s), the first at row {int(rows[0])}"
            )
        return arr

    def _forward(self, obs: FloatArray) -> FloatArray:
        """The network on checked observations (N, n_in): (N, 3) in [-1, 1]."""
        h = obs
        last = len(self._weights) - 1
        # in place where the product is a fresh array: the same floats, fewer allocations
        for i, (w, b) in enumerate(zip(self._weights, self._biases, strict=True)):
            h = h @ w
            h += b
            if i < last:
                np.tanh(h, out=h)
        np.maximum(h, -1.0, out=h)
        return np.minimum(h, 1.0, out=h)  # np.clip, without its overhead

    def act(self, force_unit: ArrayLike, direction: ArrayLike, *extra: float) -> FloatArray:
        """Action (3,) in [-1, 1] for a unit (or zero) force and a unit motion direction.

        force_unit: (3,) F/|F| or the zero vector, world frame; direction: (3,) unit d;
        extra: the layout's further inputs (zeros when not given).
        Raises InvalidInputError (a ValueError) naming the argument on NaN, inf or bad shape.
        """
        f = _vector(force_unit, "force_unit")
        d = _vector(direction, "direction")
        rest = np.zeros(len(self.observation_layout) - 6)
        if len(extra) > rest.size:
            raise InvalidInputError(
                f"extra: {len(extra)} values, but observation {self.observation!r} takes "
                f"{rest.size} beyond (F/|F|, d): {', '.join(self.observation_layout[6:])}"
            )
        for i, x in enumerate(extra):
            rest[i] = check_number(f"extra[{i}] ({self.observation_layout[6 + i]})", x)
        obs = np.concatenate([f, d, rest])[None, :]
        return self._forward(obs)[0]

    def session(self) -> DirectionUpdater:
        """A fresh per-run updater (holds the previous step for history observations)."""
        return DirectionUpdater(self)

    def reset(self) -> None:
        """Reset the state `update_direction` keeps between calls (start of a run)."""
        self._session.reset()

    def update_direction(
        self,
        force: ArrayLike,
        direction: ArrayLike,
        force_offset: ArrayLike | None = None,
        threshold: float | None = None,
        step_force: float | None = None,
        workplane_normal: ArrayLike | None = None,
    ) -> FloatArray:
        """d_{t+1} (3,): `DirectionUpdater.update_direction` on this policy's own session.

        force, force_offset: (3,) [N] F_s and F_d, world frame; direction: (3,) unit d_t;
        workplane_normal: (3,) n when known (mirror-symmetric action, see there).
        Policies with history remember the previous call; `reset()` starts a new run.
        """
        return self._session.update_direction(
            force, direction, force_offset, threshold, step_force, workplane_normal
        )

    @property
    def layers(self) -> list[tuple[FloatArray, FloatArray]]:
        """(weight (out, in), bias (out,)) per layer, the training framework's layout."""
        return [(w.T.copy(), b.copy()) for w, b in zip(self._weights, self._biases, strict=True)]

    def digests(self) -> tuple[str, str]:
        """SHA-256 hex digests of the card (canonical JSON) and of the weights (float64 bytes,
        layer by layer in `layers` order): what tells two policies apart, whatever their
        files are called."""
        card = json.dumps(self.card, sort_keys=True, separators=(",", ":")).encode()
        weights = hashlib.sha256()
        for w, b in self.layers:
            weights.update(w.astype("<f8").tobytes())
            weights.update(b.astype("<f8").tobytes())
        return hashlib.sha256(card).hexdigest(), weights.hexdigest()

    def with_card(self, card: dict[str, Any]) -> ConstraintAwarePolicy:
        """The same weights with another card."""
        return ConstraintAwarePolicy(self.layers, card)

    @property
    def metrics(self) -> dict[str, Any]:
        return dict(self.card.get("metrics", {}))


def _vector(value: ArrayLike, name: str) -> FloatArray:
    """`value` as (3,) finite real floats whose norm is finite; InvalidInputError naming `name`
    otherwise (a complex value would lose its imaginary part, an overflowing norm would turn
    the vector into an unrelated direction)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (3,):
        # the executor's own readings, every control period: only the values to check. A
        # finite norm implies finite elements, so one sum of squares checks both.
        x, y, z = value.tolist()
        if math.isfinite(math.sqrt(x * x + y * y + z * z)):
            return value
        if not all_finite(value):
            raise InvalidInputError(f"{name}: contains NaN or inf")
        return _finite_norm(value, name)
    if np.iscomplexobj(value):
        raise InvalidInputError(f"{name}: complex values; expected 3 real numbers")
    return _finite_norm(as_vector(value, name), name)


def _finite_norm(vector: FloatArray, name: str) -> FloatArray:
    # a non-finite element makes the norm non-finite too; Python floats overflow to inf
    # without a warning
    x, y, z = vector.tolist()
    if not math.isfinite(math.sqrt(x * x + y * y + z * z)):
        raise InvalidInputError(
            f"{name}: its norm overflows ({vector.tolist()}); expected a physical value"
        )
    return vector


def _read_card(path: Path) -> dict[str, Any]:
    """The JSON card, checked field by field; PolicyFileError names the file and field."""
    size = path.stat().st_size
    if size > MAX_CARD_BYTES:
        raise PolicyFileError(f"{path}: {size:,} bytes; a card has at most {MAX_CARD_BYTES:,}")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise PolicyFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from exc
    try:
        card = json.loads(text)
    except json.JSONDecodeError as exc:
        raise PolicyFileError(f"{path}: not valid JSON ({exc})") from exc
    except RecursionError as exc:
        raise PolicyFileError(f"{path}: JSON nested too deeply") from exc
    if not isinstance(card, dict):
        raise PolicyFileError(f"{path}: the card must be a JSON object")
    if card.get("format") != CARD_FORMAT:
        raise PolicyFileError(
            f"{path}: field 'format' is {card.get('format')!r}, not {CARD_FORMAT}"
        )
    layout = card.get("observation_layout")
    if not isinstance(layout, list) or _layout_name(tuple(layout)) is None:
        raise PolicyFileError(
            f"{path}: field 'observation_layout' is none of this version's layouts ("
            + ", ".join(OBSERVATIONS)
            + ")"
        )
    n = card.get("n_layers")
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= _MAX_LAYERS:
        raise PolicyFileError(f"{path}: field 'n_layers' must be an integer in [1, {_MAX_LAYERS}]")
    env = card.get("env_config", {})
    if not isinstance(env, dict):
        raise PolicyFileError(f"{path}: field 'env_config' must be a JSON object")
    scale = env.get("action_scale", 1.0)
    if (
        isinstance(scale, bool)
        or not isinstance(scale, int | float)
        or not (math.isfinite(scale) and scale > 0)
    ):
        raise PolicyFileError(
            f"{path}: field 'env_config.action_scale' must be finite and > 0, got {scale!r}"
        )
    return card
