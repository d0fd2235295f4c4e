"""The Jaco's operational-space impedance law (sim/jaco.py's module docstring), compiled.

The law runs every second simulation substep, on 6x6 matrices and six joints: at that size a
numpy call costs more than its arithmetic, so the whole law is one function compiled by
numba (the `arm` extra), called once per update with MuJoCo's Jacobian and mass matrix.
Compiled on first use and cached on disk (numba's `cache=True`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from constraint_aware.geometry import FloatArray

#: Rows of `osc_torques`'s `joint` (one column per arm joint)
POSTURE, LOW, HIGH, STIFFNESS, DAMPING_GAIN, TORQUE_LIMIT, FRICTION, ROTOR = range(8)
assert POSTURE == 0  # JacoSim keeps a view of this row as its posture
#: Entries of `osc_torques`'s `gains`
(
    POSTURE_STIFFNESS,
    POSTURE_DAMPING,
    LIMIT_STIFFNESS,
    VELOCITY_FEEDFORWARD,
    FRICTION_VELOCITY_SCALE,
    FRICTION_TORQUE_SCALE,
    INVERSE_MASS_CAP,
) = range(7)
N_GAINS = 7


@njit(cache=True, error_model="numpy")
def _solve(a: FloatArray, b: FloatArray) -> FloatArray:
    """x with a x = b for a (n, n) symmetric positive definite, b (n, k): Cholesky; Gaussian
    elimination with partial pivoting if `a` is not positive definite numerically. `a` and
    `b` are left as they are."""
    n, k = b.shape
    low = np.zeros((n, n))
    for j in range(n):
        s = a[j, j]
        for p in range(j):
            s -= low[j, p] * low[j, p]
        if not s > 0.0:
            return _solve_general(a, b)
        low[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            s = a[i, j]
            for p in range(j):
                s -= low[i, p] * low[j, p]
            low[i, j] = s / low[j, j]
    x = b.copy()
    for c in range(k):
        for i in range(n):  # L y = b
            s = x[i, c]
            for p in range(i):
                s -= low[i, p] * x[p, c]
            x[i, c] = s / low[i, i]
        for i in range(n - 1, -1, -1):  # L^T x = y
            s = x[i, c]
            for p in range(i + 1, n):
                s -= low[p, i] * x[p, c]
            x[i, c] = s / low[i, i]
    return x


@njit(cache=True, error_model="numpy")
def _solve_general(a: FloatArray, b: FloatArray) -> FloatArray:
    """x with a x = b, a (n, n) invertible, b (n, k): Gaussian elimination, partial pivoting."""
    n, k = b.shape
    m = a.copy()
    x = b.copy()
    for j in range(n):
        pivot = j
        for i in range(j + 1, n):
            if abs(m[i, j]) > abs(m[pivot, j]):
                pivot = i
        for c in range(n):
            m[j, c], m[pivot, c] = m[pivot, c], m[j, c]
        for c in range(k):
            x[j, c], x[pivot, c] = x[pivot, c], x[j, c]
        for i in range(j + 1, n):
            f = m[i, j] / m[j, j]
            for c in range(j, n):
                m[i, c] -= f * m[j, c]
            for c in range(k):
                x[i, c] -= f * x[j, c]
    for i in range(n - 1, -1, -1):
        for c in range(k):
            s = x[i, c]
            for p in range(i + 1, n):
                s -= m[i, p] * x[p, c]
            x[i, c] = s / m[i, i]
    return x


@njit(cache=True, error_model="numpy")
def rotation_vector(r: FloatArray) -> FloatArray:
    """(3,) rotation vector [rad] of a rotation matrix r (3, 3); near pi through the
    quaternion (Shepperd's method), where the antisymmetric part loses the axis."""
    x = 0.5 * (r[2, 1] - r[1, 2])
    y = 0.5 * (r[0, 2] - r[2, 0])
    z = 0.5 * (r[1, 0] - r[0, 1])
    s = math.sqrt(x * x + y * y + z * z)
    angle = math.atan2(s, 0.5 * (r[0, 0] + r[1, 1] + r[2, 2] - 1.0))
    out = np.empty(3)
    if s < 1e-9:  # angle ~ 0: the rotation vector is v itself
        out[0], out[1], out[2] = x, y, z
        return out
    if angle <= math.pi - 1e-3:
        f = angle / s
        out[0], out[1], out[2] = x * f, y * f, z * f
        return out
    # quaternion (w, v) from the largest of w^2, x^2, y^2, z^2 (Shepperd)
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    q = np.empty(4)
    big = max(trace, r[0, 0], r[1, 1], r[2, 2])
    if big == trace:
        q[0] = 0.5 * math.sqrt(1.0 + trace)
        f = 0.25 / q[0]
        q[1], q[2], q[3] = (r[2, 1] - r[1, 2]) * f, (r[0, 2] - r[2, 0]) * f, (r[1, 0] - r[0, 1]) * f
    else:
        i = 0 if big == r[0, 0] else (1 if big == r[1, 1] else 2)
        j, k = (i + 1) % 3, (i + 2) % 3
        q[1 + i] = 0.5 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        f = 0.25 / q[1 + i]
        q[0] = (r[k, j] - r[j, k]) * f
        q[1 + j] = (r[j, i] + r[i, j]) * f
        q[1 + k] = (r[k, i] + r[i, k]) * f
    if q[0] < 0.0:
        q = -q
    norm = math.sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    angle = 2.0 * math.atan2(norm, q[0])
    for c in range(3):
        out[c] = q[1 + c] * angle / norm
    return out


#: Entries of `osc_torques`'s `index`
DOF0, QPOS0, ACT0, TOOL_SITE = range(4)


@njit(cache=True, error_model="numpy")
def osc_torques(
    jac: FloatArray,
    mass: FloatArray,
    qpos: FloatArray,
    qvel: FloatArray,
    qacc: FloatArray,
    qfrc_bias: FloatArray,
    site_xpos: FloatArray,
    site_xmat: FloatArray,
    ctrl: FloatArray,
    index: np.ndarray,
    setpoint_pos: FloatArray,
    setpoint_mat: FloatArray,
    setpoint_vel: FloatArray,
    joint: FloatArray,
    gains: FloatArray,
) -> None:
    """The arm's motor torques [N m] by the OSC law, written to `ctrl`.

    jac (6, nv): the tool point's Jacobian (translation, rotation); mass (nv, nv): the joint
    space inertia M (changed: the rotor inertia the torque loop hides is taken off the arm's
    diagonal); qpos, qvel, qacc, qfrc_bias, site_xpos, site_xmat, ctrl: MjData's arrays, read
    at `index` (`DOF0`: the first of the six consecutive arm dofs, `QPOS0` its first joint
    position, `ACT0` its first motor, `TOOL_SITE` the tool point's site); setpoint_pos (3,)
    [m], setpoint_mat (3, 3), setpoint_vel (6,) [m/s, rad/s]: the tool point's setpoint and
    the setpoint's velocity; joint (8, 6): per arm joint `POSTURE`, `LOW`, `HIGH` (the
    joint-limit repulsion band) [rad], `STIFFNESS` K_ii, `DAMPING_GAIN` 2 zeta sqrt(K_ii),
    `TORQUE_LIMIT` [N m], `FRICTION` [N m] (the dry friction fed forward), `ROTOR` [kg m^2]
    (c B); gains: the scalar gains at the module's indices (OscConfig's, and 1 /
    apparent_mass_cap).
    """
    dof0, qpos0, act0, site = index[DOF0], index[QPOS0], index[ACT0], index[TOOL_SITE]
    q = qpos[qpos0 : qpos0 + 6]
    dq = qvel[dof0 : dof0 + 6]
    ddq = qacc[dof0 : dof0 + 6]
    bias = qfrc_bias[dof0 : dof0 + 6]
    tool_pos = site_xpos[site]
    tool_mat = site_xmat[site].reshape(3, 3)
    nv = mass.shape[0]
    for i in range(6):
        mass[dof0 + i, dof0 + i] -= joint[ROTOR, i]
    jac_t = np.empty((nv, 6))
    for a in range(6):
        for v in range(nv):
            jac_t[v, a] = jac[a, v]
    minv_jt = _solve(mass, jac_t)[dof0 : dof0 + 6]  # (arm dof, task axis): M^-1 J^T
    j_arm = np.empty((6, 6))
    for a in range(6):
        for i in range(6):
            j_arm[a, i] = jac[a, dof0 + i]
    # null space: posture spring and joint-limit repulsion, projected so that they do not
    # disturb the tool point (dynamically consistent: N^T = I - J^T Lambda J M^-1)
    tau0 = np.empty(6)
    for i in range(6):
        wrapped = ((joint[POSTURE, i] - q[i]) + math.pi) % (2.0 * math.pi) - math.pi
        tau0[i] = (
            gains[POSTURE_STIFFNESS] * wrapped
            - gains[POSTURE_DAMPING] * dq[i]
            - gains[LIMIT_STIFFNESS]
            * (min(q[i] - joint[LOW, i], 0.0) + max(q[i] - joint[HIGH, i], 0.0))
        )
    # Lambda and Lambda J M^-1 tau0 from one solve of Lambda^-1 [Lambda | y] = [I | ...]
    inverse = np.empty((6, 6))  # J M^-1 J^T + I / cap
    rhs = np.zeros((6, 7))
    for a in range(6):
        for b in range(6):
            s = 0.0
            for i in range(6):
                s += j_arm[a, i] * minv_jt[i, b]
            inverse[a, b] = s
        inverse[a, a] += gains[INVERSE_MASS_CAP]
        rhs[a, a] = 1.0
        s = 0.0
        for i in range(6):
            s += minv_jt[i, a] * tau0[i]
        rhs[a, 6] = s
    lam_and_y = _solve(inverse, rhs)
    err = np.empty(6)
    turn = np.empty((3, 3))  # setpoint rotation times the tool's, transposed
    for r in range(3):
        err[r] = setpoint_pos[r] - tool_pos[r]
        for c in range(3):
            turn[r, c] = (
                setpoint_mat[r, 0] * tool_mat[c, 0]
                + setpoint_mat[r, 1] * tool_mat[c, 1]
                + setpoint_mat[r, 2] * tool_mat[c, 2]
            )
    err[3:] = rotation_vector(turn)
    # damping on the tool's velocity (less f times the setpoint's: OscConfig)
    wrench = np.empty(6)
    for a in range(6):
        s = 0.0
        for i in range(6):
            s += j_arm[a, i] * dq[i]
        vel = s - gains[VELOCITY_FEEDFORWARD] * setpoint_vel[a]
        damping = joint[DAMPING_GAIN, a] * math.sqrt(lam_and_y[a, a])
        wrench[a] = joint[STIFFNESS, a] * err[a] - damping * vel
    tau = np.empty(6)
    rotation = np.empty(6)
    motor_room = np.empty(6)
    room = np.empty(6)
    excess = 0.0
    for i in range(6):
        s = 0.0
        turning = 0.0
        for a in range(6):
            s += j_arm[a, i] * (wrench[a] - lam_and_y[a, 6])
            if a >= 3:
                turning += j_arm[a, i] * wrench[a]
        tau[i] = s + tau0[i]
        rotation[i] = turning
        motor_room[i] = max(joint[TORQUE_LIMIT, i] - abs(bias[i]), 1e-3)  # after gravity
        room[i] = max(motor_room[i] - joint[FRICTION, i], 1e-3)  # and the feed-forward below
        excess = max(excess, abs(tau[i]) / room[i])
    # at the motors' limits the rotation yields first: a large orientation error (the small
    # wrist motors' 6.8 N m) must not starve the force that holds the tool point on its path
    if excess > 1.0:
        translation = tau - rotation
        fit = 0.0
        for i in range(6):
            fit = max(fit, abs(translation[i]) / room[i])
        if fit >= 1.0:
            tau = translation / fit
        else:
            share = 1.0
            for i in range(6):
                if rotation[i] != 0.0:
                    sign = 1.0 if rotation[i] > 0.0 else -1.0
                    share = min(share, (room[i] - sign * translation[i]) / abs(rotation[i]))
            tau = translation + share * rotation
    # the joints' dry friction, in the direction of the joint's motion while it moves, of the
    # commanded torque while it sticks
    excess = 0.0
    for i in range(6):
        v = dq[i]
        moving = min(abs(v) / gains[FRICTION_VELOCITY_SCALE], 1.0)
        sign = 1.0 if v > 0.0 else (-1.0 if v < 0.0 else 0.0)
        sticking = math.tanh(tau[i] / gains[FRICTION_TORQUE_SCALE])
        tau[i] += joint[FRICTION, i] * (moving * sign + (1.0 - moving) * sticking)
        excess = max(excess, abs(tau[i]) / motor_room[i])
    # at a motor's limit, scale the whole task torque down rather than clip joints one by
    # one: clipping would turn the Cartesian force away from the commanded direction
    for i in range(6):
        t = tau[i] / excess if excess > 1.0 else tau[i]
        total = t + (bias[i] + joint[ROTOR, i] * ddq[i])  # the torque loop (OscConfig)
        limit = joint[TORQUE_LIMIT, i]
        ctrl[act0 + i] = min(max(total, -limit), limit)
