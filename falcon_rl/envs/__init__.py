"""TorchRL environments: :class:`FixedWingEnv` and the flight tasks, built by :func:`make_env`."""

from __future__ import annotations

from dataclasses import fields, replace

from .fixed_wing import STATE_KEYS, FixedWingEnv, FixedWingEnvConfig
from .gym import GYM_IDS, CoreAircraftEnv, register_gym_envs
from .tasks import TASKS, Task, TaskConfig


def make_env(task: str, airframe: str = "navion", num_envs: int = 1, backend: str = "torch",
             device: str = "cpu", seed: int = 0, **options) -> FixedWingEnv:
    """Build a :class:`FixedWingEnv` for ``task`` (one of ``TASKS``) on ``airframe``.

    ``options`` name fields of :class:`FixedWingEnvConfig` (dt, decimation, integrator,
    ground_effect, wind) or of the task's config dataclass (episode_seconds, target_altitudes,
    maneuver, reward weights, ...); an unknown name raises ``TypeError``.
    """
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; choose one of {sorted(TASKS)}")
    env_fields = {f.name for f in fields(FixedWingEnvConfig)}
    _, task_config_cls = TASKS[task]
    task_fields = {f.name for f in fields(task_config_cls)}
    unknown = set(options) - env_fields - task_fields
    if unknown:
        raise TypeError(f"unknown options {sorted(unknown)} for task {task!r}; env options: "
                        f"{sorted(env_fields)}, task options: {sorted(task_fields)}")
    task_config = options.pop("task_config", None) or task_config_cls()
    task_options = {k: v for k, v in options.items() if k in task_fields and k not in env_fields}
    task_config = replace(task_config, **task_options)
    env_options = {k: v for k, v in options.items() if k in env_fields}
    config = FixedWingEnvConfig(task=task, airframe=airframe, num_envs=num_envs, backend=backend,
                                device=str(device), seed=seed, task_config=task_config, **env_options)
    return FixedWingEnv(config)


register_gym_envs()

__all__ = ["GYM_IDS", "STATE_KEYS", "TASKS", "CoreAircraftEnv", "FixedWingEnv", "FixedWingEnvConfig", "Task",
           "TaskConfig", "make_env", "register_gym_envs"]
