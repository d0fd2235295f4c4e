"""ConstraintAwarePolicy: the trained direction-update policy, run with numpy alone.

A policy file is a pair: `NAME.npz` (the MLP's weights, float32, no pickle) and `NAME.json`
(the card: observation layout, training config, seed, metrics, library versions).
"""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from constraint_aware.errors import InvalidInputError, PolicyFileError
from constraint_aware.geometry import FloatArray, as_vector, normalize_force, update_direction_rule

CARD_FORMAT = "constraint-aware-policy/1"
OBSERVATION_LAYOUT = (
    "force_unit_x",
    "force_unit_y",
    "force_unit_z",
    "direction_x",
    "direction_y",
    "direction_z",
)
#: Observation layouts by name (issue 9). "history" adds the previous step's (F/|F|, d) (zeros
#: at the first step); "magnitude" adds |F| / (k*delta), the force over the robot's step force.
OBSERVATIONS: dict[str, tuple[str, ...]] = {
    "paper": OBSERVATION_LAYOUT,
    "history": OBSERVATION_LAYOUT + tuple(f"previous_{n}" for n in OBSERVATION_LAYOUT),
    "magnitude": (*OBSERVATION_LAYOUT, "force_over_step_force"),
}
#: What each observation needs from the robot besides the force and d (the card's `inputs`).
OBSERVATION_INPUTS: dict[str, tuple[str, ...]] = {
    "paper": ("force", "direction"),
    "history": ("force", "direction"),
    "magnitude": ("force", "direction", "step_force"),
}
#: |F| / (k*delta) is clipped to this: beyond it the arm pushes far past one blocked step.
MAGNITUDE_CLIP = 3.0
DEFAULT_POLICY_NAME = "policy"


def dead_band_card() -> dict[str, Any]:
    """The card's `dead_band` entry: deadband.py's rule."""
    from constraint_aware import deadband

    return {
        "floor_N": deadband.MIN_THRESHOLD,
        "noise_sigmas": deadband.NOISE_SIGMAS,
        "rule": "max(floor_N, noise_sigmas * per-axis std of the F_d samples) [N]",
    }
#: [N] default force threshold of `update_direction`, the training env's default.
DEFAULT_THRESHOLD = 0.2


def shipped_policy_path() -> Path:
    """Path of the pre-trained policy's `.npz` inside the installed package."""
    return Path(str(resources.files("constraint_aware") / "data" / f"{DEFAULT_POLICY_NAME}.npz"))


