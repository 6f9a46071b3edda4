"""Landing: approach on a glide path to a runway, flare in ground effect, touch down.

Episode: the runway's centreline runs north through the aim point at the origin. The aircraft starts
d0 = U(``distance_min``, ``distance_max``) m short of it (north = -d0), ``lateral`` = +-U(0, ``lateral_max``)
m off the centreline, heading U(-``heading_max``, ``heading_max``) off it, on the glide path (h = h_gp(-d0)),
trimmed level at the approach airspeed V* (``trim_airspeed``; by default 1.3 V_stall, or the lowest of
1.4-2 V_stall the airframe trims at).

The glide path ends where the gear meets the ground at the aim point: with gamma the glide slope
(``glide_slope``; by default the standard 3 deg, or a sink at half the airframe's climb-rate limit when
that is shallower) and g the gear height (``gear_height`` spans: the CG's height above the wheels on the
ground),

    h_gp(n) = g + tan(gamma) max(-n, 0),   hdot_gp = -V_g tan(gamma) before the aim point, 0 after

Errors e_h = h - h_gp, e_y = east (right of the centreline), chi_err = wrap(chi), e_V = V_a - V*; the
wheels' height w = c - g (c the CG's clearance above the surface under it). Observation (19, clipped to
[-5, 5]):

    o = [e_h/5, w/b, v_z/sigma_v, e_y/10, sin chi_err, cos chi_err, e_V/sigma_V, phi/(pi/4), theta/(pi/4),
         p/2, q/2, r/2, alpha/20deg, beta/20deg, -n/d_max, a_{t-1}]

Reward (named terms): glide path w_h exp(-e_h^2 / 2 sigma_h^2), centreline w_y exp(-e_y^2 / 2 sigma_y^2),
airspeed -w_V |e_V| / V*, bank -w_phi min((phi/(pi/4))^2, 1), smoothness -w_s ||a_t - a_{t-1}||^2, and at
the touchdown w_td exp(-vz^2 / 2 sigma_td^2) when the pitch is within [``pitch_min``, ``pitch_max``] and
|phi| <= ``bank_max`` (0 otherwise).

Termination ("termination_reason"): "tip_strike" (the lower wing tip on the surface), "touchdown" (the
wheels on the surface: the episode ends at the first contact, a bounce is not modelled), then stall, and
"lost" (|e_y| above ``lost_lateral`` or past the aim point by ``long_distance`` m without a touchdown). Over
a sea (``sea_states``: ditching) the surface is the water under the aircraft. Published under ("task", ...):
glide_path_height (= reference_altitude, for altitude-hold controllers), reference_climb_rate,
glide_path_error, cross_track_error, course_error, wheel_height, the runway as a path (path_point (0, 0),
path_course 0, path_height = h_gp) for path guidance, touchdown (1 on the touchdown step), the touchdown's
sink rate (m/s, down positive; every step's until then), pitch, bank, along-track and lateral position (m
from the aim point; zero until then), and ground_effect_north (the north position where the wheels first
came below one span, ``NOT_YET`` = 1e9 before: the float in ground effect is its distance to the
touchdown).

The step, the start of episodes and the observation are written once, as Warp functions
(``landing.kernels``); the episode draws are torch, from the env's generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, ClassVar

import torch

from ....airframe import Airframe
from ....constants import DEG
from ....physics import Simulator
from ....physics.trim import TrimError, trim_level
from ..base import Task, TaskConfig

if TYPE_CHECKING:
    from ..warp_common import FusedStep

#: ground_effect_north before the wheels came below one span (a finite "not yet").
NOT_YET = 1.0e9
#: The default glide slope's upper bound: the ILS standard's 3 deg (rad; PX4's FW_LND_ANG default is 5 deg,
#: steeper than a clean, light airframe such as the Ranger glides at idle).
STANDARD_GLIDE_SLOPE = 3.0 * DEG


#: Approach speeds tried, in stall speeds: the first the airframe trims at level is the default.
APPROACH_FACTORS: tuple[float, ...] = (1.3, 1.4, 1.5, 1.6, 1.8, 2.0)


def approach_speed(airframe: Airframe) -> float:
    """The default approach airspeed (m/s): 1.3 V_stall (the usual reference landing speed), or the first
    of :data:`APPROACH_FACTORS` x V_stall at which the airframe trims in level flight (a heavy airframe at
    1.3 V_stall may need more than full throttle to hold level), at most the cruise speed."""
    envelope = airframe.envelope
    for factor in APPROACH_FACTORS:
        speed = min(factor * envelope.stall_speed, envelope.cruise_speed)
        try:
            trim_level(airframe, speed, 100.0, ground_effect=False)
        except TrimError:
            continue
        return speed
    return float(envelope.cruise_speed)


def glide_slope(airframe: Airframe, airspeed: float) -> float:
    """The default glide slope (rad): the standard 3 deg, or asin(climb-rate limit / (2 V*)) when that is
    shallower (a glide at half the airframe's rate limit leaves authority to correct it)."""
    return min(STANDARD_GLIDE_SLOPE, math.asin(min(1.0, 0.5 * airframe.envelope.climb_rate_limit / airspeed)))


@dataclass
class LandingConfig(TaskConfig):
    """Landing parameters (SI units, angles in rad, the gear height in spans)."""

    episode_seconds: float = 60.0
    #: Glide slope (rad); None: :func:`glide_slope`.
    glide_slope: float | None = None
    distance_min: float = 150.0
    distance_max: float = 250.0
    lateral_max: float = 10.0
    heading_max: float = 10.0 * DEG
    #: Height of the CG above the wheels on the ground, in spans.
    gear_height: float = 0.08
    #: Touchdown attitude limits: pitch (nose-gear first below, tail strike above) and bank.
    pitch_min: float = 0.0
    pitch_max: float = 12.0 * DEG
    bank_max: float = 5.0 * DEG
    lost_lateral: float = 60.0
    long_distance: float = 300.0
    #: Sea-state codes of a ditching (the surface is the water); empty: the runway.
    sea_states: tuple[float, ...] = ()
    airspeed_scale: float = 0.1
    w_glide_path: float = 1.0
    sigma_glide_path: float = 1.5
    w_centerline: float = 0.5
    sigma_centerline: float = 3.0
    w_airspeed: float = 0.5
    w_bank: float = 0.2
    w_smooth: float = 0.05
    w_touchdown: float = 50.0
    sigma_touchdown: float = 0.3

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "glide_slope", "distance_min", "gear_height", "pitch_max", "bank_max",
        "lost_lateral", "long_distance", "airspeed_scale", "sigma_glide_path", "sigma_centerline",
        "sigma_touchdown")
    non_negative: ClassVar[tuple[str, ...]] = ("lateral_max", "heading_max", "sea_states")
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (("distance_min", "distance_max"),
                                                      ("pitch_min", "pitch_max"))
    may_be_empty: ClassVar[tuple[str, ...]] = ("sea_states",)

    def check(self, task: str) -> None:
        super().check(task)
        if not all(float(code).is_integer() and 0 <= code <= 6 for code in self.sea_states):
            raise ValueError(f"{task} option sea_states must hold WMO sea-state codes 0-6, got "
                             f"{self.sea_states!r}")
        if self.glide_slope is not None and self.glide_slope >= 0.5 * math.pi:
            raise ValueError(f"{task} option glide_slope must be below pi/2 rad, got {self.glide_slope!r}")


