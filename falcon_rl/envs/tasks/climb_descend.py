"""Dynamic climbing and descending: track an altitude reference that moves at a commanded rate.

The altitude task's MDP (same 11-d observation, 2-d action, reward and termination; see
:mod:`.altitude`) with a different episode: the aircraft starts on its reference, in trimmed level
flight at h_0 ~ U(``start_min``, ``start_max``), and the commanded altitude lies
``+-U(change_min, change_max)`` away (kept inside [``floor``, ``ceiling``]). The reference ramps to
it at a per-episode rate r ~ U(``rate_min``, ``rate_max``) x climb_rate_limit and then holds:

    h_ref(t) = h* - sgn(h* - h_0) max(|h* - h_0| - r t, 0)

so most of the episode is spent tracking a moving reference; score it with ("task",
"reference_error") = h - h_ref rather than the altitude error against h*.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import torch

from .altitude import AltitudeConfig, AltitudeTask
from .registry import TRIM_HOLD, Metric, TaskSpec, register_task


@dataclass
class ClimbDescendConfig(AltitudeConfig):
    """Climb/descend parameters (SI units)."""

    episode_seconds: float = 60.0
    start_min: float = 30.0
    start_max: float = 120.0
    change_min: float = 20.0
    change_max: float = 60.0
    floor: float = 10.0
    ceiling: float = 200.0
    rate_min: float = 0.3
    rate_max: float = 1.0

    positive: ClassVar[tuple[str, ...]] = (*AltitudeConfig.positive, "start_min", "change_min", "floor",
                                           "rate_min")
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (
        *AltitudeConfig.ordered, ("start_min", "start_max"), ("change_min", "change_max"),
        ("floor", "ceiling"), ("rate_min", "rate_max"))


class ClimbDescendTask(AltitudeTask):
    """Altitude tracking of a reference climbing or descending at a commanded rate."""

    name = "climb_descend"
    config: ClimbDescendConfig

    def sample_targets_and_offsets(self) -> tuple[torch.Tensor, torch.Tensor]:
        cfg = self.config
        start = self.uniform(cfg.start_min, cfg.start_max)
        target = (start + self.random_sign() * self.uniform(cfg.change_min, cfg.change_max))
        return target.clamp(cfg.floor, cfg.ceiling), start

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        cfg = self.config
        rate = self.uniform(cfg.rate_min, cfg.rate_max) * self.airframe.envelope.climb_rate_limit
        self.climb_rate.copy_(torch.where(mask, rate, self.climb_rate))
        return super().sample_initial(mask)


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
