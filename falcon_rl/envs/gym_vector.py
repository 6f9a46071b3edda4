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
rows of ``mask`` [N] bool. Keyword arguments are those of :func:`falcon_rl.envs.make_env`; the
backend defaults to "warp"; ``max_episode_steps`` (passed by ``make_vec`` from the registered spec)
truncates at the smaller of it and the env's own horizon, as ``gymnasium.make``'s TimeLimit does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from tensordict import TensorDict, TensorDictBase

from ..transforms import flight_env
from .gym import DEFAULT_BACKEND, as_action, build_env, reseed, single_spaces, task_arrays


@dataclass(frozen=True)
class Transition:
    """One step of the batch as host arrays (N envs, D observation entries), plus the env's data."""

    #: [N, D] float32 after the autoreset: the next episode's first observation where ``done``.
    observation: np.ndarray
    #: [N, D] float32 before the autoreset (equal to ``observation`` where not ``done``).
    final_observation: np.ndarray
    #: [N] in the simulation's float dtype (float32 unless the env was built with float64).
    reward: np.ndarray
    #: [N] bool each.
    terminated: np.ndarray
    truncated: np.ndarray
    #: The env's ("next") data of the step, batch [N], before the autoreset.
    stepped: TensorDictBase
    #: The data after the autoreset, batch [N] (the next step starts from it).
    current: TensorDictBase

    @property
    def done(self) -> np.ndarray:
        """[N] bool: terminated or truncated (the rows that were reset)."""
        return self.terminated | self.truncated


class FalconVectorEnv(VectorEnv):
    """N aircraft of one task in one batched simulator behind the Gymnasium vector API (see the module
    docstring): observation space [N, D], action space [N, A], float32 Boxes."""

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.SAME_STEP,  # noqa: RUF012 (gymnasium's)
                                "render_modes": []}

    def __init__(self, num_envs: int = 1, task: str = "altitude", airframe: str = "navion",
                 backend: str = DEFAULT_BACKEND, device: str = "cpu", seed: int | None = None,
                 max_episode_steps: int | None = None, **options: Any):
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
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
        self._data: TensorDictBase | None = None

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
        if rows is None:
            self._data = self.env.reset()
        else:
            request = TensorDict({"_reset": torch.as_tensor(rows, device=self.env.device).reshape(-1, 1)},
                                 batch_size=[self.num_envs], device=self.env.device)
            self._data = self.env.reset(request)
        observation = self._data["observation"].detach().cpu().numpy().astype(np.float32)
        return observation, self._info(self._data, rows)

    def step(self, actions: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """(obs [N, D] float32, reward [N] float64, terminated [N] bool, truncated [N] bool, info) for
        ``actions`` [N, A] (a real float array; anything else raises ValueError before any env moves)."""
        step = self.step_transition(actions)
        info = self._info(step.current)
        done = step.done
        if done.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for row in np.flatnonzero(done):
                final_obs[row] = step.final_observation[row].copy()
            info.update(final_obs=final_obs, _final_obs=done.copy(),
                        final_info=self._info(step.stepped, done), _final_info=done.copy())
        return (step.observation, step.reward.astype(np.float64), step.terminated, step.truncated, info)

    def step_transition(self, actions: object) -> Transition:
        """Step every env with ``actions`` [N, A] and autoreset the finished ones (SAME_STEP); the
        arrays of the step in one device-to-host copy, and no info dictionaries."""
        if self._data is None:
            raise RuntimeError("call reset() before step()")
        n, d = self.num_envs, self._obs_dim
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
                          truncated=packed[:, 2 * d + 2] > 0.5, stepped=nxt, current=self._data)

    def close_extras(self, **kwargs: Any) -> None:
        """Close the TorchRL env."""
        self.env.close()

    # ------------------------------------------------------------------ internals
    def _info(self, data: TensorDictBase, rows: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """{key: [N, ...] task entry, "_" + key: [N] bool mask (``rows``, or all)}."""
        mask = np.ones(self.num_envs, dtype=bool) if rows is None else np.asarray(rows, dtype=bool)
        info: dict[str, np.ndarray] = {}
        for key, value in task_arrays(data).items():
            info[key], info[f"_{key}"] = value, mask.copy()
        return info

    def _reset_rows(self, mask: object) -> np.ndarray:
        """[N] bool rows of a ``reset_mask`` option (ValueError unless an [N] bool array with a True)."""
        if self._data is None:
            raise RuntimeError("a partial reset (options['reset_mask']) needs a full reset() first")
        rows = np.asarray(mask)
        if rows.dtype != np.bool_ or rows.shape != (self.num_envs,) or not rows.any():
            raise ValueError(f"options['reset_mask'] must be a [{self.num_envs}] bool array with at least "
                             f"one True, got {rows.dtype} {list(rows.shape)}")
        return rows.copy()


__all__ = ["FalconVectorEnv", "Transition"]
