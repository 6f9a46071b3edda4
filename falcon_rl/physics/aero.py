"""Aerodynamic coefficients, forces and moments (torch, batched, and the Warp twin).

The monomial model (``aero_monomials.py``) gives
C_k = sum_t a[t, k] prod_j x_j^e[t, j] + sum_i b[k, i] rate_hat_i,  x = (alpha, beta, d_e, d_a, d_r),
rate_hat = (p b / 2V, q c / 2V, r b / 2V), with alpha and beta clamped to the table's validity
range. Lift and drag act in stability axes and are rotated by alpha into the body frame; side force
and the moments are body axes. The moment coefficients are taken about the aero reference point r_a
(``aero.moment_reference_m``, body FRD from the CG; zero, the CG itself, unless the file gives one:
JSBSim's AERORP), where the force acts, so about the CG

    F = qbar S [-C_D cos a + C_L sin a,  C_Y,  -C_D sin a - C_L cos a]
    M = qbar S [b C_l,  c C_m,  b C_n] + r_a x F

A tabulated airframe (``aero.kind`` "tabulated") adds its table terms (``tables.py``): sums of 1-3D
tables of alpha, beta (not clamped: each table clamps at its own edges), the deflections, rate_hat,
Mach, airspeed, h/b and throttle, each times a monomial multiplier. A monomial airframe has no terms,
so the same kernel runs every airframe.

Ground effect (see ``ground_effect.py``) scales C_L and the induced drag (Phillips-Hunsaker, modes
"induced" and "paper"; over a sea at the wing's mean clearance, with the rolling and yawing moments of the
surface's span asymmetry, ``surface.py``), or, in mode "tables", the tables read the true h/b (JSBSim's
kCLge/kCDge
come across as table data); in every other mode the tables see h/b = H_OVER_B_FREE_AIR. The model switch
``no_rate_damping`` (``switches.ModelSwitches(rate_damping=False)``) sets rate_hat = 0 per env, so the
rate derivatives contribute nothing (nor do the alpha-dot terms).

Table terms that multiply alpha_dot (alpha-dot c / 2V, ``tables.split_alpha_dot``) are not added here:
the force and moment per unit alpha_dot come out beside the rest (``AeroOutput.alpha_dot_*``, None for
an airframe without such terms), and ``alpha_dot.py`` solves alpha-dot from the accelerations and adds
them. They are not scaled by ground-effect modes "induced" and "paper" (those scale the wing's lift and
induced drag; the alpha-dot terms are the tail's downwash lag), so the force stays linear in alpha-dot.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ._warp import vector_type, warp_func, warp_struct, wp
from .aero_monomials import aero_coefficients_oge, aero_coefficients_oge_wp
from .atmosphere import RHO_SEA_LEVEL
from .constants import GAMMA, R_AIR, T0
from .ground_effect import GE_INDUCED, GE_PAPER, GE_TABLES, ground_effect_factors_wp, influence_ratios
from .interpolated_terms import (
    AIRSPEED,
    ALPHA,
    ALPHA_DOT,
    BETA,
    DENSITY,
    ELEVATOR,
    H_OVER_B,
    MACH,
    P_HAT,
    THROTTLE,
    TableVars,
    has_alpha_dot_terms,
    has_terms,
    split_alpha_dot,
    table_output_split_wp,
    table_output_wp,
    table_outputs,
)
from .params import ModelParams, WarpParams

MIN_AIRSPEED = 0.1  # m/s, floor for the non-dimensional rates
#: h/b the tables see when ground effect is not in mode "tables" (beyond every ground-effect table).
H_OVER_B_FREE_AIR = 100.0
#: Sea-level speed of sound, m/s; in the ISA troposphere a = A0 (rho / rho0)^SOUND_DENSITY_EXPONENT.
A0 = (GAMMA * R_AIR * T0) ** 0.5
SOUND_DENSITY_EXPONENT = 0.5 / 4.255876


@dataclass
class AeroOutput:
    force_body: torch.Tensor  # [N, 3] N
    moment_body: torch.Tensor  # [N, 3] N m
    coefficients: torch.Tensor  # [N, 6] (CL, CD, CY, Cl, Cm, Cn) after ground effect
    induced_drag_coefficient: torch.Tensor  # [N]
    kappa_lift: torch.Tensor  # [N]
    kappa_drag: torch.Tensor  # [N]
    # per unit alpha_dot c/2V (None: no alpha-dot terms); alpha_dot.py adds alpha_dot times them
    alpha_dot_force: torch.Tensor | None = None  # [N, 3] N
    alpha_dot_moment: torch.Tensor | None = None  # [N, 3] N m
    alpha_dot_coefficients: torch.Tensor | None = None  # [N, 6]


def has_aero_tables(p: ModelParams) -> bool:
    """Whether ``p`` has any aero table term."""
    return has_terms(p, 0, 6)


def mach_number(airspeed: torch.Tensor, density: torch.Tensor) -> torch.Tensor:
    """[N] Mach from airspeed [N] m/s and density [N] kg/m^3 (ISA troposphere: T follows rho)."""
    return airspeed / (A0 * (density / RHO_SEA_LEVEL) ** SOUND_DENSITY_EXPONENT)


def table_variables(alpha: torch.Tensor, beta: torch.Tensor, surfaces: torch.Tensor, rates_hat: torch.Tensor,
                    airspeed: torch.Tensor, density: torch.Tensor, h_over_b: torch.Tensor,
                    throttle: torch.Tensor, alpha_dot_hat: torch.Tensor | None = None) -> torch.Tensor:
    """The variable vector [N, 14] of the table terms (``airframe_tables.TABLE_VARIABLES``) from [N]
    alpha, beta (rad), airspeed (m/s), density (kg/m^3), h/b, throttle, alpha_dot c/2V (None: 0) and
    [N, 3] surfaces, rates_hat."""
    alpha_dot_hat = torch.zeros_like(alpha) if alpha_dot_hat is None else alpha_dot_hat
    columns = [alpha, beta, *surfaces.unbind(-1), *rates_hat.unbind(-1), mach_number(airspeed, density),
               airspeed, h_over_b, throttle.clamp(0.0, 1.0), density, alpha_dot_hat]
    return torch.stack(columns, dim=-1)


def tables_h_over_b(h_over_b: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """[N] the h/b the tables see: the true one in ground-effect mode "tables", else free air."""
    free_air = torch.full_like(h_over_b, H_OVER_B_FREE_AIR)
    return torch.where(p.ground_effect_mode == GE_TABLES, h_over_b, free_air)


def apply_ground_effect(coeffs: torch.Tensor, h_over_b: torch.Tensor, p: ModelParams,
                        asymmetry: torch.Tensor | None = None
                        ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Scale C_L and C_D for ground effect per env mode; over a surface whose span asymmetry is
    ``asymmetry`` [N] (``surface.py``: A = sum_s w_s (y_s / b)(eta_s / b)), add the rolling and yawing
    moments of the station factors' first-order variation, dC_l = C_L,inf (d kappa_L / dx) A and
    dC_n = -(C_Di / kappa_D)(d kappa_D / dx) A (modes "induced" and "paper").

    Returns (coefficients [N, 6], induced C_D [N], kappa_L [N], kappa_D [N]).
    """
    cl_inf, cd_inf = coeffs[:, 0], coeffs[:, 1]
    slope_l = slope_d = None
    if asymmetry is None:
        kappa_l, kappa_d = influence_ratios(h_over_b, p.wing_constants, cl_inf)
    else:
        kappa_l, kappa_d, slope_l, slope_d = influence_ratios(h_over_b, p.wing_constants, cl_inf, slopes=True)
    mode = p.ground_effect_mode
    active = (mode == GE_INDUCED) | (mode == GE_PAPER)
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
    rest = coeffs[:, 2:]
    if slope_l is not None and slope_d is not None and asymmetry is not None:
        roll = torch.where(active, cl_inf * slope_l * asymmetry, 0.0)
        yaw = torch.where(active, -induced_factor * cl**2 * slope_d * asymmetry, 0.0)
        rest = torch.stack([rest[:, 0], rest[:, 1] + roll, rest[:, 2], rest[:, 3] + yaw], dim=-1)
    out = torch.cat([cl.unsqueeze(-1), cd.unsqueeze(-1), rest], dim=-1)
    return out, cdi_out, kappa_l, kappa_d


