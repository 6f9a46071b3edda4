"""Evaluation: the paper's metrics (survival, acquisition, RMSE, time-in-band, settling time,
overshoot), computed batched from rollouts on the true state."""

from .metrics import (
    acquisition,
    altitude_metrics,
    attitude_metrics,
    first_episode_mask,
    overshoot,
    rmse,
    settled_window,
    settling_index,
    settling_time,
    summarize,
    survival,
    time_in_band,
)

__all__ = [
    "acquisition", "altitude_metrics", "attitude_metrics", "first_episode_mask", "overshoot", "rmse",
    "settled_window", "settling_index", "settling_time", "summarize", "survival", "time_in_band",
]
