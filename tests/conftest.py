"""Shared fixtures."""

from __future__ import annotations

import os
from typing import Any, Protocol

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


class RequiredOnly:
    """Forwards only the Robot protocol's required members to `inner` (no grasp_contact, hold,
    translational_stiffness or tracking_time_constant): a robot with nothing optional."""

    control_period = 0.1

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def read_wrench(self) -> Any:
        return self._inner.read_wrench()

    def read_pose(self) -> Any:
        return self._inner.read_pose()

    def commanded_pose(self) -> Any:
        return self._inner.commanded_pose()

    def command_pose(self, pose: Any) -> None:
        self._inner.command_pose(pose)

    def advance(self) -> None:
        self._inner.advance()


@pytest.fixture
def required_only() -> type[RequiredOnly]:
    """The RequiredOnly wrapper class (a robot without optional members)."""
    return RequiredOnly


@pytest.fixture
def true_direction() -> type[TrueDirection]:
    """The scripted-pull controller (a simulator's ground truth as d), for grasp tests."""
    return TrueDirection
