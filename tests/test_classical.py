"""The classical baseline on ideal kinematic models (analytic constraint force, no contact)."""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable

import numpy as np
import pytest

import constraint_aware.control.classical as classical
from constraint_aware.control.classical import ClassicalController, ClassicalGains
from constraint_aware.control.interface import INPUT_NAMES, ControlInput
from constraint_aware.geometry import angle_deg, rotate_about, unit

K = 2000.0  # [N/m] compliance between the commanded and the constrained position
DT = 0.1
Z = np.array([0.0, 0.0, 1.0])


def _drive(
    ctrl: ClassicalController,
    project: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray,
    d0: np.ndarray,
    steps: int,
) -> list[np.ndarray]:
    """Quasi-static loop: command p + step * d, the constraint puts the body at project(target),
    the force on the hand is K (body - target). Returns the body positions."""
    p, d = start.copy(), d0
    force = np.zeros(3)
    ctrl.reset(d0)
    path = [p]
    for _ in range(steps):
        inp = ControlInput(force, np.zeros(3), d, DT, 0.0, Z)
        d = ctrl.next_direction(inp)
        target = p + ctrl.step_length(0.01) * d
        p = project(target)
        force = K * (p - target)
        path.append(p)
    return path


@pytest.mark.parametrize("offset", [30.0, -30.0, 60.0])
def test_estimate_converges_on_a_prismatic_joint(offset: float) -> None:
    u = unit(np.array([1.0, 1.0, 0.0]))
    ctrl = ClassicalController()
    _drive(
        ctrl, lambda x: float(x @ u) * u, np.zeros(3), rotate_about(u, Z, math.radians(offset)), 40
    )
    assert angle_deg(ctrl.estimate, u) < 1.0


@pytest.mark.parametrize("offset", [15.0, -15.0])
@pytest.mark.parametrize("radius", [0.12, 0.5])
def test_estimate_follows_the_tangent_on_a_revolute_joint(offset: float, radius: float) -> None:
    centre = np.array([0.0, radius, 0.0])

    def on_circle(x: np.ndarray) -> np.ndarray:
        return centre + radius * unit(x - centre)

    start = np.zeros(3)
    tangent0 = np.array([1.0, 0.0, 0.0])
    ctrl = ClassicalController()
    path = _drive(ctrl, on_circle, start, rotate_about(tangent0, Z, math.radians(offset)), 60)
    p = path[-1]
    tangent = unit(np.cross(Z, p - centre))
    # turning at 1 cm per step the tangent moves 0.01/r rad per step: the estimate lags a little
    assert angle_deg(ctrl.estimate, tangent) < 3.0 + math.degrees(0.01 / radius)
    swept = math.degrees(math.atan2(*(p - centre)[[0, 1]] * [1, -1]))
    assert abs(swept) > 30.0  # the body really went round


def test_force_sign_convention_moves_toward_the_constraint_force() -> None:
    """With this project's F (object on hand), a push back across the guide turns t^ toward it."""
    ctrl = ClassicalController()
    ctrl.reset(np.array([1.0, 0.0, 0.0]))
    inp = ControlInput(np.array([0.0, -5.0, 0.0]), np.zeros(3), ctrl.estimate, DT, 0.0, Z)
    ctrl.next_direction(inp)
    assert ctrl.estimate[1] < 0.0


def test_step_is_capped_at_the_nominal_length() -> None:
    ctrl = ClassicalController()
    ctrl.reset(np.array([1.0, 0.0, 0.0]))
    ctrl.next_direction(
        ControlInput(np.array([0.0, -50.0, 0.0]), np.zeros(3), ctrl.estimate, DT, 0.0)
    )
    assert ctrl.step_length(0.01) == pytest.approx(0.01)


def test_gains_have_units_and_a_source() -> None:
    assert "tune_classical.py" in (ClassicalGains.__doc__ or "")
    assert "T-RO 32(1):161-175" in (classical.__doc__ or "")
    source = inspect.getsource(ClassicalGains)
    for name in ClassicalGains.__dataclass_fields__:
        line = next(ln for ln in source.splitlines() if ln.strip().startswith(f"{name}:"))
        assert "[" in line and "]" in line, f"{name} has no unit"


def test_its_stages_say_what_they_need() -> None:
    ctrl = ClassicalController(w_d=0.2)
    assert ctrl.stage_inputs("prismatic") == {"workplane_projection": ("workplane_normal",)}
    revolute = ctrl.stage_inputs("revolute")
    assert revolute["rotational_part"] == ("rotation_rate",)
    assert all(set(v) <= set(INPUT_NAMES) for v in revolute.values())


def test_the_controller_modules_import_no_registry() -> None:
    """The classical controller and the default controller's steadying import only the
    interface, never `control.controllers` (which builds them by name): no import cycle."""
    import ast

    import constraint_aware.control.steady as steady

    for module in (classical, steady):
        tree = ast.parse(inspect.getsource(module))
        imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)} | {
            a.name for node in ast.walk(tree) if isinstance(node, ast.Import) for a in node.names
        }
        assert "constraint_aware.control.controllers" not in imported, module.__name__
