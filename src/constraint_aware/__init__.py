"""constraint-aware: the constraint-aware policy for compliant manipulation (Saito et al.)."""

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
