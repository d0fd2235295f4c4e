"""The five simulated tasks as Gymnasium environments, one executor control period per step."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import ArrayLike

from constraint_aware.control.controllers import ControlInput, project_on_plane
from constraint_aware.control.executor import Executor
from constraint_aware.control.record import RunRecord
from constraint_aware.control.simulate import executor_config, simulated_robot
from constraint_aware.envs.single_system import check_render_mode
from constraint_aware.errors import (
    ConfigError,
    InvalidInputError,
    check_int,
    check_number,
)
from constraint_aware.geometry import FloatArray, rotate_about, unit
from constraint_aware.sim.embodiment import DEFAULT_ROBOT, Embodiment, parse_robot
from constraint_aware.sim.tasks import TaskConfig, randomized, task_config
from constraint_aware.spatial import Pose, Wrench

RENDER_MODES: tuple[str, ...] = ("rgb_array",)
TIMEOUT = "timeout"  # the executor's outcome for max_steps: a truncation, not a termination
#: [px] the largest frame: the scene's offscreen buffer (sim/scene.py sets 640 x 480)
MAX_WIDTH, MAX_HEIGHT = 640, 480


class _ActionController:
    """The executor's direction controller whose answer is the agent's action."""

    name = "gymnasium"

    def __init__(self) -> None:
        self.direction = np.zeros(3)  # d_t (3,) unit, as the executor holds it
        self.action: FloatArray | None = None
        self.calls = 0  # times the executor asked for a direction

    def reset(self, direction: FloatArray) -> None:
        self.direction = np.asarray(direction, dtype=float).copy()

    def next_direction(self, inp: ControlInput) -> FloatArray:
        self.calls += 1
        # the first move (during reset) keeps d0, as every controller does below the dead
        # band, where |F - F_d| is at rest
        proposed = inp.direction if self.action is None else self.action
        d = project_on_plane(unit(np.asarray(proposed, dtype=float)), inp.workplane_normal)
        if not np.all(np.isfinite(d)) or np.linalg.norm(d) < 1e-6:
            d = inp.direction  # a zero action, or one along the workplane normal: keep d_t
        self.direction = np.asarray(d, dtype=float).copy()
        return self.direction

    def step_length(self, nominal: float) -> float:
        return nominal

    def hand_rotation(self) -> None:
        return None  # the executor's rule (paper 3.4.1, or the torque policy)


class TaskEnv(gym.Env[dict[str, np.ndarray], np.ndarray]):
    """A simulated task (drawer, plate, pole, door, handle) driven by your direction policy.

    The hand grasps the object; each `step` is one control period (100 ms unless the robot
    spec sets `period`) of the robot-agnostic
    `Executor` (constraint_aware.control), with your action as its direction controller. The
    executor does everything else it does for `cap run`: the F_d tare, the workplane
    projection, the hand rotation on revolute joints (paper 3.4.1, or the torque policy on
    fixed-orientation grasps), the 1 cm move and every safety stop.

    Observation (dict, world frame):
        "wrench" (6,): tared force F = F_s - F_d [N] and torque tau - tau_d [N m] at the wrist;
        "position" (3,) [m] and "orientation" (4,) (quaternion x, y, z, w) of the tool point;
        "direction" (3,): the current motion direction d_t (unit, in the workplane).
    Action (3,) in [-1, 1]: the next direction d_{t+1} (world frame). The executor normalizes
        it and projects it on the task's workplane; a zero action, or one along the workplane
        normal, keeps d_t. `(F/|F|, d)` from the observation is what the paper's policy reads.
        An action that is not 3 finite real numbers (NaN, inf, a wrong shape, text) raises
        InvalidInputError naming it before anything moves (Gymnasium's convention for an
        invalid action); the episode is left as it was.
    Reward: the period's progress as a fraction of the task's goal (a successful episode
        collects about 1) minus |F| / force_limit / max_steps (constraint force, as the
        training reward penalizes it; at most 1 over a whole episode held at the limit).
    Episode: `reset` grasps, samples F_d over the first periods with the hand held, and makes
        the first 1 cm move along d0 (below the dead band every controller keeps d0 there).
        The episode ends when the executor stops: `terminated` on success or any safety stop
        (force limit, lost grasp or contact, non-finite readings...), `truncated` on its
        timeout (the task's max_steps). The reading that ends a run is acted on in the next
        `step`, whose action is then not used; a run that ended during `reset` (a fault while
        sampling F_d) ends at the first `step`, as does any `step` after the end.
    info: "outcome" ("running" or the executor's outcome), "reason", "success", "progress" [m
        or rad], "progress_fraction" (of the goal), "slip_m" [m], "slip_deg" [deg],
        "force_norm" [N]; at the end also "record", the executor's full `RunRecord`.

    Keywords (gym.make(id, ...)):
        task_config: any `TaskConfig` (e.g. `sim.tasks.task_config("door-opening",
            object__mass=3)`) instead of the registered task's preset;
        offset_deg: initial direction error about the workplane normal [deg]: a number in
            [-180, 180], or (low, high) with 0 <= low <= high < 180 for
            |offset| ~ U(low, high) with a random sign (default 30);
        randomize: draw friction, mass and damping per episode (sim.tasks.randomized);
        sensor_noise: [N] std of the force reading per axis, >= 0 (default 0.1, as `cap run`);
        torque_policy: None (on exactly for fixed-orientation grasps), True or False;
        executor: ExecutorConfig fields to override, as `ExecutorConfig.with_overrides` keys
            (e.g. {"threshold": 2.0, "limits__max_steps": 80});
        robot: the embodiment, a robot spec (sim.embodiment): "hook-hand" (default), "jaco"
            (the Kinova Jaco arm and hand), optionally with variants,
            "jaco:stiffness=2000,period=0.2"; an unknown name or variant fails at
            construction, naming the valid ones;
        render_mode: None or "rgb_array" (offscreen MuJoCo, sim.render.SceneRenderer),
            width (1-640) and height (1-480) [px] of the frames.
    Every keyword is checked at construction, as `RunSpec` checks `cap run`'s: a wrong type or
    a value out of range raises ConfigError naming it and its valid range.
    Randomness comes only from `self.np_random` (seed it with `reset(seed=...)`).
    """

    metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES), "render_fps": 10}  # noqa: RUF012

    def __init__(
        self,
        task: str = "drawer-opening",
        task_config: TaskConfig | None = None,
        offset_deg: float | tuple[float, float] = 30.0,
        randomize: bool = False,
        sensor_noise: float = 0.1,
        torque_policy: bool | None = None,
        executor: dict[str, Any] | None = None,
        robot: str = DEFAULT_ROBOT,
        render_mode: str | None = None,
        width: int = 480,
        height: int = 360,
    ) -> None:
        n = "TaskEnv."
        check_render_mode(render_mode, RENDER_MODES)
        if task_config is not None and not isinstance(task_config, TaskConfig):
            raise ConfigError(
                n + "task_config", task_config, "a TaskConfig (sim.tasks.task_config)"
            )
        if not isinstance(task, str):
            raise ConfigError(n + "task", task, "a task name")
        self._base = task_config if task_config is not None else _preset(task)
        if not isinstance(randomize, bool | np.bool_):
            raise ConfigError(n + "randomize", randomize, "True or False")
        if torque_policy is not None and not isinstance(torque_policy, bool | np.bool_):
            raise ConfigError(n + "torque_policy", torque_policy, "True, False or None")
        if randomize and task_config is not None:
            raise InvalidInputError(
                "randomize draws from a named task's preset; not with task_config"
            )
        self.offset_deg = _check_offset(offset_deg)
        self.sensor_noise = check_number(n + "sensor_noise", sensor_noise, low=0, unit="N")
        if not isinstance(robot, str):
            raise ConfigError(n + "robot", robot, "a robot spec such as 'jaco:stiffness=2000'")
        parse_robot(robot)  # UnknownNameError / InvalidInputError naming the valid ones
        self.width = _check_pixels(n + "width", width, MAX_WIDTH)
        self.height = _check_pixels(n + "height", height, MAX_HEIGHT)
        if executor is not None and not isinstance(executor, dict):
            raise ConfigError(n + "executor", executor, "a dict of ExecutorConfig fields")
        self.executor_overrides = dict(executor or {})
        base_cfg = executor_config(self._base, torque_policy)
        self.robot = robot
        self.task_name = self._base.name
        self.randomize = bool(randomize)
        self.torque_policy = torque_policy
        # built once here so that invalid overrides fail at construction (an unknown key
        # raises UnknownNameError listing the valid ones)
        self.executor_config = base_cfg.with_overrides(**self.executor_overrides)
        self.render_mode = render_mode
        vec = gym.spaces.Box(-np.inf, np.inf, (3,), np.float64)
        self.observation_space = gym.spaces.Dict(  # type: ignore[assignment]
            {
                "wrench": gym.spaces.Box(-np.inf, np.inf, (6,), np.float64),
                "position": vec,
                "orientation": gym.spaces.Box(-1.0, 1.0, (4,), np.float64),
                "direction": gym.spaces.Box(-1.0, 1.0, (3,), np.float64),
            }
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.sim: Embodiment | None = None
        self.executor: Executor | None = None
        self._controller = _ActionController()
        self._reading: tuple[Wrench, Pose] | None = None
        self._record: RunRecord | None = None
        self._renderer: Any = None

    # --- episode ------------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        rng = self.np_random
        task = randomized(self.task_name, rng) if self.randomize else self._base
        sim = simulated_robot(self.robot, task, rng, self.sensor_noise)
        sim.reset()
        cfg = (
            self.executor_config
            if not self.randomize
            else executor_config(task, self.torque_policy).with_overrides(**self.executor_overrides)
        )
        # d0 turns about the executor's workplane normal; in 3-D motion (None) about the task's
        axis = task.workplane_normal if cfg.workplane_normal is None else cfg.workplane_normal
        offset = self._draw_offset(rng)
        d0 = rotate_about(sim.admissible_direction(), np.asarray(axis), math.radians(offset))
        self._close_renderer()
        self.sim = sim
        self._controller = _ActionController()
        self.executor = Executor(sim, self._controller, cfg, monitor=sim)
        label = {
            "task": task.name,
            "controller": self._controller.name,
            "offset_deg": offset,
            "randomized": self.randomize,
            "torque_policy": cfg.torque_policy.enabled,
            "sensor_noise_N": self.sensor_noise,
            "success_progress": task.success_progress,
            "constraint_type": task.constraint_type,
            "force_exertion_type": task.force_exertion_type,
            "force_limit_N": task.force_limit,
            "robot": self.robot,
        }
        self._record = self.executor.start(d0, label)
        # F_d sampling holds the hand; it ends with the first move (along d0)
        for _ in range(
            cfg.timing.offset_samples + cfg.limits.max_steps
        ):  # bounded: the executor stops
            if self._controller.calls > 0:
                break
            out = self.executor.step(sim.read_wrench(), sim.read_pose())
            if isinstance(out, RunRecord):
                break
            sim.command_pose(out)
            sim.advance()
        self._reading = (sim.read_wrench(), sim.read_pose())
        return self._observation(), self._info()

    def step(
        self, action: np.ndarray
    ) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self.executor is None or self.sim is None or self._reading is None:
            raise InvalidInputError("TaskEnv.step: call reset() first")
        record = self._record
        assert record is not None
        if record.finished:  # ended already (also possible during reset): nothing moves
            truncated = record.outcome == TIMEOUT
            return self._observation(), 0.0, not truncated, truncated, self._info()
        checked = _check_action(action)  # before anything moves
        before = self.sim.progress()
        self._controller.action = checked
        out = self.executor.step(*self._reading)
        if not isinstance(out, RunRecord):
            self.sim.command_pose(out)
            self.sim.advance()
            self._reading = (self.sim.read_wrench(), self.sim.read_pose())
        obs = self._observation()
        cfg = self.executor.config
        force_norm = float(np.linalg.norm(obs["wrench"][:3]))
        reward = (self.sim.progress() - before) / self.sim.task.success_progress
        if math.isfinite(force_norm):
            reward -= force_norm / cfg.limits.force_limit / cfg.limits.max_steps
        finished = record.finished
        truncated = finished and record.outcome == TIMEOUT
        return obs, float(reward), finished and not truncated, truncated, self._info()

    # --- observation and info -----------------------------------------------------------------
    def _observation(self) -> dict[str, np.ndarray]:
        assert self._reading is not None and self._record is not None
        wrench, pose = self._reading
        offset_f = np.asarray(self._record.force_offset, dtype=float)
        offset_t = np.asarray(self._record.torque_offset, dtype=float)
        tared = np.concatenate(
            [np.asarray(wrench.force) - offset_f, np.asarray(wrench.torque) - offset_t]
        )
        return {
            "wrench": np.nan_to_num(tared, nan=0.0),  # NaN only before F_d exists
            "position": np.asarray(pose.position, dtype=np.float64).copy(),
            "orientation": np.asarray(pose.orientation.as_quat(), dtype=np.float64),
            "direction": self._controller.direction.astype(np.float64),
        }

    def _info(self) -> dict[str, Any]:
        assert self.sim is not None and self._record is not None
        record = self._record
        slip_m, slip_deg = self.sim.slip()
        progress = self.sim.progress()
        info: dict[str, Any] = {
            "outcome": record.outcome,
            "reason": record.reason,
            "success": record.success,
            "progress": progress,
            "progress_fraction": progress / self.sim.task.success_progress,
            "slip_m": slip_m,
            "slip_deg": slip_deg,
            "force_norm": record.steps[-1].force_norm if record.steps else 0.0,
        }
        if record.finished:
            info["record"] = record
        return info

    def _draw_offset(self, rng: np.random.Generator) -> float:
        if isinstance(self.offset_deg, tuple | list):
            low, high = self.offset_deg
            sign = 1.0 if rng.random() < 0.5 else -1.0
            return sign * float(rng.uniform(low, high))
        return float(self.offset_deg)

    # --- rendering ----------------------------------------------------------------------------
    def render(self) -> np.ndarray | None:
        if self.render_mode is None or self.sim is None:
            return None
        if self._renderer is None:
            from constraint_aware.sim.render import SceneRenderer

            self._renderer = SceneRenderer(
                self.sim.model,
                width=self.width,
                height=self.height,
                lookat=self.sim.task.object.handle_position,
                distance=0.9,
            )
        frame: np.ndarray = self._renderer.frame(self.sim.data)
        return frame

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def close(self) -> None:
        self._close_renderer()
        super().close()


def _preset(task: str) -> TaskConfig:
    return task_config(task)


def _check_pixels(field: str, value: object, high: int) -> int:
    """A frame size [px]: an integer in [1, high] (the offscreen buffer's size)."""
    valid = f"an integer in [1, {high}] [px]"
    try:
        pixels = check_int(field, value, low=1)
    except ConfigError:
        raise ConfigError(field, value, valid) from None
    if pixels > high:
        raise ConfigError(field, value, valid)
    return pixels


def _check_offset(value: object) -> float | tuple[float, float]:
    """TaskEnv's offset_deg: a number in [-180, 180] [deg], or a (low, high) range with
    0 <= low <= high < 180 [deg]; ConfigError naming it otherwise."""
    field = "TaskEnv.offset_deg"
    if isinstance(value, tuple | list):
        valid = "a (low, high) range with 0 <= low <= high < 180 [deg]"
        if len(value) != 2:
            raise ConfigError(field, value, valid)
        low = check_number(field + "[0]", value[0], low=0, high=180, high_open=True, unit="deg")
        high = check_number(field + "[1]", value[1], low=0, high=180, high_open=True, unit="deg")
        if low > high:
            raise ConfigError(field, value, valid)
        return (low, high)
    return check_number(field, value, low=-180, high=180, unit="deg")


def _check_action(action: ArrayLike) -> FloatArray:
    """The action as (3,) finite floats; InvalidInputError naming it otherwise (a diverged
    policy's NaN must never be taken for "keep the direction")."""
    if isinstance(action, str | bytes) or np.iscomplexobj(action):
        raise InvalidInputError(f"action: expected 3 finite real numbers, got {action!r}")
    try:
        arr = np.asarray(action, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"action: expected 3 finite real numbers ({exc})") from exc
    if arr.shape != (3,):
        raise InvalidInputError(f"action: expected shape (3,), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"action: contains NaN or inf ({arr.tolist()})")
    return arr
