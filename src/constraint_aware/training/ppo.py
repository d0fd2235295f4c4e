"""PPO training of the constraint-aware policy with Stable-Baselines3 (needs the `train` extra).

Read top to bottom: the evaluation callback that logs the learning curve and keeps the best
weights, then `train()` itself; the hyper-parameters and presets are in `training.train_config`.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import platform
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import stable_baselines3
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.torch_layers import MlpExtractor
from stable_baselines3.common.utils import LinearSchedule
from stable_baselines3.common.vec_env import VecEnv

from constraint_aware.errors import CapError, InvalidInputError, PolicyFileError
from constraint_aware.geometry import FloatArray
from constraint_aware.policy import (
    OBSERVATION_INPUTS,
    OBSERVATIONS,
    ConstraintAwarePolicy,
    dead_band_card,
)
from constraint_aware.training.config import EnvConfig
from constraint_aware.training.evaluate import evaluate
from constraint_aware.training.reference import reference_controllers
from constraint_aware.training.train_config import TrainConfig, standard_env
from constraint_aware.training.vec_env import BatchedSingleSystemVecEnv
from constraint_aware.version import __version__

LOG_COLUMNS = (
    "timesteps",
    "wall_time_s",
    "train_mean_final_angle_deg",
    "train_mean_return",
    "eval_mean_final_angle_deg",
    "eval_p95_final_angle_deg",
    "eval_mean_return",
)


def observation_card(env: EnvConfig) -> dict[str, Any]:
    """The card fields that say what a policy of `env`'s observation reads."""
    return {"observation_layout": list(OBSERVATIONS[env.observation]), "env_config": env.to_dict()}


def export_policy(model: BaseAlgorithm, card: dict[str, Any]) -> ConstraintAwarePolicy:
    """The deterministic part of an SB3 MlpPolicy (policy_net + action_net) as a numpy policy."""
    extractor = model.policy.mlp_extractor
    assert isinstance(extractor, MlpExtractor)
    linears = [m for m in extractor.policy_net.modules() if isinstance(m, torch.nn.Linear)]
    head = model.policy.action_net
    assert isinstance(head, torch.nn.Linear)
    linears.append(head)
    layers = [
        (lin.weight.detach().cpu().numpy().copy(), lin.bias.detach().cpu().numpy().copy())
        for lin in linears
    ]
    return ConstraintAwarePolicy(layers, card)


def library_versions() -> dict[str, str]:
    return {
        "constraint_aware": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "torch": torch.__version__,
        "stable_baselines3": stable_baselines3.__version__,
    }


