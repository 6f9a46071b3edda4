"""Propeller thrust by momentum theory, discharge-velocity form, for several motors.

    V_d = V_ax + d_t (k_m - V_ax),  T = 1/2 rho S_p C_p V_d (V_d - V_ax),  T >= 0
    Q   = -spin k_tp (k_omega d_t)^2 about the thrust axis (reaction on the airframe)

V_ax is the air-relative velocity along the thrust axis. Zero throttle gives zero thrust, and the
thrust is clamped at zero above the discharge speed (a windmilling propeller gives no thrust here).
Each motor adds F = T a and M = r x F + Q a.
"""

from __future__ import annotations

import torch

from .params import ModelParams


def motor_thrust(v_air_body: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor,
                 p: ModelParams) -> torch.Tensor:
    """Thrust per motor [N, M] N from air velocity [N, 3], throttle [N, M] in [0, 1], rho [N]."""
    v_axial = torch.einsum("nmi,ni->nm", p.motor_axis, v_air_body)
    delta = throttle.clamp(0.0, 1.0)
    v_discharge = v_axial + delta * (p.discharge_speed - v_axial)
    thrust = 0.5 * density[:, None] * p.disk_area * p.thrust_coefficient * v_discharge * (
        v_discharge - v_axial)
    return torch.relu(thrust)


def propulsion_forces(v_air_body: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor,
                      p: ModelParams) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(force [N, 3], moment [N, 3], thrust per motor [N, M]) in body axes about the CG."""
    thrust = motor_thrust(v_air_body, throttle, density, p)
    force_m = thrust.unsqueeze(-1) * p.motor_axis  # [N, M, 3]
    delta = throttle.clamp(0.0, 1.0)
    torque = -p.motor_spin * p.torque_coefficient * (p.torque_speed_constant * delta) ** 2
    moment_m = torch.linalg.cross(p.motor_position, force_m, dim=-1) + torque.unsqueeze(-1) * (
        p.motor_axis)
    return force_m.sum(dim=1), moment_m.sum(dim=1), thrust
