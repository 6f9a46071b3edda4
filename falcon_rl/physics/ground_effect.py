"""Phillips-Hunsaker (2013) lifting-line ground-effect correlations.

kappa_L = C_L,IGE / C_L,OGE at the same alpha, kappa_D = C_Di,IGE / C_Di,OGE at the same C_L, for a
tapered untwisted wing of aspect ratio R_A and taper ratio R_T at height h above the ground:

    kappa_D = beta_D [1 - delta_D exp(-4.74 x^0.814) - x^2 exp(-3.88 x^0.758)]
    kappa_L = (1/beta_L) [1 + delta_L 288 x^0.787 exp(-9.14 x^0.327) / R_A^0.882]
    delta_D = 1 - 0.157 (R_T^0.775 - 0.373)(R_A^0.417 - 1.27)
    delta_L = 1 - 2.25 (R_T^0.00273 - 0.997)(R_A^0.717 + 13.6)
    beta_D  = 1 + 0.0361 C_L^1.21 / (R_A^1.19 x^1.51)     (high-lift corrections, only when a
    beta_L  = 1 + 0.269  C_L^1.45 / (R_A^3.18 x^1.12)      lift coefficient is given)

with x = h/b. The lift bump vanishes as h -> 0 and the beta terms diverge like x^-1.5, so x is
clamped below at ``H_OVER_B_MIN`` = 0.05, the conservative end of the 0.03-0.05 range over which the
correlations are quoted; |C_L| is used so that negative lift gives finite factors.

How the factors enter the aero model (``aero.py``), per env by ``ground_effect_mode``:
- ``GE_INDUCED`` (default): C_L = kappa_L C_L_inf; C_D = C_D_inf + (kappa_D C_L^2 - C_L_inf^2)/(pi e R_A)
  (only the induced part of the drag changes, parasitic drag is untouched).
- ``GE_PAPER``: the reference paper's form C_D = C_D_inf (1 - mu_D)(1 + mu_L)^2 on the whole drag,
  with mu_D = 1 - kappa_D and mu_L = kappa_L - 1. It overstates the saving at cruise.
- ``GE_TABLES``: no Phillips-Hunsaker correction; the airframe's table terms read the true h/b (an
  imported JSBSim aircraft's kCLge/kCDge tables). Airframes without such tables fly as with ``GE_OFF``.
- ``GE_OFF``: no correction.
"""

from __future__ import annotations

import torch

from ._warp import vector_type, warp_func, wp

H_OVER_B_MIN = 0.05
GE_OFF, GE_INDUCED, GE_PAPER, GE_TABLES = 0, 1, 2, 3
GE_MODES = {"off": GE_OFF, "induced": GE_INDUCED, "paper": GE_PAPER, "tables": GE_TABLES}


def ground_effect_mode(value: bool | str | int) -> int:
    """Map the user's ``ground_effect`` argument (True/False/'induced'/'paper'/'tables'/'off') to a code."""
    if value is True:
        return GE_INDUCED
    if value is False or value is None:
        return GE_OFF
    if isinstance(value, str) and value in GE_MODES:
        return GE_MODES[value]
    if isinstance(value, int) and value in GE_MODES.values():
        return value
    raise ValueError(f"ground_effect must be True, False or one of {list(GE_MODES)}, got {value!r}")


def taper_corrections(aspect_ratio: torch.Tensor, taper_ratio: torch.Tensor
                      ) -> tuple[torch.Tensor, torch.Tensor]:
    """(delta_D, delta_L) tapered-wing corrections, shaped like the inputs."""
    delta_d = 1.0 - 0.157 * (taper_ratio**0.775 - 0.373) * (aspect_ratio**0.417 - 1.27)
    delta_l = 1.0 - 2.25 * (taper_ratio**0.00273 - 0.997) * (aspect_ratio**0.717 + 13.6)
    return delta_d, delta_l


def wing_constants(aspect_ratio: torch.Tensor, taper_ratio: torch.Tensor) -> torch.Tensor:
    """[..., 5] (delta_D, delta_L, R_A^0.882, R_A^1.19, R_A^3.18): the factors of the correlations
    that depend on the wing alone. The simulator computes them once per env (``ModelParams``)
    instead of in every derivative evaluation, where their seven powers cost as much as the rest
    of the ground-effect model."""
    aspect_ratio, taper_ratio = torch.broadcast_tensors(aspect_ratio, taper_ratio)
    delta_d, delta_l = taper_corrections(aspect_ratio, taper_ratio)
    return torch.stack([delta_d, delta_l, aspect_ratio**0.882, aspect_ratio**1.19, aspect_ratio**3.18],
                       dim=-1)


