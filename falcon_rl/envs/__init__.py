"""TorchRL environments: :class:`FixedWingEnv` and the flight tasks, built by :func:`make_env`."""

from __future__ import annotations

from .factory import make_env
from .fixed_wing import STATE_KEYS, FixedWingEnv, FixedWingEnvConfig
from .gym import GYM_IDS, CoreAircraftEnv, register_gym_envs
from .tasks import TASKS, Task, TaskConfig, TaskSpec, register_task, task_spec

register_gym_envs()

__all__ = ["GYM_IDS", "STATE_KEYS", "TASKS", "CoreAircraftEnv", "FixedWingEnv", "FixedWingEnvConfig", "Task",
           "TaskConfig", "TaskSpec", "make_env", "register_gym_envs", "register_task", "task_spec"]
