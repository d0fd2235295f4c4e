"""Training the contact-points recognizer (recognizer.py's CNN) with torch: the `train` extra.

The network is recognizer.py's (`CONV_LAYERS`, `forward`), written here as a torch module with
the same weights layout, so that the trained weights run on numpy alone. Inputs are height maps
(N, P, P) [m] with NaN where the camera saw nothing, handle-shape indices (N,) and the truth in
the crop frame: contact points (N, 3) [m] and approaches (N, 3) unit (lfo/grasp_data.py makes
them from the scene builders). The loss is the smooth-L1 of the contact point's error in units
of `position_scale` plus that of the approach's tilt in units of `tilt_scale`. Each batch is
mirrored across the crop's x axis with probability 1/2 (a mirrored scene is a valid scene;
the crop's y and the approach's y change sign). Seeded; deterministic on one thread.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from torch import nn

from constraint_aware import recognizer as rec
from constraint_aware.errors import ConfigError, check_int, check_number


@dataclass(frozen=True)
class GraspTrainConfig:
    """How the recognizer is trained. Units in brackets."""

    epochs: int = 40
    batch_size: int = 128
    learning_rate: float = 2e-3  # Adam, cosine-decayed to zero over the epochs
    weight_decay: float = 1e-4
    position_scale: float = 0.005  # [m] the contact point's error is measured in these
    tilt_scale: float = 0.05  # [-] the approach tilt's error is measured in these
    seed: int = 0
    threads: int = 1  # torch's intra-op threads (the machine is shared)
    validation_samples: int = 1000  # crops scored after each epoch (the first ones)

    def __post_init__(self) -> None:
        n = "GraspTrainConfig."
        check_int(n + "epochs", self.epochs, low=1)
        check_int(n + "batch_size", self.batch_size, low=1)
        check_int(n + "seed", self.seed, low=0)
        check_int(n + "threads", self.threads, low=1)
        check_int(n + "validation_samples", self.validation_samples, low=1)
        for name in ("learning_rate", "position_scale", "tilt_scale"):
            check_number(n + name, getattr(self, name), low=0.0, low_open=True)
        check_number(n + "weight_decay", self.weight_decay, low=0.0)


class RecognizerNet(nn.Module):
    """recognizer.forward in torch (same parameter names and shapes, `rec.weight_shapes`)."""

    def __init__(self) -> None:
        super().__init__()
        convs = []
        cin = rec.INPUT_CHANNELS
        for cout, stride in rec.CONV_LAYERS:
            convs.append(nn.Conv2d(cin, cout, 3, stride=stride, padding=1))
            cin = cout
        self.convs = nn.ModuleList(convs)
        k = len(rec.HANDLE_SHAPES)
        self.heat = nn.Linear(cin, k)
        self.fc0 = nn.Linear(2 * cin + k, rec.HIDDEN)
        self.fc1 = nn.Linear(rec.HIDDEN, 3 * k)
        g = torch.as_tensor(rec.heat_grid(), dtype=torch.float32)
        gx, gy = torch.meshgrid(g, g, indexing="ij")
        self.gx: torch.Tensor
        self.gy: torch.Tensor
        self.register_buffer("gx", gx.reshape(-1))
        self.register_buffer("gy", gy.reshape(-1))

    def forward(self, x: torch.Tensor, shapes: torch.Tensor) -> torch.Tensor:
        h = x
        for conv in self.convs:
            h = torch.relu(conv(h))
        n, c = h.shape[:2]
        feats = h.reshape(n, c, -1)  # (N, C, P)
        heat = self.heat(feats.transpose(1, 2))  # (N, P, K)
        logits = heat.gather(2, shapes.view(n, 1, 1).expand(n, heat.shape[1], 1))[..., 0]
        p = torch.softmax(logits, dim=1)
        ex = p @ self.gx
        ey = p @ self.gy
        attended = torch.einsum("ncp,np->nc", feats, p)
        pooled = feats.mean(dim=2)
        onehot = torch.nn.functional.one_hot(shapes, len(rec.HANDLE_SHAPES)).float()
        z = torch.relu(self.fc0(torch.cat([attended, pooled, onehot], dim=1)))
        out = self.fc1(z).view(n, len(rec.HANDLE_SHAPES), 3)
        rest = out[torch.arange(n), shapes]
        return torch.cat([ex[:, None], ey[:, None], rest], dim=1)

    def numpy_weights(self) -> dict[str, np.ndarray]:
        """The weights in recognizer.py's layout (float64)."""
        out: dict[str, np.ndarray] = {}
        for i, conv in enumerate(self.convs):
            assert isinstance(conv, nn.Conv2d) and conv.bias is not None
            out[f"conv{i}_w"] = conv.weight.detach().double().numpy().copy()
            out[f"conv{i}_b"] = conv.bias.detach().double().numpy().copy()
        for name in ("heat", "fc0", "fc1"):
            layer: nn.Linear = getattr(self, name)
            out[f"{name}_w"] = layer.weight.detach().double().numpy().copy()
            out[f"{name}_b"] = layer.bias.detach().double().numpy().copy()
        return out


def inputs(heights: np.ndarray) -> np.ndarray:
    """(N, 4, P, P) float32 network inputs of height maps (N, P, P) [m]."""
    return np.asarray(rec.network_input(heights), dtype=np.float32)


def _mirror(x: torch.Tensor, target: torch.Tensor, flip: torch.Tensor) -> None:
    """Mirror the flagged samples across the crop's x axis, in place: the columns reversed,
    the y-coordinate channel, the targets' y and tilt y negated."""
    if not bool(flip.any()):
        return
    xf = x[flip].flip(dims=[3])
    xf[:, 3] = -xf[:, 3]
    x[flip] = xf
    target[flip, 1] = -target[flip, 1]
    target[flip, 4] = -target[flip, 4]


