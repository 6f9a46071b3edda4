"""Attitude-command streams (phi*, hdot*, V_a*)(t): the paper's four maneuvers and random streams.

Every maneuver is built from the airframe's own envelope, so a name denotes a comparable
difficulty rather than a comparable geometry (the paper's maneuver table). With V = cruise speed and
phi_c = ``CIRCLE_BANK_FRACTION`` x max_bank (28 of 45 deg, the paper's Volantex Ranger circle):

    maneuver   bank phi_max       turn radius R = V^2 / (g tan phi_max)   load factor n = 1/cos phi_max
    circle     phi_c              hold max(30 s, one full turn), hdot* = 0
    figure8    phi_c              one full turn right, reverse, one full turn left
    helix      0.6 phi_c          two full turns climbing at min(1 m/s, climb_rate_limit / 2)
    s_turn     0.7 phi_c          phi_max sin(2 pi t / P), 3 periods, P = pi^2 R / (2 V)
                                  (each lobe turns the heading by about 90 deg)

Every stream starts with ``LEAD_IN_S`` of level flight, rolls in and out with a half-cosine ramp of
``ROLL_S`` and ends with ``LEAD_IN_S`` of level flight. On the Volantex Ranger this gives 28.0 / 16.8 /
19.6 deg and R = 43 / 76 / 64 m, the paper's values.

:class:`RandomCommandStream` draws training streams: piecewise-constant targets held U(3, 10) s,
slewed at bounded rates, with bank in +-0.8 max_bank, climb rate in +-0.6 climb_rate_limit and
airspeed in [1.3 V_stall, 0.9 V_max] around cruise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..airframe import Airframe
from ..constants import G0

CIRCLE_BANK_FRACTION = 28.0 / 45.0
BANK_RATIO = {"circle": 1.0, "figure8": 1.0, "helix": 0.6, "s_turn": 0.7}
MANEUVERS: tuple[str, ...] = tuple(BANK_RATIO)
LEAD_IN_S = 2.0
ROLL_S = 2.0


@dataclass(frozen=True)
class ManeuverSpec:
    """Geometry of one maneuver on one airframe (SI units, angles in rad)."""

    name: str
    bank: float  # phi_max
    radius: float  # R, m, of a steady turn at phi_max and cruise speed
    load_factor: float  # n = 1 / cos(phi_max)
    airspeed: float  # m/s
    climb_rate: float  # m/s


def maneuver_spec(name: str, airframe: Airframe) -> ManeuverSpec:
    """The row of the paper's maneuver table for ``name`` on ``airframe``."""
    if name not in BANK_RATIO:
        raise ValueError(f"unknown maneuver {name!r}; choose one of {MANEUVERS}")
    env = airframe.envelope
    bank = BANK_RATIO[name] * CIRCLE_BANK_FRACTION * env.max_bank
    v = env.cruise_speed
    climb = min(1.0, 0.5 * env.climb_rate_limit) if name == "helix" else 0.0
    return ManeuverSpec(name, bank, v * v / (G0 * math.tan(bank)), 1.0 / math.cos(bank), v, climb)


def _ramp(t: torch.Tensor, start: float, duration: float) -> torch.Tensor:
    """Half-cosine step from 0 (t <= start) to 1 (t >= start + duration)."""
    s = ((t - start) / duration).clamp(0.0, 1.0)
    return 0.5 - 0.5 * torch.cos(math.pi * s)


