"""Evaluation: the paper's metrics (survival, acquisition, RMSE, time-in-band, settling time,
overshoot) and those of the climb/descend, path-following and trajectory protocols, computed batched
from rollouts on the true state.

The public names load on first use (PEP 562).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .metrics import (
        acquisition,
        altitude_metrics,
        attitude_metrics,
        first_episode_mask,
        overshoot,
        ramp_end_index,
        rmse,
        settled_window,
        settling_index,
        settling_time,
        summarize,
        survival,
        time_in_band,
    )
    from .tracking_metrics import climb_descend_metrics, path_following_metrics, trajectory_metrics

__all__ = [
    "acquisition", "altitude_metrics", "attitude_metrics", "climb_descend_metrics", "first_episode_mask",
    "overshoot", "path_following_metrics", "ramp_end_index", "rmse", "settled_window", "settling_index",
    "settling_time", "summarize", "survival", "time_in_band", "trajectory_metrics",
]
_TRACKING = ("climb_descend_metrics", "path_following_metrics", "trajectory_metrics")
#: Public name -> the submodule that defines it.
_LAZY = {name: "tracking_metrics" if name in _TRACKING else "metrics" for name in __all__}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
