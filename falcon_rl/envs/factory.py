"""The :func:`make_env` factory: a :class:`FixedWingEnv` for a task, under the robustness transforms
asked for."""

from __future__ import annotations

from dataclasses import fields, replace

from torchrl.envs import Compose, EnvBase, TransformedEnv

from ..defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ..transforms.presets import robustness_transforms
from .fixed_wing import FixedWingEnv, FixedWingEnvConfig
from .tasks import task_spec


def unknown_options(task: str, unknown: list[str], env_fields: set[str], task_fields: set[str]) -> TypeError:
    """The ``TypeError`` for options ``make_env`` does not know, worded as Python words it for a function
    ("got an unexpected keyword argument 'frameskip'"): clients that probe a keyword and drop it when
    refused (TorchRL's ``GymEnv`` does so with ``frameskip``) read that phrase."""
    names = ", ".join(repr(name) for name in unknown)
    got = "an unexpected keyword argument" if len(unknown) == 1 else "unexpected keyword arguments"
    return TypeError(f"make_env() got {got} {names} (task {task!r}); env options: {sorted(env_fields)}, "
                     f"task options: {sorted(task_fields)}")


def make_env(task: str, airframe: str = DEFAULT_AIRFRAME, num_envs: int = 1, backend: str = DEFAULT_BACKEND,
             device: str = "cpu", seed: int | None = None, *, sensors: object = None,
             obs_delay_ms: object = None, action_delay_ms: object = None, randomize: object = None,
             normalize: bool = False, **options) -> EnvBase:
    """Build a :class:`FixedWingEnv` for ``task`` (a registered task, see ``task_spec``) on ``airframe``.

    ``backend``: one of ``defaults.BATCH_BACKENDS``; the default (``DEFAULT_BACKEND``) is the fastest.
    ``seed``: None draws fresh entropy (two unseeded envs differ); an int makes the env and its
    transforms reproducible (``env.set_seed`` / ``reset(seed=)`` reseed them all).

    ``options`` name fields of :class:`FixedWingEnvConfig` (dt, decimation, integrator,
    ground_effect, wind, turbulence, model: the switches of ``falcon_rl.physics.switches``, dtype,
    compile, warp_cpu_threads, lean) or of the task's config dataclass (episode_seconds,
    target_altitudes, maneuver, reward weights, ...); an unknown name raises ``TypeError``. What is not
    given takes the task's defaults (``task_spec(task).defaults``: 20 Hz control and the reward
    settings the recipes train with), then the config dataclasses' own.

    ``normalize=True`` appends TorchRL's ``ObservationNorm`` on "observation", its statistics
    initialised from a short random-action rollout of the env (see :func:`add_observation_norm`).

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
        raise unknown_options(task, sorted(unknown), env_fields, task_fields)
    spec = task_spec(task)
    task_config = options.pop("task_config", None)
    task_options = {k: v for k, v in options.items() if k in task_fields and k not in env_fields}
    task_config = (spec.default_config(**task_options) if task_config is None
                   else replace(task_config, **task_options))
    env_options = {k: v for k, v in options.items() if k in env_fields}
    config = FixedWingEnvConfig(task=task, airframe=airframe, num_envs=num_envs, backend=backend,
                                device=str(device), seed=seed, task_config=task_config, **env_options)
    env = FixedWingEnv(config)
    transforms = robustness_transforms(sensors, obs_delay_ms, action_delay_ms, randomize, seed=seed)
    if normalize:
        return add_observation_norm(TransformedEnv(env, Compose(*transforms)))
    return TransformedEnv(env, Compose(*transforms)) if transforms else env


def add_observation_norm(env: EnvBase, frames: int = 1000, min_std: float = 1e-2) -> TransformedEnv:
    """Append TorchRL's ``ObservationNorm`` on "observation" to ``env`` and initialise its loc and
    scale from ``frames`` env-steps of uniform random actions, over the batch and time dims
    (``init_stats(num_iter, reduce_dim=(0, 1), cat_dim=1)``: the statistics are
    per observation entry [D]); scales below ``min_std`` are raised to it (channels that barely move
    under random actions). The env is reset afterwards. Returns the transformed env."""
    from torchrl.envs import ObservationNorm

    if not isinstance(env, TransformedEnv):
        env = TransformedEnv(env)
    norm = ObservationNorm(in_keys=["observation"], standard_normal=True)
    env.append_transform(norm)
    norm.init_stats(num_iter=max(1, int(frames)), reduce_dim=(0, 1), cat_dim=1)  # num_iter counts frames
    norm.scale.data.clamp_min_(min_std)
    env.reset()
    return env


__all__ = ["add_observation_norm", "make_env", "unknown_options"]
