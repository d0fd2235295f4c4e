"""How the executor runs: `ExecutorConfig`, its fields grouped by what they decide.

The top level holds the motion (constraint type, workplane normal, step length, dead band,
how the target is built, the hinge and the rotation radius). The groups hold the rest:

- `limits`: when the run must end (the object's force limit, the step budget);
- `guards`: the safety checks' settings (control.guards);
- `self_check`: the start-of-run sensor self-check (control.self_check);
- `timing`: the hold before moving, while F_d is sampled;
- `goal`: the executor's own success criterion from the robot's poses;
- `robot`: values measured on the robot that replace its reports (control.probe);
- `torque_policy`: the appendix's hand rotation for fixed-orientation grasps.

Every field is validated at construction: a bad value raises ConfigError naming the full
dotted field (`ExecutorConfig.limits.force_limit`) and its valid range. A copy with some
fields changed: `config.with_overrides(step_length=0.005, limits__force_limit=40)`: a group's
field is `GROUP__FIELD`, as `object__mass` for a task (`cap run --set
executor.limits.force_limit=40` reaches it the same way).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from constraint_aware.deadband import MIN_THRESHOLD
from constraint_aware.errors import (
    ConfigError,
    UnknownNameError,
    check_choice,
    check_int,
    check_number,
    check_unit_vector,
    check_vector,
)

ConstraintType = Literal["prismatic", "revolute"]
CommandFrom = Literal["measured", "target"]

#: [m] the largest step length the executor accepts: 5 cm per 100 ms period is 0.5 m/s, beyond
#: any compliant manipulation speed and 5 times the paper's 1 cm.
MAX_STEP_LENGTH = 0.05
#: [N/m] the largest stiffness override accepted (far above any compliant arm).
MAX_STIFFNESS = 1e6


def max_grasp_play(step_length: float) -> float:
    """[m] The most grasp play the executor accepts for a step of `step_length` [m]: half a
    step. More would hide the constraint for most of every step (a step along d meets the
    constraint only when the error passes asin(play / step), 30 deg at half a step)."""
    return 0.5 * step_length


def _check_flag(name: str, value: object) -> None:
    if not isinstance(value, bool):
        raise ConfigError(name, value, "true or false")


@dataclass(frozen=True)
class LimitsConfig:
    """When the run must end: the object's damage limit and the step budget."""

    PATH: ClassVar[str] = "ExecutorConfig.limits"

    force_limit: float = 60.0  # [N] stop: the object's damage limit; > threshold
    max_steps: int = 60  # stop `timeout` after this many moves (>= 1)

    def __post_init__(self) -> None:
        p = self.PATH + "."
        check_number(p + "force_limit", self.force_limit, low=0, low_open=True, unit="N")
        check_int(p + "max_steps", self.max_steps, low=1)


@dataclass(frozen=True)
class GuardsConfig:
    """The safety checks' settings (control.guards; each check is a named stop)."""

    PATH: ClassVar[str] = "ExecutorConfig.guards"

    pose_jump_margin: float = 0.01  # [m] a pose further from the last trusted one than the
    # change of the command since then plus this is implausible (a glitch), and is not used
    pose_fault_steps: int = 3  # implausible or non-finite poses in a row that stop the run
    max_lead: float | None = None  # [m] bound on |target - measured pose|; None:
    # force_limit / stiffness + 2 step lengths if the stiffness is known, else 5 cm
    follow_patience: int = 5  # steps held at the lead bound before `not_following`
    stale_steps: int = 3  # identical wrench samples in a row that stop the run (>= 2)
    predictive_force: bool = True  # shorten or refuse a step whose predicted |F| passes the
    # force limit (the whole move blocked: |F| + k l)
    min_step_fraction: float = 0.2  # a step the prediction shortens below this fraction of
    # step_length is refused (stop `force_limit`)
    contact_force: float = 1.0  # [N] without hand contact sensing: |F| above this once means
    # contact was made,
    lost_contact_force: float = 0.25  # [N] and |F| below this means none
    lost_contact_steps: int = 5  # stop `contact_lost` after this many steps without contact

    def __post_init__(self) -> None:
        p = self.PATH + "."
        check_number(p + "pose_jump_margin", self.pose_jump_margin, low=0, low_open=True, unit="m")
        check_int(p + "pose_fault_steps", self.pose_fault_steps, low=1)
        if self.max_lead is not None:
            check_number(p + "max_lead", self.max_lead, low=0, low_open=True, unit="m")
        check_int(p + "follow_patience", self.follow_patience, low=1)
        check_int(p + "stale_steps", self.stale_steps, low=2)
        _check_flag(p + "predictive_force", self.predictive_force)
        check_number(p + "min_step_fraction", self.min_step_fraction, low=0, high=1)
        lost = check_number(p + "lost_contact_force", self.lost_contact_force, low=0, unit="N")
        check_number(p + "contact_force", self.contact_force, low=lost, unit="N")
        check_int(p + "lost_contact_steps", self.lost_contact_steps, low=1)


