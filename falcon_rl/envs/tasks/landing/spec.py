"""The landing task's record: its protocol, metrics, baselines, figure and training defaults
(:class:`~falcon_rl.envs.tasks.registry.TaskSpec`), registered on import."""

from __future__ import annotations

from ..registry import TRAINING_DECIMATION, TRIM_HOLD, Metric, TaskSpec, register_task
from .task import LandingConfig, LandingTask

#: The landing protocol's columns: touchdowns within every limit, touchdowns, the touchdown's sink rate,
#: pitch and bank, its lateral offset and longitudinal dispersion, and the float in ground effect.
LANDING_METRICS: tuple[Metric, ...] = (
    Metric("landed_within_limits", "In limits"), Metric("touchdown", "Touchdown"),
    Metric("sink_rate_mps", "Sink", "m/s"), Metric("pitch_deg", "Pitch", "deg"),
    Metric("bank_deg", "Bank", "deg"), Metric("lateral_m", "Lateral", "m"),
    Metric("longitudinal_m", "Long.", "m"), Metric("float_m", "Float", "m"))

SPEC = register_task(TaskSpec(
    name="landing", task=LandingTask, config=LandingConfig, gym_id="falcon_rl/Landing-v0",
    title="Landing: approach, flare and touchdown",
    protocol="falcon_rl.evaluation.landing:landing_protocol", metrics=LANDING_METRICS,
    controllers={"tecs-flare": "falcon_rl.baselines.landing:tecs_flare", "trim": TRIM_HOLD},
    figure="falcon_rl.viz.landing:plot_landing",
    defaults={"decimation": TRAINING_DECIMATION},
))
