"""Gymnasium integration: registration on import, check_env, determinism, the vector twin."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import constraint_aware  # registers the environments
from constraint_aware.envs import ENV_IDS, SINGLE_SYSTEM_ID, TASK_ENV_IDS
from constraint_aware.envs.single_system_vector import SingleSystemVectorEnv
from constraint_aware.training.batch import SingleSystemBatch
from constraint_aware.training.config import EnvConfig


def test_every_id_is_registered_on_import_without_heavy_imports() -> None:
    code = (
        "import sys, constraint_aware, gymnasium as gym; "
        f"missing = [i for i in {list(ENV_IDS)!r} if i not in gym.registry]; "
        "heavy = [m for m in ('mujoco', 'torch', 'matplotlib') if m in sys.modules]; "
        "print(missing, heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[] []"
    for env_id in ENV_IDS:
        assert isinstance(gym.spec(env_id).entry_point, str)


def test_task_ids_name_the_five_tasks() -> None:
    assert TASK_ENV_IDS == {
        "drawer-opening": "constraint_aware/DrawerOpening-v0",
        "plate-sliding": "constraint_aware/PlateSliding-v0",
        "pole-pulling": "constraint_aware/PolePulling-v0",
        "door-opening": "constraint_aware/DoorOpening-v0",
        "handle-rotating": "constraint_aware/HandleRotating-v0",
    }


def rollout(env: gym.Env[Any, Any], seed: int, steps: int) -> list[Any]:
    """Observations, rewards and flags of `steps` steps with seeded actions."""
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    out: list[Any] = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        out.append((obs, reward, terminated, truncated))
        if terminated or truncated:
            obs, _ = env.reset()
            out.append(obs)
    return out


def assert_same(a: list[Any], b: list[Any]) -> None:
    from gymnasium.utils.env_checker import data_equivalence

    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert data_equivalence(x, y, exact=True)


def test_single_system_check_env_and_render() -> None:
    env = gym.make(SINGLE_SYSTEM_ID, render_mode="rgb_array")
    check_env(env.unwrapped)
    env.reset(seed=0)
    frame = env.render()
    assert isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.shape[2] == 3
    assert frame.std() > 0  # something was drawn


def test_single_system_same_seed_same_episodes() -> None:
    a = rollout(gym.make(SINGLE_SYSTEM_ID), 5, 12)
    b = rollout(gym.make(SINGLE_SYSTEM_ID), 5, 12)
    assert_same(a, b)
    c = rollout(gym.make(SINGLE_SYSTEM_ID), 6, 12)
    assert not np.array_equal(a[0], c[0])


def test_unknown_render_mode_lists_valid_ones() -> None:
    with pytest.raises(constraint_aware.UnknownNameError, match="rgb_array"):
        gym.make(SINGLE_SYSTEM_ID, render_mode="ansi")


def test_vector_twin_is_the_vector_entry_point() -> None:
    envs = gym.make_vec(SINGLE_SYSTEM_ID, num_envs=8)
    assert isinstance(envs.unwrapped, SingleSystemVectorEnv)
    obs, _ = envs.reset(seed=0)
    single_shape = envs.unwrapped.single_observation_space.shape
    assert single_shape is not None and obs.shape == (8, *single_shape)
    assert single_shape == envs.unwrapped.batch.reset().shape[1:]


def test_vector_twin_steps_the_batch_and_autoresets_next_step() -> None:
    config = EnvConfig()
    envs = SingleSystemVectorEnv(num_envs=16, config=config)
    obs, _ = envs.reset(seed=3)
    batch = SingleSystemBatch(16, config)
    np.testing.assert_array_equal(obs, batch.reset(np.random.default_rng(3)).astype(np.float32))
    actions = np.random.default_rng(0).uniform(-1, 1, (config.episode_length, 16, 3))
    for t in range(config.episode_length):
        obs, reward, terminated, truncated, info = envs.step(actions[t])
        ref_obs, ref_reward, done = batch.step(actions[t])
        np.testing.assert_array_equal(obs, ref_obs.astype(np.float32))
        np.testing.assert_array_equal(reward, ref_reward)
        assert terminated.all() == done and not truncated.any()
    np.testing.assert_array_equal(info["final_angle_deg"], batch.angle_to_axis_deg())
    obs, reward, terminated, _, _ = envs.step(actions[0])  # the reset step
    assert not terminated.any() and not reward.any()
    envs.close()


def test_vector_twin_passes_gymnasiums_vector_checks() -> None:
    from gymnasium.utils.env_checker import data_equivalence

    a = SingleSystemVectorEnv(num_envs=4)
    b = SingleSystemVectorEnv(num_envs=4)
    assert data_equivalence(a.reset(seed=1), b.reset(seed=1))
    assert a.observation_space.contains(a.reset(seed=1)[0])
    a.action_space.seed(0)
    act = a.action_space.sample()
    assert data_equivalence(a.step(act), b.step(act))


# --- the five tasks ---------------------------------------------------------------------------
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_check_env_on_every_registered_id(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped)  # also calls render()
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_episode_on_every_registered_id(env_id: str) -> None:
    kwargs: dict[str, Any] = {}
    if env_id in TASK_ENV_IDS.values():
        kwargs = {"offset_deg": (10.0, 40.0), "randomize": True}  # draws from np_random too
    a = rollout(gym.make(env_id, **kwargs), 11, 8)
    b = rollout(gym.make(env_id, **kwargs), 11, 8)
    assert_same(a, b)
    c = rollout(gym.make(env_id, **kwargs), 12, 8)
    first = a[0]["direction"] if isinstance(a[0], dict) else a[0]
    other = c[0]["direction"] if isinstance(c[0], dict) else c[0]
    assert not np.array_equal(first, other)


def test_task_step_is_one_executor_period_and_ends_with_the_executors_outcome() -> None:
    env = gym.make("constraint_aware/DrawerOpening-v0", offset_deg=0.0)
    obs, info = env.reset(seed=0)
    assert info["outcome"] == "running"
    record = env.unwrapped.executor.record  # type: ignore[attr-defined]
    n0 = len(record.steps)
    terminated = truncated = False
    total = 0.0
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(obs["direction"])
        total += float(reward)
        n0 += 1
        assert len(record.steps) == n0  # one executor control step per env step
    assert terminated and not truncated
    assert info["outcome"] == "success" and info["success"] is True
    assert info["progress_fraction"] >= 1.0 and 0.8 < total <= info["progress_fraction"]
    assert info["record"].outcome == "success"


def test_task_action_is_the_next_direction_projected_on_the_workplane() -> None:
    env = gym.make("constraint_aware/DoorOpening-v0")
    obs, _ = env.reset(seed=0)
    normal = np.asarray(env.unwrapped.executor.config.workplane_normal)  # type: ignore[attr-defined]
    action = np.array([0.3, -0.2, 0.9], dtype=np.float32)
    obs, *_ = env.step(action)
    expected = action - (action @ normal) * normal
    np.testing.assert_allclose(obs["direction"], expected / np.linalg.norm(expected), atol=1e-12)
    assert abs(obs["direction"] @ normal) < 1e-12


def test_task_force_limit_is_a_termination_and_timeout_a_truncation() -> None:
    env = gym.make("constraint_aware/DrawerOpening-v0", offset_deg=75.0)
    obs, _ = env.reset(seed=0)
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(obs["direction"])  # never corrects
    assert terminated and info["outcome"] == "force_limit"
    env = gym.make("constraint_aware/DrawerOpening-v0", executor={"limits__max_steps": 3})
    obs, _ = env.reset(seed=0)
    terminated = truncated = False
    while not (terminated or truncated):
        obs, _, terminated, truncated, info = env.step(obs["direction"])
    assert truncated and not terminated and info["outcome"] == "timeout"


def test_task_run_ended_during_reset_ends_at_the_first_step() -> None:
    # a 3.5 N limit: the executor refuses the first move (predicted |F| ~ 20 N) during reset
    env = gym.make("constraint_aware/DrawerOpening-v0", executor={"limits__force_limit": 3.5})
    obs, info = env.reset(seed=0)
    assert info["outcome"] == "force_limit"
    _, reward, terminated, truncated, info = env.step(obs["direction"])
    assert terminated and not truncated and info["outcome"] == "force_limit"
    _, reward, terminated, _, _ = env.step(obs["direction"])  # after the end: nothing moves
    assert terminated and reward == 0.0


def test_task_config_kwarg_takes_any_task() -> None:
    from constraint_aware.sim.tasks import task_config

    heavy = task_config("drawer-opening", object__mass=3.0)
    env = gym.make("constraint_aware/DrawerOpening-v0", task_config=heavy)
    env.reset(seed=0)
    assert env.unwrapped.sim.task.object.mass == 3.0  # type: ignore[attr-defined]


def test_task_rgb_array_frames() -> None:
    env = gym.make(
        "constraint_aware/HandleRotating-v0", render_mode="rgb_array", width=160, height=120
    )
    env.reset(seed=0)
    frame = env.render()
    assert isinstance(frame, np.ndarray) and frame.shape == (120, 160, 3) and frame.std() > 0


def test_readme_one_liner() -> None:
    code = (
        "import constraint_aware, gymnasium as gym; "
        "gym.make('constraint_aware/SingleSystem-v0'); "
        "gym.make('constraint_aware/DoorOpening-v0', render_mode='rgb_array')"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


# --- another embodiment -----------------------------------------------------------------------
def test_task_env_on_the_jaco_passes_check_env_and_repeats_with_its_seed() -> None:
    from constraint_aware.sim.jaco import JacoSim

    env = gym.make("constraint_aware/DrawerOpening-v0", robot="jaco", render_mode="rgb_array")
    check_env(env.unwrapped)  # also calls render()
    env.close()
    kwargs: dict[str, Any] = {"robot": "jaco", "offset_deg": (10.0, 40.0), "sensor_noise": 0.3}
    first = gym.make("constraint_aware/DrawerOpening-v0", **kwargs)
    a = rollout(first, 3, 5)
    assert isinstance(first.unwrapped.sim, JacoSim)  # type: ignore[attr-defined]
    assert_same(a, rollout(gym.make("constraint_aware/DrawerOpening-v0", **kwargs), 3, 5))
    c = rollout(gym.make("constraint_aware/DrawerOpening-v0", **kwargs), 4, 5)
    assert not np.array_equal(a[0]["direction"], c[0]["direction"])


@pytest.mark.parametrize(
    ("robot", "message"),
    [("nao", "valid names: hook-hand, jaco"), ("jaco:stiffness=5", "valid range"),
     ("jaco:mass=2", "period, stiffness")],
)  # fmt: skip
def test_task_env_robot_is_validated_at_construction(robot: str, message: str) -> None:
    from constraint_aware.errors import CapError

    with pytest.raises(CapError, match=message):
        gym.make("constraint_aware/DoorOpening-v0", robot=robot)
