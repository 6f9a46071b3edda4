"""Gain-scheduled LQRI policies for the altitude and attitude tasks (TensorDictModules).

Gains are designed offline (``lqr_design``) on a grid of trim points and interpolated bilinearly
in (height, airspeed) at run time, so one controller serves the whole protocol, ground effect
included. The control law at each env step, for the reduced state x (``linear_models``):

    z  <- clamp(z + dt (y - r), +-z_max)            integrators, reset at t = 0 of each episode
    u   = u_trim - K_x (x - x_ref) - K_z z          normalised commands, clipped to [-1, 1]

Altitude task: y = h, r = h_ref, with the reference pitch raised by the reference flight-path
angle hdot_ref / V. Attitude task: y = (phi, hdot, V_a), r = the commands, with x_ref carrying the
coordinated-turn body rates of the commanded bank. The policies read only ("state", ...) and
("task", ...) keys (the true state) and write "action".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from ..airframe import Airframe
from ..constants import G0
from ..envs.layout import flat_scalars
from ..physics import state as S
from ..physics.trim import TrimError, trim_level
from .linear_models import (
    FULL_INDEX,
    FULL_STATES,
    LONGITUDINAL_INDEX,
    LONGITUDINAL_STATES,
    climb_rate_row,
    linear_model_at,
    reduced_state,
)
from .lqr_design import design_lqri

if TYPE_CHECKING:
    from ..envs import FixedWingEnv

#: Body velocity (u, v, w) and body rates (p, q, r) in the full reduced state.
_UVW = [FULL_INDEX[name] for name in ("u", "v", "w")]
_PQR = [FULL_INDEX[name] for name in ("p", "q", "r")]

#: Bryson maxima (SI, rad) shared by all airframes.
ALTITUDE_STATE_MAX = {"u": 1.0, "w": 2.0, "q": 0.3, "theta": 0.15, "h": 1.0}
ALTITUDE_INPUT_MAX = np.array([0.3, 0.6])
ALTITUDE_INTEGRAL_MAX = np.array([3.0])
ATTITUDE_STATE_MAX = {"u": 1.0, "v": 1.0, "w": 2.0, "p": 0.5, "q": 0.3, "r": 0.3, "phi": 0.05,
                      "theta": 0.15}
ATTITUDE_INPUT_MAX = np.array([0.3, 0.3, 0.3, 0.3])
ATTITUDE_INTEGRAL_MAX = np.array([0.1, 1.0, 1.0])


@dataclass
class GainSchedule:
    """Gains and trims on a (height, airspeed) grid. Gh x Gv points, n states, m inputs, k integrators."""

    heights: torch.Tensor  # [Gh] m
    airspeeds: torch.Tensor  # [Gv] m/s
    K: torch.Tensor  # [Gh, Gv, m, n + k]
    x_trim: torch.Tensor  # [Gh, Gv, n]
    u_trim: torch.Tensor  # [Gh, Gv, m]
    outputs: torch.Tensor  # [Gh, Gv, k, n] tracked-output rows C
    spectral_radius: float  # worst closed-loop |z| over the grid

    def at(self, height: torch.Tensor, airspeed: torch.Tensor
           ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Bilinear interpolation at [N] points -> (K [N, m, n+k], x_trim, u_trim, C)."""
        wh, ih = _weights(self.heights, height)
        wv, iv = _weights(self.airspeeds, airspeed)

        def blend(table: torch.Tensor) -> torch.Tensor:
            out = 0.0
            for a in range(2):
                for b in range(2):
                    w = (wh[:, a] * wv[:, b]).reshape(-1, *([1] * (table.dim() - 2)))
                    out = out + w * table[ih[:, a], iv[:, b]]
            return out

        return blend(self.K), blend(self.x_trim), blend(self.u_trim), blend(self.outputs)

    def to(self, device: torch.device, dtype: torch.dtype) -> GainSchedule:
        return GainSchedule(*(t.to(device, dtype) for t in (self.heights, self.airspeeds, self.K,
                                                            self.x_trim, self.u_trim, self.outputs)),
                            self.spectral_radius)


