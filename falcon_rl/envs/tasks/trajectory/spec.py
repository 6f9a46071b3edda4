"""The 3D trajectory tracking task's record: its protocol, metrics, baselines, figure and training
defaults (:class:`~falcon_rl.envs.tasks.registry.TaskSpec`), registered on import."""

from __future__ import annotations

from ..registry import TRIM_HOLD, Metric, TaskSpec, register_task
from .task import TrajectoryConfig, TrajectoryTask

SPEC = register_task(TaskSpec(
    name="trajectory", task=TrajectoryTask, config=TrajectoryConfig, gym_id="falcon_rl/Trajectory-v0",
    title="3D trajectory tracking",
    protocol="falcon_rl.evaluation.protocols:trajectory_protocol", select_on="position_rmse_m",
    metrics=(Metric("survival", "Surv."), Metric("position_rmse_m", "RMSE", "m"),
             Metric("horizontal_rmse_m", "horiz. RMSE", "m"), Metric("vertical_rmse_m", "vert. RMSE", "m"),
             Metric("cross_track_rmse_m", "e_y RMSE", "m"),
             Metric("time_in_band", "in band")),
    controllers={"guided-lqr": "falcon_rl.baselines.guided:guided_lqr",
                 "guided-l1-lqr": "falcon_rl.baselines.guided:guided_l1_lqr",
                 "guided-ppo": "falcon_rl.baselines.guided:guided_ppo",
                 "guided-l1-ppo": "falcon_rl.baselines.guided:guided_l1_ppo", "trim": TRIM_HOLD},
    figure="falcon_rl.viz.tracking:plot_trajectory",
))