@dataclass(frozen=True)
class SelfCheckConfig:
    """The start-of-run sensor self-check (control.self_check)."""

    PATH: ClassVar[str] = "ExecutorConfig.self_check"

    steps: int = 8  # moves during which the wrench convention is checked (0: off)

    def __post_init__(self) -> None:
        check_int(self.PATH + ".steps", self.steps, low=0)


@dataclass(frozen=True)
class TimingConfig:
    """The hold before moving, while the offset F_d is sampled."""

    PATH: ClassVar[str] = "ExecutorConfig.timing"

    offset_samples: int = 10  # wrench readings averaged into F_d, one per control period
    # while holding before moving (>= 2: their spread is the sensor noise). Cost: the hand
    # holds offset_samples - 1 extra periods (0.9 s at 10 samples of 100 ms) before moving

    def __post_init__(self) -> None:
        check_int(self.PATH + ".offset_samples", self.offset_samples, low=2)


@dataclass(frozen=True)
class GoalConfig:
    """The executor's own success criterion, from the robot's poses (at most one)."""

    PATH: ClassVar[str] = "ExecutorConfig.goal"

    travel: float | None = None  # [m] success when the tool point is this far from its start
    # pose (straight line); prismatic skills
    rotation: float | None = None  # [rad] success when the hand has turned this far about the
    # workplane normal; revolute skills

    def __post_init__(self) -> None:
        p = self.PATH + "."
        if self.travel is not None:
            check_number(p + "travel", self.travel, low=0, low_open=True, unit="m")
        if self.rotation is not None:
            check_number(p + "rotation", self.rotation, low=0, low_open=True, unit="rad")
            if self.travel is not None:
                raise ConfigError(p + "rotation", self.rotation, "None when goal.travel is set")


@dataclass(frozen=True)
class RobotOverrides:
    """Values measured on the robot (control.probe) that replace or complete its reports."""

    PATH: ClassVar[str] = "ExecutorConfig.robot"

    stiffness: float | None = None  # [N/m] the arm's stiffness as the wrist sensor sees it,
    # used instead of the robot's `translational_stiffness`; None: the robot's report
    grasp_play: float | None = None  # [m] play in the grasp across the path, at most
    # `max_grasp_play` (half a step); the controller is told the force it hides, stiffness x
    # play (ControlInput.play_force). None: unknown

    def __post_init__(self) -> None:
        p = self.PATH + "."
        if self.stiffness is not None:
            check_number(
                p + "stiffness", self.stiffness, low=0, low_open=True, high=MAX_STIFFNESS,
                unit="N/m",
            )  # fmt: skip
        if self.grasp_play is not None:
            check_number(p + "grasp_play", self.grasp_play, low=0, unit="m")


@dataclass(frozen=True)
class TorquePolicyConfig:
    """The appendix's torque policy (control.torque_policy) for fixed-orientation grasps."""

    PATH: ClassVar[str] = "ExecutorConfig.torque_policy"

    enabled: bool = False  # rotate the hand by the torque policy's w (needs rotation_radius)
    alpha: float = 0.1  # [N m] torque dead band
    beta_deg: float = 1.0  # [deg] adjustment of w per step

    def __post_init__(self) -> None:
        p = self.PATH + "."
        _check_flag(p + "enabled", self.enabled)
        check_number(p + "alpha", self.alpha, low=0, low_open=True, unit="N m")
        check_number(p + "beta_deg", self.beta_deg, low=0, low_open=True, high=90, unit="deg")


#: The nested groups of ExecutorConfig: field name -> its class.
GROUPS: dict[str, type] = {
    "limits": LimitsConfig,
    "guards": GuardsConfig,
    "self_check": SelfCheckConfig,
    "timing": TimingConfig,
    "goal": GoalConfig,
    "robot": RobotOverrides,
    "torque_policy": TorquePolicyConfig,
}