def influence_ratios(h_over_b: torch.Tensor, constants: torch.Tensor,
                     lift_coefficient: torch.Tensor | None = None, slopes: bool = False
                     ) -> tuple[torch.Tensor, ...]:
    """(kappa_L, kappa_D) at h_over_b [...] for a wing given by its ``constants`` [..., 5]
    (:func:`wing_constants`); ``lift_coefficient`` [...] turns on the high-lift corrections. With
    ``slopes`` also (d kappa_L / dx, d kappa_D / dx) at x = h/b (0 where x is clamped), from the same
    powers and exponentials: with P_a = x^a,

        d kappa_D0/dx = delta_D 4.74 (0.814 P_0.814 / x) E_1 - x E_2 (2 - 3.88 0.758 P_0.758)
        d kappa_L0/dx = (kappa_L0 - 1) (0.787 - 9.14 0.327 P_0.327) / x
        d beta_D/dx = -1.51 (beta_D - 1) / x,   d beta_L/dx = -1.12 (beta_L - 1) / x
    """
    x = torch.clamp(h_over_b, min=H_OVER_B_MIN)
    delta_d, delta_l, ar_0882, ar_119, ar_318 = constants.unbind(-1)
    p1, p2, p4 = x**0.814, x**0.758, x**0.327
    e1, e2 = torch.exp(-4.74 * p1), torch.exp(-3.88 * p2)
    kappa_d = 1.0 - delta_d * e1 - x**2 * e2
    bump = delta_l * 288.0 * x**0.787 * torch.exp(-9.14 * p4) / ar_0882
    kappa_l = 1.0 + bump
    slope_d = delta_d * 4.74 * 0.814 * p1 / x * e1 - x * e2 * (2.0 - 3.88 * 0.758 * p2)
    slope_l = bump * (0.787 - 9.14 * 0.327 * p4) / x
    if lift_coefficient is not None:
        cl = torch.abs(lift_coefficient)
        beta_d = 1.0 + 0.0361 * cl**1.21 / (ar_119 * x**1.51)
        beta_l = 1.0 + 0.269 * cl**1.45 / (ar_318 * x**1.12)
        slope_d = slope_d * beta_d - kappa_d * 1.51 * (beta_d - 1.0) / x
        slope_l = slope_l / beta_l + kappa_l * 1.12 * (beta_l - 1.0) / (x * beta_l**2)
        kappa_d = kappa_d * beta_d
        kappa_l = kappa_l / beta_l
    if not slopes:
        return kappa_l, kappa_d
    clamped = h_over_b < H_OVER_B_MIN
    return (kappa_l, kappa_d, slope_l.masked_fill(clamped, 0.0), slope_d.masked_fill(clamped, 0.0))


def phillips_hunsaker(
    h_over_b: torch.Tensor,
    aspect_ratio: torch.Tensor,
    taper_ratio: torch.Tensor,
    lift_coefficient: torch.Tensor | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Lift and induced-drag influence ratios.

    Args:
        h_over_b: [...] height of the wing quarter chord over span (clamped below at 0.05).
        aspect_ratio, taper_ratio: broadcastable to ``h_over_b``.
        lift_coefficient: out-of-ground-effect C_L for the high-lift corrections, or None.

    Returns:
        (kappa_L, kappa_D), broadcast shape of the inputs.
    """
    shape = torch.broadcast_shapes(h_over_b.shape, torch.as_tensor(aspect_ratio).shape,
                                   torch.as_tensor(taper_ratio).shape)
    constants = wing_constants(torch.as_tensor(aspect_ratio, dtype=h_over_b.dtype).expand(shape),
                               torch.as_tensor(taper_ratio, dtype=h_over_b.dtype).expand(shape))
    return influence_ratios(h_over_b.expand(shape), constants, lift_coefficient)


# ---------------------------------------------------------------------------------------- warp twin
#: One env's :func:`wing_constants` row.
WingConstants = vector_type(5)


@warp_func
def ground_effect_factors_wp(h_over_b: float, constants: WingConstants, lift_coefficient: float) -> wp.vec4:
    """(kappa_L, kappa_D, d kappa_L / dx, d kappa_D / dx) with the high-lift corrections (twin of
    :func:`influence_ratios` with a lift coefficient and ``slopes``). The powers of x share one
    logarithm: x^a = exp(a ln x)."""
    x = wp.max(h_over_b, H_OVER_B_MIN)
    lx = wp.log(x)
    p1 = wp.exp(0.814 * lx)
    p2 = wp.exp(0.758 * lx)
    p4 = wp.exp(0.327 * lx)
    e1 = wp.exp(-4.74 * p1)
    e2 = wp.exp(-3.88 * p2)
    kappa_d = 1.0 - constants[0] * e1 - x * x * e2
    bump = constants[1] * 288.0 * wp.exp(0.787 * lx) * wp.exp(-9.14 * p4) / constants[2]
    kappa_l = 1.0 + bump
    slope_d = constants[0] * 4.74 * 0.814 * p1 / x * e1 - x * e2 * (2.0 - 3.88 * 0.758 * p2)
    slope_l = bump * (0.787 - 9.14 * 0.327 * p4) / x
    cl = wp.abs(lift_coefficient)
    if cl > 0.0:
        lc = wp.log(cl)
        beta_d = 1.0 + 0.0361 * wp.exp(1.21 * lc - 1.51 * lx) / constants[3]
        beta_l = 1.0 + 0.269 * wp.exp(1.45 * lc - 1.12 * lx) / constants[4]
        slope_d = slope_d * beta_d - kappa_d * 1.51 * (beta_d - 1.0) / x
        slope_l = slope_l / beta_l + kappa_l * 1.12 * (beta_l - 1.0) / (x * beta_l * beta_l)
        kappa_d = kappa_d * beta_d
        kappa_l = kappa_l / beta_l
    if h_over_b < H_OVER_B_MIN:
        slope_l = 0.0
        slope_d = 0.0
    return wp.vec4(kappa_l, kappa_d, slope_l, slope_d)


@warp_func
def phillips_hunsaker_wp(h_over_b: float, constants: WingConstants, lift_coefficient: float) -> wp.vec2:
    """(kappa_L, kappa_D) with the high-lift corrections (twin of :func:`influence_ratios` with a
    lift coefficient)."""
    factors = ground_effect_factors_wp(h_over_b, constants, lift_coefficient)
    return wp.vec2(factors[0], factors[1])
