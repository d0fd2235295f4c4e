"""MuJoCo worlds: the five tasks on two embodiments (the hook hand, the Kinova Jaco arm).

`make_embodiment(robot, task)` builds either by name (`EMBODIMENTS`; robot specs such as
"jaco:stiffness=5000" select variants); both satisfy the executor's `Robot` and `TaskMonitor`
protocols. Names are resolved on first use, so importing `constraint_aware.sim.tasks` (and the
package) does not import MuJoCo.
"""

from __future__ import annotations

from constraint_aware.lazy import lazy_getattr

_EXPORTS = {
    "DEFAULT_ROBOT": "embodiment",
    "EMBODIMENTS": "embodiment",
    "Embodiment": "base",
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

__getattr__ = lazy_getattr(__name__, _EXPORTS)
