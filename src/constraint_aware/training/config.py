"""Configuration of the single-system training environment (paper 3.3 and 5.1)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

from constraint_aware.errors import InvalidInputError
from constraint_aware.policy import MAGNITUDE_OBSERVATIONS, OBSERVATIONS

Workplane = Literal["random", "horizontal"]

_RANGES = (
    "offset_deg",
    "friction",
    "stiffness",
    "force_gain",
    "dry_friction",
    "dry_friction_abs",
    "damping",
    "inertia",
    "preload",
)


@dataclass(frozen=True)
class EnvConfig:
    """Distribution of episodes of the single composite body on a prismatic joint.

    Every range is (low, high), sampled uniformly once per episode. The defaults are the
    paper's environment (no resistance along the joint: assumption 3).

    The object's own resistance along the joint (an addition to the paper's environment) is
    drawn per episode, as a fraction of the step force k*delta (the force of one fully blocked
    step; k in `stiffness` and delta = `step_length` give 10-30 N by default), so it scales
    with the robot:

    - `dry_friction`: constant along-axis friction R0 [fraction of k*delta], plus
      `dry_friction_abs` [N] on top (an absolute floor that does not scale with the arm);
    - `damping`: viscous c*v, given as c*v_nom [fraction of k*delta] at the nominal speed
      v_nom = step_length / control_period (0.1 m/s);
    - `inertia`: m*a, given as m*a_nom [fraction of k*delta] with a_nom = v_nom / control_period
      (the body starting from rest within one control period);
    - `preload`: a grasp preload p [fraction of k*delta] recorded in F_d that vanishes once the
      body first slides: from then on the observed force carries -p along a direction within
      `preload_cone_deg` of the joint axis u.

    `resistance_free_share` of the episodes draw none of these (the paper's case), which keeps
    the resistance-free accuracy (feasibility study, notes/resistance.md). Coulomb guide
    friction (`friction`) applies in every episode.
    """

    episode_length: int = 5  # T: number of actions per episode (paper 5.1)
    step_length: float = 0.01  # [m] hand command per step along d (paper: 1 cm)
    offset_deg: tuple[float, float] = (0.0, 45.0)  # |angle(d0, u)| [deg], sign drawn at random
    workplane: Workplane = "random"  # "random": plane normal uniform on the sphere (any pose)
    friction: tuple[float, float] = (0.0, 0.15)  # Coulomb coefficient of the guide [-]
    stiffness: tuple[float, float] = (1000.0, 3000.0)  # hand (wrist) stiffness [N/m]
    stiffness_log_uniform: bool = False  # draw k log-uniformly (for ranges over decades)
    force_gain: tuple[float, float] = (0.8, 1.25)  # sensor scale error [-]: moves |F| vs threshold
    threshold: float = 0.2  # [N] measured |F| below this is observed as the zero vector
    force_noise: float = 0.05  # std of Gaussian noise on the observed unit force, first step
    direction_noise: float = 0.05  # std of Gaussian noise on the observed direction, first step
    noise_every_step: bool = False  # False: noise only on the first observation (paper 5.1)
    action_scale: float = 1.0  # a = action_scale * clip(action, -1, 1)
    substeps: int = 10  # MuJoCo backend: 2 ms substeps between command and force reading
    hand_mass: float = 1.0  # [kg] MuJoCo backend: mass of the composite body
    damping_ratio: float = 1.0  # MuJoCo backend: damping of the hand spring (1 = critical)
    observation: str = "paper"  # policy.OBSERVATIONS: paper (F^, d), history, magnitude
    control_period: float = 0.1  # [s] one step: sets v_nom and a_nom of damping and inertia
    resistance_free_share: float = 1.0  # share of episodes without resistance [0, 1]
    dry_friction: tuple[float, float] = (0.0, 0.0)  # R0 [fraction of k*delta]
    dry_friction_abs: tuple[float, float] = (0.0, 0.0)  # [N] added to R0
    damping: tuple[float, float] = (0.0, 0.0)  # c*v_nom [fraction of k*delta]
    inertia: tuple[float, float] = (0.0, 0.0)  # m*a_nom [fraction of k*delta]
    preload: tuple[float, float] = (0.0, 0.0)  # released preload [fraction of k*delta]
    preload_cone_deg: float = 5.0  # [deg] preload direction: within this cone about u
    step_force_unknown_share: float = 0.0  # "magnitude": share of episodes in which the robot
    # reports no stiffness (the ratio input is zero), so the policy has a defined fallback

    def __post_init__(self) -> None:
        def bad(name: str, rule: str) -> InvalidInputError:
            return InvalidInputError(f"EnvConfig.{name}: {rule}, got {getattr(self, name)!r}")

        for name in _RANGES:
            value = getattr(self, name)
            if not (isinstance(value, tuple) and len(value) == 2):
                raise bad(name, "must be a (low, high) pair")
            lo, hi = value
            if not (math.isfinite(lo) and math.isfinite(hi)) or not lo <= hi:
                raise bad(name, "must be finite with low <= high")
        if not isinstance(self.episode_length, int) or self.episode_length < 1:
            raise bad("episode_length", "must be an integer >= 1")
        if not 0.0 <= self.offset_deg[0] <= self.offset_deg[1] < 90.0:
            raise bad("offset_deg", "must lie in [0, 90) deg")
        for name in ("step_length", "control_period", "hand_mass", "damping_ratio"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0):
                raise bad(name, "must be finite and > 0")
        for name in ("stiffness", "force_gain"):
            if getattr(self, name)[0] <= 0:
                raise bad(name, "must be > 0")
        for name in ("friction", "dry_friction", "dry_friction_abs", "damping", "inertia"):
            if getattr(self, name)[0] < 0:
                raise bad(name, "must be >= 0")
        if self.preload[0] < 0:
            raise bad("preload", "must be >= 0")
        for name in ("threshold", "force_noise", "direction_noise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise bad(name, "must be finite and >= 0")
        if not (math.isfinite(self.action_scale) and self.action_scale > 0):
            raise bad("action_scale", "must be finite and > 0")
        for name in ("resistance_free_share", "step_force_unknown_share"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise bad(name, "must lie in [0, 1]")
        if not 0.0 <= self.preload_cone_deg < 90.0:
            raise bad("preload_cone_deg", "must lie in [0, 90) deg")
        if not isinstance(self.substeps, int) or self.substeps < 1:
            raise bad("substeps", "must be an integer >= 1")
        if self.workplane not in ("random", "horizontal"):
            raise InvalidInputError(
                f"EnvConfig.workplane: {self.workplane!r}; valid names: horizontal, random"
            )
        if self.observation not in OBSERVATIONS:
            raise InvalidInputError(
                f"EnvConfig.observation: {self.observation!r}; valid names: "
                + ", ".join(OBSERVATIONS)
            )

    @property
    def has_resistance(self) -> bool:
        """Whether any episode can draw resistance along the joint."""
        return self.resistance_free_share < 1.0 and any(
            getattr(self, name)[1] > 0
            for name in ("dry_friction", "dry_friction_abs", "damping", "inertia", "preload")
        )

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EnvConfig:
        fields = {f.name for f in dataclasses.fields(cls)}
        kwargs: dict[str, Any] = {
            k: tuple(v) if isinstance(v, list) else v for k, v in data.items() if k in fields
        }
        return cls(**kwargs)


#: The resistance the default policy is trained with (ranges from the feasibility
#: study in notes/resistance.md, extended by damping, inertia and preload release). With
#: k*delta in 10-30 N: R0 up to 0.3 k*delta (3-9 N) plus up to 1 N, c*v_nom and m*a_nom up to
#: 0.1 k*delta each (1-3 N), a released preload up to 0.3 k*delta (3-9 N). The sum stays below
#: the drive of a 45 deg offset (cos 45 - 0.15 sin 45 = 0.6 k*delta) in nearly every episode,
#: so the body slides: a resistance that holds the body needs a stronger arm, not a new policy.
RESISTANCE: dict[str, Any] = {
    "resistance_free_share": 0.5,
    "dry_friction": (0.0, 0.3),
    "dry_friction_abs": (0.0, 1.0),
    "damping": (0.0, 0.1),
    "inertia": (0.0, 0.1),
    "preload": (0.0, 0.3),
}


#: [N/m] the wrist stiffness k the default policy is trained over, drawn log-uniformly
#: (`stiffness_log_uniform`): from a soft 500 N/m wrist to the 20,000 N/m stiffness variants of
#: embodiment 2 (k*delta 5-200 N), so every robot of the bench is inside the training range.
#: The analytic physics scales with k except for the absolute terms (the 0.2 N threshold, the
#: up-to-1 N absolute dry friction), so the range costs little accuracy at 1000-3000 N/m
#: (measured in benchmarks/studies/results/default_policy.json).
WIDE_STIFFNESS = (500.0, 20_000.0)


#: "magnitude": the share of episodes in which the robot reports no step force (the input is
#: zero), so that a robot without `translational_stiffness` gets a trained fallback.
STEP_FORCE_UNKNOWN_SHARE = 0.25


def resistance_config(observation: str = "paper", **overrides: Any) -> EnvConfig:
    """The paper's environment with the object's own resistance drawn as in `RESISTANCE`
    (and, for "magnitude", `STEP_FORCE_UNKNOWN_SHARE` of the episodes without k*delta)."""
    unknown = STEP_FORCE_UNKNOWN_SHARE if observation in MAGNITUDE_OBSERVATIONS else 0.0
    fields = {**RESISTANCE, "step_force_unknown_share": unknown, **overrides}
    return dataclasses.replace(EnvConfig(), observation=observation, **fields)