class LandingTask(Task):
    """Approach, flare and touchdown; see the module docstring."""

    name = "landing"
    observation_dim = 19
    action_dim = 4
    observation_clip = 5.0
    reward_terms = ("glide_path", "centerline", "airspeed", "bank", "smoothness", "touchdown")
    config: LandingConfig

    def __init__(self, config: LandingConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        airspeed = config.trim_airspeed or approach_speed(sim.airframe)
        config = replace(config, trim_airspeed=airspeed,
                         glide_slope=config.glide_slope or glide_slope(sim.airframe, airspeed))
        super().__init__(config, sim, generator, control_dt, ground_effect)
        self.span = float(self.airframe.geometry.span)
        self.gear = config.gear_height * self.span
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        self.errors = torch.zeros(n, 3, **kw)  # (e_h, e_y, chi_err)
        self.glide_path_height = torch.zeros(n, **kw)
        self.reference_climb_rate = torch.zeros(n, **kw)
        self.wheel_height = torch.zeros(n, **kw)
        self.touchdown = torch.zeros(n, **kw)
        self.touchdown_state = torch.zeros(n, 5, **kw)  # (sink, pitch, bank, along, lateral)
        self.ground_effect_north = torch.zeros(n, **kw)
        self._fused: FusedStep | None = None  # bound on the first fused step

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        cfg = self.config
        distance = self.uniform(cfg.distance_min, cfg.distance_max)
        lateral = self.random_sign() * self.uniform(0.0, cfg.lateral_max)
        heading = self.uniform(-cfg.heading_max, cfg.heading_max)
        if cfg.sea_states:
            code = self.choice(cfg.sea_states)
            for value in cfg.sea_states:
                self.sim.set_sea(int(value), mask & (code == value))
        assert cfg.glide_slope is not None
        height = self.gear + math.tan(cfg.glide_slope) * distance
        self.ground_effect_north.masked_fill_(mask, NOT_YET)
        position = torch.stack([-distance, lateral, torch.zeros_like(distance)], dim=-1)
        return {**self.trim_initial(heading), "position_ned": position, "height": height}

    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``landing.kernels``, :class:`FusedLandingStep`):
        (observation [N, 19], reward [N], reason [N] long), buffers overwritten by the next call."""
        from ..warp_common import fused_stepper
        from .kernels import FusedLandingStep

        return fused_stepper(self, FusedLandingStep)

    def info(self) -> dict[str, torch.Tensor]:
        zeros, td = torch.zeros_like(self.glide_path_height), self.touchdown_state
        info = {"glide_path_height": self.glide_path_height, "reference_altitude": self.glide_path_height,
                "reference_climb_rate": self.reference_climb_rate, "glide_path_error": self.errors[:, 0],
                "cross_track_error": self.errors[:, 1], "course_error": self.errors[:, 2],
                "wheel_height": self.wheel_height, "path_point": torch.zeros_like(self.errors[:, :2]),
                "path_course": zeros, "path_height": self.glide_path_height, "touchdown": self.touchdown,
                "touchdown_sink_rate": td[:, 0], "touchdown_pitch": td[:, 1], "touchdown_bank": td[:, 2],
                "touchdown_along": td[:, 3], "touchdown_lateral": td[:, 4],
                "ground_effect_north": self.ground_effect_north}
        return {key: value.to(self.dtype, copy=True) for key, value in info.items()}
