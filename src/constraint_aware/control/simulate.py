"""Run a direction controller on a simulated task: sim + executor, one call."""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from constraint_aware.control.controllers import (
    CONTROLLERS,
    DirectionController,
    driving_policy,
    make_controller,
)
from constraint_aware.control.executor import Executor
from constraint_aware.control.executor_config import (
    ExecutorConfig,
    LimitsConfig,
    TorquePolicyConfig,
    override_keys,
)
from constraint_aware.control.motion import orient_normal
from constraint_aware.control.probe import (
    CONVENTION_VERDICTS,
    ProbeConfig,
    ProbeResult,
    check_force_limit,
    probe_sensor,
    probed_settings,
)
from constraint_aware.control.profile import RobotProfile
from constraint_aware.control.record import RunRecord
from constraint_aware.control.robot import Robot
from constraint_aware.control.settings import Settings
from constraint_aware.errors import (
    ConfigError,
    UnknownNameError,
    check_int,
    check_number,
    check_vector,
)
from constraint_aware.geometry import FloatArray, rotate_about
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim.embodiment import (
    DEFAULT_ROBOT,
    Embodiment,
    make_embodiment,
    parse_robot,
)
from constraint_aware.sim.tasks import TASKS, TaskConfig, randomized, task_config
from constraint_aware.sim.world import ManipulationSim
from constraint_aware.spatial import Wrench


class NoisySensorSim(ManipulationSim):
    """The simulated robot with Gaussian noise and a constant bias on the wrench reading."""

    def __init__(
        self,
        task: TaskConfig,
        rng: np.random.Generator,
        noise: float = 0.0,
        bias: FloatArray | None = None,
    ) -> None:
        super().__init__(task)
        self.rng = rng
        self.noise = noise  # [N] std per axis (torque: noise / 10 [N m])
        self.bias = np.zeros(3) if bias is None else np.asarray(bias, dtype=float)

    def read_wrench(self) -> Wrench:
        w = super().read_wrench()
        if self.noise == 0.0 and not np.any(self.bias):
            return w
        return Wrench(
            force=w.force + self.bias + self.noise * self.rng.normal(size=3),
            torque=w.torque + 0.1 * self.noise * self.rng.normal(size=3),
        )


#: `RunSpec.overrides` keys with this prefix set ExecutorConfig fields (`executor__threshold`,
#: `executor__limits__force_limit`: the key after the prefix is an
#: `ExecutorConfig.with_overrides` key).
EXECUTOR_PREFIX = "executor__"