def aero_forces(
    airspeed: torch.Tensor, alpha: torch.Tensor, beta: torch.Tensor, omega_air: torch.Tensor,
    surfaces: torch.Tensor, density: torch.Tensor, h_over_b: torch.Tensor, p: ModelParams,
    throttle: torch.Tensor | None = None, asymmetry: torch.Tensor | None = None,
) -> AeroOutput:
    """Body-axis aero force and moment about the CG (the force acting at ``p.aero_reference``).

    Args:
        airspeed, alpha, beta: [N] air-relative speed (m/s) and angles (rad).
        omega_air: [N, 3] body rates relative to the air mass (rad/s).
        surfaces: [N, 3] deflections (rad). density: [N] kg/m^3.
        h_over_b: [N] height of the wing quarter chord (above the mean surface under it) over span.
        throttle: [N] first motor's throttle state in [0, 1] (table terms may read it), None for 0.
        asymmetry: [N] the surface's span asymmetry A under the wing (``surface.py``), None over the
            flat ground.
    """
    v = airspeed.clamp_min(MIN_AIRSPEED)
    half_over_v = 0.5 / v
    lengths = torch.stack([p.span, p.chord, p.span], dim=-1)  # [N, 3]
    rates_hat = omega_air * lengths * half_over_v[:, None]
    rates_hat = rates_hat.masked_fill((p.no_rate_damping != 0).unsqueeze(-1), 0.0)
    coeffs = aero_coefficients_oge(alpha, beta, surfaces, rates_hat, p)
    per_alpha_dot = None
    if has_aero_tables(p):
        throttle = torch.zeros_like(airspeed) if throttle is None else throttle
        x = table_variables(alpha, beta, surfaces, rates_hat, airspeed, density, tables_h_over_b(h_over_b, p),
                            throttle)
        if has_alpha_dot_terms(p):
            steady, per_unit = split_alpha_dot(x, p)
            coeffs = coeffs + steady[:, :6]
            per_alpha_dot = per_unit[:, :6].masked_fill((p.no_rate_damping != 0).unsqueeze(-1), 0.0)
        else:
            coeffs = coeffs + table_outputs(x, p)[:, :6]
    coeffs, cdi, kappa_l, kappa_d = apply_ground_effect(coeffs, h_over_b, p, asymmetry)
    qs = 0.5 * density * airspeed**2 * p.wing_area
    force, moment = coefficient_loads(coeffs, alpha, qs, lengths, p)
    out = AeroOutput(force, moment, coeffs, cdi, kappa_l, kappa_d)
    if per_alpha_dot is not None:
        out.alpha_dot_force, out.alpha_dot_moment = coefficient_loads(per_alpha_dot, alpha, qs, lengths, p)
        out.alpha_dot_coefficients = per_alpha_dot
    return out


