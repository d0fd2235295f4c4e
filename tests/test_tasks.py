"""Per-task checks of the MuJoCo world (dm_control style)."""

from __future__ import annotations

import math
from collections.abc import Callable

import mujoco
import numpy as np
import pytest

from constraint_aware.control.controllers import DirectionController
from constraint_aware.control.executor import Executor
from constraint_aware.control.simulate import RunSpec, executor_config, run
from constraint_aware.errors import UnknownNameError
from constraint_aware.geometry import angle_deg
from constraint_aware.sim.tasks import TASKS, task_config
from constraint_aware.sim.world import ManipulationSim, build_mjcf, build_spec
from constraint_aware.spatial import Pose

NAMED = [
    (mujoco.mjtObj.mjOBJ_BODY, "nbody", 1),  # body 0 is the world
    (mujoco.mjtObj.mjOBJ_JOINT, "njnt", 0),
    (mujoco.mjtObj.mjOBJ_GEOM, "ngeom", 0),
    (mujoco.mjtObj.mjOBJ_SITE, "nsite", 0),
    (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu", 0),
    (mujoco.mjtObj.mjOBJ_SENSOR, "nsensor", 0),
]


@pytest.mark.parametrize("name", list(TASKS))
def test_task_builds_and_every_element_is_named(name: str) -> None:
    model = build_spec(task_config(name)).compile()
    for obj, count, first in NAMED:
        for i in range(first, getattr(model, count)):
            assert mujoco.mj_id2name(model, obj, i), f"unnamed {obj.name} {i} in {name}"
    # the composed scene has the sizes the former MJCF template had (hand chain, object)
    assert (model.nq, model.nv, model.nu, model.nbody, model.nsite, model.nsensor) == (
        9,
        9,
        8,
        11,
        3,
        2,
    )
    # and its written-out MJCF compiles to the same model
    again = mujoco.MjModel.from_xml_string(build_mjcf(task_config(name)))
    assert (again.nq, again.ngeom, again.nu) == (model.nq, model.ngeom, model.nu)


@pytest.mark.parametrize("name", list(TASKS))
def test_grasp_settles_without_nan_or_slip(name: str) -> None:
    sim = ManipulationSim(task_config(name))
    sim.reset()
    w = sim.read_wrench()
    assert np.all(np.isfinite(w.force)) and np.all(np.isfinite(w.torque))
    assert sim.slip() == (0.0, 0.0)
    assert abs(sim.progress()) < 2e-3
    assert sim.grasp_contact() or task_config(name).force_exertion_type == "lazy_closure"


@pytest.mark.parametrize("name", list(TASKS))
def test_same_seed_same_rollout(name: str) -> None:
    spec = RunSpec(task=name, controller="policy", offset_deg=10.0, seed=3, randomize=True)
    a, _ = run(spec)
    b, _ = run(spec)
    assert a.to_dict() == b.to_dict()
    for step in a.steps:
        assert np.all(np.isfinite(step.force)) and np.all(np.isfinite(step.hand_position))


def test_unknown_task_lists_valid_names() -> None:
    with pytest.raises(UnknownNameError, match="door-opening, drawer-opening"):
        task_config("fridge")


def test_overrides_reach_the_object_and_reject_unknown_fields() -> None:
    cfg = task_config("drawer-opening", object__mass=3.5, force_limit=40.0)
    assert cfg.object.mass == 3.5 and cfg.force_limit == 40.0
    with pytest.raises(UnknownNameError, match="mass"):
        task_config("drawer-opening", object__weight=1.0)


def test_wrist_sensor_sign_and_magnitude_in_a_scripted_push() -> None:
    """Press 5 mm deeper into the plate (which cannot move vertically): the object's force on
    the hand must point up and grow by about stiffness x 5 mm."""
    task = task_config("plate-sliding")
    sim = ManipulationSim(task)
    sim.reset()
    before = sim.read_wrench().force
    target = sim.commanded_pose()
    sim.command_pose(target.moved(np.array([0.0, 0.0, -0.005])))
    for _ in range(5):
        sim.advance()
    delta = sim.read_wrench().force - before
    expected = task.hand.translational_stiffness * 0.005
    assert delta[2] > 0  # the plate pushes the hand up
    assert delta[2] == pytest.approx(expected, rel=0.1)
    assert np.linalg.norm(delta[:2]) < 0.05 * expected


@pytest.mark.parametrize("name", list(TASKS))
def test_grasp_holds_under_a_scripted_pull(
    name: str, true_direction: Callable[..., DirectionController]
) -> None:
    task = task_config(name)
    sim = ManipulationSim(task)
    sim.reset()
    cfg = executor_config(task)
    record = Executor(sim, true_direction(sim), cfg, monitor=sim).run(sim.admissible_direction())
    assert record.outcome == "success", record.reason
    assert record.slip_m < 0.01
    assert record.peak_force < 20.0


def test_revolute_tangent_is_perpendicular_to_radius_and_axis() -> None:
    sim = ManipulationSim(task_config("door-opening"))
    sim.reset()
    t = sim.admissible_direction()
    assert abs(t @ np.array([0.0, 0.0, 1.0])) < 1e-9
    radial = sim.read_pose().position - np.array(task_config("door-opening").object.position)
    assert angle_deg(t, radial) == pytest.approx(90.0, abs=1.0)


def test_commanded_pose_round_trip() -> None:
    sim = ManipulationSim(task_config("door-opening"))
    sim.reset()
    pose = sim.commanded_pose()
    turned = Pose(pose.position, pose.orientation)
    sim.command_pose(turned)
    sim.advance()
    after = sim.commanded_pose()
    np.testing.assert_allclose(after.position, pose.position, atol=1e-9)
    assert (after.orientation.inv() * pose.orientation).magnitude() < 1e-9
    assert math.isfinite(sim.progress())


@pytest.mark.parametrize(
    ("yaw", "shift", "turn"),
    [
        (None, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),  # holding
        (None, (0.01, -0.004, 0.002), (0.02, -0.05, 0.3)),  # a step with a turn
        (3.1, (0.0, 0.01, 0.0), (0.0, 0.0, 0.2)),  # the yaw goes past pi: no 2 pi spin
    ],
)
def test_the_hook_hands_ramp_holds_the_interpolated_poses(
    yaw: float | None, shift: tuple[float, ...], turn: tuple[float, ...]
) -> None:
    # `_ramp` computes a period's joint targets in one product; they must be the joint
    # targets of the interpolated poses (start + f shift, exp(f turn) R0), piece by piece
    from constraint_aware.sim.robot_adapter import RAMP_FRACTIONS, rotation_matrices

    sim = ManipulationSim(task_config("door-opening"))
    sim.reset()
    if yaw is not None:
        sim._target[3] = yaw
    start, start_rotation = sim._setpoint()
    f = RAMP_FRACTIONS[:, None]
    positions = start + f * np.array(shift)
    rotations = rotation_matrices(f * np.array(turn)) @ start_rotation
    want = sim._unwrapped(sim._joint_targets(positions, rotations))
    held: list[np.ndarray] = []
    sim._step = lambda n: held.append(sim.data.ctrl[sim._arm_ctrl].copy())  # type: ignore[method-assign]
    sim._ramp(start, np.array(shift), start_rotation, np.array(turn))
    np.testing.assert_allclose(np.array(held), want, rtol=0, atol=1e-12)
    assert np.all(np.abs(np.diff(np.array(held)[:, 3:], axis=0)) < 0.1)  # no spins
    if yaw is not None:
        assert held[-1][3] > math.pi  # unwrapped past pi, not wrapped to -pi