class EvalCallback(BaseCallback):
    """Every `eval_every` rollouts: evaluate the deterministic policy, log, keep the best."""

    def __init__(
        self,
        config: TrainConfig,
        vec_env: BatchedSingleSystemVecEnv,
        on_progress: Callable[[int, dict[str, float] | None], None] | None = None,
    ) -> None:
        super().__init__()
        self.config = config
        self.vec_env = vec_env
        self.on_progress = on_progress
        self.rows: list[dict[str, float]] = []
        self.best_angle = float("inf")
        self.best_policy: ConstraintAwarePolicy | None = None
        self.best_timesteps = 0
        self.start = time.perf_counter()
        self.rollouts = 0
        self.stop = False
        self.target_reached_s: float | None = None
        self.checkpoint: Path | None = None  # model.zip rewritten at each evaluation
        self.log_metrics = False  # record each evaluation in SB3's logger (--tensorboard)

    def _on_training_start(self) -> None:
        self.start = time.perf_counter()
        self.evaluate_now()  # the untrained policy: the curve's first point

    def _on_step(self) -> bool:
        return not self.stop

    def _on_rollout_end(self) -> None:
        self.rollouts += 1
        last = self.model.num_timesteps >= self.config.total_timesteps
        if self.rollouts % self.config.eval_every and not last:
            if self.on_progress is not None:
                self.on_progress(self.model.num_timesteps, None)
            return
        self.evaluate_now()

    def evaluate_now(self) -> None:
        cfg = self.config
        policy = export_policy(self.model, observation_card(cfg.env))

        def act(obs: FloatArray, _friction: FloatArray) -> FloatArray:
            return policy.act_batch(obs)

        result = evaluate(
            act,
            cfg.env,
            episodes=cfg.eval_episodes,
            seed=cfg.seed + 1,  # evaluation episodes differ from training and from the test set
        )
        angles = self.vec_env.completed_final_angles
        train_angle = float(np.mean(np.concatenate(angles))) if angles else float("nan")
        self.vec_env.completed_final_angles = []
        ep_info = [e["r"] for e in self.model.ep_info_buffer] if self.model.ep_info_buffer else []
        now = time.perf_counter() - self.start
        row = {
            "timesteps": float(self.model.num_timesteps),
            "wall_time_s": now,
            "train_mean_final_angle_deg": train_angle,
            "train_mean_return": float(np.mean(ep_info)) if ep_info else float("nan"),
            "eval_mean_final_angle_deg": result.mean_final_angle_deg,
            "eval_p95_final_angle_deg": result.p95_final_angle_deg,
            "eval_mean_return": result.mean_return,
        }
        self.rows.append(row)
        if result.mean_final_angle_deg < self.best_angle:
            self.best_angle = result.mean_final_angle_deg
            self.best_policy = policy
            self.best_timesteps = self.model.num_timesteps
        target = cfg.target_angle_deg
        reached = result.mean_final_angle_deg
        if target is not None and cfg.target_evaluation == "standard":
            reached = evaluate(
                act,
                standard_env(cfg.env),
                episodes=cfg.eval_episodes,
                seed=cfg.seed + 1,
            ).mean_final_angle_deg
        if target is not None and reached <= target:
            self.target_reached_s = now
            self.stop = True
        if cfg.time_budget_s is not None and now >= cfg.time_budget_s:
            self.stop = True
        if self.log_metrics:
            for key, value in row.items():  # eval_mean_return -> eval/mean_return
                if key != "timesteps":  # the step axis itself
                    tag = key.replace("_", "/", 1) if key[:5] in ("eval_", "train") else key
                    self.logger.record(tag, value)
            self.logger.dump(step=self.model.num_timesteps)
        if self.checkpoint is not None:
            self.model.save(self.checkpoint)
        if self.on_progress is not None:
            self.on_progress(self.model.num_timesteps, row)


@dataclass
class TrainResult:
    policy: ConstraintAwarePolicy
    log: list[dict[str, float]]
    wall_time_s: float
    target_reached_s: float | None
    policy_path: Path | None


def write_log(rows: list[dict[str, float]], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(LOG_COLUMNS))
        writer.writeheader()
        for row in rows:
            writer.writerow({k: f"{row[k]:.6g}" for k in LOG_COLUMNS})


def build_model(vec_env: VecEnv, config: TrainConfig) -> PPO:
    """The PPO model of a config: MLP tanh policy and value nets (paper 5.1), on the CPU."""
    learning_rate: float | LinearSchedule = config.learning_rate
    if config.final_learning_rate is not None:
        # annealed over total_timesteps: large early steps for speed, small late ones so the
        # last evaluations are not dominated by the step noise of a constant rate
        learning_rate = LinearSchedule(config.learning_rate, config.final_learning_rate, 1.0)
    model = PPO(
        "MlpPolicy",
        vec_env,
        learning_rate=learning_rate,
        n_steps=config.env.episode_length,  # one episode per env per rollout
        batch_size=config.batch_size,
        n_epochs=config.n_epochs,
        gamma=config.gamma,
        gae_lambda=config.gae_lambda,
        clip_range=config.clip_range,
        ent_coef=config.ent_coef,
        policy_kwargs={
            "net_arch": {"pi": list(config.net_arch), "vf": list(config.net_arch)},
            "activation_fn": torch.nn.Tanh,
            "log_std_init": config.log_std_init,
        },
        seed=config.seed,
        device="cpu",
        verbose=0,
    )
    # a logger of its own: SB3's default makes an empty SB3-<date> folder in the temp directory
    # at every learn()
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


CHECKPOINT = "model.zip"


def resume_from(model: PPO, path: str | Path) -> None:
    """Load a model.zip's weights, optimizer state and step count into `model`, unpickled.

    SB3's `PPO.load` unpickles the archive's hyper-parameter objects (arbitrary code); here only
    its tensors (torch `weights_only`) and the plain-JSON step counters are read, and every
    hyper-parameter comes from the current TrainConfig.
    """
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
        model.set_parameters(str(path), exact_match=True, device="cpu")
    except (OSError, KeyError, ValueError, RuntimeError, zipfile.BadZipFile) as exc:
        raise PolicyFileError(
            f"resume: {path} is not a checkpoint of this network ({exc})"
        ) from exc
    model.num_timesteps = int(data.get("num_timesteps", 0))
    model._n_updates = int(data.get("_n_updates", 0))


