"""MuJoCo worlds: the five tasks on two embodiments (the hook hand, the Kinova Jaco arm).

`make_embodiment(robot, task)` builds either by name (`EMBODIMENTS`; robot specs such as
"jaco:stiffness=5000" select variants); both satisfy the executor's `Robot` and `TaskMonitor`
protocols. Names are resolved on first use, so importing `constraint_aware.sim.tasks` (and the
package) does not import MuJoCo.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "DEFAULT_ROBOT": "embodiment",
    "EMBODIMENTS": "embodiment",
    "Embodiment": "embodiment",
    "RobotSpec": "embodiment",
    "make_embodiment": "embodiment",
    "parse_robot": "embodiment",
    "JacoSim": "jaco",
    "OscConfig": "jaco",
    "TASKS": "tasks",
    "TaskConfig": "tasks",
    "task_config": "tasks",
    "ManipulationSim": "world",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'constraint_aware.sim' has no attribute {name!r}")
    return getattr(importlib.import_module(f"constraint_aware.sim.{_EXPORTS[name]}"), name)
