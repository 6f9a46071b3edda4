"""The sea-skimming task: :mod:`.task` (config, episode, observation, reward, termination), :mod:`.kernels`
(its fused Warp step), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import SEA_SKIMMING_METRICS, SPEC
from .task import SeaSkimmingConfig, SeaSkimmingTask

__all__ = ["SEA_SKIMMING_METRICS", "SPEC", "SeaSkimmingConfig", "SeaSkimmingTask"]
