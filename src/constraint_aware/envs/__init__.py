"""Gymnasium environments, registered by name on `import constraint_aware`.

- `constraint_aware/SingleSystem-v0`: the paper's training environment (one composite body on
  a prismatic joint); `gym.make_vec(..., vectorization_mode="vector_entry_point")` gives its
  batched twin (`envs.single_system_vector.SingleSystemVectorEnv`, all episodes in one numpy batch).
- `constraint_aware/DrawerOpening-v0`, `PlateSliding-v0`, `PolePulling-v0`, `DoorOpening-v0`,
  `HandleRotating-v0`: the five simulated tasks, one executor control period per step
  (`envs.task.TaskEnv`; its docstring is the manual).

Registration uses string entry points only: nothing heavy (MuJoCo, torch) is imported until an
environment is made.
"""

from __future__ import annotations

import gymnasium as gym

from constraint_aware.sim.tasks import TASKS

SINGLE_SYSTEM_ID = "constraint_aware/SingleSystem-v0"


def task_env_id(task: str) -> str:
    """`drawer-opening` -> `constraint_aware/DrawerOpening-v0`."""
    return "constraint_aware/" + "".join(w.capitalize() for w in task.split("-")) + "-v0"


TASK_ENV_IDS: dict[str, str] = {name: task_env_id(name) for name in TASKS}
ENV_IDS: tuple[str, ...] = (SINGLE_SYSTEM_ID, *TASK_ENV_IDS.values())


def register_envs() -> None:
    """Register every environment with Gymnasium (idempotent)."""
    if SINGLE_SYSTEM_ID not in gym.registry:
        gym.register(
            id=SINGLE_SYSTEM_ID,
            entry_point="constraint_aware.envs.single_system:SingleSystemGymEnv",
            vector_entry_point="constraint_aware.envs.single_system_vector:SingleSystemVectorEnv",
        )
    for task, env_id in TASK_ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point="constraint_aware.envs.task:TaskEnv",
                kwargs={"task": task},
            )


__all__ = ["ENV_IDS", "SINGLE_SYSTEM_ID", "TASK_ENV_IDS", "register_envs", "task_env_id"]
