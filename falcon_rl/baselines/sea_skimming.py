"""The sea-skimming LQR: an altimeter loop over the attitude LQRI, scheduled in ground effect.

The attitude LQRI (``lqr.AttitudeLQR``: bank, climb rate and airspeed, with integrators) is designed on a
grid of clearances (0.15, 0.25, 0.5, 1, 2) b in ground effect x airspeeds (0.9, 1, 1.1) cruise and scheduled
at the measured clearance c.
Above it, the altimeter loop commands

    bank* = 0,   V_a* = the task's trim airspeed,
    hdot* = clamp(hdot_s + (c* - c) / tau, +-hdot_max)

hdot_s the rate of the water under the aircraft (the task's ``surface_rate``: the climb rate minus the
altimeter's rate), so that the aircraft follows the waves, and the clearance error closed in ``tau``
(``time_constant``, 1 s). It reads ("task", ...) commanded_clearance, clearance and surface_rate, what a
radar altimeter and an air-data/inertial unit give, and the true state like the other LQRs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch
from tensordict import TensorDictBase

from ..airframe import Airframe
from ..envs.layout import flat_scalars
from .lqr import AttitudeLQR, attitude_schedule

if TYPE_CHECKING:
    from ..envs import FixedWingEnv

#: Clearances (spans) and airspeeds (fractions of cruise) of the ground-effect gain schedule: the task holds
#: the trim airspeed, so three airspeeds span what it flies.
SCHEDULE_CLEARANCES: tuple[float, ...] = (0.15, 0.25, 0.5, 1.0, 2.0)
SCHEDULE_SPEEDS: tuple[float, ...] = (0.9, 1.0, 1.1)


class SeaSkimmingLQR(AttitudeLQR):
    """Clearance hold over the waves (module docstring): action [elevator, aileron, rudder, throttle]."""

    command_keys = ("commanded_clearance", "clearance", "surface_rate")

    def __init__(self, airframe: Airframe, dt: float = 0.01, ground_effect: bool | str = True,
                 device: str | torch.device = "cpu", dtype: torch.dtype = torch.float32,
                 airspeed: float | None = None, time_constant: float = 1.0):
        span = airframe.geometry.span
        heights = tuple(round(f * span, 4) for f in SCHEDULE_CLEARANCES)
        schedule = attitude_schedule(airframe, dt, heights=heights, ground_effect=ground_effect,
                                     speed_fractions=SCHEDULE_SPEEDS)
        super().__init__(airframe, dt, device, dtype, schedule=schedule)
        self.airspeed = float(airspeed or airframe.envelope.cruise_speed)
        self.time_constant = float(time_constant)
        self.climb_limit = float(airframe.envelope.climb_rate_limit)

    @classmethod
    def from_env(cls, env: FixedWingEnv) -> SeaSkimmingLQR:  # type: ignore[override]
        """The controller of ``env``'s airframe, control step, ground-effect mode, trim airspeed, device and
        dtype (any task publishing the ("task", ...) clearance entries)."""
        task = env.task
        return cls(env.sim.airframe, env.control_dt, env.config.ground_effect, env.device, env.sim.dtype,
                   airspeed=getattr(task, "trim_airspeed", None))

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        v = flat_scalars(td)  # [N] scalars
        commanded, clearance, surface_rate = (v["task", k] for k in self.command_keys)
        climb = (surface_rate + (commanded - clearance) / self.time_constant).clamp(-self.climb_limit,
                                                                                     self.climb_limit)
        bank = torch.zeros_like(climb)
        speed = torch.full_like(climb, self.airspeed)
        td.set(self.out_keys[0], self.control(v, bank, climb, speed, clearance))
        return td


__all__ = ["SCHEDULE_CLEARANCES", "SCHEDULE_SPEEDS", "SeaSkimmingLQR"]