class ConstraintAwarePolicy:
    """MLP (tanh hidden layers) mapping s = (F/|F|, d) in R^6 to an action a in [-1, 1]^3.

    The direction update is d <- (d + s_a a)/|d + s_a a| with s_a the card's action scale.
    """

    def __init__(self, layers: list[tuple[FloatArray, FloatArray]], card: dict[str, Any]) -> None:
        if not layers:
            raise PolicyFileError("a policy needs at least one layer")
        if layers[0][0].shape[1] != 6 or layers[-1][0].shape[0] != 3:
            raise PolicyFileError(
                f"policy maps {layers[0][0].shape[1]} -> {layers[-1][0].shape[0]}, expected 6 -> 3"
            )
        # Float64 copies: the float32 training weights are reproduced to ~1e-7 while the
        # matrix products avoid float32 round-off.
        self._weights = [np.ascontiguousarray(w.T, dtype=np.float64) for w, _ in layers]
        self._biases = [np.asarray(b, dtype=np.float64) for _, b in layers]
        self.card = card
        env = card.get("env_config", {})
        self.action_scale = float(env.get("action_scale", 1.0))
        self.threshold = float(env.get("threshold", DEFAULT_THRESHOLD))

    # --- loading --------------------------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path | None = None) -> ConstraintAwarePolicy:
        """Load a policy (`.npz` plus its `.json` card beside it); default: the shipped one."""
        npz_path = Path(path) if path is not None else shipped_policy_path()
        if npz_path.suffix == ".json":
            npz_path = npz_path.with_suffix(".npz")
        card_path = npz_path.with_suffix(".json")
        if not npz_path.is_file():
            raise PolicyFileError(f"policy weights not found: {npz_path}")
        if not card_path.is_file():
            raise PolicyFileError(f"policy card not found: {card_path}")
        try:
            card = json.loads(card_path.read_text())
        except json.JSONDecodeError as exc:
            raise PolicyFileError(f"{card_path}: not valid JSON ({exc})") from exc
        if card.get("format") != CARD_FORMAT:
            raise PolicyFileError(f"{card_path}: format {card.get('format')!r}, not {CARD_FORMAT}")
        if tuple(card.get("observation_layout", ())) != OBSERVATION_LAYOUT:
            raise PolicyFileError(f"{card_path}: observation layout differs from this version's")
        try:
            with np.load(npz_path, allow_pickle=False) as data:
                n = int(card["n_layers"])
                layers = [(data[f"w{i}"], data[f"b{i}"]) for i in range(n)]
        except (KeyError, ValueError, OSError) as exc:
            raise PolicyFileError(f"{npz_path}: cannot read layers ({exc})") from exc
        return cls(layers, card)

    def save(self, path: str | Path) -> Path:
        """Write `path` (.npz) and its card (.json). Returns the .npz path."""
        npz_path = Path(path).with_suffix(".npz")
        npz_path.parent.mkdir(parents=True, exist_ok=True)
        arrays: dict[str, np.ndarray] = {}
        for i, (w, b) in enumerate(self.layers):
            arrays[f"w{i}"] = w.astype(np.float32)
            arrays[f"b{i}"] = b.astype(np.float32)
        np.savez(npz_path, **arrays)  # type: ignore[arg-type]
        card = dict(self.card, format=CARD_FORMAT, observation_layout=list(OBSERVATION_LAYOUT))
        card["n_layers"] = len(self._weights)
        npz_path.with_suffix(".json").write_text(json.dumps(card, indent=2) + "\n")
        return npz_path

    # --- inference ------------------------------------------------------------------------
    def act_batch(self, obs: FloatArray) -> FloatArray:
        """Deterministic actions for observations (N, 6): (N, 3), clipped to [-1, 1]."""
        h = obs
        last = len(self._weights) - 1
        for i, (w, b) in enumerate(zip(self._weights, self._biases, strict=True)):
            h = h @ w + b
            if i < last:
                h = np.tanh(h)
        return np.clip(h, -1.0, 1.0)

    def act(self, force_unit: ArrayLike, direction: ArrayLike) -> FloatArray:
        """Action (3,) in [-1, 1] for a unit (or zero) force and a unit motion direction.

        force_unit: (3,) F/|F| or the zero vector, world frame; direction: (3,) unit d.
        Raises InvalidInputError (a ValueError) naming the argument on NaN, inf or bad shape.
        """
        f = as_vector(force_unit, "force_unit")
        d = as_vector(direction, "direction")
        obs = np.concatenate([f, d])[None, :]
        return self.act_batch(obs)[0]

    def update_direction(
        self,
        force: ArrayLike,
        direction: ArrayLike,
        force_offset: ArrayLike | None = None,
        threshold: float | None = None,
    ) -> FloatArray:
        """The next motion direction d_{t+1} (3,) from a raw wrist force and d_t (paper 3.4.2).

        force: (3,) [N] measured force F_s, world frame; force_offset: (3,) [N] F_d recorded
        after grasping (default zero); F = F_s - F_d. If |F| < threshold [N] (default: the
        card's training threshold) the direction is returned unchanged.
        """
        f = as_vector(force, "force")
        d = as_vector(direction, "direction")
        if force_offset is not None:
            f = f - as_vector(force_offset, "force_offset")
        thr = self.threshold if threshold is None else float(threshold)
        if not np.isfinite(thr) or thr < 0:
            raise InvalidInputError(f"threshold: must be finite and >= 0, got {threshold}")
        norm_d = float(np.linalg.norm(d))
        if norm_d < 1e-9:
            raise InvalidInputError("direction: must be a non-zero vector")
        d = d / norm_d
        f_hat = normalize_force(f, thr)
        if not np.any(f_hat):
            return d
        a = self.action_scale * self.act_batch(np.concatenate([f_hat, d])[None, :])[0]
        return np.asarray(update_direction_rule(d, a))

    @property
    def layers(self) -> list[tuple[FloatArray, FloatArray]]:
        """(weight (out, in), bias (out,)) per layer, the training framework's layout."""
        return [(w.T.copy(), b.copy()) for w, b in zip(self._weights, self._biases, strict=True)]

    def with_card(self, card: dict[str, Any]) -> ConstraintAwarePolicy:
        """The same weights with another card."""
        return ConstraintAwarePolicy(self.layers, card)

    @property
    def metrics(self) -> dict[str, Any]:
        return dict(self.card.get("metrics", {}))
