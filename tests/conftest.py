"""Shared fixtures."""

from __future__ import annotations

import os
from typing import Protocol

import numpy as np
import pytest

from constraint_aware.control.controllers import ControlInput, FixedDirection

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


class _KnowsTruth(Protocol):
    def admissible_direction(self) -> np.ndarray: ...


class TrueDirection(FixedDirection):
    """Moves along the simulator's true admissible direction: a scripted pull."""

    name = "truth"

    def __init__(self, sim: _KnowsTruth) -> None:
        self.sim = sim

    def next_direction(self, inp: ControlInput) -> np.ndarray:
        return self.sim.admissible_direction()


@pytest.fixture
def true_direction() -> type[TrueDirection]:
    """The scripted-pull controller (a simulator's ground truth as d), for grasp tests."""
    return TrueDirection
