"""The climb and descent on a reference task: :mod:`.task` (config, episode, observation, reward,
termination), :mod:`.spec` (its registered record and training defaults)."""

from __future__ import annotations

from .spec import SPEC
from .task import ClimbDescendConfig, ClimbDescendTask

__all__ = ["SPEC", "ClimbDescendConfig", "ClimbDescendTask"]
