"""Evaluation: the paper's metrics (survival, acquisition, RMSE, time-in-band, settling time,
overshoot) and those of the climb/descend, path-following and trajectory protocols, computed batched
from rollouts on the true state."""

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
