"""Fitting a second-order tracking model: the arm's impedance m x'' = k (s - x) - c x' to
tool-point positions sampled once per control period.

Both calibrations fit it: the grasp's (`control.calibrate`) to a free push against the
object's measured resistance (`fit_impedance`), the free-space one (`control.free_space`) to
setpoint steps the arm's dry friction may hold short (`fit_step_response`, then
`step_rise_time`). The fit runs on the model's exact discretization, the setpoint a straight
line within each period (the Robot protocol's "reached over the next control period"), over
the two parameters m / k and c / k (as c / k and the damping ratio). scipy is imported
inside the functions: importing the package stays light.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from constraint_aware.geometry import FloatArray

__all__ = [
    "DAMPING_RATIO_RANGE",
    "STALL_RANGE",
    "fit_impedance",
    "fit_step_response",
    "step_rise_time",
]

#: The damping ratio the tau fit may take: [low, high]. Past `high` the arm is a first-order
#: lag and its mass no longer shows in per-period readings; `low` excludes ringing no
#: impedance controller is tuned to.
DAMPING_RATIO_RANGE = (0.3, 5.0)
#: The share of a free-space step the arm's dry friction may hold it short by: [low, high]
#: (a step response stalled 60 % short never reaches 63.2 % of the step).
STALL_RANGE = (-0.2, 0.6)


def step_rise_time(b: float, zeta: float, level: float = 1.0 - math.exp(-1.0)) -> float:
    """[s] the time x'' = (1 - x) / a - (b / a) x' (a = (b / (2 zeta))^2) takes from rest at
    0 to `level` after a unit step at t = 0: the first crossing; inf when it never does.

    Args:
        b: [s] c / k, the damping over the stiffness.
        zeta: the damping ratio b / (2 sqrt(a)), > 0.
        level: the share of the step, > 0 (the 63.2 % rise time by default).
    """
    if not level < 1.0 + math.exp(-math.pi * zeta / math.sqrt(max(1.0 - zeta**2, 1e-12))):
        return math.inf  # beyond the first overshoot (none when zeta >= 1)
    from scipy.optimize import brentq  # here: importing the package stays light

    a = (b / (2.0 * zeta)) ** 2
    m = np.array([[0.0, 1.0], [-1.0 / a, -b / a]])

    def x(t: float) -> float:
        return 1.0 - float(_expm(m * t)[0, 0])  # from rest: x = 1 - [e^{mt} (1, 0)]_0

    horizon = max(b, 2.0 * math.sqrt(a))
    t0 = 0.0
    for t1 in np.linspace(horizon / 50.0, 20.0 * horizon, 1000):
        if x(float(t1)) >= level:
            return float(brentq(lambda t: x(t) - level, t0, float(t1), xtol=1e-9 * horizon))
        t0 = float(t1)
    return math.inf


def fit_step_response(
    drive: FloatArray, position: FloatArray, period: float
) -> tuple[float, float, float, float, float] | None:
    """Fit x'' = ((1 - f) w - x) / a - (b / a) x' to a step response sampled once per period:
    the impedance of `fit_impedance` with the drive w (the setpoint, a straight line between
    samples, from rest at x = w = 0) short by a share f, the arm's dry friction holding it
    short of the setpoint (a linear arm fits f = 0).

    Args:
        drive: (n,) [m] the setpoint along the step at each sample.
        position: (n,) [m] the tool point along the step at each sample.
        period: [s] between samples.

    Returns:
        (b = c / k [s], its standard error [s], the damping ratio, f, the residual RMS [m]),
        or None when the fit fails. The damping ratio is held in DAMPING_RATIO_RANGE, f in
        STALL_RANGE.
    """
    w = np.asarray(drive, dtype=float)
    x = np.asarray(position, dtype=float)

    def residual(p: FloatArray) -> FloatArray:
        return _impedance_response(math.exp(p[0]), math.exp(p[1]), (1.0 - p[2]) * w, period) - x

    fit = _fit_lag(residual, [0.0], [STALL_RANGE[0]], [STALL_RANGE[1]], period, len(x))
    if fit is None:
        return None
    b, b_u, zeta, (stall,), rms = fit
    return b, b_u, zeta, stall, rms


def _fit_lag(
    residual: Callable[[FloatArray], FloatArray],
    start: list[float],
    low: list[float],
    high: list[float],
    period: float,
    n: int,
) -> tuple[float, float, float, list[float], float] | None:
    """Least squares of `residual` over (log b, log damping ratio, *rest) from three starts of
    b (the lag per speed from fast to slow; the rest from `start`, within `low`..`high`), the
    best of them: (b [s], its standard error [s], the damping ratio (held in
    DAMPING_RATIO_RANGE), the rest, the residual RMS over the `n` samples), or None when every
    start fails."""
    from scipy.optimize import least_squares  # here: importing the package stays light

    lo, hi = (math.log(z) for z in DAMPING_RATIO_RANGE)
    best = None
    for b0 in (0.3 * period, period, 3.0 * period):
        try:
            r = least_squares(
                residual,
                [math.log(b0), 0.0, *start],
                bounds=(
                    [math.log(1e-3 * period), lo, *low],
                    [math.log(30.0 * period), hi, *high],
                ),
            )
        except (ValueError, np.linalg.LinAlgError):
            continue
        if np.isfinite(r.cost) and (best is None or r.cost < best.cost):
            best = r
    if best is None or not best.success:
        return None
    b, zeta = math.exp(best.x[0]), math.exp(best.x[1])
    dof = max(n - len(best.x), 1)
    rms = math.sqrt(2.0 * best.cost / n)
    try:
        cov = (2.0 * best.cost / dof) * np.linalg.inv(best.jac.T @ best.jac)
        b_u = b * math.sqrt(max(float(cov[0, 0]), 0.0))  # d b = b d(log b)
    except np.linalg.LinAlgError:
        b_u = math.inf
    return b, b_u, zeta, [float(v) for v in best.x[2:]], rms


def fit_impedance(
    drive: FloatArray, position: FloatArray, period: float
) -> tuple[float, float, float, float] | None:
    """Fit x'' = (w - x) / a - (b / a) x' (a = m / k [s^2], b = c / k [s]) to positions
    sampled once per period, with the drive w (the setpoint less the resisting force over k)
    a straight line between samples; from rest at x = w = 0.

    Args:
        drive: (n,) [m] w at each sample.
        position: (n,) [m] x at each sample.
        period: [s] between samples.

    Returns:
        (b [s], its standard error [s], the damping ratio b / (2 sqrt(a)), the residual RMS
        [m]), or None when the fit fails. The damping ratio is held in DAMPING_RATIO_RANGE.
    """
    w = np.asarray(drive, dtype=float)
    x = np.asarray(position, dtype=float)

    def residual(p: FloatArray) -> FloatArray:
        return _impedance_response(math.exp(p[0]), math.exp(p[1]), w, period) - x

    fit = _fit_lag(residual, [], [], [], period, len(x))
    if fit is None:
        return None
    b, b_u, zeta, _, rms = fit
    return b, b_u, zeta, rms


def _impedance_response(b: float, zeta: float, w: FloatArray, period: float) -> FloatArray:
    """Positions at the samples of x'' = (w - x) / a - (b / a) x', a = (b / (2 zeta))^2,
    from rest at w[0]; w a straight line between samples (exact discretization)."""
    a = (b / (2.0 * zeta)) ** 2
    m = np.zeros((4, 4))
    m[0, 1] = 1.0
    m[1, 0], m[1, 1], m[1, 2] = -1.0 / a, -b / a, 1.0 / a
    m[2, 3] = 1.0  # the drive's slope, constant over a period
    e = _expm(m * period)
    phi, g0, g1 = e[:2, :2], e[:2, 2], e[:2, 3]
    z = np.array([w[0], 0.0])
    out = np.empty(len(w))
    out[0] = z[0]
    for i in range(1, len(w)):
        z = phi @ z + g0 * w[i - 1] + g1 * (w[i] - w[i - 1]) / period
        out[i] = z[0]
    return out


def _expm(m: FloatArray) -> FloatArray:
    """The matrix exponential of a small (n, n) matrix: a Taylor series after scaling by a
    power of two, then squared back (scipy's expm costs a millisecond or more per call on
    a 4 x 4, and the fit calls this hundreds of times)."""
    norm = float(np.max(np.sum(np.abs(m), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = m / (2.0**squarings)
    term = np.eye(len(m))
    out = term.copy()
    for i in range(1, 13):
        term = term @ a / i
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out
