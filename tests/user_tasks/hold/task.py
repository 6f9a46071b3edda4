"""Hold ``height`` with the throttle alone: observation [e_h / 10, V_a / V* - 1], reward
-w e_h^2 - w_V |V_a - V*| / V*, the shared terminations; the torch step and its Warp twin."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict import TensorDictBase

from falcon_rl.envs.tasks import Task, TaskConfig
from falcon_rl.envs.tasks.warp_common import FusedStep, fused_stepper


@dataclass
class HoldConfig(TaskConfig):
    """Hold ``height`` (m) with the throttle; ``w_height`` and ``w_airspeed`` weigh the reward."""

    episode_seconds: float = 2.0
    height: float = 50.0
    w_height: float = 1.0
    w_airspeed: float = 0.5


class HoldTask(Task):
    """See the module docstring. N envs, D = 2, A = 1 (throttle)."""

    name = "user_hold"
    observation_dim = 2
    action_dim = 1
    observation_clip = 5.0
    action_channels = (3,)
    config: HoldConfig

    def __init__(self, config, sim, generator, control_dt, ground_effect=True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        self.height_error = torch.zeros(self.num_envs, device=self.device, dtype=self.dtype)

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        offset = self.uniform(-5.0, 5.0)
        return {**self.trim_initial(), "height": self.config.height + offset}

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        self.update(state)

    def update(self, state: TensorDictBase) -> None:
        self.height_error.copy_(state["height"] - self.config.height)

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        obs = torch.stack([(state["height"] - self.config.height) / 10.0,
                           state["airspeed"] / self.trim_airspeed - 1.0], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward(self, state: TensorDictBase, action: torch.Tensor) -> torch.Tensor:
        cfg = self.config
        return (-cfg.w_height * self.height_error**2
                - cfg.w_airspeed * (state["airspeed"] - self.trim_airspeed).abs() / self.trim_airspeed)

    def info(self) -> dict[str, torch.Tensor]:
        return {"height_error": self.height_error.clone()}

    def fused_stepper(self) -> FusedStep | None:
        if not self.sim.engine.runs_task_kernels:
            return None
        from .kernels import FusedHoldStep

        return fused_stepper(self, HoldTask, _FUSED_METHODS, FusedHoldStep)


#: The methods the kernel twins: a subclass that overrides one steps in torch (and is warned once).
_FUSED_METHODS = ("step", "advance", "update", "reward", "observe", "termination_checks",
                  "termination_reason")
