"""The force dead band: the |F| below which a reading counts as no force (paper 3.3.2).

One home for it. The dead band is not a hand-tuned constant: it is derived from what the robot
measures, the spread of the wrench samples taken for F_d before moving (sensor noise), with a
small floor (the training environment's threshold). Policies, the executor and the card all
use these names.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: [N] floor of the dead band: the training environment's threshold (a measured |F| below it
#: is observed as the zero vector in training, so the policy never acts on less).
MIN_THRESHOLD = 0.2
#: The dead band in standard deviations of the per-axis force noise. The norm of a 3-D Gaussian
#: noise vector exceeds 4 sigma with probability ~0.1 %, so noise alone almost never moves d.
NOISE_SIGMAS = 4.0


def noise_std(force_samples: ArrayLike) -> float:
    """Per-axis standard deviation [N] of wrench force samples (n, 3), pooled over the axes.

    The samples must be taken across time (one fresh or filtered reading per control period),
    not copies of one reading. Fewer than two samples give 0.
    """
    f = np.asarray(force_samples, dtype=float).reshape(-1, 3)
    if f.shape[0] < 2:
        return 0.0
    return float(np.sqrt(np.mean(np.var(f, axis=0, ddof=1))))


def threshold_from_noise(sigma: float) -> float:
    """The dead band [N] for a per-axis force noise `sigma` [N]: max(floor, NOISE_SIGMAS sigma)."""
    if not np.isfinite(sigma) or sigma < 0:
        raise ValueError(f"sigma: must be finite and >= 0 [N], got {sigma}")
    return max(MIN_THRESHOLD, NOISE_SIGMAS * float(sigma))