@dataclass(frozen=True)
class RunSpec:
    """One simulated run."""

    task: str = "drawer-opening"
    controller: str = "policy"
    offset_deg: float = 30.0  # initial direction error about the workplane normal [deg]
    seed: int = 0
    randomize: bool = False  # draw friction, mass and damping (sim.tasks.randomized)
    torque_policy: bool | None = None  # None: on exactly for fixed-orientation grasps
    sensor_noise: float = 0.1  # [N] std of the force reading per axis
    sensor_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [N]
    overrides: tuple[tuple[str, object], ...] = ()  # task parameter overrides, and
    # ExecutorConfig fields as `executor__FIELD` or `executor__GROUP__FIELD`
    controller_params: tuple[tuple[str, float], ...] = ()  # e.g. classical gains
    robot: str = DEFAULT_ROBOT  # embodiment spec (sim.embodiment): "hook-hand", "jaco",
    # optionally with variants: "jaco:stiffness=2000,period=0.08"
    probe: bool = False  # probe at setup (control.probe) on a twin of this task (same
    # robot, object, grasp and seed), then run on a fresh grasp: the arm stiffness measured
    # at the wrist replaces the robot's report (kept, with a note, when the probe cannot
    # measure it), the grasp's measured play goes to ExecutorConfig.robot.grasp_play
    # (`probed_settings`), and a probe that finds the wrench convention wrong stops the run
    # before it moves (`sensor_convention`). On a real arm: probe, re-grasp, run. Probing
    # the object and then running without re-grasping disturbs the grasp
    # (benchmarks/probe.py)

    def with_settings(self, settings: Settings) -> RunSpec:
        """This spec with `--set` settings (control.settings.parse_settings) added: task
        overrides as they are, ExecutorConfig fields as `executor__KEY` overrides."""
        executor = tuple((EXECUTOR_PREFIX + k, v) for k, v in settings.executor_overrides)
        return dataclasses.replace(
            self, overrides=(*self.overrides, *settings.task_overrides, *executor)
        )

    @property
    def executor_overrides(self) -> dict[str, object]:
        """The `ExecutorConfig.with_overrides` keys set through `executor__KEY` overrides."""
        n = len(EXECUTOR_PREFIX)
        return {k[n:]: v for k, v in self.overrides if k.startswith(EXECUTOR_PREFIX)}

    @property
    def task_overrides(self) -> dict[str, object]:
        """The TaskConfig overrides (`object__mass`, `force_limit`, ...)."""
        return {k: v for k, v in self.overrides if not k.startswith(EXECUTOR_PREFIX)}

    def __post_init__(self) -> None:
        n = "RunSpec."
        if self.task not in TASKS:
            raise UnknownNameError("task", str(self.task), list(TASKS))
        if self.controller not in CONTROLLERS:
            raise UnknownNameError("controller", str(self.controller), list(CONTROLLERS))
        check_number(n + "offset_deg", self.offset_deg, low=-180, high=180, unit="deg")
        check_int(n + "seed", self.seed, low=0)
        check_number(n + "sensor_noise", self.sensor_noise, low=0, unit="N")
        check_vector(n + "sensor_bias", self.sensor_bias, unit="N")
        for pair in (*self.overrides, *self.controller_params):
            if not (isinstance(pair, tuple) and len(pair) == 2 and isinstance(pair[0], str)):
                raise ConfigError(n + "overrides", pair, "(name, value) pairs")
        executor_keys = override_keys()
        for name in self.executor_overrides:
            if name not in executor_keys:
                valid = [EXECUTOR_PREFIX + k for k in executor_keys]
                raise UnknownNameError("executor override", EXECUTOR_PREFIX + name, valid)
        parse_robot(self.robot)  # an unknown embodiment or variant names the valid ones


def executor_config(task: TaskConfig, torque_policy: bool | None = None) -> ExecutorConfig:
    """The executor's settings for a task, from what a demonstration would tell (LfO)."""
    use_torque = task.fixed_orientation if torque_policy is None else torque_policy
    revolute = task.constraint_type == "revolute"
    return ExecutorConfig(
        constraint_type=task.constraint_type,  # type: ignore[arg-type]
        workplane_normal=task.workplane_normal,
        limits=LimitsConfig(force_limit=task.force_limit, max_steps=task.max_steps),
        torque_policy=TorquePolicyConfig(enabled=bool(use_torque) and revolute),
        rotation_radius=task.object.radius if revolute else None,
        # revolute: the executor orients the workplane normal from the hinge's side
        hinge_point=task.object.position if revolute else None,
    )


def build_task(spec: RunSpec) -> TaskConfig:
    rng = np.random.default_rng(spec.seed)
    task = randomized(spec.task, rng) if spec.randomize else task_config(spec.task)
    overrides = spec.task_overrides
    return task.with_overrides(**overrides) if overrides else task


def simulated_robot(
    robot: str,
    task: TaskConfig,
    rng: np.random.Generator,
    noise: float,
    bias: FloatArray | None = None,
) -> Embodiment:
    """The embodiment `robot` (a robot spec, sim.embodiment) on `task`, with Gaussian sensor
    noise `noise` [N] per axis drawn from `rng` and a force bias (3,) [N]; not reset."""
    if robot == DEFAULT_ROBOT:
        return NoisySensorSim(task, rng, noise, bias)
    return make_embodiment(robot, task, rng, noise, bias)


def grasped(spec: RunSpec) -> tuple[TaskConfig, Embodiment]:
    """The spec's task and its simulated robot, reset: holding the grasp, at rest."""
    task = build_task(spec)
    sensor_rng = np.random.default_rng(spec.seed + 7919)
    bias = np.asarray(spec.sensor_bias, dtype=float)
    sim = simulated_robot(spec.robot, task, sensor_rng, spec.sensor_noise, bias)
    sim.reset()
    return task, sim


