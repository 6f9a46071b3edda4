"""The altitude acquisition and hold task: :mod:`.task` (config, episode, observation, reward, termination),
:mod:`.kernels` (its fused Warp step), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import (
    ALTITUDE_METRICS,
    ALTITUDE_SOLVED,
    ENERGY_RATE_PENALTY,
    HEAVIER_AIRSPEED_PENALTY,
    OFF_POLICY_CRITIC,
    RANGER_SAC,
    SPEC,
    TRAINING_ENV_OPTIONS,
    V7_OFF_POLICY,
    V7_PPO,
    V7_SAC,
    V7_TD3,
)
from .task import AltitudeConfig, AltitudeTask

__all__ = [
    "ALTITUDE_METRICS",
    "ALTITUDE_SOLVED",
    "ENERGY_RATE_PENALTY",
    "HEAVIER_AIRSPEED_PENALTY",
    "OFF_POLICY_CRITIC",
    "RANGER_SAC",
    "SPEC",
    "TRAINING_ENV_OPTIONS",
    "V7_OFF_POLICY",
    "V7_PPO",
    "V7_SAC",
    "V7_TD3",
    "AltitudeConfig",
    "AltitudeTask",
]
