"""constraint-aware: the constraint-aware policy for compliant manipulation (Saito et al.).

Importing the package has no side effects beyond registering its Gymnasium environments by
name (string entry points: nothing heavy is imported); no environment variable, no matplotlib
backend, no GL choice (see `constraint_aware.sim.render` for when the GL backend is chosen).
"""

from constraint_aware.envs import register_envs as _register_envs
from constraint_aware.errors import CapError, InvalidInputError, PolicyFileError, UnknownNameError
from constraint_aware.policy import ConstraintAwarePolicy
from constraint_aware.version import __version__

_register_envs()  # string entry points only: nothing heavy is imported here

__all__ = [
    "CapError",
    "ConstraintAwarePolicy",
    "InvalidInputError",
    "PolicyFileError",
    "UnknownNameError",
    "__version__",
]
