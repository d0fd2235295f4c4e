"""Configuration of the single-system training environment (paper 3.3 and 5.1)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Literal

Workplane = Literal["random", "horizontal"]


@dataclass(frozen=True)
class EnvConfig:
    """Distribution of episodes of the single composite body on a prismatic joint.

    Every range is (low, high), sampled uniformly once per episode.
    """

    episode_length: int = 5  # T: number of actions per episode (paper 5.1)
    step_length: float = 0.01  # [m] hand command per step along d (paper: 1 cm)
    offset_deg: tuple[float, float] = (0.0, 45.0)  # |angle(d0, u)| [deg], sign drawn at random
    workplane: Workplane = "random"  # "random": plane normal uniform on the sphere (any pose)
    friction: tuple[float, float] = (0.0, 0.15)  # Coulomb coefficient of the guide [-]
    stiffness: tuple[float, float] = (1000.0, 3000.0)  # hand (wrist) stiffness [N/m]
    force_gain: tuple[float, float] = (0.8, 1.25)  # sensor scale error [-]: moves |F| vs threshold
    threshold: float = 0.2  # [N] measured |F| below this is observed as the zero vector
    force_noise: float = 0.05  # std of Gaussian noise on the observed unit force, first step
    direction_noise: float = 0.05  # std of Gaussian noise on the observed direction, first step
    noise_every_step: bool = False  # False: noise only on the first observation (paper 5.1)
    action_scale: float = 1.0  # a = action_scale * clip(action, -1, 1)
    substeps: int = 10  # MuJoCo backend: 2 ms substeps between command and force reading
    hand_mass: float = 1.0  # [kg] MuJoCo backend: mass of the composite body
    damping_ratio: float = 1.0  # MuJoCo backend: damping of the hand spring (1 = critical)

    def __post_init__(self) -> None:
        from constraint_aware.errors import InvalidInputError

        if self.episode_length < 1:
            raise InvalidInputError("episode_length must be >= 1")
        for name in ("offset_deg", "friction", "stiffness", "force_gain"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise InvalidInputError(f"{name}: low {lo} > high {hi}")
        if self.offset_deg[1] >= 90.0 or self.offset_deg[0] < 0.0:
            raise InvalidInputError("offset_deg must lie in [0, 90) deg")
        if self.stiffness[0] <= 0 or self.step_length <= 0 or self.force_gain[0] <= 0:
            raise InvalidInputError("stiffness, step_length and force_gain must be positive")
        if self.friction[0] < 0 or self.threshold < 0:
            raise InvalidInputError("friction and threshold must be >= 0")
        if self.workplane not in ("random", "horizontal"):
            raise InvalidInputError(
                f"workplane {self.workplane!r}; valid names: horizontal, random"
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
