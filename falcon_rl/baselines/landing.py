"""The landing baseline ``tecs-flare``: NPFG on the centreline, TECS on the glide path and PX4's flare,
over the attitude LQRI scheduled in ground effect.

Approach: NPFG flies the runway's centreline (the task's ("task", "path_point") / ("task", "path_course")),
TECS's altitude loop the glide path with its rate fed forward in full (h_gp, hdot_gp: ("task",
"glide_path_height") / ("task", "reference_climb_rate")), the airspeed the task's approach speed.

Flare (PX4's landing defaults): from the wheels' height (("task", "wheel_height")) w <= h_f =
max(FW_LND_FLALT, FW_LND_FL_TIME x s_g) (s_g the glide path's sink rate), latched until the episode ends,

    hdot* = -max(FW_LND_FL_SINK, w / tau_f),   tau_f = h_f / s_g

an exponential flare that starts at the glide's sink (continuous at w = h_f) and ends at the flare sink
(0.25 m/s), and the bank command held within ``FLARE_BANK`` (the touchdown's limit).

The executor is the attitude LQRI (bank, climb rate, airspeed) designed on clearances (0.15, 0.25, 0.5, 1, 2,
4, 8) b in the env's ground-effect mode (so the gains know the cushion it lands on) and airspeeds 0.55-1.0
cruise (those that trim; the approach speed inside).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

from ..constants import DEG
from .guidance.paths import PathFrame, line_frame
from .guidance.tecs import TECSParams
from .guided import GuidedController, LQRExecutor, PathGuidance
from .lqr import GainSchedule, attitude_schedule

if TYPE_CHECKING:
    from ..airframe import Airframe
    from ..envs import FixedWingEnv

#: Clearances (spans) and airspeeds (fractions of cruise) of the landing LQRI's gain schedule.
LANDING_CLEARANCES: tuple[float, ...] = (0.15, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)
LANDING_SPEEDS: tuple[float, ...] = (0.55, 0.65, 0.8, 1.0)
#: The largest bank commanded in the flare (rad).
FLARE_BANK = 4.0 * DEG



@dataclass
class FlareParams:
    """PX4's flare parameters by name (SI units)."""

    FW_LND_FLALT: float = 0.5  # m, the lowest flare height
    FW_LND_FL_TIME: float = 1.0  # s, the flare height as time to touchdown at the glide's sink
    FW_LND_FL_SINK: float = 0.25  # m/s, the sink rate the flare ends at


class LandingGuidance(PathGuidance):
    """Centreline, glide path and flare (module docstring): (bank, climb rate, airspeed) [N]."""

    path_keys = ("path_point", "path_course", "glide_path_height", "reference_climb_rate", "wheel_height")

    def __init__(self, airframe: Airframe, dt: float, airspeed: float | None = None,
                 flare: FlareParams | None = None):
        super().__init__(airframe, dt, "npfg", airspeed, tecs_params=TECSParams(FW_T_HRATE_FF=1.0))
        sink = 2.0 * float(airframe.envelope.climb_rate_limit)
        self.tecs_params = replace(self.tecs_params, FW_T_SINK_MAX=sink)
        self.flare = flare or FlareParams()
        self.flaring: torch.Tensor | None = None

    def path(self, v: TensorDictBase) -> tuple[PathFrame, torch.Tensor, torch.Tensor]:
        position = v["state", "position_ned"][:, :2]
        frame = line_frame(position, v["task", "path_point"], v["task", "path_course"])
        # the glide path aimed the flare's length short of the task's aim point, so that the flare ends there
        glide_sink, flare_height, tau = self._flare_shape(v)
        ground_speed = v["state", "velocity_ned"][:, :2].norm(dim=-1).clamp_min(1.0)
        tan_glide = glide_sink / ground_speed
        floor = self.flare.FW_LND_FL_SINK * tau
        flare_length = ground_speed * tau * (1.0 + torch.log(flare_height / floor))
        task_height = v["task", "glide_path_height"]
        gear = task_height - tan_glide * (-position[:, 0]).clamp_min(0.0)
        height = torch.maximum(task_height - tan_glide * flare_length, gear)
        rate = torch.where(height > gear, v["task", "reference_climb_rate"], torch.zeros_like(height))
        return frame, height, rate

    def _flare_shape(self, v: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(the glide's sink s_g, the flare height h_f, the flare's time constant tau_f), [N] each."""
        p = self.flare
        glide_sink = (-v["task", "reference_climb_rate"]).clamp_min(2.0 * p.FW_LND_FL_SINK)
        flare_height = torch.clamp_min(p.FW_LND_FL_TIME * glide_sink, p.FW_LND_FLALT)
        return glide_sink, flare_height, flare_height / glide_sink

    def commands(self, v: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        bank, climb, speed = super().commands(v)
        p = self.flare
        wheels = v["task", "wheel_height"]
        _, flare_height, tau = self._flare_shape(v)
        fresh = v["state", "time"] <= 0.5 * self.dt
        flaring = self.flaring
        if flaring is None or flaring.shape != fresh.shape:
            flaring = torch.zeros_like(fresh)
        flaring = (flaring & ~fresh) | (wheels <= flare_height)
        self.flaring = flaring
        flare_climb = -torch.clamp_min(wheels.clamp_min(0.0) / tau, p.FW_LND_FL_SINK)
        climb = torch.where(flaring, flare_climb, climb)
        bank = torch.where(flaring, bank.clamp(-FLARE_BANK, FLARE_BANK), bank)
        return bank, climb, speed


#: Landing gain schedules by (airframe, its file, control step, ground-effect mode): a design trims and
#: linearises 28 points (seconds); the schedule is read only, each controller keeps its own integrators.
_SCHEDULES: dict[tuple[str, str, float, str], GainSchedule] = {}


def landing_schedule(airframe: Airframe, dt: float, ground_effect: bool | str) -> GainSchedule:
    """The landing LQRI's gain schedule (module docstring), designed once per process and key."""
    key = (airframe.name, str(airframe.path), float(dt), str(ground_effect))
    if key not in _SCHEDULES:
        span = float(airframe.geometry.span)
        _SCHEDULES[key] = attitude_schedule(airframe, dt, heights=tuple(round(f * span, 4) for f in
                                                                        LANDING_CLEARANCES),
                                            ground_effect=ground_effect, speed_fractions=LANDING_SPEEDS)
    return _SCHEDULES[key]


def tecs_flare(env: FixedWingEnv) -> GuidedController:
    """The ``tecs-flare`` landing baseline for ``env`` (module docstring)."""
    airframe = env.sim.airframe
    schedule = landing_schedule(airframe, env.control_dt, env.config.ground_effect)
    executor = LQRExecutor(airframe, env.control_dt, env.device, env.sim.dtype, schedule=schedule)
    guidance = LandingGuidance(airframe, env.control_dt, airspeed=env.task.trim_airspeed)
    return GuidedController(guidance, executor)


__all__ = ["FLARE_BANK", "LANDING_CLEARANCES", "LANDING_SPEEDS", "FlareParams", "LandingGuidance",
           "landing_schedule", "tecs_flare"]