def maneuver_stream(name: str, airframe: Airframe, dt: float) -> torch.Tensor:
    """Command stream [T, 3] = (bank rad, climb rate m/s, airspeed m/s), sampled every ``dt`` s."""
    spec = maneuver_spec(name, airframe)
    turn_s = 2.0 * math.pi * spec.radius / spec.airspeed
    on = LEAD_IN_S
    if name == "circle":
        hold = max(30.0, turn_s)
        total = on + 2 * ROLL_S + hold + LEAD_IN_S
        t = torch.arange(0.0, total, dt, dtype=torch.float64)
        bank = spec.bank * (_ramp(t, on, ROLL_S) - _ramp(t, on + ROLL_S + hold, ROLL_S))
    elif name == "figure8":
        total = on + 4 * ROLL_S + 2 * turn_s + LEAD_IN_S
        t = torch.arange(0.0, total, dt, dtype=torch.float64)
        reverse = on + ROLL_S + turn_s
        bank = spec.bank * (_ramp(t, on, ROLL_S) - 2.0 * _ramp(t, reverse, 2 * ROLL_S)
                            + _ramp(t, reverse + 2 * ROLL_S + turn_s, ROLL_S))
    elif name == "helix":
        hold = 2.0 * turn_s
        total = on + 2 * ROLL_S + hold + LEAD_IN_S
        t = torch.arange(0.0, total, dt, dtype=torch.float64)
        envelope = _ramp(t, on, ROLL_S) - _ramp(t, on + ROLL_S + hold, ROLL_S)
        bank = spec.bank * envelope
    else:  # s_turn
        period = math.pi**2 * spec.radius / (2.0 * spec.airspeed)
        total = on + 3 * period + LEAD_IN_S
        t = torch.arange(0.0, total, dt, dtype=torch.float64)
        weaving = (t >= on) & (t < on + 3 * period)
        bank = torch.where(weaving, spec.bank * torch.sin(2 * math.pi * (t - on) / period), 0.0)
    climb = spec.climb_rate * (bank.abs() / spec.bank if name == "helix" else torch.zeros_like(t))
    airspeed = torch.full_like(t, spec.airspeed)
    return torch.stack([bank, climb, airspeed], dim=-1).float()


class RandomCommandStream:
    """Vectorised random (phi*, hdot*, V_a*) streams for training, one per env. Shapes [N, 3].

    Its state (command, target, timer) and its draws at a reset live here; its step (the timer runs
    down by dt, an expired target and hold are redrawn from 4 uniforms, the command slews toward the
    target at ``rate``) is the attitude task's Warp function ``random_stream_step``."""

    def __init__(self, airframe: Airframe, num_envs: int, generator: torch.Generator, dt: float,
                 device: torch.device, dtype: torch.dtype = torch.float32,
                 hold_seconds: tuple[float, float] = (3.0, 10.0)):
        env = airframe.envelope
        kw = {"device": device, "dtype": dtype}
        self.generator, self.dt, self.hold_seconds = generator, dt, hold_seconds
        self.low = torch.tensor([-0.8 * env.max_bank, -0.6 * env.climb_rate_limit,
                                 max(1.3 * env.stall_speed, 0.8 * env.cruise_speed)], **kw)
        self.high = torch.tensor([0.8 * env.max_bank, 0.6 * env.climb_rate_limit,
                                  min(0.9 * env.max_speed, 1.2 * env.cruise_speed)], **kw)
        #: Slew rates: 15 deg/s of bank, 0.5 m/s^2 of climb rate, 0.5 m/s^2 of airspeed.
        self.rate = torch.tensor([math.radians(15.0), 0.5, 0.5], **kw)
        self.level = torch.tensor([0.0, 0.0, env.cruise_speed], **kw)
        self.command = self.level.expand(num_envs, 3).clone()
        self.target = self.command.clone()
        self.timer = torch.zeros(num_envs, **kw)

    def _draw(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(target [N, 3], hold time [N]) from 4 float32 uniforms per env (float32 whatever the stream's
        dtype: the task's Warp step draws the same)."""
        n = self.command.shape[0]
        u = torch.rand(n, 4, generator=self.generator, device=self.command.device, dtype=torch.float32)
        u = u.to(self.command.dtype)
        target = self.low + (self.high - self.low) * u[:, :3]
        lo, hi = self.hold_seconds
        return target, lo + (hi - lo) * u[:, 3]

    def reset(self, mask: torch.Tensor) -> None:
        """Rows in ``mask`` [N] restart from level cruise with a fresh target."""
        target, timer = self._draw()
        self.command.copy_(torch.where(mask[:, None], self.level, self.command))
        self.target.copy_(torch.where(mask[:, None], target, self.target))
        self.timer.copy_(torch.where(mask, timer, self.timer))