def probe(
    spec: RunSpec,
    config: ProbeConfig | None = None,
    wrap: Callable[[Embodiment], Robot] | None = None,
) -> tuple[ProbeResult, Embodiment]:
    """`control.probe.probe_sensor` on the spec's grasped task, pushing in its workplane.
    wrap: puts a Robot between the probe and the simulator (fault injection)."""
    task, sim = grasped(spec)
    robot: Robot = sim if wrap is None else wrap(sim)
    if config is None:
        config = _probe_config(task)
    else:
        check_force_limit(config, task.force_limit)
    return probe_sensor(robot, task.workplane_normal, config), sim


def probed_config(spec: RunSpec, config: ExecutorConfig) -> ExecutorConfig:
    """`config` with what a setup probe on a twin of the spec's task measured
    (`probed_settings`), for experiments that prepare their own run; a probe that finds the
    wrench convention wrong raises RuntimeError (`run` would stop before the first move)."""
    probed, _twin = probe(spec)
    if probed.verdict in CONVENTION_VERDICTS:
        raise RuntimeError(f"the setup probe found {probed.verdict}: {probed.reason}")
    return config.with_overrides(**probed_settings(probed, config))


def _probe_config(task: TaskConfig) -> ProbeConfig:
    """The probe's defaults, its force limit no higher than the task's."""
    default = ProbeConfig()
    return dataclasses.replace(default, force_limit=min(default.force_limit, task.force_limit))


def controller_geometry(
    cfg: ExecutorConfig, robot: Robot, d0: FloatArray
) -> tuple[FloatArray, float | None]:
    """What a direction controller is given besides the force: the workplane normal (3,),
    oriented from the hinge on revolute joints so that moving along d0 (3,) turns positively
    about it (the classical controller and controller "policy" turn about this axis), and the
    rotation rate w_d = v_d / r [rad/s] on revolute joints with a known radius (else None).
    Raises ConfigError naming ExecutorConfig.workplane_normal when it is None (3-D motion:
    no axis to turn about; `run` then gives the controller neither)."""
    if cfg.workplane_normal is None:
        raise ConfigError(
            "ExecutorConfig.workplane_normal", None, "a vector (the controllers' rotation axis)"
        )
    normal = np.asarray(cfg.workplane_normal, dtype=float)
    if cfg.constraint_type == "revolute" and cfg.hinge_point is not None:
        normal = orient_normal(normal, d0, robot.read_pose().position, cfg.hinge_point)
    rate = None
    if cfg.constraint_type == "revolute" and cfg.rotation_radius:
        rate = cfg.step_length / robot.control_period / cfg.rotation_radius  # w_d = v_d / r
    return normal, rate