def coefficient_loads(coeffs: torch.Tensor, alpha: torch.Tensor, qs: torch.Tensor, lengths: torch.Tensor,
                      p: ModelParams) -> tuple[torch.Tensor, torch.Tensor]:
    """(force [N, 3] N, moment about the CG [N, 3] N m) in body axes of the coefficients [N, 6] (lift and
    drag in stability axes) at alpha [N], qbar S [N] and reference lengths (b, c, b) [N, 3]."""
    cl, cd, cy = coeffs[:, 0], coeffs[:, 1], coeffs[:, 2]
    ca, sa = torch.cos(alpha), torch.sin(alpha)
    force = torch.stack([-cd * ca + cl * sa, cy, -cd * sa - cl * ca], dim=-1) * qs[:, None]
    moment = coeffs[:, 3:] * lengths * qs[:, None] + torch.linalg.cross(p.aero_reference, force, dim=-1)
    return force, moment


# ---------------------------------------------------------------------------------------- warp twins
Vec6 = vector_type(6)  # (CL, CD, CY, Cl, Cm, Cn)


@warp_struct
class AeroResultWp:
    """Per-env twin of :class:`AeroOutput`."""

    force_body: wp.vec3
    moment_body: wp.vec3
    coefficients: Vec6
    induced_drag_coefficient: float
    kappa_lift: float
    kappa_drag: float
    # per unit alpha_dot c/2V (zero unless the airframe has alpha-dot terms)
    alpha_dot_force: wp.vec3
    alpha_dot_moment: wp.vec3
    alpha_dot_coefficients: Vec6


@warp_func
def table_variables_wp(alpha: float, beta: float, surfaces: wp.vec3, rates_hat: wp.vec3, airspeed: float,
                       density: float, h_over_b: float, throttle: float) -> TableVars:
    """The table variables of one env (twin of :func:`table_variables`)."""
    x = TableVars()
    x[ALPHA] = alpha
    x[BETA] = beta
    for k in range(3):
        x[ELEVATOR + k] = surfaces[k]
        x[P_HAT + k] = rates_hat[k]
    x[MACH] = airspeed / (A0 * wp.pow(density / RHO_SEA_LEVEL, SOUND_DENSITY_EXPONENT))
    x[AIRSPEED] = airspeed
    x[H_OVER_B] = h_over_b
    x[THROTTLE] = wp.clamp(throttle, 0.0, 1.0)
    x[DENSITY] = density
    return x


@warp_func
def aero_forces_wp(airspeed: float, alpha: float, beta: float, omega_air: wp.vec3, surfaces: wp.vec3,
                   density: float, h_over_b: float, p: WarpParams, i: int) -> AeroResultWp:
    """Body-axis aero force and moment of env ``i`` at zero throttle (twin of :func:`aero_forces`)."""
    return aero_forces_throttle_wp(airspeed, alpha, beta, omega_air, surfaces, density, h_over_b, 0.0, 0.0, p,
                                   i)


