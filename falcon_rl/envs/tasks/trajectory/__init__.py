"""The 3D trajectory tracking task: :mod:`.task` (config, episode, observation, reward, termination),
:mod:`.kernels` (its fused Warp step), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import SPEC
from .task import TrajectoryConfig, TrajectoryTask

__all__ = ["SPEC", "TrajectoryConfig", "TrajectoryTask"]
