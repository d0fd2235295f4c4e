"""constraint-aware: the constraint-aware policy for compliant manipulation (Saito et al.)."""

import os as _os

# Offscreen rendering must choose its GL backend before MuJoCo is first imported; without a
# display, EGL is the one that works on a headless machine with no extra package.
if "MUJOCO_GL" not in _os.environ and not _os.environ.get("DISPLAY"):
    _os.environ["MUJOCO_GL"] = "egl"

from constraint_aware.errors import CapError, InvalidInputError, PolicyFileError, UnknownNameError
from constraint_aware.policy import ConstraintAwarePolicy

__version__ = "0.1.0"

__all__ = [
    "CapError",
    "ConstraintAwarePolicy",
    "InvalidInputError",
    "PolicyFileError",
    "UnknownNameError",
    "__version__",
]
