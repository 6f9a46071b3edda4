"""The :func:`make_env` factory: a :class:`FixedWingEnv` for a task, under the robustness transforms
asked for."""

from __future__ import annotations

from dataclasses import fields, replace

from torchrl.envs import Compose, EnvBase, TransformedEnv

from ..transforms.presets import robustness_transforms
from .fixed_wing import FixedWingEnv, FixedWingEnvConfig
from .tasks import task_spec


def make_env(task: str, airframe: str = "navion", num_envs: int = 1, backend: str = "torch",
             device: str = "cpu", seed: int = 0, *, sensors: object = None, obs_delay_ms: object = None,
             action_delay_ms: object = None, randomize: object = None, **options) -> EnvBase:
    """Build a :class:`FixedWingEnv` for ``task`` (a registered task, see ``task_spec``) on ``airframe``.

    ``options`` name fields of :class:`FixedWingEnvConfig` (dt, decimation, integrator,
    ground_effect, wind, turbulence, model: the switches of ``falcon_rl.physics.switches``) or of
    the task's config dataclass (episode_seconds, target_altitudes, maneuver, reward weights, ...);
    an unknown name raises ``TypeError``.

    Robustness (all off by default; see :mod:`falcon_rl.transforms`): ``sensors`` (a grid name
    "nominal" | "mild" | "medium" | "severe" or a SensorConfig), ``obs_delay_ms`` and
    ``action_delay_ms`` (a grid name, milliseconds, or a (low, high) range drawn per episode),
    ``randomize`` (True or a RandomizationConfig), ``turbulence`` (MIL or grid name, sigma_u/V_a,
    or a TurbulenceConfig) and ``wind`` (NED, m/s). With any transform on, the result is a
    ``TransformedEnv`` over the FixedWingEnv (``env.base_env``).
    """
    task_config_cls = task_spec(task).config
    env_fields = {f.name for f in fields(FixedWingEnvConfig)}
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
    env = FixedWingEnv(config)
    transforms = robustness_transforms(sensors, obs_delay_ms, action_delay_ms, randomize, seed=seed)
    return TransformedEnv(env, Compose(*transforms)) if transforms else env


__all__ = ["make_env"]
