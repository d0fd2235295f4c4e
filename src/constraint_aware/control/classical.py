"""The classical baseline: Karayiannidis et al.'s adaptive controller, velocity form.

Y. Karayiannidis, C. Smith, F. E. Vina, P. Ogren, D. Kragic, "Adaptive control for pulling
constrained doors/drawers with uncertain kinematics", IEEE T-RO 32(1):161-175, 2016 (and the
ICRA 2013 "Model-free robot manipulation of doors and drawers by means of fixed-grasps"), in
the velocity form of the authors' group's own implementation (KTH, `AdaptiveController::control`
in pr2_algorithms / folding_assembly_controller), with t^ the estimated admissible direction
and P = I - t^ t^T:

    f_e = f - f_d n^                      force error (f_d = 0 here: no desired normal force)
    I_f <- I_f + P f_e dt                 integral of the force error across t^
    v_f = alpha_f f_e + beta_f I_f        force-feedback velocity
    v_ref = v_d t^ - P v_f                reference velocity
    t^ <- normalize(t^ - gamma_t v_d P v_f dt)    adaptation of the direction estimate

and the analogous rotational part with the estimated axis r^, the torque error projected off
the motion plane's normal, and a torque dead-band:

    tau_e = (I - n n^T) tau  (zeroed when |tau_e| < dead-band);  I_t <- I_t + P_r tau_e dt
    w_f = alpha_t tau_e + beta_t I_t;  w_ref = w_d r^ - P_r w_f;
    r^ <- normalize(r^ - gamma_r w_d P_r w_f dt)

Sign: f is the force the robot applies to the object (the authors' measured wrench), i.e.
f = -(F_s - F_d) with this project's F (the object's force on the hand); likewise tau.

Adaptation to this executor (100 ms period, position-commanded compliant arm): with a known
workplane (assumption 4, given to every controller) f and t^ are projected onto it; the reference
velocity becomes a displacement v_ref dt with its norm capped at the executor's 1 cm, its
direction is the next motion direction, and the raw force F_s - F_d is used (no normalization,
no threshold: the method works on force magnitudes). The rotational part replaces the
executor's hand-rotation rule on revolute tasks when `w_d` is set (w_d = v_d / r).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from constraint_aware.control.interface import ControlInput
from constraint_aware.geometry import FloatArray, cross, norm, unit


@dataclass(frozen=True)
class ClassicalGains:
    """Gains in SI units, tuned on drawer-opening only by `benchmarks/tune_classical.py`
    (grid search, seeds 0-4, objective: success first, then mean |F|; results in
    `benchmarks/results/classical_tuning.json`)."""

    v_d: float = 0.1  # [m/s] desired speed along t^ (1 cm per 100 ms, as the policy moves)
    alpha_f: float = 0.008  # [m/(s N)] proportional force feedback (tuned)
    beta_f: float = 0.0  # [m/(s^2 N)] integral force feedback (tuned: 0 beat 0.002, 0.008)
    gamma_t: float = 800.0  # [s/m^2] adaptation rate of t^ (tuned; 3200 was worse)
    f_d: float = 0.0  # [N] desired force along the constraint normal
    alpha_t: float = 0.5  # [rad/(s N m)] proportional torque feedback (not tuned: the drawer
    # exercises no rotation; only tilt torques reach it, the rotation about r^ is w_d)
    beta_t: float = 0.0  # [rad/(s^2 N m)] integral torque feedback
    gamma_r: float = 0.0  # [s/rad^2] adaptation rate of r^ (0: the workplane normal is known)
    torque_deadband: float = 0.05  # [N m]


class ClassicalController:
    """Karayiannidis et al.'s adaptive velocity controller behind the executor's interface."""

    name = "classical"

    def __init__(
        self,
        gains: ClassicalGains | None = None,
        w_d: float | None = None,
        axis: FloatArray | None = None,
    ) -> None:
        self.gains = gains or ClassicalGains()
        self.w_d = w_d  # [rad/s] desired rotation rate; None: no rotational part
        self.axis0 = None if axis is None else unit(np.asarray(axis, dtype=float))
        self.reset(np.array([1.0, 0.0, 0.0]))

    def reset(self, direction: FloatArray) -> None:
        self.t_hat = unit(np.asarray(direction, dtype=float))
        self.i_f = np.zeros(3)
        self.r_hat = self.axis0.copy() if self.axis0 is not None else np.array([0.0, 0.0, 1.0])
        self.i_t = np.zeros(3)
        self._step = 0.01
        self._turn: FloatArray | None = None  # [rad] this step's rotation vector

    def next_direction(self, inp: ControlInput) -> FloatArray:
        g = self.gains
        dt = inp.dt
        f = -inp.force  # the robot's force on the object
        plane = inp.workplane_normal
        if plane is not None:  # assumption 4, known to every controller: stay in the plane
            f = f - float(f @ plane) * plane
        normal = unit(cross(self.t_hat, self.r_hat))
        f_e = f - g.f_d * normal
        p = np.eye(3) - np.outer(self.t_hat, self.t_hat)
        self.i_f = self.i_f + p @ f_e * dt
        v_f = g.alpha_f * f_e + g.beta_f * self.i_f
        v_ref = g.v_d * self.t_hat - p @ v_f
        self.t_hat = unit(self.t_hat - g.gamma_t * g.v_d * (p @ v_f) * dt)
        if plane is not None:
            self.t_hat = unit(self.t_hat - float(self.t_hat @ plane) * plane)
        self._step = norm(v_ref) * dt
        self._turn = self._rotation_step(inp, normal) if self.w_d is not None else None
        return unit(v_ref)

    def _rotation_step(self, inp: ControlInput, normal: FloatArray) -> FloatArray:
        """The rotational part's turn this step, w_ref dt [rad] (3,)."""
        g = self.gains
        assert self.w_d is not None
        tau = -inp.torque
        tau_e = tau - float(tau @ normal) * normal
        if norm(tau_e) < g.torque_deadband:
            tau_e = np.zeros(3)
        p_r = np.eye(3) - np.outer(self.r_hat, self.r_hat)
        self.i_t = self.i_t + p_r @ tau_e * inp.dt
        w_f = g.alpha_t * tau_e + g.beta_t * self.i_t
        w_ref = self.w_d * self.r_hat - p_r @ w_f
        self.r_hat = unit(self.r_hat - g.gamma_r * self.w_d * (p_r @ w_f) * inp.dt)
        return np.asarray(w_ref * inp.dt)

    def step_length(self, nominal: float) -> float:
        """|v_ref| dt, capped at the executor's nominal step (1 cm)."""
        return min(self._step, nominal)

    def hand_rotation(self) -> Rotation | None:
        """This step's hand rotation from the rotational part, or None (executor's rule)."""
        return None if self._turn is None else Rotation.from_rotvec(self._turn)

    def hand_turn(self) -> FloatArray | None:
        """`hand_rotation` as a rotation vector (3,) [rad], or None; the executor composes it
        with the hand's orientation (`spatial.turned`)."""
        return self._turn

    def stage_inputs(self, constraint_type: str) -> dict[str, tuple[str, ...]]:
        """The force and t^ are projected onto the workplane (needs its normal); on a
        revolute joint the rotational part needs the known rotation rate w_d."""
        stages: dict[str, tuple[str, ...]] = {"workplane_projection": ("workplane_normal",)}
        if constraint_type == "revolute":
            stages["rotational_part"] = ("rotation_rate",)
        return stages

    @property
    def estimate(self) -> FloatArray:
        """(3,) the current estimate t^ of the admissible direction."""
        return self.t_hat.copy()