@dataclass
class GraspTrainResult:
    recognizer: rec.ContactPointRecognizer
    log: list[dict[str, float]]  # per epoch: train loss, validation errors
    wall_time_s: float


def position_errors(predicted: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) [m] contact-point errors."""
    return np.asarray(np.linalg.norm(predicted - points, axis=1))


def train_recognizer(
    heights: np.ndarray,
    shapes: np.ndarray,
    points: np.ndarray,
    approaches: np.ndarray,
    config: GraspTrainConfig | None = None,
    validation: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None,
    progress: Callable[[int, dict[str, float]], None] | None = None,
    card: dict[str, Any] | None = None,
) -> GraspTrainResult:
    """Train the CNN on crops (module docstring); `validation` (same four arrays) is scored
    after every epoch (median and 95th percentile contact-point error [mm], 95th percentile
    approach error [deg]). Returns the recognizer with its card (config, seed, log, versions
    and `card`'s entries)."""
    cfg = config or GraspTrainConfig()
    n = len(shapes)
    if not (len(heights) == len(points) == len(approaches) == n) or n == 0:
        raise ConfigError("training data", n, "equally long, non-empty arrays")
    start = time.perf_counter()
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads)
    rng = np.random.default_rng(cfg.seed)
    x_all = torch.from_numpy(inputs(heights))
    y_all = torch.from_numpy(rec.encode(points, approaches).astype(np.float32))
    s_all = torch.from_numpy(np.asarray(shapes, dtype=np.int64))
    net = RecognizerNet()
    optimizer = torch.optim.Adam(
        net.parameters(), lr=cfg.learning_rate, weight_decay=cfg.weight_decay
    )
    steps = cfg.epochs * math.ceil(n / cfg.batch_size)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=steps)
    # per output: the error in metres (x, y, depth) or tilt units, over the loss's scale
    scale = torch.tensor(
        [
            0.5 * rec.CROP_SIZE / cfg.position_scale,
            0.5 * rec.CROP_SIZE / cfg.position_scale,
            rec.DEPTH_RANGE / cfg.position_scale,
            rec.TILT_SCALE / cfg.tilt_scale,
            rec.TILT_SCALE / cfg.tilt_scale,
        ]
    )
    loss_fn = nn.SmoothL1Loss()
    log: list[dict[str, float]] = []
    for epoch in range(cfg.epochs):
        net.train()
        order = torch.from_numpy(rng.permutation(n))
        total = 0.0
        for i in range(0, n, cfg.batch_size):
            idx = order[i : i + cfg.batch_size]
            x, y, s = x_all[idx].clone(), y_all[idx].clone(), s_all[idx]
            _mirror(x, y, torch.from_numpy(rng.uniform(size=len(idx)) < 0.5))
            out = net(x, s)
            loss = loss_fn(out * scale, y * scale)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            total += float(loss.item()) * len(idx)
        row = {"epoch": float(epoch + 1), "train_loss": total / n}
        if validation is not None:
            row.update(_validate(net, validation, cfg.validation_samples))
        log.append(row)
        if progress is not None:
            progress(epoch + 1, row)
    weights = net.numpy_weights()
    meta = {
        "name": "recognizer",
        "training": asdict(cfg),
        "samples": n,
        "log": log,
        "versions": {"torch": torch.__version__, "numpy": np.__version__},
        **(card or {}),
    }
    return GraspTrainResult(
        rec.ContactPointRecognizer(weights, meta), log, time.perf_counter() - start
    )


def _validate(
    net: RecognizerNet,
    validation: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    limit: int,
) -> dict[str, float]:
    """`evaluate`'s errors on the first `limit` validation crops, with the torch network."""
    heights, shapes, points, approaches = (v[:limit] for v in validation)
    net.eval()
    with torch.no_grad():
        out = net(
            torch.from_numpy(inputs(heights)), torch.from_numpy(np.asarray(shapes, np.int64))
        ).numpy()
    p, a = rec.decode(out)
    return _errors(p, a, points, approaches)


def _errors(
    predicted: np.ndarray, approach: np.ndarray, points: np.ndarray, approaches: np.ndarray
) -> dict[str, float]:
    err = position_errors(predicted, points) * 1000.0
    cos = np.clip(np.sum(approach * approaches, axis=1), -1.0, 1.0)
    ang = np.degrees(np.arccos(cos))
    return {
        "val_median_mm": float(np.median(err)),
        "val_p95_mm": float(np.percentile(err, 95)),
        "val_approach_p95_deg": float(np.percentile(ang, 95)),
    }


def evaluate(
    weights: dict[str, np.ndarray],
    heights: np.ndarray,
    shapes: np.ndarray,
    points: np.ndarray,
    approaches: np.ndarray,
) -> dict[str, float]:
    """Validation errors of numpy `weights` on crops: contact point median and 95th
    percentile [mm], approach 95th percentile [deg]."""
    model = rec.ContactPointRecognizer(weights, {})
    names = [rec.HANDLE_SHAPES[int(i)] for i in shapes]
    predicted: list[np.ndarray] = []
    tilts: list[np.ndarray] = []
    for i in range(0, len(shapes), 256):
        p, a = model.predict(heights[i : i + 256], names[i : i + 256])
        predicted.append(p)
        tilts.append(a)
    return _errors(np.concatenate(predicted), np.concatenate(tilts), points, approaches)
