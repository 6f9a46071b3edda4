"""The straight-path following task: :mod:`.task` (config, episode, observation, reward, termination),
:mod:`.kernels` (its fused Warp step), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import SPEC
from .task import PathFollowingConfig, PathFollowingTask

__all__ = ["SPEC", "PathFollowingConfig", "PathFollowingTask"]
