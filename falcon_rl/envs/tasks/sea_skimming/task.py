"""Sea skimming: hold a commanded clearance above the waves, in ground effect, over a sea drawn per episode.

Episode: the env flies over its own sea (``Simulator.set_sea``), a sea-state code drawn per episode from
``sea_states`` (WMO 0-6; 0 is a calm sea) with the waves travelling north, and the aircraft trimmed at
cruise heading ``heading_to_waves`` off the waves' direction (0 a following sea, pi/2 a beam sea, pi a
head sea; one of the tuple per episode). The commanded clearance is c* = U(clearance_min, clearance_max)
b (b the span) and the aircraft starts c* + U(offset_min, offset_max) b above the water under it, already
following it: the trimmed flight (solved in ground effect at the middle of the commanded band) pitched by
the path angle asin(etadot / V*) of the water's rate under it (a level start over a rising crest would
meet the water within a fraction of a second, before any controller could act).

Clearance c is what a radar altimeter reads: the CG's height above the water under it (the derived state's
``surface_clearance``; over the ground the height). e_c = c - c*, e_Va = V_a - V_a*. Observation (15 + P,
clipped to [-5, 5]):

    o = [e_c/(b/4), cdot/sigma_v, e_Va/sigma_V, phi/(pi/4), theta/(pi/4), p/2, q/2, r/2, alpha/20deg,
         v_z/sigma_v, c*/b, a_{t-1}]

cdot the altimeter's rate (finite difference over the env step, 0 on an episode's first step), sigma_v
the airframe's climb-rate limit, sigma_V = ``airspeed_scale`` V_a*, v_z the NED (down) velocity, a_{t-1}
the previous action (4). With ``preview_seconds`` tau_1..tau_P the forward-looking altimeter's P clearance
errors ahead follow, (h - eta(p + V_g tau_k, t) - c*)/(b/4): h the height above the mean level, p the
CG's horizontal position, V_g its horizontal ground velocity and eta the water's elevation there now (what
a scanning laser reads of the water ahead; the aircraft gets there about tau_k later, the waves by then
moved on). Action [delta_e, delta_a, delta_r, delta_t] in [-1, 1]^4: over waves the span's clearance
varies, so the aircraft needs its ailerons to stay level.

Reward (named terms):

    r = w_c exp(-e_c^2 / 2 (sigma_c b)^2) - w_V |e_Va| / V_a* - w_phi min((phi / (pi/4))^2, 1)
        - w_tip max(0, 1 - c_tip / (m_tip b)) - w_s ||a_t - a_{t-1}||^2 - w_P delta_t + b_surv

c_tip the lower wing tip's clearance above the water under it (the tip margin term warns before contact),
delta_t the mean throttle in [0, 1] (the power term: ground effect pays when the same flight costs less).

Termination: water (or ground) contact of the CG or a wing tip, |alpha| > 1.5 alpha_stall, V_a < V_stall,
or "lost": c above ``ceiling`` b (the aircraft has left the ground-effect band the task is about);
truncation at the horizon. Published under ("task", ...): commanded_clearance c*, clearance c,
clearance_error e_c, clearance_rate cdot, surface_rate (the rate of the water under the aircraft, hdot -
cdot), lowest_tip_clearance, surface_elevation (of the water under the CG), sea_state (the code),
heading_to_waves, and for altitude-hold controllers reference_altitude h - e_c (the height that gives c*)
and reference_climb_rate (= surface_rate).

The step, the start of episodes and the observation are written once, as Warp functions
(``sea_skimming.kernels``); the episode draws (sea state, heading, clearance, start) are torch, from the
env's generator, and the wave fields from the simulator's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch

from ....physics import Simulator
from ..base import Task, TaskConfig, trim_point

if TYPE_CHECKING:
    from ..warp_common import FusedStep


#: The most look-ahead times of the forward-looking altimeter.
MAX_PREVIEW = 8


@dataclass
class SeaSkimmingConfig(TaskConfig):
    """Sea-skimming parameters (SI units, angles in rad, clearances as fractions of the span)."""

    episode_seconds: float = 30.0
    #: Sea-state codes (WMO 0-6) drawn per episode.
    sea_states: tuple[float, ...] = (0.0, 1.0, 2.0)
    #: Flight heading off the waves' direction of travel, one drawn per episode.
    heading_to_waves: tuple[float, ...] = (0.0, 0.5 * math.pi, math.pi)
    clearance_min: float = 0.15
    clearance_max: float = 0.5
    #: The start is U(offset_min, offset_max) b above the commanded clearance.
    offset_min: float = 0.0
    offset_max: float = 0.25
    #: Look-ahead times (s) of the forward-looking altimeter: the clearance the aircraft would have over
    #: the water ahead along its ground track, V_g tau seconds away, if it held its height (one observation
    #: each; empty: no look-ahead, the 15 observations alone).
    preview_seconds: tuple[float, ...] = (0.25, 0.5, 0.75, 1.0)
    #: "lost" above this many spans of clearance.
    ceiling: float = 4.0
    airspeed_scale: float = 0.1
    w_clearance: float = 1.0
    sigma_clearance: float = 0.1
    w_airspeed: float = 0.5
    w_bank: float = 0.2
    w_tip: float = 1.0
    tip_margin: float = 0.1
    w_smooth: float = 0.05
    w_power: float = 0.05
    survival_bonus: float = 0.5

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "clearance_min", "clearance_max", "ceiling", "airspeed_scale",
        "sigma_clearance", "tip_margin")
    non_negative: ClassVar[tuple[str, ...]] = ("offset_min", "offset_max", "sea_states")
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (("clearance_min", "clearance_max"),
                                                      ("offset_min", "offset_max"))
    may_be_empty: ClassVar[tuple[str, ...]] = ("preview_seconds",)

    def check(self, task: str) -> None:
        super().check(task)
        if not all(float(code).is_integer() and 0 <= code <= 6 for code in self.sea_states):
            raise ValueError(f"{task} option sea_states must hold WMO sea-state codes 0-6, got "
                             f"{self.sea_states!r}")
        if len(self.preview_seconds) > MAX_PREVIEW or not all(
                0.0 < tau <= 5.0 for tau in self.preview_seconds):
            raise ValueError(f"{task} option preview_seconds must hold at most {MAX_PREVIEW} look-ahead "
                             f"times in (0, 5] s, got {self.preview_seconds!r}")
        if self.clearance_max + self.offset_max >= self.ceiling:
            raise ValueError(f"{task} options clearance_max + offset_max < ceiling required, got "
                             f"{self.clearance_max} + {self.offset_max} >= {self.ceiling}")


class SeaSkimmingTask(Task):
    """Clearance hold over the waves; see the module docstring for the equations."""

    name = "sea_skimming"
    observation_dim = 15
    action_dim = 4
    observation_clip = 5.0
    reward_terms = ("clearance", "airspeed", "bank", "tip_margin", "smoothness", "power", "survival")
    config: SeaSkimmingConfig

    def __init__(self, config: SeaSkimmingConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        self.observation_dim = type(self).observation_dim + len(config.preview_seconds)
        self.span = float(self.airframe.geometry.span)
        middle = 0.5 * (config.clearance_min + config.clearance_max) * self.span
        self.trim = trim_point(sim, self.trim_airspeed, height=max(middle, 0.1), ground_effect=ground_effect)
        self.command_buffer.copy_(self.trim.command.expand(self.num_envs, 4))
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        self.commanded_clearance = torch.zeros(n, **kw)
        self.clearance = torch.zeros(n, **kw)
        self.clearance_error = torch.zeros(n, **kw)
        self.clearance_rate = torch.zeros(n, **kw)
        self.surface_rate = torch.zeros(n, **kw)
        self.lowest_tip_clearance = torch.zeros(n, **kw)
        self.surface_elevation = torch.zeros(n, **kw)
        self.reference_altitude = torch.zeros(n, **kw)
        self.sea_state = torch.zeros(n, **kw)
        self.heading_to_waves = torch.zeros(n, **kw)
        self._fused: FusedStep | None = None  # bound on the first fused step

    # ------------------------------------------------------------------ episode start
    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        cfg, b = self.config, self.span
        code = self.choice(cfg.sea_states)
        heading = self.choice(cfg.heading_to_waves)
        clearance = self.uniform(cfg.clearance_min, cfg.clearance_max) * b
        offset = self.uniform(cfg.offset_min, cfg.offset_max) * b
        for buffer, value in ((self.sea_state, code), (self.heading_to_waves, heading),
                              (self.commanded_clearance, clearance)):
            buffer.copy_(torch.where(mask, value.to(buffer.dtype), buffer))
        for value in cfg.sea_states:  # one wave field per env of the drawn code
            self.sim.set_sea(int(value), mask & (code == value))
        sea = self.sim.sea
        assert sea is not None
        zeros = torch.zeros(self.num_envs, device=self.device, dtype=self.dtype)
        water = sea.elevation(zeros, zeros, 0.0).to(self.dtype)  # the start is at (0, 0) and t = 0
        rising = sea.elevation_rate(zeros, zeros, 0.0).to(self.dtype)
        height = water + clearance + offset
        initial = self.trim_initial(heading)
        # already following the water: the trimmed flight pitched by the path angle of the water's rate
        path_angle = torch.asin((rising / self.trim_airspeed).clamp(-0.5, 0.5))
        initial["euler"] = initial["euler"] + torch.stack([zeros, path_angle, zeros], dim=-1)
        return {**initial, "position_ned": torch.zeros(3, device=self.device, dtype=self.dtype),
                "height": height}

    # ------------------------------------------------------------------ step
    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``sea_skimming.kernels``,
        :class:`FusedSeaSkimmingStep`): (observation [N, 15], reward [N], reason [N] long), buffers
        overwritten by the next call."""
        from ..warp_common import fused_stepper
        from .kernels import FusedSeaSkimmingStep

        return fused_stepper(self, FusedSeaSkimmingStep)

    def info_views(self) -> dict[str, torch.Tensor]:
        return {
            "commanded_clearance": self.commanded_clearance,
            "clearance": self.clearance,
            "clearance_error": self.clearance_error,
            "clearance_rate": self.clearance_rate,
            "surface_rate": self.surface_rate,
            "lowest_tip_clearance": self.lowest_tip_clearance,
            "surface_elevation": self.surface_elevation,
            "sea_state": self.sea_state,
            "heading_to_waves": self.heading_to_waves,
            "reference_altitude": self.reference_altitude,
            "reference_climb_rate": self.surface_rate,
        }