def run(
    spec: RunSpec,
    policy: ConstraintAwarePolicy | None = None,
    controller: DirectionController | None = None,
    on_step: Callable[[Embodiment], None] | None = None,
    initial_direction: FloatArray | None = None,
    executor_overrides: dict[str, object] | None = None,
    wrap: Callable[[Embodiment], Robot] | None = None,
    profile: RobotProfile | None = None,
) -> tuple[RunRecord, Embodiment]:
    """Build the task, grasp, and run the controller from d0 = u rotated by `offset_deg`.

    initial_direction (3,) replaces that d0 and executor_overrides replace ExecutorConfig
    fields: how a demonstration's estimates (LfO) drive a run instead of the task's truth.
    wrap: puts a Robot between the executor and the simulator (fault injection); the
    simulator stays the task monitor. profile: the robot's calibration (`Executor.profile`).
    Exceptions carry the record as `exc.run_record`.
    """
    probed: ProbeResult | None = None
    if spec.probe:  # at setup, on a twin: the run below starts from an undisturbed grasp
        try:
            probed, _twin = probe(spec, wrap=wrap)
        except BaseException as exc:  # the run's record, finished before it started
            _attach_setup_record(exc, spec)
            raise
    task, sim = grasped(spec)
    robot: Robot = sim if on_step is None else observed(sim, on_step)
    if wrap is not None:
        robot = wrap(robot)  # type: ignore[arg-type]
    cfg = executor_config(task, spec.torque_policy)
    changes = {**spec.executor_overrides, **(executor_overrides or {})}
    if changes:
        cfg = cfg.with_overrides(**changes)
    if probed is not None:  # what the probe measured, unless set explicitly
        measured = {k: v for k, v in probed_settings(probed, cfg).items() if k not in changes}
        cfg = cfg.with_overrides(**measured)
    # d0 turns about the executor's workplane normal; in 3-D motion (None) about the task's
    axis = task.workplane_normal if cfg.workplane_normal is None else cfg.workplane_normal
    if initial_direction is not None:
        d0 = np.asarray(initial_direction, dtype=float)
    else:
        turn = math.radians(spec.offset_deg)
        d0 = rotate_about(sim.admissible_direction(), np.asarray(axis, dtype=float), turn)
    normal: FloatArray | None = None
    rate: float | None = None
    if cfg.workplane_normal is not None:  # 3-D motion: no rotation axis, no rotation rate
        normal, rate = controller_geometry(cfg, sim, d0)
    ctrl = controller or make_controller(
        spec.controller, policy, rate, normal, dict(spec.controller_params)
    )
    executor = Executor(robot, ctrl, cfg, monitor=sim, profile=profile)
    label = {
        "task": spec.task,
        "controller": ctrl.name,
        "offset_deg": spec.offset_deg,
        "seed": spec.seed,
        "randomized": spec.randomize,
        "torque_policy": cfg.torque_policy.enabled,
        "sensor_noise_N": spec.sensor_noise,
        "success_progress": task.success_progress,
        "constraint_type": task.constraint_type,
        "force_exertion_type": task.force_exertion_type,
        "force_limit_N": task.force_limit,
        "command_from": cfg.command_from,
        "robot": spec.robot,
    }
    driver = driving_policy(ctrl)
    if driver is not None:
        label["policy"] = driver.name  # which policy drove the run (the card's name)
    if probed is None:
        return executor.run(d0, label), sim
    label["probe"] = probed.verdict
    said = f"probe: {probed.verdict}: {probed.reason}"
    if probed.verdict in CONVENTION_VERDICTS:
        executor.start(d0, label)
        record = executor.stop("sensor_convention", said)
    else:
        record = executor.run(d0, label)
    record.notes.insert(0, said)
    return record, sim


def _attach_setup_record(exc: BaseException, spec: RunSpec) -> None:
    """A record for a run whose setup probe raised: outcome "error", a note with how many
    pushes the probe made, attached to `exc` as `run_record` (as the executor does for a
    run)."""
    record = RunRecord(
        {"task": spec.task, "controller": spec.controller, "seed": spec.seed,
         "robot": spec.robot, "probe": "error"},
        [math.nan] * 3,
        [math.nan] * 3,
    )  # fmt: skip
    record.finish("error", f"setup probe: {type(exc).__name__}: {exc}", None)
    partial = getattr(exc, "probe_result", None)
    if partial is not None:
        record.notes.append(f"probe: {len(partial.pushes)} pushes before the error")
    with contextlib.suppress(AttributeError):  # an exception type with __slots__
        exc.run_record = record  # type: ignore[attr-defined]


def observed(sim: Embodiment, on_period: Callable[[Embodiment], None]) -> Robot:
    """`sim` as the Robot an executor drives, calling on_period(sim) once now and after every
    `advance()` (observers: video frames, scoring; not for control)."""
    return _Observed(sim, on_period)  # type: ignore[return-value]


class _Observed:
    """Forwards to the sim and calls `on_step` after each period (`observed`)."""

    def __init__(self, sim: Embodiment, on_step: Callable[[Embodiment], None]) -> None:
        self._sim = sim
        self._on_step = on_step
        on_step(sim)

    def __getattr__(self, name: str) -> object:
        return getattr(self._sim, name)

    def advance(self) -> None:
        self._sim.advance()
        self._on_step(self._sim)
