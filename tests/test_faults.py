"""Fault injection on the simulated tasks: the executor's safety invariants hold for each fault.

Each fault of bench.faults.FAULTS runs on each of the five tasks with the default policy (one
offset, one seed; `python benchmarks/faults.py` runs more). Invariants (bench/faults.py): no
non-finite command, no commanded jump beyond the bound, no true |F| above 1.1 x the force limit,
no success above the limit, a record every time, a named stop with a reason, hold() called.
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np
import pytest

from constraint_aware.bench.faults import (
    FAULTS,
    QUICK_FAULTS,
    FaultRun,
    FaultyRobot,
    fault_suite,
    hook_hand_time_constant,
    run_fault,
)
from constraint_aware.control.simulate import RunSpec, run
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.sim import hand
from constraint_aware.sim.tasks import TASKS, task_config
from constraint_aware.sim.world import HOOK_PREFIX, ManipulationSim
from constraint_aware.spatial import Wrench

POLICY = ConstraintAwarePolicy.load()
TASK_NAMES = list(TASKS)
#: what the executor must do with each fault (outcome), where the answer is unambiguous
EXPECTED = {
    "nan_wrench": "nan",
    "frozen": "not_following",
    "comms_exception": "error",
    "spike_200N": "force_limit",
    "stale_wrench": "stale_wrench",
}

# the hook hand's names as composed into the scene (sim/world.py: prefixed)
FORCE_SENSOR, HAND_BODY, TCP_SITE, TORQUE_SENSOR, WRIST_SITE = (
    HOOK_PREFIX + n
    for n in (hand.FORCE_SENSOR, hand.HAND_BODY, hand.TCP_SITE, hand.TORQUE_SENSOR, hand.WRIST_SITE)
)


@functools.cache
def baseline(task: str) -> FaultRun:
    return run_fault(task, "none", policy=POLICY)


@pytest.mark.parametrize("fault", list(FAULTS))
@pytest.mark.parametrize("task", TASK_NAMES)
def test_no_fault_makes_the_executor_dangerous(task: str, fault: str) -> None:
    result = run_fault(task, fault, policy=POLICY)
    assert result.classification != "dangerous", (task, fault, result.dangers)
    assert result.holds >= 1
    if fault in CONVENTION_FAULTS:  # a wrong convention is stopped or left unjudged
        assert result.self_check != "passed", (task, fault, result.outcome)
    if fault in EXPECTED:
        assert result.outcome == EXPECTED[fault], (task, fault, result.reason)
    if fault.startswith(("pose_glitch", "nan_pose")):
        # a single bad pose is not acted on: the run ends as the fault-free run does
        assert result.outcome == baseline(task).outcome, (task, fault, result.reason)


#: the wrong wrench conventions (the start-of-run self-check's faults)
CONVENTION_FAULTS = ("flipped_sign", "rotated_90")
#: the faults the executor's lag-aware guards (arm force, self-check) must still catch
LAG_GUARD_FAULTS = {
    "frozen": ("not_following",),
    "frozen_10": ("not_following",),
    "flipped_sign": ("sensor_convention",),
    "rotated_90": ("sensor_convention", "force_limit"),
    "lagging_pose": ("not_following",),
}


@pytest.mark.parametrize("fault", list(LAG_GUARD_FAULTS))
@pytest.mark.parametrize("task", TASK_NAMES)
def test_the_lag_model_still_catches_the_faults(task: str, fault: str) -> None:
    """With the robot reporting its tracking_time_constant (c / k of the hook hand's arm), the
    faults the arm-deflection guards catch are still caught, as without it."""
    result = run_fault(task, fault, policy=POLICY, lag=hook_hand_time_constant)
    assert result.classification == "safe_stop", (task, fault, result.outcome, result.reason)
    assert result.outcome in LAG_GUARD_FAULTS[fault], (task, fault, result.reason)


@pytest.mark.parametrize(
    ("task", "offset", "stiffness"),
    [
        ("drawer-opening", 30.0, 500.0),
        ("pole-pulling", -30.0, 500.0),
        ("handle-rotating", 15.0, 8000.0),
    ],
)
def test_a_lagging_or_stiff_hand_reporting_its_lag_is_not_stopped(
    task: str, offset: float, stiffness: float
) -> None:
    """At 500 N/m the hook hand lags 1.5 steps (tau 0.15 s) and the quasi-static arm-force
    check stopped it `not_following`; at 8000 N/m the handle's inertia pushed along the move
    at the end of each period and the self-check stopped it `sensor_convention`."""

    def wrap(sim: ManipulationSim) -> FaultyRobot:
        return FaultyRobot(sim, "none", 0, hook_hand_time_constant(sim))

    spec = RunSpec(
        task, "policy", offset, overrides=(("hand__translational_stiffness", stiffness),)
    )
    record, _ = run(spec, policy=POLICY, wrap=wrap)  # type: ignore[arg-type]
    assert record.outcome == "success", record.reason
    assert any("with the lag model" in n for n in record.notes)


def test_quick_suite_counts() -> None:
    suite = fault_suite(tasks=["door-opening"], faults=QUICK_FAULTS, policy=POLICY)
    counts = suite.counts
    assert counts["dangerous"] == 0
    assert sum(counts.values()) == len(QUICK_FAULTS)
    assert set(suite.by_fault()) == set(QUICK_FAULTS)


def test_the_wrench_helper_matches_the_simulators_own_transform() -> None:
    """Wrench.from_sensor on MuJoCo's raw sensor data gives ManipulationSim's F_s exactly."""
    sim = ManipulationSim(task_config("door-opening"))
    sim.reset()
    m, d = sim.model, sim.data
    # load the wrist: command the hand 1 cm off and 0.1 rad about z, then step a little
    pose = sim.commanded_pose()
    sim.command_pose(pose.moved(np.array([0.01, 0.004, -0.003])))
    sim.advance()
    fs, ts = m.sensor(FORCE_SENSOR), m.sensor(TORQUE_SENSOR)
    wrist, tcp = m.site(WRIST_SITE).id, m.site(TCP_SITE).id
    w = Wrench.from_sensor(
        d.sensordata[fs.adr[0] : fs.adr[0] + 3],
        d.sensordata[ts.adr[0] : ts.adr[0] + 3],
        d.site_xmat[wrist].reshape(3, 3),
        d.site_xpos[wrist],
        d.site_xpos[tcp],
        sign=-1.0,  # MuJoCo reports the arm's action on the hand
    )
    expected = sim._sample_wrench()
    assert np.linalg.norm(expected[:3]) > 1.0  # a loaded sensor, not a trivial comparison
    np.testing.assert_allclose(w.force, expected[:3], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(w.torque, expected[3:], rtol=1e-12, atol=1e-12)


def test_hand_weight_compensation_removes_the_weight_at_rest() -> None:
    """At rest and free of contact, F_s is the hand's weight: compensation leaves ~0."""
    sim = ManipulationSim(task_config("drawer-opening", finger_angle=-0.6))
    sim.reset()
    model, data = sim.model, sim.data
    hand = model.body(HAND_BODY).id
    mass = float(model.body_subtreemass[hand])  # palm and fingers (the arm is compensated)
    wrist, tcp = model.site(WRIST_SITE).id, model.site(TCP_SITE).id
    fs, ts = model.sensor(FORCE_SENSOR), model.sensor(TORQUE_SENSOR)
    # back the open hand off the bar along its palm normal so nothing touches it, then settle
    pose = sim.commanded_pose()
    sim.command_pose(pose.moved(-0.08 * pose.orientation.apply([0.0, 0.0, 1.0])))
    for _ in range(8):
        sim.advance()
    assert not sim.in_contact()
    mujoco.mj_forward(model, data)
    com = data.subtree_com[hand]
    w = Wrench.from_sensor(
        data.sensordata[fs.adr[0] : fs.adr[0] + 3],
        data.sensordata[ts.adr[0] : ts.adr[0] + 3],
        data.site_xmat[wrist].reshape(3, 3),
        data.site_xpos[wrist],
        data.site_xpos[tcp],
        sign=-1.0,
        hand_mass=mass,
        hand_com=com,
    )
    assert np.linalg.norm(w.force) < 0.01 * mass * 9.81
    assert np.linalg.norm(w.torque) < 1e-3  # about the tool point, with the weight at its COM


@pytest.mark.parametrize("task", ["door-opening", "handle-rotating"])
@pytest.mark.parametrize("controller", ["policy", "classical"])
def test_a_wrong_sign_of_the_revolute_normal_is_corrected(task: str, controller: str) -> None:
    """The workplane normal's sign comes from the hinge's side, not from the user: a normal of
    the wrong sign no longer turns the hand backwards (uncorrected: 4/10 successes, 129 deg off)."""
    spec = RunSpec(
        task, controller, 15.0, overrides=(("executor__workplane_normal", (0.0, 0.0, -1.0)),)
    )
    record, _ = run(spec)
    assert record.success, record.reason
    assert any("workplane_normal flipped" in n for n in record.notes)
