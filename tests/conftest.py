"""Shared fixtures."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
