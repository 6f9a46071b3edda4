"""Control-surface and throttle actuators.

Commands in [-1, 1] are clipped and mapped affinely onto [min, max] deflection (surfaces) or
[0, 1] (throttle). Surfaces are first order (x' = (x_c - x)/tau) or second order
(x'' = w_n^2 (x_c - x) - 2 zeta w_n x'); each motor's throttle is first order. Positions used by
the forces are clamped to the limits, and ``saturate`` clamps the integrated state after each step
(zeroing the rate where the limit is hit).

Model switches (``switches.ModelSwitches``), per env: with ``ideal_actuators`` the surfaces follow
the command with zero lag (``hold_ideal`` sets position = clamped target and rate = 0 before each
step, the command is held over the step and the derivative is zero); with ``ideal_throttle`` the
throttle state is likewise the commanded throttle.
"""

from __future__ import annotations

import torch

from ._warp import warp_func, wp
from .params import ModelParams, WarpParams
from .state import SURFACE_POSITION_START, SURFACE_RATE_START, THROTTLE, THROTTLE_START, StateVec


def command_targets(command: torch.Tensor, p: ModelParams) -> tuple[torch.Tensor, torch.Tensor]:
    """Physical targets from normalised commands [N, 4] -> (surfaces [N, 3] rad, throttle [N])."""
    u = command.clamp(-1.0, 1.0)
    surfaces = p.surface_min + 0.5 * (u[:, :3] + 1.0) * (p.surface_max - p.surface_min)
    throttle = 0.5 * (u[:, THROTTLE] + 1.0)
    return surfaces, throttle


def normalised_command(surfaces: torch.Tensor, throttle: torch.Tensor, p: ModelParams
                       ) -> torch.Tensor:
    """Inverse of :func:`command_targets`: [N, 3] rad and [N] throttle -> [N, 4] in [-1, 1]."""
    u_surf = 2.0 * (surfaces - p.surface_min) / (p.surface_max - p.surface_min) - 1.0
    return torch.cat([u_surf, (2.0 * throttle - 1.0).unsqueeze(-1)], dim=-1)


