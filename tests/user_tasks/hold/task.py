"""Hold ``height`` with the throttle alone: observation [e_h / 10, V_a / V* - 1], reward
-w e_h^2 - w_V |V_a - V*| / V*, the shared terminations. Its step is written once, as Warp functions
(:mod:`.kernels`); this module holds the config, the buffers and the episode draws."""

from __future__ import annotations

from dataclasses import dataclass

import torch

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
    reward_terms = ("height", "airspeed")
    config: HoldConfig

    def __init__(self, config, sim, generator, control_dt, ground_effect=True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        #: h - h* [N] (a buffer of the Warp step, float32).
        self.height_error = torch.zeros(self.num_envs, device=self.device, dtype=self.buffer_dtype)

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        offset = self.uniform(-5.0, 5.0)
        return {**self.trim_initial(), "height": self.config.height + offset}

    def info_views(self) -> dict[str, torch.Tensor]:
        return {"height_error": self.height_error}

    def fused_stepper(self) -> FusedStep:
        from .kernels import FusedHoldStep

        return fused_stepper(self, FusedHoldStep)
