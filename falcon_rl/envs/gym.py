"""Gymnasium wrapper: one aircraft, NumPy in and out, for Stable-Baselines3 and other Gym users.

    import gymnasium as gym
    import falcon_rl  # registers falcon_rl/<Task>-v0
    env = gym.make("falcon_rl/Altitude-v0", airframe="volantex_ranger")
    obs, info = env.reset(seed=0)

Registered ids: each task's ``TaskSpec.gym_id`` (falcon_rl/Altitude-v0, falcon_rl/Attitude-v0,
falcon_rl/ClimbDescend-v0, falcon_rl/PathFollowing-v0, falcon_rl/Trajectory-v0, and any task registered
later once ``register_gym_envs()`` runs again). Keyword arguments are those of
:func:`falcon_rl.envs.make_env` (airframe, backend, device and task or env options).
``info`` carries the task's references and errors (("task", ...) keys) as floats or arrays.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from tensordict import TensorDict

from .tasks.registry import TASK_SPECS, SpecView

#: Task name -> Gymnasium id (a live, read-only view of the task registry).
GYM_IDS: SpecView[str] = SpecView(lambda spec: spec.gym_id)


class CoreAircraftEnv(gymnasium.Env):
    """A single-aircraft :class:`FixedWingEnv` behind the Gymnasium API (float32 Box spaces)."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's class attribute)

    def __init__(self, task: str = "altitude", airframe: str = "navion", backend: str = "torch",
                 device: str = "cpu", seed: int = 0, **options: Any):
        from .factory import make_env

        self.env = make_env(task, airframe, num_envs=1, backend=backend, device=device, seed=seed, **options)
        observation_spec, action_spec = self.env.observation_spec["observation"], self.env.action_spec
        self.observation_space = spaces.Box(observation_spec.low[0].cpu().numpy().astype(np.float32),
                                            observation_spec.high[0].cpu().numpy().astype(np.float32),
                                            dtype=np.float32)
        self.action_space = spaces.Box(action_spec.low[0].cpu().numpy().astype(np.float32),
                                       action_spec.high[0].cpu().numpy().astype(np.float32), dtype=np.float32)
        self._action_dtype = action_spec.dtype
        self._action = TensorDict({"action": action_spec.zero()}, batch_size=[1], device=self.env.device)

    @staticmethod
    def _info(data: TensorDict) -> dict[str, Any]:
        info = {}
        for key, value in data["task"].items():
            array = value[0].detach().cpu().numpy()
            info[key] = float(array) if array.ndim == 0 else array
        return info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        if seed is not None:
            self.env.set_seed(seed)
        data = self.env.reset()
        obs = data["observation"][0].detach().cpu().numpy().astype(np.float32)
        return obs, self._info(data)

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        action_t = torch.as_tensor(np.asarray(action, dtype=np.float32), device=self.env.device)
        self._action["action"] = action_t.reshape(1, -1).to(self._action_dtype).clamp(-1.0, 1.0)
        data = self.env.step(self._action.clone())["next"]
        obs = data["observation"][0].detach().cpu().numpy().astype(np.float32)
        return (obs, float(data["reward"][0, 0]), bool(data["terminated"][0, 0]),
                bool(data["truncated"][0, 0]), self._info(data))


def register_gym_envs() -> list[str]:
    """Register every registered task's gym id with Gymnasium (idempotent: ids already known are
    skipped); returns the ids registered by this call."""
    added = []
    for task, spec in TASK_SPECS.items():
        if spec.gym_id not in gymnasium.registry:
            gymnasium.register(id=spec.gym_id, entry_point="falcon_rl.envs.gym:CoreAircraftEnv",
                               kwargs={"task": task})
            added.append(spec.gym_id)
    return added
