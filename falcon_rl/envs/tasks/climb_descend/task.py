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

from ..altitude import AltitudeConfig, AltitudeTask


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
