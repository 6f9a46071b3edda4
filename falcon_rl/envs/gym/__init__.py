"""Gymnasium wrapper: one aircraft, NumPy in and out, for Stable-Baselines3 and other Gym users.

    import gymnasium as gym  # registers falcon_rl/<Task>-v0 (falcon_rl_gymnasium_hook; or import falcon_rl)
    env = gym.make("falcon_rl/Altitude-v0", airframe="volantex_ranger")
    obs, info = env.reset(seed=0)
    envs = gym.make_vec("falcon_rl/Altitude-v0", num_envs=256, vectorization_mode="vector_entry_point")

Registered ids: each task's ``TaskSpec.gym_id`` (falcon_rl/Altitude-v0, falcon_rl/Attitude-v0,
falcon_rl/ClimbDescend-v0, falcon_rl/PathFollowing-v0, falcon_rl/Trajectory-v0, falcon_rl/SeaSkimming-v0,
falcon_rl/Landing-v0, and any task registered later once ``register_gym_envs()`` runs again), each with a
``vector_entry_point`` (one batched simulator, :class:`falcon_rl.envs.gym.vector.FalconVectorEnv`) and
``max_episode_steps`` = the task's default horizon (episode_seconds / control period of the default
configs). Keyword arguments are those of :func:`falcon_rl.envs.make_env` (airframe, backend, device, seed
and task or env options); the backend defaults to ``defaults.DEFAULT_BACKEND``.

Horizon: the env truncates at its own horizon (episode_seconds / (dt x decimation)) and
``gymnasium.make`` adds ``TimeLimit(max_episode_steps)``; both count from the same reset, so with the
default options they truncate at the same step, and otherwise the episode ends at the smaller of the
two (``make_vec`` applies the same rule). Options that lengthen the horizon (episode_seconds, dt,
decimation) therefore need ``max_episode_steps`` as well (or ``max_episode_steps=-1`` in ``make``).

Seeding: ``seed=None`` (the default) draws fresh OS entropy when the env is built, so the first
``reset()`` without a seed differs run to run; ``reset(seed=s)`` reseeds the env, the simulator and
the robustness transforms, so the same ``s`` gives the same episodes. Actions follow the action
contract (``falcon_rl.transforms.action_check``): shape [A] exactly, a real float
dtype; anything else raises a one-line ValueError before the env moves. ``info`` carries the task's
references and errors (("task", ...) keys) and the env's ``termination_reason`` (an index into
``TERMINATION_REASONS``) as numbers or arrays.

Speed: an env without robustness options steps through the env's tensor core
(:mod:`falcon_rl.envs.gym.core`, no TensorDicts; ``fast_path=False`` turns it off), one with them
through TorchRL's step, which runs the transforms; both give the same numbers.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from tensordict import TensorDict, TensorDictBase
from torchrl.envs import EnvBase

from ...defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ...physics.engine import fresh_seed
from ...transforms.action_check import refuse_bad_action
from ..tasks.registry import TASK_SPECS, SpecView, task_spec
from .render import RENDER_MODES, GymRenderer, available_render_modes, check_render_mode

#: Task name -> Gymnasium id (a live, read-only view of the task registry).
GYM_IDS: SpecView[str] = SpecView(lambda spec: spec.gym_id)

#: Entry points registered for every task.
ENTRY_POINT: str = "falcon_rl.envs.gym:CoreAircraftEnv"
VECTOR_ENTRY_POINT: str = "falcon_rl.envs.gym.vector:FalconVectorEnv"


def build_env(task: str, airframe: str, num_envs: int, backend: str, device: str, seed: int | None,
              options: dict[str, Any]) -> tuple[EnvBase, int]:
    """(the TorchRL env of ``make_env`` with batch [num_envs], the int seed it was built with)."""
    from ..factory import make_env

    seed = fresh_seed() if seed is None else int(seed)
    env = make_env(task, airframe, num_envs=num_envs, backend=backend, device=device, seed=seed, **options)
    return env, seed


def single_spaces(env: EnvBase) -> tuple[spaces.Box, spaces.Box]:
    """(observation space [D], action space [A]) of one aircraft of ``env``, float32 Boxes."""
    def box(spec: Any) -> spaces.Box:
        low, high = (bound[0].detach().cpu().numpy().astype(np.float32) for bound in (spec.low, spec.high))
        return spaces.Box(low, high, dtype=np.float32)

    return box(env.observation_spec["observation"]), box(env.action_spec)


def float_array(action: object, num_envs: int, action_dim: int, name: str = "action") -> np.ndarray:
    """``action`` as a NumPy array of a real floating dtype (no copy when it is one), or the action
    contract's one-line ValueError naming the expected shape [N, A]."""
    array = np.asarray(action)
    if array.dtype.kind != "f":
        raise ValueError(f"{name} must be a real floating array of shape [{num_envs}, {action_dim}], "
                         f"got dtype {array.dtype}")
    return array