def metrics_logger(directory: str | Path) -> Any:
    """SB3's logger writing CSV and TensorBoard event files to `directory`."""
    if importlib.util.find_spec("tensorboard") is None:
        raise CapError(
            "tensorboard: logging needs the 'tensorboard' package: pip install tensorboard "
            "(part of the 'train' extra)"
        )
    from stable_baselines3.common.logger import configure

    return configure(str(directory), ["csv", "tensorboard"])


def train(
    config: TrainConfig,
    out_dir: str | Path | None = None,
    on_progress: Callable[[int, dict[str, float] | None], None] | None = None,
    final_eval_episodes: int = 10_000,
) -> TrainResult:
    """Train PPO on the batched analytic env; write policy, card and log to `out_dir`."""
    torch.set_num_threads(config.torch_threads)
    vec_env = BatchedSingleSystemVecEnv(config.n_envs, config.env, seed=config.seed)
    model = build_model(vec_env, config)
    if config.tensorboard is not None:
        model.set_logger(metrics_logger(config.tensorboard))
    if config.resume is not None:
        resume_from(model, config.resume)
        if model.num_timesteps >= config.total_timesteps:
            raise InvalidInputError(
                f"total_timesteps: {config.total_timesteps} <= the checkpoint's "
                f"{model.num_timesteps} steps; raise it to train further"
            )
    callback = EvalCallback(config, vec_env, on_progress)
    callback.log_metrics = config.tensorboard is not None
    if out_dir is not None:
        Path(out_dir).mkdir(parents=True, exist_ok=True)
        callback.checkpoint = Path(out_dir) / CHECKPOINT
    start = time.perf_counter()
    model.learn(
        total_timesteps=config.total_timesteps - model.num_timesteps,
        callback=callback,
        reset_num_timesteps=config.resume is None,
    )
    wall = time.perf_counter() - start
    if callback.best_policy is None:  # total_timesteps smaller than one rollout
        callback.evaluate_now()
    assert callback.best_policy is not None
    best = callback.best_policy

    # The card's metrics use the standard test set (a seed no training evaluation used).
    refs = reference_controllers(config.env)
    metrics = {
        name: evaluate(ctrl, config.env, episodes=final_eval_episodes).to_dict()
        for name, ctrl in refs.items()
    }
    metrics["policy"] = evaluate(
        lambda obs, _f: best.act_batch(obs), config.env, episodes=final_eval_episodes
    ).to_dict()
    card: dict[str, Any] = {
        "description": "Constraint-aware policy (Saito et al.): "
        + f"{config.env.observation} observation -> direction update",
        "units": {
            "force_unit": "dimensionless unit vector (or zero below threshold), world frame",
            "direction": "dimensionless unit vector, world frame",
            "action": "added to d before renormalizing, after scaling by action_scale",
            "threshold": "N",
        },
        "env_config": config.env.to_dict(),
        "train_config": config.to_dict(),
        "seed": config.seed,
        "best_timesteps": callback.best_timesteps,
        "total_timesteps": int(model.num_timesteps),
        "wall_time_s": wall,
        "target_reached_s": callback.target_reached_s,
        "metrics": metrics,
        "versions": library_versions(),
        **observation_card(config.env),
        "inputs": list(OBSERVATION_INPUTS[config.env.observation]),
        "dead_band": dead_band_card(),
    }
    if config.env.has_resistance:
        # the paper's resistance-free test set too: the standard evaluation's bar applies there
        standard = standard_env(config.env)
        card["metrics_standard"] = {
            name: evaluate(ctrl, standard, episodes=final_eval_episodes).to_dict()
            for name, ctrl in {
                **reference_controllers(standard),
                "policy": lambda obs, _f: best.act_batch(obs),
            }.items()
        }
    policy = best.with_card(card)
    path = None
    if out_dir is not None:
        out = Path(out_dir)
        path = policy.save(out / "policy.npz")
        model.save(out / CHECKPOINT)  # the last weights (policy.npz holds the best evaluation's)
        write_log(callback.rows, out / "training_log.csv")
        (out / "train_config.json").write_text(json.dumps(config.to_dict(), indent=2) + "\n")
    return TrainResult(policy, callback.rows, wall, callback.target_reached_s, path)
