"""The landing task: :mod:`.task` (config, episode, observation, reward, termination), :mod:`.kernels` (its
fused Warp step), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import LANDING_METRICS, SPEC
from .task import LandingConfig, LandingTask

__all__ = ["LANDING_METRICS", "SPEC", "LandingConfig", "LandingTask"]