def action_tensor(action: object, num_envs: int, action_dim: int, name: str = "action") -> torch.Tensor:
    """An [N, A] real floating tensor of ``action`` (a view of a writeable C-contiguous array, else a
    copy; not yet cast, clamped or moved), or a one-line ValueError: not a numeric array, a bool,
    integer or complex dtype, or a shape other than [N, A] (the action contract's refusals)."""
    if isinstance(action, torch.Tensor):
        tensor = action
    else:
        array = float_array(action, num_envs, action_dim, name)
        if not (array.flags.writeable and array.flags.c_contiguous):
            array = np.array(array)
        try:
            tensor = torch.from_numpy(array)
        except TypeError:
            raise ValueError(f"{name} must be a real floating array, got dtype {array.dtype}") from None
    refuse_bad_action(tensor, num_envs, action_dim, name)
    return tensor


def as_action(action: object, num_envs: int, action_dim: int, dtype: torch.dtype, device: torch.device,
              name: str = "action") -> torch.Tensor:
    """[N, A] ``dtype`` tensor on ``device`` from an array-like ``action`` [N, A] (the action contract,
    :func:`action_tensor`'s refusals). Infinities are clamped to [-1, 1]; a NaN is passed on for the
    env to flag (it terminates that env)."""
    return action_tensor(action, num_envs, action_dim, name).to(device=device, dtype=dtype).clamp(-1.0, 1.0)


def reseed(env: EnvBase, seed: int) -> None:
    """Seed ``env`` with ``seed``: the env's and the simulator's streams, and the robustness transforms
    over it, which derive their own streams from the base env's seed record (as ``make_env(seed=)``)."""
    env.set_seed(int(seed))


def first_row(arrays: dict[str, np.ndarray]) -> dict[str, Any]:
    """The single env's info of entry arrays [1] or [1, ...]: a Python number per scalar entry, the
    row [...] of a wider one."""
    return {key: array[0].item() if array.ndim == 1 else array[0] for key, array in arrays.items()}


def task_arrays(data: TensorDictBase) -> dict[str, np.ndarray]:
    """{name: [N] or [N, k] array}: the ("task", ...) entries of ``data`` and its "termination_reason"
    when present (fresh copies; a scalar entry [N, 1] comes out as [N])."""
    task, reason = data.get("task", None), data.get("termination_reason", None)
    entries = {} if task is None else dict(task.items())
    if reason is not None:
        entries["termination_reason"] = reason
    n = data.batch_size[0]
    return {key: np.array(value.detach().reshape(n, -1).squeeze(-1).cpu().numpy()) if value[0].numel() == 1
            else np.array(value.detach().cpu().numpy()) for key, value in entries.items()}


def default_max_episode_steps(task: str) -> int:
    """Env steps in an episode of ``task`` built with its defaults (the task's ``defaults`` over the
    config dataclasses; the registered ``max_episode_steps``): episode_seconds / (dt x decimation), as
    :class:`FixedWingEnv` counts them."""
    from ..fixed_wing import FixedWingEnvConfig

    spec, config = task_spec(task), FixedWingEnvConfig()
    decimation = config.decimation if config.decimation is not None else spec.env_default("decimation", 1)
    control_dt = spec.env_default("dt", config.dt) * decimation
    return max(1, round(spec.default_config().episode_seconds / control_dt))


