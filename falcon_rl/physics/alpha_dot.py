"""Alpha-dot aero terms, solved in closed form (torch + Warp twin): no extra state.

alpha = atan2(w, u) of the air-relative body velocity, so

    alpha_dot = (u w_dot - w u_dot) / (u^2 + w^2)

where (u_dot, w_dot) is the body-axis acceleration the dynamics integrates (forces over mass, gravity,
-omega x v; like JSBSim's ``aero/alphadot-rad_sec``, the wind's own rate of change is not in it). The
table terms that multiply alpha_dot c/2V (``tables.split_alpha_dot``) make the force linear in it:
F = F_0 + ad F_1 with ad = alpha_dot c / 2V, so with a_0 the acceleration at ad = 0 and a_1 = F_1 / m,

    ad = k (u a_0w - w a_0u + ad (u a_1w - w a_1u)) / (u^2 + w^2),   k = c / 2V
    ad = k A_0 / (1 - k B),   A_0 = (u a_0w - w a_0u) / (u^2 + w^2),   B = (u a_1w - w a_1u) / (u^2 + w^2)

exactly (1 - k B is the effective-mass factor 1 - Z_wdot / m of the classical derivation; a positive
C_L_alphadot makes it larger than 1). The aero force, moment and coefficients then gain ad times their
per-unit parts. Only the moment's alpha-dot part changes no acceleration that alpha reads, so nothing
else is implicit. Airframes without alpha-dot terms never come here (``tables.has_alpha_dot_terms``,
``WarpParams.num_alpha_dot_terms``).
"""

from __future__ import annotations

from dataclasses import replace

import torch

from ._warp import warp_func, wp
from .aero import MIN_AIRSPEED, AeroOutput, AeroResultWp
from .params import ModelParams, WarpParams

#: Floor of the effective-mass factor 1 - k B and of u^2 + w^2 (m^2/s^2): a factor at or below zero
#: would need alpha-dot lift beyond the airframe's weight per unit acceleration, which no aircraft has.
MIN_EFFECTIVE_MASS_FACTOR = 0.1
MIN_UW_SQUARED = 1e-6


def solve_alpha_dot_hat(v_air_body: torch.Tensor, acceleration_steady: torch.Tensor,
                        acceleration_per_unit: torch.Tensor, airspeed: torch.Tensor, p: ModelParams
                        ) -> torch.Tensor:
    """[N] alpha_dot c / 2V from the air-relative body velocity [N, 3] (m/s), the body acceleration [N, 3]
    at alpha_dot = 0 and its change per unit alpha_dot c/2V [N, 3] (m/s^2), and the airspeed [N] m/s."""
    u, w = v_air_body[:, 0], v_air_body[:, 2]
    uw2 = (u * u + w * w).clamp_min(MIN_UW_SQUARED)
    steady = (u * acceleration_steady[:, 2] - w * acceleration_steady[:, 0]) / uw2
    per_unit = (u * acceleration_per_unit[:, 2] - w * acceleration_per_unit[:, 0]) / uw2
    k = 0.5 * p.chord / airspeed.clamp_min(MIN_AIRSPEED)
    return k * steady / (1.0 - k * per_unit).clamp_min(MIN_EFFECTIVE_MASS_FACTOR)


def with_alpha_dot(aero: AeroOutput, alpha_dot_hat: torch.Tensor) -> AeroOutput:
    """``aero`` with its alpha-dot parts added at alpha_dot c/2V = ``alpha_dot_hat`` [N] (a new output)."""
    if aero.alpha_dot_force is None or aero.alpha_dot_moment is None or aero.alpha_dot_coefficients is None:
        raise ValueError("the aero output has no alpha-dot terms")
    ad = alpha_dot_hat.unsqueeze(-1)
    return replace(aero, force_body=aero.force_body + ad * aero.alpha_dot_force,
                   moment_body=aero.moment_body + ad * aero.alpha_dot_moment,
                   coefficients=aero.coefficients + ad * aero.alpha_dot_coefficients)


# ---------------------------------------------------------------------------------------- warp twins
@warp_func
def solve_alpha_dot_hat_wp(v_air_body: wp.vec3, acceleration_steady: wp.vec3, acceleration_per_unit: wp.vec3,
                           airspeed: float, p: WarpParams, i: int) -> float:
    """alpha_dot c / 2V of env i (twin of :func:`solve_alpha_dot_hat`)."""
    u = v_air_body[0]
    w = v_air_body[2]
    uw2 = wp.max(u * u + w * w, MIN_UW_SQUARED)
    steady = (u * acceleration_steady[2] - w * acceleration_steady[0]) / uw2
    per_unit = (u * acceleration_per_unit[2] - w * acceleration_per_unit[0]) / uw2
    k = 0.5 * p.chord[i] / wp.max(airspeed, MIN_AIRSPEED)
    return k * steady / wp.max(1.0 - k * per_unit, MIN_EFFECTIVE_MASS_FACTOR)


@warp_func
def with_alpha_dot_wp(aero: AeroResultWp, alpha_dot_hat: float) -> AeroResultWp:
    """``aero`` with its alpha-dot parts added (twin of :func:`with_alpha_dot`)."""
    out = AeroResultWp()
    out.force_body = aero.force_body + alpha_dot_hat * aero.alpha_dot_force
    out.moment_body = aero.moment_body + alpha_dot_hat * aero.alpha_dot_moment
    out.coefficients = aero.coefficients + alpha_dot_hat * aero.alpha_dot_coefficients
    out.induced_drag_coefficient = aero.induced_drag_coefficient
    out.kappa_lift = aero.kappa_lift
    out.kappa_drag = aero.kappa_drag
    out.alpha_dot_force = aero.alpha_dot_force
    out.alpha_dot_moment = aero.alpha_dot_moment
    out.alpha_dot_coefficients = aero.alpha_dot_coefficients
    return out
