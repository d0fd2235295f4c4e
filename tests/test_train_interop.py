"""SB3 interop of training: model.zip checkpoint, resume without unpickling, TensorBoard."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

from constraint_aware.errors import InvalidInputError, PolicyFileError
from constraint_aware.training.ppo import CHECKPOINT, train
from constraint_aware.training.train_config import TrainConfig, make_config

EPISODES = 50  # evaluation episodes: enough to compare two evaluations of the same weights


def tiny(**overrides: object) -> TrainConfig:
    """Two rollouts of 8 episodes on a 16-16 network: seconds, not minutes."""
    base: dict[str, object] = {
        "total_timesteps": 80,
        "n_envs": 8,
        "batch_size": 40,
        "net_arch": (16, 16),
        "eval_every": 1,
        "eval_episodes": EPISODES,
        "torch_threads": 1,
    }
    return make_config("fast", **{**base, **overrides})


def saved_timesteps(path: Path) -> int:
    with zipfile.ZipFile(path) as archive:
        return int(json.loads(archive.read("data"))["num_timesteps"])


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("train") / "first"
    train(tiny(), out, final_eval_episodes=EPISODES)
    return out


def test_model_zip_beside_policy(first_run: Path) -> None:
    assert (first_run / "policy.npz").is_file()
    assert saved_timesteps(first_run / CHECKPOINT) == 80
    from stable_baselines3 import PPO

    model = PPO.load(first_run / CHECKPOINT, device="cpu")  # plain SB3 reads it
    assert model.num_timesteps == 80


def test_resume_loads_weights_optimizer_and_step_count(first_run: Path) -> None:
    import torch
    from stable_baselines3 import PPO

    from constraint_aware.training.ppo import build_model, resume_from
    from constraint_aware.training.vec_env import BatchedSingleSystemVecEnv

    config = tiny(seed=5)  # a different initialization, overwritten by the checkpoint
    model = build_model(BatchedSingleSystemVecEnv(config.n_envs, config.env), config)
    saved = PPO.load(first_run / CHECKPOINT, device="cpu")
    fresh = model.policy.state_dict()
    assert any(not torch.equal(fresh[k], v) for k, v in saved.policy.state_dict().items())
    resume_from(model, first_run / CHECKPOINT)
    assert model.num_timesteps == 80
    for key, value in saved.policy.state_dict().items():
        assert torch.equal(model.policy.state_dict()[key], value), key
    adam_saved = saved.policy.optimizer.state_dict()["state"]
    adam_loaded = model.policy.optimizer.state_dict()["state"]
    assert adam_saved.keys() == adam_loaded.keys() and adam_saved
    for key in adam_saved:
        assert torch.equal(adam_saved[key]["exp_avg"], adam_loaded[key]["exp_avg"])


def test_resume_continues_to_the_total(first_run: Path, tmp_path: Path) -> None:
    config = tiny(total_timesteps=160, resume=str(first_run / CHECKPOINT))
    result = train(config, tmp_path, final_eval_episodes=EPISODES)
    assert saved_timesteps(tmp_path / CHECKPOINT) == 160
    assert result.log[0]["timesteps"] == 80.0  # the checkpoint's weights, evaluated first
    assert result.log[-1]["timesteps"] == 160.0
    assert result.policy.card["total_timesteps"] == 160


def test_resume_is_validated(first_run: Path, tmp_path: Path) -> None:
    with pytest.raises(InvalidInputError, match="resume"):
        tiny(resume=str(tmp_path / "missing.zip"))
    with pytest.raises(InvalidInputError, match="total_timesteps"):
        train(tiny(resume=str(first_run / CHECKPOINT)), tmp_path / "a")
    with pytest.raises(PolicyFileError, match="resume"):  # another network's checkpoint
        train(tiny(total_timesteps=160, net_arch=(8,), resume=str(first_run / CHECKPOINT)))
    not_zip = tmp_path / "model.zip"
    not_zip.write_text("not a zip")
    with pytest.raises(PolicyFileError, match="resume"):
        train(tiny(total_timesteps=160, resume=str(not_zip)))


def test_tensorboard_logs_the_evaluations(tmp_path: Path) -> None:
    pytest.importorskip("tensorboard")
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    logdir = tmp_path / "tb"
    result = train(tiny(tensorboard=str(logdir)), final_eval_episodes=EPISODES)
    (event_file,) = logdir.glob("events.out.tfevents.*")
    events = EventAccumulator(str(event_file))
    events.Reload()
    scalars = events.Scalars("eval/mean_final_angle_deg")
    assert [s.step for s in scalars] == [int(r["timesteps"]) for r in result.log]
    assert [s.value for s in scalars] == pytest.approx(
        [r["eval_mean_final_angle_deg"] for r in result.log], rel=1e-6
    )
    assert "eval/mean_final_angle_deg" in (logdir / "progress.csv").read_text()