def actuator_derivative(
    position: torch.Tensor, rate: torch.Tensor, throttle: torch.Tensor, command: torch.Tensor,
    p: ModelParams,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(d position [N, 3], d rate [N, 3], d throttle [N, M]) for the actuator states."""
    target, throttle_target = command_targets(command, p)
    wn = p.actuator_natural_frequency
    second = p.actuator_second_order
    d_pos = torch.where(second, rate, (target - position) / p.actuator_time_constant)
    d_rate = torch.where(second, wn * wn * (target - position) - 2.0 * p.actuator_damping * wn * rate,
                         torch.zeros_like(rate))
    d_throttle = (throttle_target.unsqueeze(-1) - throttle) / p.throttle_time_constant
    ideal = (p.ideal_actuators != 0).unsqueeze(-1)
    d_pos = d_pos.masked_fill(ideal, 0.0)
    d_rate = d_rate.masked_fill(ideal, 0.0)
    d_throttle = d_throttle.masked_fill((p.ideal_throttle != 0).unsqueeze(-1), 0.0)
    return d_pos, d_rate, d_throttle


def hold_ideal(position: torch.Tensor, rate: torch.Tensor, throttle: torch.Tensor, command: torch.Tensor,
               p: ModelParams) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Actuator states at the start of a step: in ideal-actuator envs position [N, 3] = clamped
    target and rate [N, 3] = 0, in ideal-throttle envs throttle [N, M] = commanded throttle; the
    others unchanged. With the derivative zero there, the states stay on the command over the step."""
    target, throttle_target = command_targets(command, p)
    target = torch.minimum(torch.maximum(target, p.surface_min), p.surface_max)
    ideal = (p.ideal_actuators != 0).unsqueeze(-1)
    position = torch.where(ideal, target, position)
    rate = rate.masked_fill(ideal, 0.0)
    instant = (p.ideal_throttle != 0).unsqueeze(-1)
    throttle = torch.where(instant, throttle_target.unsqueeze(-1).expand_as(throttle), throttle)
    return position, rate, throttle


def saturate(position: torch.Tensor, rate: torch.Tensor, throttle: torch.Tensor, p: ModelParams
             ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Clamp integrated actuator states to their limits; zero the rate where clamped."""
    clamped = torch.minimum(torch.maximum(position, p.surface_min), p.surface_max)
    rate = rate.masked_fill(clamped != position, 0.0)
    return clamped, rate, throttle.clamp(0.0, 1.0)


# ---------------------------------------------------------------------------------------- warp twins
@warp_func
def actuator_derivative_wp(x: StateVec, command: wp.vec4, p: WarpParams, i: int) -> StateVec:
    """Actuator part of the state derivative of env ``i`` (twin of :func:`actuator_derivative`):
    only the surface position, surface rate and throttle slots of the result are non-zero."""
    u = wp.vec4(wp.clamp(command[0], -1.0, 1.0), wp.clamp(command[1], -1.0, 1.0),
                wp.clamp(command[2], -1.0, 1.0), wp.clamp(command[3], -1.0, 1.0))
    lo = p.surface_min[i]
    hi = p.surface_max[i]
    tau = p.actuator_time_constant[i]
    wn = p.actuator_natural_frequency[i]
    zeta = p.actuator_damping[i]
    d = StateVec()
    for j in range(3):
        target = lo[j] + 0.5 * (u[j] + 1.0) * (hi[j] - lo[j])
        position = x[SURFACE_POSITION_START + j]
        rate = x[SURFACE_RATE_START + j]
        if p.actuator_second_order[i, j]:
            d[SURFACE_POSITION_START + j] = rate
            d[SURFACE_RATE_START + j] = wn[j] * wn[j] * (target - position) - 2.0 * zeta[j] * wn[j] * rate
        else:
            d[SURFACE_POSITION_START + j] = (target - position) / tau[j]
    if p.ideal_actuators[i] != 0:
        for j in range(3):
            d[SURFACE_POSITION_START + j] = 0.0
            d[SURFACE_RATE_START + j] = 0.0
    throttle_target = 0.5 * (u[3] + 1.0)
    if p.ideal_throttle[i] == 0:
        for m in range(p.num_motors):
            k = THROTTLE_START + m
            d[k] = (throttle_target - x[k]) / p.throttle_time_constant[i, m]
    return d


@warp_func
def hold_ideal_wp(x: StateVec, command: wp.vec4, p: WarpParams, i: int) -> StateVec:
    """Actuator states of env ``i`` at the start of a step (twin of :func:`hold_ideal`)."""
    y = StateVec(x)
    if p.ideal_actuators[i] != 0:
        lo = p.surface_min[i]
        hi = p.surface_max[i]
        for j in range(3):
            target = lo[j] + 0.5 * (wp.clamp(command[j], -1.0, 1.0) + 1.0) * (hi[j] - lo[j])
            y[SURFACE_POSITION_START + j] = wp.min(wp.max(target, lo[j]), hi[j])
            y[SURFACE_RATE_START + j] = 0.0
    if p.ideal_throttle[i] != 0:
        for m in range(p.num_motors):
            y[THROTTLE_START + m] = 0.5 * (wp.clamp(command[3], -1.0, 1.0) + 1.0)
    return y


@warp_func
def saturate_wp(x: StateVec, p: WarpParams, i: int) -> StateVec:
    """Clamp surfaces to their limits (zeroing the rate where clamped) and throttles to [0, 1]
    (twin of :func:`saturate`)."""
    y = StateVec(x)
    lo = p.surface_min[i]
    hi = p.surface_max[i]
    for j in range(3):
        k = SURFACE_POSITION_START + j
        clamped = wp.min(wp.max(x[k], lo[j]), hi[j])
        if clamped != x[k]:
            y[SURFACE_RATE_START + j] = 0.0
        y[k] = clamped
    for m in range(p.num_motors):
        k = THROTTLE_START + m
        y[k] = wp.clamp(x[k], 0.0, 1.0)
    return y