def _weights(grid: torch.Tensor, value: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Linear-interpolation weights [N, 2] and indices [N, 2] into ``grid`` (clamped at the ends)."""
    if grid.numel() == 1:
        zeros = torch.zeros(value.shape[0], 2, dtype=torch.long, device=value.device)
        return torch.tensor([1.0, 0.0], dtype=value.dtype, device=value.device).expand(
            value.shape[0], 2), zeros
    v = value.clamp(float(grid[0]), float(grid[-1]))
    hi = torch.searchsorted(grid, v.contiguous()).clamp(1, grid.numel() - 1)
    lo = hi - 1
    t = ((v - grid[lo]) / (grid[hi] - grid[lo])).clamp(0.0, 1.0)
    return torch.stack([1 - t, t], dim=-1), torch.stack([lo, hi], dim=-1)


def _grid(airframe: Airframe, heights: list[float], speeds: list[float], full: bool,
          ground_effect: bool | str, dt: float) -> GainSchedule:
    grid_h = torch.tensor(heights, dtype=torch.float64).repeat_interleave(len(speeds))
    grid_v = torch.tensor(speeds, dtype=torch.float64).repeat(len(heights))
    trims = trim_level(airframe, grid_v, grid_h, ground_effect=ground_effect)  # one batched solve
    Ks, xs, us, cs, radius = [], [], [], [], 0.0
    for i in range(grid_h.numel()):
        model = linear_model_at(airframe, trims, i, full=full, ground_effect=ground_effect)
        n = model.A.shape[0]
        if full:
            outputs = np.zeros((3, n))
            outputs[0, FULL_INDEX["phi"]] = 1.0
            outputs[1] = climb_rate_row(model)
            uvw = model.x_trim[_UVW]
            outputs[2, _UVW] = uvw / np.linalg.norm(uvw)
            gain = design_lqri(model, dt, outputs, ATTITUDE_STATE_MAX, ATTITUDE_INPUT_MAX,
                               ATTITUDE_INTEGRAL_MAX)
        else:
            outputs = np.zeros((1, n))
            outputs[0, LONGITUDINAL_INDEX["h"]] = 1.0
            gain = design_lqri(model, dt, outputs, ALTITUDE_STATE_MAX, ALTITUDE_INPUT_MAX,
                               ALTITUDE_INTEGRAL_MAX)
        radius = max(radius, gain.spectral_radius)
        Ks.append(gain.K)
        xs.append(model.x_trim)
        us.append(model.u_trim)
        cs.append(outputs)
    shape = (len(heights), len(speeds))

    def t(a) -> torch.Tensor:
        return torch.as_tensor(np.asarray(a), dtype=torch.float64)

    def grid(rows: list) -> torch.Tensor:
        table = t(rows)
        return table.reshape(*shape, *table.shape[1:])

    return GainSchedule(t(heights), t(speeds), grid(Ks), grid(xs), grid(us), grid(cs), radius)


def _trimmable_speeds(airframe: Airframe, fractions: tuple[float, ...], *heights: float,
                      ground_effect: bool | str = True) -> list[float]:
    """The airspeeds ``fractions`` x cruise at which the airframe trims at every one of ``heights``."""
    speeds = []
    for f in fractions:
        v = f * airframe.envelope.cruise_speed
        try:
            for height in heights:
                trim_level(airframe, v, height, ground_effect=ground_effect)
        except TrimError:
            continue
        speeds.append(v)
    return speeds


def altitude_schedule(airframe: Airframe, dt: float, ground_effect: bool | str = True) -> GainSchedule:
    """Longitudinal LQRI on heights (0.5, 1, 2, 4, 8) b and 150 m x airspeeds 0.85..1.15 cruise."""
    b = airframe.geometry.span
    heights = sorted({round(f * b, 3) for f in (0.5, 1.0, 2.0, 4.0, 8.0)} | {150.0})
    speeds = _trimmable_speeds(airframe, (0.85, 1.0, 1.15), 100.0)
    return _grid(airframe, heights, speeds, False, ground_effect, dt)


def attitude_schedule(airframe: Airframe, dt: float, height: float = 100.0,
                      heights: tuple[float, ...] | None = None, ground_effect: bool | str = False,
                      speed_fractions: tuple[float, ...] = (0.8, 0.9, 1.0, 1.1, 1.2)) -> GainSchedule:
    """Full-state LQRI (bank, climb rate, airspeed) at ``height`` (or on the grid ``heights``, m, with
    ``ground_effect``) x airspeeds ``speed_fractions`` of cruise (those that trim at every height)."""
    grid = list(heights or (height,))
    speeds = _trimmable_speeds(airframe, speed_fractions, *grid, ground_effect=ground_effect)
    return _grid(airframe, grid, speeds, True, ground_effect, dt)


class _LQRPolicy(TensorDictModuleBase):
    def __init__(self, schedule: GainSchedule, dt: float, integral_limit: torch.Tensor,
                 in_keys: list, out_key: str = "action"):
        super().__init__()
        self.in_keys = in_keys
        self.out_keys = [out_key]
        self.schedule = schedule
        self.dt = float(dt)
        self.integral_limit = integral_limit
        self.integral: torch.Tensor | None = None
        self.feedforward: torch.Tensor | None = None
        self.feedforward_tau = 1.0

    def _integrate(self, error: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        if self.integral is None or self.integral.shape != error.shape:
            self.integral = torch.zeros_like(error)
        fresh = (time <= 0.5 * self.dt).unsqueeze(-1)
        limit = self.integral_limit.to(error)
        z = torch.where(fresh, torch.zeros_like(error), self.integral + self.dt * error)
        self.integral = torch.maximum(torch.minimum(z, limit), -limit)
        return self.integral

    def _smooth(self, value: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        """First-order filter (time constant ``feedforward_tau``) of a feedforward term, so that
        reference steps do not kick the surfaces; restarts from 0 at each episode start."""
        if self.feedforward is None or self.feedforward.shape != value.shape:
            self.feedforward = torch.zeros_like(value)
        fresh = time <= 0.5 * self.dt
        blend = self.dt / (self.feedforward_tau + self.dt)
        self.feedforward = torch.where(fresh, torch.zeros_like(value),
                                       self.feedforward + blend * (value - self.feedforward))
        return self.feedforward

    def _control(self, x: torch.Tensor, x_ref: torch.Tensor, z: torch.Tensor, K: torch.Tensor,
                 u_trim: torch.Tensor) -> torch.Tensor:
        err = torch.cat([x - x_ref, z], dim=-1)
        return (u_trim - (K @ err.unsqueeze(-1)).squeeze(-1)).clamp(-1.0, 1.0)


class AltitudeLQR(_LQRPolicy):
    """LQRI for the altitude task: action [elevator, throttle]."""

    def __init__(self, airframe: Airframe, dt: float = 0.01, ground_effect: bool | str = True,
                 device: str | torch.device = "cpu", dtype: torch.dtype = torch.float32):
        schedule = altitude_schedule(airframe, dt, ground_effect).to(torch.device(device), dtype)
        limit = torch.tensor(3.0 * ALTITUDE_INTEGRAL_MAX, dtype=dtype, device=device)
        keys = [("state", k) for k in ("velocity_body", "angular_rate_body", "euler", "height",
                                       "airspeed", "surface_position", "throttle", "time")]
        super().__init__(schedule, dt, limit, [*keys, ("task", "reference_altitude"),
                                               ("task", "reference_climb_rate")])

    @classmethod
    def from_env(cls, env: FixedWingEnv) -> AltitudeLQR:
        """The LQRI of ``env``'s airframe, control step, ground-effect mode, device and dtype (any task
        that publishes ("task", "reference_altitude") and ("task", "reference_climb_rate"))."""
        return cls(env.sim.airframe, env.control_dt, env.config.ground_effect, env.device, env.sim.dtype)

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        v = flat_scalars(td)  # [N] scalars
        height, airspeed = v["state", "height"], v["state", "airspeed"]
        x = reduced_state(v["state"], LONGITUDINAL_STATES)
        K, x_trim, u_trim, _ = self.schedule.at(height, airspeed)
        h_ref = v["task", "reference_altitude"]
        x_ref = x_trim.clone()
        x_ref[:, LONGITUDINAL_INDEX["h"]] = h_ref
        gamma = v["task", "reference_climb_rate"] / airspeed.clamp_min(1.0)
        x_ref[:, LONGITUDINAL_INDEX["theta"]] += self._smooth(gamma, v["state", "time"])
        z = self._integrate((height - h_ref).unsqueeze(-1), v["state", "time"])
        td.set(self.out_keys[0], self._control(x, x_ref, z, K, u_trim))
        return td


class AttitudeLQR(_LQRPolicy):
    """LQRI for the attitude task: action [elevator, aileron, rudder, throttle]."""

    #: The ("task", ...) commands the policy reads.
    command_keys: tuple[str, ...] = ("bank_command", "climb_rate_command", "airspeed_command")

    def __init__(self, airframe: Airframe, dt: float = 0.01, device: str | torch.device = "cpu",
                 dtype: torch.dtype = torch.float32, schedule: GainSchedule | None = None):
        schedule = (schedule or attitude_schedule(airframe, dt)).to(torch.device(device), dtype)
        limit = torch.tensor(3.0 * ATTITUDE_INTEGRAL_MAX, dtype=dtype, device=device)
        keys = [("state", k) for k in ("velocity_body", "velocity_ned", "angular_rate_body", "euler",
                                       "height", "airspeed", "surface_position", "throttle", "time")]
        super().__init__(schedule, dt, limit, [*keys, *(("task", k) for k in self.command_keys)])

    @classmethod
    def from_env(cls, env: FixedWingEnv) -> AttitudeLQR:
        """The LQRI of ``env``'s airframe, control step, device and dtype (any task that publishes the
        ("task", ...) bank, climb-rate and airspeed commands)."""
        return cls(env.sim.airframe, env.control_dt, env.device, env.sim.dtype)

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        v = flat_scalars(td)  # [N] scalars
        bank, climb, speed = (v["task", k] for k in self.command_keys)
        td.set(self.out_keys[0], self.control(v, bank, climb, speed, v["state", "height"]))
        return td

    def control(self, v: TensorDictBase, bank: torch.Tensor, climb: torch.Tensor, speed: torch.Tensor,
                height: torch.Tensor) -> torch.Tensor:
        """[N, 4] action holding ``bank`` (rad), ``climb`` (m/s) and ``speed`` (m/s) [N] from the [N]
        scalars ``v`` of the env's TensorDict, with the gains scheduled at ``height`` [N] m."""
        euler, airspeed = v["state", "euler"], v["state", "airspeed"]
        x = reduced_state(v["state"], FULL_STATES)
        K, x_trim, u_trim, _ = self.schedule.at(height, airspeed)
        x_ref = x_trim.clone()
        uvw = x_trim[:, _UVW]
        x_ref[:, _UVW] = uvw * (speed / uvw.norm(dim=-1)).unsqueeze(-1)
        gamma = self._smooth(climb / speed.clamp_min(1.0), v["state", "time"])
        theta = x_trim[:, FULL_INDEX["theta"]] + gamma
        yaw_rate = G0 * torch.tan(bank) / speed.clamp_min(1.0)
        # Coordinated turn: body rates (p, q, r) of the yaw rate at bank phi and pitch theta.
        x_ref[:, _PQR] = yaw_rate.unsqueeze(-1) * torch.stack(
            [-torch.sin(theta), torch.sin(bank) * torch.cos(theta), torch.cos(bank) * torch.cos(theta)],
            dim=-1)
        x_ref[:, FULL_INDEX["phi"]] = bank
        x_ref[:, FULL_INDEX["theta"]] = theta
        climb_rate = -v["state", "velocity_ned"][:, S.DOWN]
        error = torch.stack([euler[:, S.ROLL] - bank, climb_rate - climb, airspeed - speed], dim=-1)
        z = self._integrate(error, v["state", "time"])
        return self._control(x, x_ref, z, K, u_trim)


__all__ = ["AltitudeLQR", "AttitudeLQR", "GainSchedule", "altitude_schedule", "attitude_schedule"]