class CoreAircraftEnv(gymnasium.Env):
    """A single-aircraft :class:`FixedWingEnv` behind the Gymnasium API (float32 Box spaces [D], [A]).

    ``fast_path`` (the default) steps an env with no TorchRL transform over it through its tensor core
    (:class:`~falcon_rl.envs.gym.core.TensorCore`: no TensorDicts, one host copy per step); False, or
    any robustness option (a ``TransformedEnv``), steps through TorchRL's ``step``. Both give the same
    numbers (tests/test_gym.py steps both side by side)."""

    #: Every mode the class knows; an instance lists those that work here (no "human" when headless).
    metadata: dict[str, Any] = {"render_modes": list(RENDER_MODES)}  # noqa: RUF012 (gymnasium's)

    def __init__(self, task: str = "altitude", airframe: str = DEFAULT_AIRFRAME,
                 backend: str = DEFAULT_BACKEND,
                 device: str = "cpu", seed: int | None = None, fast_path: bool = True,
                 render_mode: str | None = None, **options: Any):
        from .core import TensorCore, tensor_core_env

        check_render_mode(render_mode)
        self.env, self.build_seed = build_env(task, airframe, 1, backend, device, seed, options)
        base = getattr(self.env, "base_env", self.env)
        self.metadata = {**self.metadata, "render_modes": available_render_modes(),
                         "render_fps": 1.0 / base.control_dt}
        #: Gymnasium's render mode; the view is built only when there is one (see ``gym.render``).
        self.render_mode = render_mode
        self._renderer: GymRenderer | None = None if render_mode is None else GymRenderer(
            render_mode, base, [0], self.metadata["render_fps"])
        self.observation_space, self.action_space = single_spaces(self.env)
        self._action_dtype = self.env.action_spec.dtype
        self._action_dim = int(self.action_space.shape[0])
        core = tensor_core_env(self.env) if fast_path else None
        #: The tensor core stepping the env, or None (TorchRL's step).
        self.core: TensorCore | None = None if core is None else TensorCore(core)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """(observation [D] float32, info); ``seed`` reseeds every stream (see the module docstring).
        The env takes no reset options (an unknown one raises ValueError)."""
        if options:
            raise ValueError(f"unknown reset options {sorted(options)}: the falcon_rl envs take none")
        super().reset(seed=seed)
        if seed is not None:
            reseed(self.env, seed)
        if self.core is not None:
            observation, arrays = self.core.reset()
            info = first_row(arrays)
        else:
            data = self.env.reset()
            observation, info = data["observation"].detach().cpu().numpy().astype(np.float32), first_row(
                task_arrays(data))
        if self._renderer is not None:
            self._renderer.observe(np.empty(0, dtype=bool))
        return observation[0], info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """One control period with ``action`` [A] (refused with ValueError unless [A] real float)."""
        shape = np.shape(action)
        if shape != (self._action_dim,):
            raise ValueError(f"action must have shape [{self._action_dim}], got {list(shape)}")
        fast = None if self.core is None else self.core.numpy_step
        if fast is not None:
            out = fast.step(float_array(action, 1, self._action_dim))
        elif self.core is not None:
            step = self.core.step(action_tensor(np.asarray(action)[None], 1, self._action_dim))
            out = (step.observation[0], step.reward[0].item(), bool(step.terminated[0]),
                   bool(step.truncated[0]), first_row(step.info))
        else:
            action_t = as_action(np.asarray(action)[None], 1, self._action_dim, self._action_dtype,
                                 self.env.device)
            data = self.env.step(TensorDict({"action": action_t}, batch_size=[1],
                                            device=self.env.device))["next"]
            obs = data["observation"][0].detach().cpu().numpy().astype(np.float32)
            out = (obs, float(data["reward"][0, 0]), bool(data["terminated"][0, 0]),
                   bool(data["truncated"][0, 0]), first_row(task_arrays(data)))
        if self._renderer is not None:
            self._renderer.observe()
        return out

    def render(self) -> np.ndarray | None:
        """The current frame [H, W, 3] uint8 with ``render_mode="rgb_array"``; None in human mode (the
        window is drawn at every step) and, with a warning, when the env was made without a mode."""
        if self._renderer is None:
            gymnasium.logger.warn("render() called on an env made without render_mode "
                                  "(make it with render_mode='rgb_array' or 'human')")
            return None
        return self._renderer.frame() if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()


def register_gym_envs() -> list[str]:
    """Register every registered task's gym id with Gymnasium (idempotent: ids already known are
    skipped), with the single-env and the vector entry points and ``max_episode_steps``; returns the
    ids registered by this call."""
    added = []
    for task, spec in TASK_SPECS.items():
        if spec.gym_id not in gymnasium.registry:
            gymnasium.register(id=spec.gym_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT,
                               max_episode_steps=default_max_episode_steps(task), kwargs={"task": task})
            added.append(spec.gym_id)
    return added
