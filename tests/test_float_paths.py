"""The per-period paths in Python floats agree with the numpy and scipy expressions they stand
for: the hand's turn (`spatial.turned`), the IK's orientation error
(`robot_adapter.orientation_error`), the executor's next target, the steady controller's
force across d, and the controllers' hand turns as rotation vectors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from constraint_aware.control.classical import ClassicalController
from constraint_aware.control.controllers import FixedDirection
from constraint_aware.control.interface import ControlInput
from constraint_aware.control.motion import next_target, paper_turn
from constraint_aware.control.steady import SteadyDirection, across_force
from constraint_aware.errors import InvalidInputError
from constraint_aware.geometry import cross, cross3, rotate_about, turn_vector
from constraint_aware.policy import ConstraintAwarePolicy, mirror_average
from constraint_aware.sim.robot_adapter import orientation_error
from constraint_aware.spatial import Pose, turned

TOL = 1e-12


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(11)


def _rotvecs(rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Rotation vectors from 1e-9 rad to ~3 rad (both sides of scipy's 1e-3 rad series), and
    zero."""
    out = [np.zeros(3)]
    for _ in range(n):
        axis = rng.normal(size=3)
        out.append(axis / np.linalg.norm(axis) * 10.0 ** rng.uniform(-9, 0.5))
    return out


def test_turned_is_scipys_composition(rng: np.random.Generator) -> None:
    for rotvec in _rotvecs(rng, 300):
        orientation = Rotation.from_quat(rng.normal(size=4))
        ours = turned(rotvec, orientation)
        ref = Rotation.from_rotvec(rotvec) * orientation
        assert ours.single
        assert np.allclose(ours.as_matrix(), ref.as_matrix(), rtol=0, atol=TOL)


def test_orientation_error_is_scipys(rng: np.random.Generator) -> None:
    for rotvec in _rotvecs(rng, 300):
        target = Rotation.from_quat(rng.normal(size=4))
        matrix = (Rotation.from_rotvec(rotvec) * target).as_matrix()
        ref = (target * Rotation.from_matrix(matrix).inv()).as_rotvec()
        ours = orientation_error(target, matrix.reshape(9))
        assert np.allclose(ours, ref, rtol=0, atol=TOL)
        assert np.allclose(ours, -rotvec, rtol=0, atol=1e-9)  # the turn back to the target


def test_orientation_error_of_a_matrix_that_is_not_orthonormal_is_scipys() -> None:
    """A matrix off by more than scipy's tolerance goes to scipy, which orthonormalizes it."""
    target = Rotation.from_rotvec([0.1, -0.2, 0.3])
    matrix = Rotation.from_rotvec([0.2, 0.1, -0.1]).as_matrix() * (1.0 + 1e-6)
    ref = (target * Rotation.from_matrix(matrix).inv()).as_rotvec()
    assert np.allclose(orientation_error(target, matrix), ref, rtol=0, atol=TOL)


def test_float_rotate_about_and_turn_vector_match_the_batched_path(
    rng: np.random.Generator,
) -> None:
    for _ in range(200):
        v, axis = rng.normal(size=3), rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = float(rng.normal())
        single = rotate_about(v, axis, angle)
        batched = rotate_about(v[None], axis[None], np.array([angle]))[0]
        assert np.allclose(single, batched, rtol=0, atol=TOL)
        a, b = v / np.linalg.norm(v), batched / np.linalg.norm(batched)
        turn = turn_vector(a, b)
        assert np.allclose(Rotation.from_rotvec(turn).apply(a), b, rtol=0, atol=1e-9)
        assert np.allclose(paper_turn(a, b), turn, rtol=0, atol=TOL)


def _reference_target(
    target: Pose, measured: np.ndarray, move: np.ndarray, normal: np.ndarray, step: float
) -> np.ndarray:
    """next_target's rule in numpy: the tracking error in the workplane and across the move,
    at most two step lengths, plus the move."""
    err = measured - target.position
    err = err - (err @ normal) * normal
    d = move / np.linalg.norm(move)
    err = err - (err @ d) * d
    size = np.linalg.norm(err)
    if size > 2.0 * step:
        err = err * (2.0 * step / size)
    return np.asarray(target.position + err + move)


@pytest.mark.parametrize("error_scale", [1e-4, 0.1])  # within and beyond the bound
def test_next_target_follows_its_rule(rng: np.random.Generator, error_scale: float) -> None:
    normal = np.array([0.0, 0.0, 1.0])
    for _ in range(100):
        target = Pose(rng.normal(size=3), Rotation.identity())
        measured = target.position + error_scale * rng.normal(size=3)
        move = 0.01 * np.array([*rng.normal(size=2), 0.0])
        out = next_target(target, measured, move, normal, 0.01, reanchor=True)
        ref = _reference_target(target, measured, move, normal, 0.01)
        assert np.allclose(out.position, ref, rtol=0, atol=TOL)
        assert out.orientation is target.orientation


def test_cross3_is_numpys_cross(rng: np.random.Generator) -> None:
    for _ in range(200):
        a, b = rng.normal(size=3), rng.normal(size=3)
        assert cross3(a.tolist(), b.tolist()) == tuple(np.cross(a, b).tolist())
        assert np.array_equal(cross(a, b), np.cross(a, b))


def test_across_force_is_the_force_along_n_cross_d(rng: np.random.Generator) -> None:
    normal = np.array([0.0, 0.0, 1.0])
    for _ in range(100):
        d = np.array([*rng.normal(size=2), 0.0])
        d /= np.linalg.norm(d)
        force = rng.normal(size=3) * 10.0
        inp = ControlInput(force, np.zeros(3), d, 0.1, 0.5, normal)
        across = across_force(inp)
        assert across is not None
        m = np.cross(normal, d)
        m /= np.linalg.norm(m)
        assert np.allclose(across[1], m, rtol=0, atol=TOL)
        assert abs(across[0] - float(force @ m)) < TOL


def test_the_controllers_hand_turn_is_their_hand_rotation() -> None:
    """The executor composes `hand_turn` where a controller has it: the same rotation as
    `hand_rotation`."""
    normal = np.array([0.0, 0.0, 1.0])
    d = np.array([1.0, 0.0, 0.0])
    inp = ControlInput(np.array([-3.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.2]), d, 0.1, 0.5, normal)
    steady = SteadyDirection(FixedDirection(), rotation_rate=0.5)
    steady.reset(d)
    classical = ClassicalController(w_d=0.5, axis=normal)
    classical.reset(d)
    for controller in (steady, classical):
        for _ in range(3):
            controller.next_direction(inp)
            turn, rotation = controller.hand_turn(), controller.hand_rotation()
            assert turn is not None and rotation is not None
            assert np.allclose(rotation.as_rotvec(), turn, rtol=0, atol=TOL)
    assert ClassicalController().hand_turn() is None


def test_mirror_average_still_checks_a_callers_observation() -> None:
    """The executor's own observations skip the network's input checks; a caller's do not."""
    policy = ConstraintAwarePolicy.load()
    obs = np.zeros(len(policy.observation_layout))
    obs[0], obs[3] = math.nan, 1.0
    with pytest.raises(InvalidInputError, match="obs"):
        mirror_average(policy, obs, np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
