"""Native batched Gymnasium ``VectorEnv``: N aircraft in ONE batched :class:`FixedWingEnv` (one
simulator stepping all N at once, not N copies of a single env).

    import gymnasium as gym
    import falcon_rl  # registers falcon_rl/<Task>-v0 with this class as vector_entry_point
    envs = gym.make_vec("falcon_rl/Altitude-v0", num_envs=256, vectorization_mode="vector_entry_point")
    obs, info = envs.reset(seed=0)                                     # obs [N, D] float32
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())   # action [N, A]

Autoreset: ``AutoresetMode.SAME_STEP`` (``metadata["autoreset_mode"]``), as TorchRL's
``step_and_maybe_reset`` does it. On the step where env i terminates or truncates, ``terminated[i]`` /
``truncated[i]`` and ``reward[i]`` are those of the last transition, ``obs[i]`` is already the first
observation of its next episode (what a reset at that point gives), and ``info["final_obs"][i]``
([N] object array, ``info["_final_obs"]`` [N] bool mask) and ``info["final_info"]`` (task entries of
the last transition, masked likewise) hold the end of the finished episode.

Infos follow Gymnasium's vector convention: ``info[key]`` is an [N, ...] array of the task's
("task", key) entry with mask ``info["_" + key]`` [N] bool. ``reset(seed=s)`` reseeds the batch's
streams (env, simulator, robustness transforms): the same ``s`` gives the same episodes, and the
sub-envs draw distinct values of those streams; ``seed=None`` continues them (fresh OS entropy at
construction unless a ``seed`` is given). ``reset(options={"reset_mask": mask})`` resets only the
rows of ``mask`` [N] bool (the other rows keep their observation; their info entries are masked
out). Keyword arguments are those of :func:`falcon_rl.envs.make_env`; the backend defaults to
"warp"; ``max_episode_steps`` (passed by ``make_vec`` from the registered spec) truncates at the
smaller of it and the env's own horizon, as ``gymnasium.make``'s TimeLimit does.

Speed: without robustness options the batch steps through the env's tensor core
(:class:`~falcon_rl.envs.gym.core.TensorCore`: no TensorDicts, host arrays from one device-to-host
copy per step); ``fast_path=False``, or any robustness option (a ``TransformedEnv``), steps through
TorchRL's ``step_and_maybe_reset``, which runs the transforms. Both give the same numbers
(tests/test_gym_vector.py steps them side by side).
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from ...defaults import DEFAULT_AIRFRAME
from ...transforms import flight_env
from . import DEFAULT_BACKEND, action_tensor, as_action, build_env, reseed, single_spaces, task_arrays
from .core import TensorCore, Transition, tensor_core_env
from .render import GymRenderer

#: The most sub-envs a vector env renders (one chase view each).
MAX_RENDERED_ENVS = 16


class FalconVectorEnv(VectorEnv):
    """N aircraft of one task in one batched simulator behind the Gymnasium vector API (see the module
    docstring): observation space [N, D], action space [N, A], float32 Boxes."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.SAME_STEP,  # noqa: RUF012 (gymnasium's)
                                "render_modes": ["rgb_array"]}

    def __init__(self, num_envs: int = 1, task: str = "altitude", airframe: str = DEFAULT_AIRFRAME,
                 backend: str = DEFAULT_BACKEND, device: str = "cpu", seed: int | None = None,
                 max_episode_steps: int | None = None, fast_path: bool = True,
                 render_mode: str | None = None, **options: Any):
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"the vector env renders with render_mode='rgb_array' only, got {render_mode!r}")
        if render_mode is not None and int(num_envs) > MAX_RENDERED_ENVS:
            raise ValueError(f"render_mode with {num_envs} envs: at most {MAX_RENDERED_ENVS} are rendered "
                             "(record the flight with RecordFlightVector and animate the recording instead)")
        self.num_envs = int(num_envs)
        self.env, self.build_seed = build_env(task, airframe, self.num_envs, backend, device, seed, options)
        self.single_observation_space, self.single_action_space = single_spaces(self.env)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        base = flight_env(self.env, "max_episode_steps")
        if max_episode_steps is not None and 0 < int(max_episode_steps) < base.max_episode_steps:
            base.max_episode_steps = int(max_episode_steps)
        #: Env steps after which an episode is truncated.
        self.max_episode_steps: int = base.max_episode_steps
        self._obs_dim = int(self.single_observation_space.shape[0])
        self._action_dim = int(self.single_action_space.shape[0])
        core = tensor_core_env(self.env) if fast_path else None
        #: The tensor core stepping the batch, or None (TorchRL's ``step_and_maybe_reset``).
        self.core: TensorCore | None = None if core is None else TensorCore(core)
        self._data: Any = None  # the TorchRL path's current TensorDict
        self._started = False
        #: Gymnasium's render mode; one view per sub-env, built only when rendering (``gym.render``).
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": 1.0 / base.control_dt}
        self._renderers = [] if render_mode is None else [
            GymRenderer(render_mode, base, [e], self.metadata["render_fps"]) for e in range(self.num_envs)]

    # ------------------------------------------------------------------ Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        """(observation [N, D] float32, info); see the module docstring for ``seed`` and
        ``options={"reset_mask": [N] bool}`` (the only option)."""
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if options:
            raise ValueError(f"unknown reset options {sorted(options)}; the only one is 'reset_mask'")
        if seed is not None and not isinstance(seed, int | np.integer):
            raise ValueError(f"seed must be an int or None (one batched simulator, one stream whose draws "
                             f"differ per sub-env), got {type(seed).__name__}")
        rows = None if mask is None else self._reset_rows(mask)
        super().reset(seed=None if seed is None else int(seed))
        if seed is not None:
            reseed(self.env, int(seed))
        self._started = True
        for renderer in self._renderers:
            renderer.observe(np.empty(0, dtype=bool) if rows is None else rows)
        if self.core is not None:
            observation, arrays = self.core.reset(rows)
            return observation, self._info(arrays, rows)
        if rows is None:
            self._data = self.env.reset()
        else:  # the rows not reset keep the current data (TorchRL's maybe_reset)
            self._data.set("_reset", torch.as_tensor(rows, device=self.env.device).reshape(-1, 1))
            self._data = self.env.reset(self._data, select_reset_only=True)
        observation = self._data["observation"].detach().cpu().numpy().astype(np.float32)
        return observation, self._info(task_arrays(self._data), rows)

    def step(self, actions: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """(obs [N, D] float32, reward [N] float64, terminated [N] bool, truncated [N] bool, info) for
        ``actions`` [N, A] (a real float array; anything else raises ValueError before any env moves)."""
        step = self.step_transition(actions)
        info = self._info(step.info)
        done = step.done
        for renderer in self._renderers:
            renderer.observe(done)
        if done.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for row in np.flatnonzero(done):
                final_obs[row] = step.final_observation[row].copy()
            info.update(final_obs=final_obs, _final_obs=done.copy(),
                        final_info=self._info(step.final_info, done), _final_info=done.copy())
        return (step.observation, step.reward.astype(np.float64), step.terminated, step.truncated, info)

    def step_transition(self, actions: object, infos: bool = True) -> Transition:
        """Step every env with ``actions`` [N, A] and autoreset the finished ones (SAME_STEP): the arrays
        of the step from one device-to-host copy; ``infos=False`` lets the TorchRL path skip the task
        entries (``info`` and ``final_info`` are None then; the fast path always has them)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        n, d = self.num_envs, self._obs_dim
        if self.core is not None:
            return self.core.step(action_tensor(actions, n, self._action_dim, "actions"), autoreset=True)
        self._data["action"] = as_action(actions, n, self._action_dim, self.env.action_spec.dtype,
                                         self.env.device, "actions")
        stepped, self._data = self.env.step_and_maybe_reset(self._data)
        nxt = stepped["next"]
        dtype = nxt["observation"].dtype
        flags = [nxt[key].reshape(n, 1).to(dtype) for key in ("reward", "terminated", "truncated")]
        packed = torch.cat([self._data["observation"], nxt["observation"], *flags], dim=-1)
        packed = packed.detach().cpu().numpy()
        return Transition(observation=packed[:, :d].astype(np.float32),
                          final_observation=packed[:, d:2 * d].astype(np.float32),
                          reward=packed[:, 2 * d].copy(), terminated=packed[:, 2 * d + 1] > 0.5,
                          truncated=packed[:, 2 * d + 2] > 0.5,
                          info=task_arrays(self._data) if infos else None,
                          final_info=task_arrays(nxt) if infos else None)

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One frame [H, W, 3] uint8 per sub-env (a chase view of each aircraft) with
        ``render_mode="rgb_array"``; None, with a warning, without a render mode."""
        if not self._renderers:
            gymnasium.logger.warn("render() called on a vector env made without render_mode='rgb_array'")
            return None
        return tuple(renderer.frame() for renderer in self._renderers)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the views and the TorchRL env."""
        for renderer in self._renderers:
            renderer.close()
        self._renderers = []
        self.env.close()

    # ------------------------------------------------------------------ internals
    def _info(self, arrays: dict[str, np.ndarray] | None, rows: np.ndarray | None = None
              ) -> dict[str, np.ndarray]:
        """{key: [N, ...] task entry, "_" + key: [N] bool mask (``rows``, or all)}."""
        mask = np.ones(self.num_envs, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        info: dict[str, np.ndarray] = {}
        for key, value in (arrays or {}).items():
            info[key], info[f"_{key}"] = value, mask.copy()
        return info

    def _reset_rows(self, mask: object) -> np.ndarray:
        """[N] bool rows of a ``reset_mask`` option (ValueError unless an [N] bool array with a True)."""
        if not self._started:
            raise RuntimeError("a partial reset (options['reset_mask']) needs a full reset() first")
        rows = np.asarray(mask)
        if rows.dtype != np.bool_ or rows.shape != (self.num_envs,) or not rows.any():
            raise ValueError(f"options['reset_mask'] must be a [{self.num_envs}] bool array with at least "
                             f"one True, got {rows.dtype} {list(rows.shape)}")
        return rows.copy()


__all__ = ["FalconVectorEnv", "Transition"]
