"""The object's visual parts: what touches them, and what goes through them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from constraint_aware.control.controllers import make_controller
from constraint_aware.control.executor import Executor, orient_normal
from constraint_aware.control.simulate import RunSpec, executor_config, run
from constraint_aware.geometry import rotate_about
from constraint_aware.sim.embodiment import Embodiment
from constraint_aware.sim.jaco import JacoSim
from constraint_aware.sim.objects import ARM_CONTACT_BIT
from constraint_aware.sim.scene import OBJECT_PREFIX, Intrusion, intrusions, scene_spec
from constraint_aware.sim.tasks import TASKS, TaskConfig, task_config
from constraint_aware.sim.world import HOOK_PREFIX, ManipulationSim, build_model


@pytest.mark.parametrize("name", list(TASKS))
def test_the_hook_hand_stays_out_of_the_visual_parts(name: str) -> None:
    # the visual-only main parts and furniture are only honest if the hand never needs them
    found: list[Intrusion] = []

    def check(sim: Embodiment) -> None:
        found.extend(intrusions(sim.model, sim.data, HOOK_PREFIX))

    record, _ = run(RunSpec(task=name, controller="policy", offset_deg=30.0, seed=0), on_step=check)
    assert record.success, record.reason
    assert found == []


def _noise_free_run(task: TaskConfig, model: mujoco.MjModel) -> dict[str, object]:
    sim = ManipulationSim(task, model=model)
    sim.reset()
    cfg = executor_config(task)
    assert cfg.workplane_normal is not None and cfg.hinge_point is not None
    d0 = rotate_about(sim.admissible_direction(), np.asarray(cfg.workplane_normal), 0.3)
    normal = orient_normal(
        np.asarray(cfg.workplane_normal), d0, sim.read_pose().position, cfg.hinge_point
    )
    assert cfg.rotation_radius is not None
    rate = cfg.step_length / sim.control_period / cfg.rotation_radius
    controller = make_controller("policy", None, rate, normal, {})
    return Executor(sim, controller, cfg, monitor=sim).run(d0, {}).to_dict()


def test_solid_parts_leave_the_hook_hand_run_as_it_was() -> None:
    task = task_config("door-opening")
    solid = build_model(task, solid_for_arms=True)
    panel = solid.geom(OBJECT_PREFIX + "object_panel").id
    assert solid.geom_conaffinity[panel] == ARM_CONTACT_BIT
    visual = build_model(task)
    assert visual.geom_conaffinity[visual.geom(OBJECT_PREFIX + "object_panel").id] == 0
    assert _noise_free_run(task, solid) == _noise_free_run(task, visual)


@pytest.mark.parametrize("solid", [False, True])
def test_solid_parts_touch_arm_geoms_only(solid: bool) -> None:
    # two probes inside the closed door's panel: one with dm-control's arm contact bits
    # (contype 3, conaffinity 2, as the Jaco's geoms), one with the hook hand's (1, 1)
    task = task_config("door-opening")
    panel_centre = [-0.055, 0.25, 1.0]

    def probes(spec: mujoco.MjSpec) -> None:
        body = spec.worldbody.add_body(name="probes", pos=panel_centre)
        box = mujoco.mjtGeom.mjGEOM_BOX
        body.add_geom(name="arm_probe", type=box, size=[0.01] * 3, pos=[0, -0.05, 0],
                      contype=3, conaffinity=ARM_CONTACT_BIT)  # fmt: skip
        body.add_geom(name="hand_probe", type=box, size=[0.01] * 3, pos=[0, 0.05, 0],
                      contype=1, conaffinity=1)  # fmt: skip

    model = scene_spec(task, probes, solid_for_arms=solid).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    touching = {
        frozenset((model.geom(int(c.geom1)).name, model.geom(int(c.geom2)).name))
        for c in data.contact[: data.ncon]
    }
    panel = OBJECT_PREFIX + "object_panel"
    assert (frozenset(("arm_probe", panel)) in touching) == solid
    assert frozenset(("hand_probe", panel)) not in touching
    # the probes are inside the panel either way: ground truth, contacts or not
    inside = {i.robot_geom for i in intrusions(model, data, "probes")}
    assert inside == {"arm_probe", "hand_probe"}


@pytest.mark.parametrize("name", ["door-opening", "drawer-opening"])
@pytest.mark.xfail(
    strict=True,
    reason="the Jaco's curled fingertips reach 61.6 mm behind the bar's centre and the door "
    "panel's / drawer box's front is 40 mm behind it (the bar objects' standoff): at the grasp "
    "they are 21.6 mm inside (and on the door its link 2, based on the hinge side, 12.6 mm); "
    "remove this mark when the Jaco's grasp stays out",
)
def test_the_jaco_grasp_stays_out_of_the_visual_parts(name: str) -> None:
    sim = JacoSim(task_config(name))
    sim.reset()
    assert intrusions(sim.model, sim.data, "jaco") == []


def test_a_cranks_shaft_ends_at_its_hub_a_doors_post_spans_its_edge() -> None:
    # the crank is turned from above its knob: its shaft stands below the hub, where no hand
    # reaching for the knob meets it; a door's post runs along its hinged edge on both sides
    # of the handle's height
    from constraint_aware.sim.objects import KNOB_STEM, object_frame

    def post_ends(task: TaskConfig) -> tuple[np.ndarray, np.ndarray]:
        model = build_model(task)
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        geom = model.geom(OBJECT_PREFIX + "scene_hinge").id
        axis = data.geom_xmat[geom].reshape(3, 3)[:, 2] * model.geom_size[geom][1]
        return data.geom_xpos[geom] - axis, data.geom_xpos[geom] + axis

    crank = task_config("handle-rotating")
    up = object_frame(crank.object)[:, 2]
    hub = float(crank.object.handle_position @ up) - (2 * crank.object.handle_half[2] + KNOB_STEM)
    tops = sorted(float(end @ up) for end in post_ends(crank))
    assert tops[1] == pytest.approx(hub, abs=1e-4)
    door = task_config("door-opening")
    up = object_frame(door.object)[:, 2]
    handle = float(door.object.handle_position @ up)
    spans = sorted(float(end @ up) - handle for end in post_ends(door))
    assert spans == pytest.approx([-0.3, 0.3], abs=1e-4)
