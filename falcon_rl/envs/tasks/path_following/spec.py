"""The straight-path following task's record: its protocol, metrics, baselines, figure and training
defaults (:class:`~falcon_rl.envs.tasks.registry.TaskSpec`), registered on import."""

from __future__ import annotations

from ..registry import TRIM_HOLD, Metric, TaskSpec, register_task
from .task import PathFollowingConfig, PathFollowingTask

SPEC = register_task(TaskSpec(
    name="path_following", task=PathFollowingTask, config=PathFollowingConfig,
    gym_id="falcon_rl/PathFollowing-v0", title="Straight-line path following",
    protocol="falcon_rl.evaluation.protocols:path_following_protocol", select_on="cross_track_rmse_m",
    metrics=(Metric("survival", "Surv."), Metric("completion", "Compl."),
             Metric("cross_track_rmse_m", "e_y RMSE", "m"), Metric("capture_time_s", "t_capture", "s"),
             Metric("course_rmse_deg", "course RMSE", "deg"), Metric("altitude_rmse_m", "h RMSE", "m")),
    controllers={"guided-lqr": "falcon_rl.baselines.guided:guided_lqr",
                 "guided-l1-lqr": "falcon_rl.baselines.guided:guided_l1_lqr",
                 "guided-ppo": "falcon_rl.baselines.guided:guided_ppo",
                 "guided-l1-ppo": "falcon_rl.baselines.guided:guided_l1_ppo", "trim": TRIM_HOLD},
    figure="falcon_rl.viz.tracking:plot_path_following",
))
