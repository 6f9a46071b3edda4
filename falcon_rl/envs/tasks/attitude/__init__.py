"""The attitude (bank/pitch/airspeed) tracking task: :mod:`.task` (config, episode, observation, reward,
termination), :mod:`.kernels` (its fused Warp step), :mod:`.spec` (its registered record and training
defaults)."""

from __future__ import annotations

from .spec import RANGER_ENV_OPTIONS, RANGER_OFF_POLICY, RANGER_PPO_ENV_OPTIONS, SPEC, V7_PPO_ENV_OPTIONS
from .task import AttitudeConfig, AttitudeTask

__all__ = [
    "RANGER_ENV_OPTIONS",
    "RANGER_OFF_POLICY",
    "RANGER_PPO_ENV_OPTIONS",
    "SPEC",
    "V7_PPO_ENV_OPTIONS",
    "AttitudeConfig",
    "AttitudeTask",
]