@dataclass(frozen=True)
class ExecutorConfig:
    """How the loop runs. Units in brackets. Validated at construction (ConfigError names the
    dotted field and its valid range); `workplane_normal` is normalized."""

    constraint_type: ConstraintType = "prismatic"  # decides whether the hand rotates
    workplane_normal: tuple[float, float, float] | None = (0.0, 0.0, 1.0)  # None: 3-D motion
    # (no projection, no rotation about a normal); revolute: oriented so that the motion
    # turns positively about it (automatic when hinge_point is given)
    step_length: float = 0.01  # [m] per control step (paper: 1 cm), in (0, MAX_STEP_LENGTH]
    threshold: float | None = None  # [N] |F| below this is no force (paper 3.3.2). None:
    # derived from the spread of the F_d samples (deadband.threshold_from_noise)
    command_from: CommandFrom = "measured"  # "measured": re-anchor the target across d at
    # the measured pose each step; "target": accumulate targets like a stiff position robot
    hinge_point: tuple[float, float, float] | None = None  # [m] a point on the hinge axis
    # (revolute): orients the workplane normal so that d0 turns positively about it
    rotation_radius: float | None = None  # [m] r of a revolute motion (the torque policy's
    # initial w = step_length / r, and the rotation rate a controller is given)
    limits: LimitsConfig = field(default_factory=LimitsConfig)
    guards: GuardsConfig = field(default_factory=GuardsConfig)
    self_check: SelfCheckConfig = field(default_factory=SelfCheckConfig)
    timing: TimingConfig = field(default_factory=TimingConfig)
    goal: GoalConfig = field(default_factory=GoalConfig)
    robot: RobotOverrides = field(default_factory=RobotOverrides)
    torque_policy: TorquePolicyConfig = field(default_factory=TorquePolicyConfig)

    def __post_init__(self) -> None:
        name = "ExecutorConfig."
        for group, cls in GROUPS.items():
            value = getattr(self, group)
            if not isinstance(value, cls):
                raise ConfigError(name + group, value, f"a {cls.__name__}")
        check_choice(name + "constraint_type", self.constraint_type, ("prismatic", "revolute"))
        check_choice(name + "command_from", self.command_from, ("measured", "target"))
        if self.workplane_normal is not None:
            normal = check_unit_vector(name + "workplane_normal", self.workplane_normal)
            object.__setattr__(self, "workplane_normal", normal)
        step = check_number(
            name + "step_length", self.step_length, low=0, low_open=True, high=MAX_STEP_LENGTH,
            unit="m",
        )  # fmt: skip
        # a derived dead band is at least deadband.MIN_THRESHOLD, so the limit must exceed that
        thr = MIN_THRESHOLD
        if self.threshold is not None:
            thr = check_number(name + "threshold", self.threshold, low=0, unit="N")
        if self.limits.force_limit <= thr:
            raise ConfigError(
                name + "limits.force_limit", self.limits.force_limit, f"> threshold ({thr:g} N) [N]"
            )
        if self.hinge_point is not None:
            point = check_vector(name + "hinge_point", self.hinge_point, unit="m")
            object.__setattr__(self, "hinge_point", point)
        if self.rotation_radius is not None:
            check_number(
                name + "rotation_radius", self.rotation_radius, low=0, low_open=True, unit="m"
            )
        play = self.robot.grasp_play
        if play is not None and play > max_grasp_play(step):
            raise ConfigError(
                name + "robot.grasp_play",
                play,
                f"in [0, {max_grasp_play(step):g}] [m] (half a step)",
            )
        if self.torque_policy.enabled:
            if self.rotation_radius is None:
                raise ConfigError(
                    name + "rotation_radius", None, "a positive radius [m] (the torque policy)"
                )
            if self.workplane_normal is None:
                raise ConfigError(
                    name + "workplane_normal", None, "a vector (the torque policy turns about it)"
                )
        if self.goal.rotation is not None and self.workplane_normal is None:
            raise ConfigError(
                name + "workplane_normal", None, "a vector (goal.rotation is about it)"
            )

    def with_overrides(self, **changes: object) -> ExecutorConfig:
        """A copy with fields replaced: `step_length=0.005` for a top-level field,
        `limits__force_limit=40` for a group's (`override_keys()` lists them). An unknown key
        raises UnknownNameError listing the valid ones; the new values are validated."""
        valid = override_keys()
        top: dict[str, object] = {}
        nested: dict[str, dict[str, object]] = {}
        for key, value in changes.items():
            if key not in valid:
                raise UnknownNameError("executor setting", key, valid)
            group, sep, name = key.partition("__")
            if sep:
                nested.setdefault(group, {})[name] = value
            else:
                top[key] = value
        for group, items in nested.items():
            top[group] = dataclasses.replace(getattr(self, group), **items)
        return dataclasses.replace(self, **top)  # type: ignore[arg-type]


def override_keys() -> list[str]:
    """Every key `ExecutorConfig.with_overrides` accepts: top-level fields, and
    `GROUP__FIELD` for the groups' fields."""
    keys = [f.name for f in dataclasses.fields(ExecutorConfig) if f.name not in GROUPS]
    for group, cls in GROUPS.items():
        keys += [f"{group}__{f.name}" for f in dataclasses.fields(cls)]
    return keys