@warp_func
def aero_forces_throttle_wp(airspeed: float, alpha: float, beta: float, omega_air: wp.vec3, surfaces: wp.vec3,
                            density: float, h_over_b: float, asymmetry: float, throttle: float, p: WarpParams,
                            i: int) -> AeroResultWp:
    """Body-axis aero force and moment of env ``i`` over a surface of span ``asymmetry`` (0 over the
    ground), ``throttle`` the first motor's (twin of :func:`aero_forces`)."""
    span = p.span[i]
    chord = p.chord[i]
    half_over_v = 0.5 / wp.max(airspeed, MIN_AIRSPEED)
    rates_hat = wp.vec3(omega_air[0] * span, omega_air[1] * chord, omega_air[2] * span) * half_over_v
    if p.no_rate_damping[i] != 0:
        rates_hat = wp.vec3(0.0, 0.0, 0.0)
    c = aero_coefficients_oge_wp(alpha, beta, surfaces, rates_hat, p, i)
    mode = p.ground_effect_mode[i]
    per_alpha_dot = Vec6()
    if p.table_output_start[6] > 0:
        table_hb = H_OVER_B_FREE_AIR
        if mode == GE_TABLES:
            table_hb = h_over_b
        x = table_variables_wp(alpha, beta, surfaces, rates_hat, airspeed, density, table_hb, throttle)
        if p.num_alpha_dot_terms > 0:
            x[ALPHA_DOT] = 1.0
            for k in range(6):
                split = table_output_split_wp(x, p, i, k)
                c[k] = c[k] + split[0]
                per_alpha_dot[k] = split[1]
            if p.no_rate_damping[i] != 0:
                per_alpha_dot = Vec6()
        else:
            for k in range(6):
                c[k] = c[k] + table_output_wp(x, p, i, k)
    cl_inf = c[0]
    cd_inf = c[1]
    kappa_l = float(1.0)  # noqa: UP018 (a mutable Warp local)
    kappa_d = float(1.0)  # noqa: UP018 (a mutable Warp local)
    slope_l = float(0.0)  # noqa: UP018 (a mutable Warp local)
    slope_d = float(0.0)  # noqa: UP018 (a mutable Warp local)
    if mode == GE_INDUCED or mode == GE_PAPER:  # noqa: SIM109 (Warp has no tuple membership)
        kappas = ground_effect_factors_wp(h_over_b, p.wing_constants[i], cl_inf)
        kappa_l = kappas[0]
        kappa_d = kappas[1]
        slope_l = kappas[2]
        slope_d = kappas[3]
    induced_factor = 1.0 / (wp.pi * p.oswald[i] * p.aspect_ratio[i])
    cl = kappa_l * cl_inf
    if asymmetry != 0.0:
        c[3] = c[3] + cl_inf * slope_l * asymmetry
        c[5] = c[5] - induced_factor * cl * cl * slope_d * asymmetry
    cdi_inf = induced_factor * cl_inf * cl_inf
    cdi = kappa_d * induced_factor * cl * cl
    cd = cd_inf
    cdi_out = cdi_inf * kappa_d * kappa_l * kappa_l
    if mode == GE_INDUCED:
        cd = cd_inf - cdi_inf + cdi
        cdi_out = cdi
    elif mode == GE_PAPER:
        cd = cd_inf * kappa_d * kappa_l * kappa_l
    c[0] = cl
    c[1] = cd
    qs = 0.5 * density * airspeed * airspeed * p.wing_area[i]
    ca = wp.cos(alpha)
    sa = wp.sin(alpha)
    out = AeroResultWp()
    out.force_body = wp.vec3(-cd * ca + cl * sa, c[2], -cd * sa - cl * ca) * qs
    out.moment_body = wp.vec3(c[3] * span, c[4] * chord, c[5] * span) * qs + wp.cross(p.aero_reference[i],
                                                                                       out.force_body)
    out.coefficients = c
    if p.num_alpha_dot_terms > 0:
        d = per_alpha_dot
        out.alpha_dot_force = wp.vec3(-d[1] * ca + d[0] * sa, d[2], -d[1] * sa - d[0] * ca) * qs
        out.alpha_dot_moment = wp.vec3(d[3] * span, d[4] * chord, d[5] * span) * qs + wp.cross(
            p.aero_reference[i], out.alpha_dot_force)
        out.alpha_dot_coefficients = d
    out.induced_drag_coefficient = cdi_out
    out.kappa_lift = kappa_l
    out.kappa_drag = kappa_d
    return out
