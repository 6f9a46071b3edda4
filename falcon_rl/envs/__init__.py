"""TorchRL environments: :class:`FixedWingEnv` and the flight tasks, built by :func:`make_env`.

The public names load on first use (PEP 562): importing this package imports Gymnasium only, and
registers the built-in tasks' Gymnasium ids with the entry points, kwargs and ``max_episode_steps`` that
:func:`register_gym_envs` gives them (a Gymnasium entry point is a string, imported by ``gym.make``).
Tasks registered later get their ids when ``register_gym_envs()`` runs again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import gymnasium

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .factory import make_env
    from .fixed_wing import STATE_KEYS, FixedWingEnv, FixedWingEnvConfig
    from .gym import GYM_IDS, CoreAircraftEnv, register_gym_envs
    from .gym.recorder import RecordFlight, RecordFlightVector
    from .tasks import Task, TaskConfig, TaskSpec, register_task, task_spec

#: Public name -> the submodule that defines it.
_LAZY = {"make_env": "factory", "STATE_KEYS": "fixed_wing", "FixedWingEnv": "fixed_wing",
         "FixedWingEnvConfig": "fixed_wing", "GYM_IDS": "gym", "CoreAircraftEnv": "gym",
         "register_gym_envs": "gym", "Task": "tasks", "TaskConfig": "tasks",
         "TaskSpec": "tasks", "register_task": "tasks", "task_spec": "tasks",
         "RecordFlight": "gym.recorder", "RecordFlightVector": "gym.recorder"}

#: The built-in tasks' Gymnasium registrations, task -> (id, max_episode_steps), as ``register_gym_envs``
#: makes them from the task registry (tests/test_startup.py checks that they agree).
BUILTIN_GYM_IDS: dict[str, tuple[str, int]] = {
    "altitude": ("falcon_rl/Altitude-v0", 600),
    "attitude": ("falcon_rl/Attitude-v0", 600),
    "climb_descend": ("falcon_rl/ClimbDescend-v0", 1200),
    "landing": ("falcon_rl/Landing-v0", 1200),
    "path_following": ("falcon_rl/PathFollowing-v0", 800),
    "sea_skimming": ("falcon_rl/SeaSkimming-v0", 600),
    "trajectory": ("falcon_rl/Trajectory-v0", 800),
}
_ENTRY_POINT = "falcon_rl.envs.gym:CoreAircraftEnv"
_VECTOR_ENTRY_POINT = "falcon_rl.envs.gym.vector:FalconVectorEnv"

__all__ = ["BUILTIN_GYM_IDS", "GYM_IDS", "STATE_KEYS", "CoreAircraftEnv", "FixedWingEnv",
           "FixedWingEnvConfig", "RecordFlight", "RecordFlightVector", "Task",
           "TaskConfig", "TaskSpec", "make_env", "register_gym_envs",
           "register_task", "task_spec"]


def _register_builtin_gym_ids() -> None:
    """Register the built-in tasks' Gymnasium ids without importing torch (ids already known are kept)."""
    for task, (gym_id, steps) in BUILTIN_GYM_IDS.items():
        if gym_id not in gymnasium.registry:
            gymnasium.register(id=gym_id, entry_point=_ENTRY_POINT, vector_entry_point=_VECTOR_ENTRY_POINT,
                               max_episode_steps=steps, kwargs={"task": task})


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)


_register_builtin_gym_ids()
