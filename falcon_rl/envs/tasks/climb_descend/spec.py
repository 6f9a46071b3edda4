"""The climb and descent on a reference task's record: its protocol, metrics, baselines, figure and training
defaults (:class:`~falcon_rl.envs.tasks.registry.TaskSpec`), registered on import."""

from __future__ import annotations

from ..registry import TRIM_HOLD, Metric, TaskSpec, register_task
from .task import ClimbDescendConfig, ClimbDescendTask

#: The altitude baselines read the same ("task", ...) keys (reference_altitude, reference_climb_rate,
#: target_altitude), so they fly this task too.
SPEC = register_task(TaskSpec(
    name="climb_descend", task=ClimbDescendTask, config=ClimbDescendConfig,
    gym_id="falcon_rl/ClimbDescend-v0", title="Climb and descend",
    protocol="falcon_rl.evaluation.protocols:climb_descend_protocol", select_on="ramp_rmse_m",
    metrics=(Metric("survival", "Surv."), Metric("climb_rate_rmse_mps", "hdot RMSE", "m/s"),
             Metric("ramp_rmse_m", "ramp RMSE", "m"), Metric("level_off", "Level-off"),
             Metric("level_off_time_s", "t_level", "s"), Metric("level_off_rmse_m", "level RMSE", "m"),
             Metric("overshoot_m", "Over.", "m")),
    controllers={"lqr": "falcon_rl.baselines.lqr:AltitudeLQR.from_env",
                 "mppi": "falcon_rl.baselines.mppi:altitude_mppi", "trim": TRIM_HOLD},
    figure="falcon_rl.viz.tracking:plot_climb_descend",
))
