"""Six-degree-of-freedom rigid-body dynamics: f(state, command, params, air) -> state derivative.

    p_dot  = R(q) v                                (NED position)
    q_dot  = 1/2 q (x) (0, omega)                  (unit quaternion, renormalised after each step)
    v_dot  = (F_aero + F_prop) / m + R(q)^T g - omega x v
    w_dot  = J^-1 (M_aero + M_prop - omega x J omega)

The aero model sees the air-relative velocity V_a = v - R^T w_ned - w_gust and the rates
omega - omega_gust, so wind and turbulence act on alpha, beta and dynamic pressure.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from . import state as S
from .actuators import actuator_derivative, saturate
from .aero import aero_forces
from .atmosphere import isa_density
from .params import ModelParams
from .propulsion import propulsion_forces
from .rotations import normalize_quaternion, quaternion_derivative, rotation_matrix


@dataclass
class AirInputs:
    """Air-mass motion seen by each env (None fields mean still air)."""

    wind_ned: torch.Tensor | None = None  # [N, 3] m/s, steady wind in NED
    gust_velocity_body: torch.Tensor | None = None  # [N, 3] m/s
    gust_rate_body: torch.Tensor | None = None  # [N, 3] rad/s


@dataclass
class Evaluation:
    """Everything the derivative computes on the way, for diagnostics and trim."""

    force_body: torch.Tensor  # [N, 3] total non-gravity force
    moment_body: torch.Tensor  # [N, 3]
    aero_force_body: torch.Tensor  # [N, 3]
    thrust: torch.Tensor  # [N, M]
    coefficients: torch.Tensor  # [N, 6]
    induced_drag_coefficient: torch.Tensor  # [N]
    kappa_lift: torch.Tensor  # [N]
    kappa_drag: torch.Tensor  # [N]
    airspeed: torch.Tensor  # [N]
    alpha: torch.Tensor  # [N]
    beta: torch.Tensor  # [N]
    density: torch.Tensor  # [N]
    height: torch.Tensor  # [N] CG height above ground
    wing_height: torch.Tensor  # [N] height of the wing quarter chord
    rotation: torch.Tensor  # [N, 3, 3] body -> NED
    surfaces: torch.Tensor  # [N, 3] clamped deflections, rad


def air_data(v_air_body: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(airspeed, alpha, beta), each [N], from air-relative body velocity [N, 3]."""
    u, v, w = v_air_body.unbind(-1)
    airspeed = torch.sqrt(u * u + v * v + w * w + 1e-12)
    alpha = torch.atan2(w, u)
    beta = torch.asin(torch.clamp(v / airspeed, -1.0, 1.0))
    return airspeed, alpha, beta


def evaluate(x: torch.Tensor, p: ModelParams, air: AirInputs | None = None) -> Evaluation:
    """Forces, moments and air data at state x [N, S]. The surfaces sit where the actuator
    states put them (clamped to their limits), so the command is not needed here."""
    q = x[:, S.QUATERNION]
    vel = x[:, S.VELOCITY]
    omega = x[:, S.ANGULAR_RATE]
    rot = rotation_matrix(q)
    v_air = vel
    omega_air = omega
    if air is not None:
        if air.wind_ned is not None:
            v_air = v_air - (rot.transpose(-1, -2) @ air.wind_ned.unsqueeze(-1)).squeeze(-1)
        if air.gust_velocity_body is not None:
            v_air = v_air - air.gust_velocity_body
        if air.gust_rate_body is not None:
            omega_air = omega - air.gust_rate_body
    airspeed, alpha, beta = air_data(v_air)
    height = -x[:, 2]
    wing_height = height - (rot[:, 2, :] * p.wing_quarter_chord).sum(-1)
    density = isa_density(height)
    surfaces = torch.minimum(torch.maximum(x[:, S.SURFACE_POSITION], p.surface_min), p.surface_max)
    aero = aero_forces(airspeed, alpha, beta, omega_air, surfaces, density,
                       wing_height / p.span, p)
    throttle = x[:, S.THROTTLE_START:]
    f_prop, m_prop, thrust = propulsion_forces(v_air, throttle, density, p)
    return Evaluation(
        force_body=aero.force_body + f_prop,
        moment_body=aero.moment_body + m_prop,
        aero_force_body=aero.force_body,
        thrust=thrust,
        coefficients=aero.coefficients,
        induced_drag_coefficient=aero.induced_drag_coefficient,
        kappa_lift=aero.kappa_lift,
        kappa_drag=aero.kappa_drag,
        airspeed=airspeed,
        alpha=alpha,
        beta=beta,
        density=density,
        height=height,
        wing_height=wing_height,
        rotation=rot,
        surfaces=surfaces,
    )


def derivative(x: torch.Tensor, command: torch.Tensor, p: ModelParams,
               air: AirInputs | None = None) -> torch.Tensor:
    """State derivative [N, S] at state x [N, S] under normalised command [N, 4]."""
    ev = evaluate(x, p, air)
    q = x[:, S.QUATERNION]
    vel = x[:, S.VELOCITY]
    omega = x[:, S.ANGULAR_RATE]
    gravity_ned = torch.zeros_like(vel)
    gravity_ned[:, 2] = p.gravity
    gravity_body = (ev.rotation.transpose(-1, -2) @ gravity_ned.unsqueeze(-1)).squeeze(-1)
    v_dot = ev.force_body / p.mass[:, None] + gravity_body - torch.linalg.cross(omega, vel, dim=-1)
    j_omega = (p.inertia @ omega.unsqueeze(-1)).squeeze(-1)
    w_dot = (p.inertia_inv @ (ev.moment_body - torch.linalg.cross(omega, j_omega, dim=-1))
             .unsqueeze(-1)).squeeze(-1)
    p_dot = (ev.rotation @ vel.unsqueeze(-1)).squeeze(-1)
    q_dot = quaternion_derivative(q, omega)
    d_pos, d_rate, d_thr = actuator_derivative(
        x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE], x[:, S.THROTTLE_START:], command, p)
    return torch.cat([p_dot, q_dot, v_dot, w_dot, d_pos, d_rate, d_thr], dim=-1)


def project(x: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """After a step: renormalise the quaternion and saturate the actuator states (new tensor)."""
    pos, rate, thr = saturate(x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE],
                              x[:, S.THROTTLE_START:], p)
    return torch.cat([x[:, S.POSITION], normalize_quaternion(x[:, S.QUATERNION]),
                      x[:, S.VELOCITY], x[:, S.ANGULAR_RATE], pos, rate, thr], dim=-1)


def ground_contact(x: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """[N] bool: the CG or a wing tip (quarter chord, +-b/2) is at or below the ground."""
    rot_z = rotation_matrix(x[:, S.QUATERNION])[:, 2, :]  # NED-down row
    height = -x[:, 2]
    tip = p.wing_quarter_chord.unsqueeze(1).repeat(1, 2, 1)
    tip[:, 0, 1] = 0.5 * p.span
    tip[:, 1, 1] = -0.5 * p.span
    tip_height = height[:, None] - (tip * rot_z[:, None, :]).sum(-1)
    return (height <= 0.0) | (tip_height.min(dim=-1).values <= 0.0)


