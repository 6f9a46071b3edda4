"""Aerodynamic coefficients, forces and moments from monomial tables (torch, batched).

C_k = sum_t a[t, k] prod_j x_j^e[t, j] + sum_i b[k, i] rate_hat_i,  x = (alpha, beta, d_e, d_a, d_r),
rate_hat = (p b / 2V, q c / 2V, r b / 2V), with alpha and beta clamped to the table's validity
range. Lift and drag act in stability axes and are rotated by alpha into the body frame; side force
and the moments (about the CG) are body axes:

    F = qbar S [-C_D cos a + C_L sin a,  C_Y,  -C_D sin a - C_L cos a]
    M = qbar S [b C_l,  c C_m,  b C_n]

Ground effect (see ``ground_effect.py``) scales C_L and the induced drag.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from .ground_effect import GE_INDUCED, GE_PAPER, phillips_hunsaker
from .params import ModelParams

MIN_AIRSPEED = 0.1  # m/s, floor for the non-dimensional rates


@dataclass
class AeroOutput:
    force_body: torch.Tensor  # [N, 3] N
    moment_body: torch.Tensor  # [N, 3] N m
    coefficients: torch.Tensor  # [N, 6] (CL, CD, CY, Cl, Cm, Cn) after ground effect
    induced_drag_coefficient: torch.Tensor  # [N]
    kappa_lift: torch.Tensor  # [N]
    kappa_drag: torch.Tensor  # [N]


def monomials(x: torch.Tensor, exponents: torch.Tensor) -> torch.Tensor:
    """Evaluate prod_j x_j^e[t, j]. x: [N, V], exponents: [T, V] long -> [N, T].

    Powers are built by repeated multiplication (not ``pow``) so gradients stay finite at x = 0.
    """
    max_power = int(exponents.max()) if exponents.numel() else 0
    powers = [torch.ones_like(x)]
    for _ in range(max_power):
        powers.append(powers[-1] * x)
    stacked = torch.stack(powers, dim=-1)  # [N, V, P+1]
    var_index = torch.arange(x.shape[-1], device=x.device)
    picked = stacked[:, var_index.unsqueeze(0), exponents]  # [N, T, V]
    return picked.prod(dim=-1)


def aero_coefficients_oge(
    alpha: torch.Tensor, beta: torch.Tensor, surfaces: torch.Tensor, rates_hat: torch.Tensor,
    p: ModelParams,
) -> torch.Tensor:
    """Out-of-ground-effect coefficients [N, 6] from alpha, beta [N], surfaces [N, 3] rad,
    non-dimensional rates [N, 3]."""
    a = torch.minimum(torch.maximum(alpha, p.alpha_range[:, 0]), p.alpha_range[:, 1])
    b = torch.minimum(torch.maximum(beta, p.beta_range[:, 0]), p.beta_range[:, 1])
    x = torch.cat([a.unsqueeze(-1), b.unsqueeze(-1), surfaces], dim=-1)  # [N, 5]
    mono = monomials(x, p.aero_exponents)  # [N, T]
    coeffs = torch.einsum("nt,ntk->nk", mono, p.aero_coefficients)
    return coeffs + torch.einsum("nki,ni->nk", p.aero_rates, rates_hat)


def apply_ground_effect(coeffs: torch.Tensor, h_over_b: torch.Tensor, p: ModelParams
                        ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Scale C_L and C_D for ground effect per env mode.

    Returns (coefficients [N, 6], induced C_D [N], kappa_L [N], kappa_D [N]).
    """
    cl_inf, cd_inf = coeffs[:, 0], coeffs[:, 1]
    kappa_l, kappa_d = phillips_hunsaker(h_over_b, p.aspect_ratio, p.taper_ratio, cl_inf)
    mode = p.ground_effect_mode
    active = mode != 0
    kappa_l = torch.where(active, kappa_l, torch.ones_like(kappa_l))
    kappa_d = torch.where(active, kappa_d, torch.ones_like(kappa_d))
    induced_factor = 1.0 / (torch.pi * p.oswald * p.aspect_ratio)
    cl = kappa_l * cl_inf
    cdi_inf = induced_factor * cl_inf**2
    cdi = kappa_d * induced_factor * cl**2
    cd_induced_form = cd_inf - cdi_inf + cdi
    cd_paper_form = cd_inf * kappa_d * kappa_l**2
    cd = torch.where(mode == GE_INDUCED, cd_induced_form,
                     torch.where(mode == GE_PAPER, cd_paper_form, cd_inf))
    cdi_out = torch.where(mode == GE_INDUCED, cdi, cdi_inf * kappa_d * kappa_l**2)
    out = torch.cat([cl.unsqueeze(-1), cd.unsqueeze(-1), coeffs[:, 2:]], dim=-1)
    return out, cdi_out, kappa_l, kappa_d


def aero_forces(
    airspeed: torch.Tensor, alpha: torch.Tensor, beta: torch.Tensor, omega_air: torch.Tensor,
    surfaces: torch.Tensor, density: torch.Tensor, h_over_b: torch.Tensor, p: ModelParams,
) -> AeroOutput:
    """Body-axis aero force and moment about the CG.

    Args:
        airspeed, alpha, beta: [N] air-relative speed (m/s) and angles (rad).
        omega_air: [N, 3] body rates relative to the air mass (rad/s).
        surfaces: [N, 3] deflections (rad). density: [N] kg/m^3.
        h_over_b: [N] height of the wing quarter chord over span.
    """
    v = airspeed.clamp_min(MIN_AIRSPEED)
    half_over_v = 0.5 / v
    rates_hat = omega_air * torch.stack([p.span, p.chord, p.span], dim=-1) * half_over_v[:, None]
    coeffs = aero_coefficients_oge(alpha, beta, surfaces, rates_hat, p)
    coeffs, cdi, kappa_l, kappa_d = apply_ground_effect(coeffs, h_over_b, p)
    qs = 0.5 * density * airspeed**2 * p.wing_area
    cl, cd, cy = coeffs[:, 0], coeffs[:, 1], coeffs[:, 2]
    ca, sa = torch.cos(alpha), torch.sin(alpha)
    force = torch.stack([-cd * ca + cl * sa, cy, -cd * sa - cl * ca], dim=-1) * qs[:, None]
    lengths = torch.stack([p.span, p.chord, p.span], dim=-1)
    moment = coeffs[:, 3:] * lengths * qs[:, None]
    return AeroOutput(force, moment, coeffs, cdi, kappa_l, kappa_d)
