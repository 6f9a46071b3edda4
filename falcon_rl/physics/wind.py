"""Steady wind and Dryden turbulence (MIL-F-8785C), torch functions beside their Warp twins.

Steady wind is a per-env NED vector (``Simulator.wind_ned``); the dynamics subtract it, rotated into
the body frame, from the inertial velocity, so it acts on alpha, beta and dynamic pressure.

Dryden gusts are body-axis velocities (u_g, v_g, w_g) and air-mass rotation rates (p_g, q_g, r_g)
that the dynamics subtract from the body velocity and rates. Scale lengths L and intensities sigma
follow MIL-F-8785C with h the CG height above ground in feet (clipped at 10 ft):

    h <= 1000 ft:  L_w = h,  L_u = L_v = h / (0.177 + 0.000823 h)^1.2,
                   sigma_w = 0.1 W20,  sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4
    h >= 2000 ft:  L = 1750 ft, sigma_u = sigma_v = sigma_w from the probability-of-exceedance table
    in between:    L and sigma blended linearly from their 1000 ft and 2000 ft values.

W20 (wind speed at 20 ft) sets the severity: very_light 2, light 15, moderate 30, severe 45 kt.
Above 2000 ft the table rows light / moderate / severe sit at W20 = 15 / 30 / 45 kt and are
interpolated linearly in W20 (from zero at W20 = 0, proportional beyond 45 kt).

Discrete realisation, exact for frozen (L, sigma, V) over one step of length dt, re-evaluated every
step at the current height and airspeed V (the mean-air speed, gusts excluded). Filter states are
normalised to unit stationary variance so that a change of L or sigma never makes the gust jump:

    u:     y <- e^{-s} y + sqrt(1 - e^{-2s}) eta,           u_g = sigma_u y,        s = V dt / L_u
    v, w:  y <- Phi(s) y + chol(Q_d(s)) eta (2 samples),   v_g = sigma_v (y_1 / 2 + sqrt(3) y_2 / 2)

Phi and Q_d are the exact transition and noise covariance of the critically damped Dryden filter
A = [[0, 1], [-a^2, -2a]], a = V / L, in coordinates scaled by diag(2 a^1.5, 2 a^0.5):

    Phi = e^{-s} [[1 + s, s], [-s, 1 - s]],   Q_d = I - Phi Phi^T   (= the Van Loan integral)

p_g is a first-order lag with tau_p = 4b/(pi V) driven by its own noise, stationary variance
sigma_p^2 = 0.1 pi^2 (pi/4b)^(1/3) sigma_w^2 / (b L_w^(2/3)). q_g and r_g come from the exact
filters without differentiators (first-order hold of w_g, v_g across the step):

    z_q' = (w_g - z_q)/T_q,  q_g = -(w_g - z_q)/(V T_q),   T_q = 4b/(pi V)
    z_r' = (v_g - z_r)/T_r,  r_g = +(v_g - z_r)/(V T_r),   T_r = 3b/(pi V)

so (p_g, q_g, r_g) is the rotation of the air mass (q_g = -dw_g/dx, r_g = +dv_g/dx): q_g is built
from w_g only and r_g from v_g only. Six unit normal samples per env and step drive the filters:
(eta_u, eta_v1, eta_v2, eta_w1, eta_w2, eta_p).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ._warp import vector_type, warp_func, warp_struct, wp
from .constants import FT, KT

#: MIL-F-8785C severities by W20, knots.
SEVERITY_W20_KT: dict[str, float] = {"very_light": 2.0, "light": 15.0, "moderate": 30.0, "severe": 45.0}
#: Filter states per env: (y_u, y_v1, y_v2, y_w1, y_w2, y_p, z_q, z_r).
NUM_FILTER_STATES = 8
#: Unit normal samples per env and step: (eta_u, eta_v1, eta_v2, eta_w1, eta_w2, eta_p).
NUM_NOISE = 6
#: Floor of the airspeed the filters see, m/s.
MIN_TURBULENCE_AIRSPEED = 1.0
#: Medium/high-altitude sigma table, MIL-F-8785C Fig. 7 as coded in JSBSim (ft, ft/s); the
#: 1750 ft column is the left end of the 1750-80000 ft interpolation (used from 2000 ft up).
HIGH_ALTITUDE_FT = (1750.0, 3750.0, 7500.0, 15000.0, 25000.0, 35000.0, 45000.0, 55000.0, 65000.0,
                    75000.0, 80000.0)
HIGH_ALTITUDE_SIGMA_FPS = (
    (6.9, 7.4, 6.7, 4.6, 2.7, 0.4, 0.0, 0.0, 0.0, 0.0, 0.0),  # light (P = 1e-2)
    (9.6, 10.6, 10.1, 8.0, 6.6, 5.0, 4.2, 2.7, 0.0, 0.0, 0.0),  # moderate (1e-3)
    (17.6, 23.0, 23.6, 22.1, 20.0, 16.0, 15.1, 12.1, 7.9, 6.2, 5.1),  # severe (1e-5)
)
_SQRT3_2 = 0.5 * math.sqrt(3.0)


def steady_wind(wind: object, num_envs: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """``wind`` (NED m/s, [3] for every env or [N, 3] per env) as an [N, 3] tensor, or a one-line
    ValueError naming the constraint: real numbers, finite, one of those two shapes."""
    try:
        array = torch.as_tensor(wind, dtype=torch.float64)
    except (TypeError, ValueError, RuntimeError):
        raise ValueError(f"wind must be real numbers in NED m/s, [3] or [{num_envs}, 3]; "
                         f"got {wind!r}") from None
    if tuple(array.shape) not in ((3,), (num_envs, 3)):
        raise ValueError(f"wind must have shape [3] or [{num_envs}, 3] (NED m/s), got {list(array.shape)}")
    if not torch.isfinite(array).all():
        raise ValueError(f"wind must be finite (NED m/s), got {array.tolist()}")
    return array.to(dtype=dtype, device=device).expand(num_envs, 3)


def severity_w20(severity: str | float) -> float:
    """W20 in m/s of a MIL severity name, or of a number given in m/s (returned as is)."""
    if isinstance(severity, str):
        key = severity.lower().replace(" ", "_").replace("-", "_")
        if key not in SEVERITY_W20_KT:
            raise ValueError(f"unknown turbulence severity {severity!r}; choose one of "
                             f"{sorted(SEVERITY_W20_KT)} or give W20 in m/s")
        return SEVERITY_W20_KT[key] * KT
    if not severity >= 0.0:
        raise ValueError(f"W20 must be >= 0 m/s, got {severity}")
    return float(severity)


# ------------------------------------------------------------------------------ scales (torch)
def _high_altitude_sigma(h_ft: torch.Tensor, w20_kt: torch.Tensor) -> torch.Tensor:
    """Table sigma (ft/s) at h_ft [N] (clamped to the table) for W20 [N] kt, interpolated in both."""
    knots = torch.tensor(HIGH_ALTITUDE_FT, dtype=h_ft.dtype, device=h_ft.device)
    rows = torch.tensor(HIGH_ALTITUDE_SIGMA_FPS, dtype=h_ft.dtype, device=h_ft.device)  # [3, 11]
    h = h_ft.clamp(knots[0], knots[-1])
    hi = torch.searchsorted(knots, h.contiguous()).clamp(1, knots.numel() - 1)
    t = ((h - knots[hi - 1]) / (knots[hi] - knots[hi - 1])).clamp(0.0, 1.0)
    at_h = rows[:, hi - 1] * (1.0 - t) + rows[:, hi] * t  # [3, N]
    u = w20_kt / 15.0
    c1 = (1.0 - (u - 1.0).abs()).clamp_min(0.0)
    c2 = (1.0 - (u - 2.0).abs()).clamp_min(0.0)
    c3 = torch.where(u > 3.0, u / 3.0, (1.0 - (u - 3.0).abs()).clamp_min(0.0))
    return c1 * at_h[0] + c2 * at_h[1] + c3 * at_h[2]


def dryden_scales(height: torch.Tensor, w20: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """MIL-F-8785C scale lengths and intensities at ``height`` [N] m AGL for ``w20`` [N] m/s.

    Returns (length [N, 3] m, sigma [N, 3] m/s), columns (u, v, w).
    """
    h = (height / FT).clamp_min(10.0)
    d = 0.177 + 0.000823 * h.clamp_max(1000.0)
    l_uv_low = h.clamp_max(1000.0) / d**1.2
    l_w_low = h.clamp_max(1000.0)
    sigma_w_low = 0.1 * w20
    sigma_uv_low = sigma_w_low / d**0.4
    sigma_high = FT * _high_altitude_sigma(h.clamp_min(2000.0), w20 / KT)
    f = ((h - 1000.0) / 1000.0).clamp(0.0, 1.0)
    l_mid = (1000.0 + 750.0 * f) * FT
    sigma_mid = sigma_w_low + f * (sigma_high - sigma_w_low)
    low = h <= 1000.0
    l_uv = torch.where(low, l_uv_low * FT, l_mid)
    l_w = torch.where(low, l_w_low * FT, l_mid)
    s_uv = torch.where(low, sigma_uv_low, sigma_mid)
    s_w = torch.where(low, sigma_w_low, sigma_mid)
    return torch.stack([l_uv, l_uv, l_w], dim=-1), torch.stack([s_uv, s_uv, s_w], dim=-1)


def roll_gust_sigma(sigma_w: torch.Tensor, length_w: torch.Tensor, span: torch.Tensor) -> torch.Tensor:
    """Stationary sigma_p [N] rad/s of the 8785C roll gust (sigma_w, L_w, b: [N], SI)."""
    return (math.sqrt(0.1) * math.pi * (math.pi / (4.0 * span)) ** (1.0 / 6.0) * sigma_w
            / (torch.sqrt(span) * length_w ** (1.0 / 3.0)))


# ------------------------------------------------------------------------------ exact filter pieces
def one_minus_exp(x: torch.Tensor) -> torch.Tensor:
    """1 - e^{-x} for x >= 0 without cancellation at small x."""
    series = x * (1.0 - x / 2.0 * (1.0 - x / 3.0 * (1.0 - x / 4.0 * (1.0 - x / 5.0))))
    return torch.where(x < 0.05, series, 1.0 - torch.exp(-x))


def _gamma3(x: torch.Tensor) -> torch.Tensor:
    """1 - e^{-x} (1 + x + x^2/2) for x >= 0 (a series below x = 1, where it is O(x^3))."""
    inner = torch.ones_like(x)
    for k in range(11, 3, -1):
        inner = 1.0 + x / k * inner
    series = torch.exp(-x) * x**3 / 6.0 * inner
    return torch.where(x < 1.0, series, 1.0 - torch.exp(-x) * (1.0 + x + 0.5 * x * x))


def _noise_factors(s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(l11, l21, l22): the Cholesky factor of Q_d(s) = I - Phi Phi^T, elementwise over s [...]."""
    x = 2.0 * s
    ex = torch.exp(-x)
    l11 = torch.sqrt(_gamma3(x))
    l21 = 0.5 * x * x * ex / l11.clamp_min(1e-30)
    l22 = torch.sqrt((one_minus_exp(x) + ex * x * (1.0 - 0.5 * x) - l21 * l21).clamp_min(0.0))
    return l11, l21, l22


def critically_damped_step(s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Exact transition and noise factor of the normalised Dryden v/w filter for s = V dt / L.

    s: [...]. Returns (Phi [..., 2, 2], L [..., 2, 2] lower triangular with L L^T = Q_d).
    """
    e = torch.exp(-s)
    phi = torch.stack([torch.stack([e * (1.0 + s), e * s], -1),
                       torch.stack([-e * s, e * (1.0 - s)], -1)], -2)
    l11, l21, l22 = _noise_factors(s)
    chol = torch.stack([torch.stack([l11, torch.zeros_like(s)], -1), torch.stack([l21, l22], -1)], -2)
    return phi, chol


def critically_damped_update(y1: torch.Tensor, y2: torch.Tensor, eta1: torch.Tensor, eta2: torch.Tensor,
                             s: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """y <- Phi(s) y + chol(Q_d(s)) eta, written out elementwise (all [...])."""
    e = torch.exp(-s)
    l11, l21, l22 = _noise_factors(s)
    es = e * s
    return (e * y1 + es * (y1 + y2) + l11 * eta1,
            e * y2 - es * (y1 + y2) + l21 * eta1 + l22 * eta2)


def _lag_with_hold(z: torch.Tensor, w0: torch.Tensor, w1: torch.Tensor, r: torch.Tensor) -> torch.Tensor:
    """Exact step of z' = (w - z)/T over dt = r T with w linear from w0 to w1 (all [N])."""
    om = one_minus_exp(r)
    return (1.0 - om) * z + om * w0 + (w1 - w0) * (1.0 - om / r)


def dryden_step(filt: torch.Tensor, noise: torch.Tensor, gust_velocity: torch.Tensor, w20: torch.Tensor,
                height: torch.Tensor, airspeed: torch.Tensor, span: torch.Tensor, dt: float
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Advance the Dryden filters of all envs by one step.

    filt: [N, 8] normalised filter states; noise: [N, 6] unit normal samples; gust_velocity: [N, 3]
    gust of the previous step (its v, w feed the first-order hold of z_r, z_q); w20, height (m AGL),
    airspeed (mean-air, m/s), span (m): [N]. Returns (filt [N, 8], gust_velocity [N, 3] m/s,
    gust_rate [N, 3] rad/s), new tensors.
    """
    length, sigma = dryden_scales(height, w20)
    v = airspeed.clamp_min(MIN_TURBULENCE_AIRSPEED)
    s = v[:, None] * dt / length  # [N, 3]
    y_u = torch.exp(-s[:, 0]) * filt[:, 0] + torch.sqrt(one_minus_exp(2.0 * s[:, 0])) * noise[:, 0]
    # v and w together: columns (v, w) of [N, 2] tensors.
    y1, y2 = critically_damped_update(filt[:, 1:5:2], filt[:, 2:5:2], noise[:, 1:5:2], noise[:, 2:5:2],
                                      s[:, 1:])
    tau_p = 4.0 * span / (math.pi * v)
    r_p = dt / tau_p
    y_p = torch.exp(-r_p) * filt[:, 5] + torch.sqrt(one_minus_exp(2.0 * r_p)) * noise[:, 5]
    u_g = sigma[:, 0] * y_u
    vw_g = sigma[:, 1:] * (0.5 * y1 + _SQRT3_2 * y2)
    v_g, w_g = vw_g[:, 0], vw_g[:, 1]
    z_q = _lag_with_hold(filt[:, 6], gust_velocity[:, 2], w_g, r_p)  # T_q = tau_p
    z_r = _lag_with_hold(filt[:, 7], gust_velocity[:, 1], v_g, r_p * (4.0 / 3.0))  # T_r = 3b/(pi V)
    p_g = roll_gust_sigma(sigma[:, 2], length[:, 2], span) * y_p
    q_g = -(w_g - z_q) * (math.pi / (4.0 * span))
    r_g = (v_g - z_r) * (math.pi / (3.0 * span))
    new = torch.stack([y_u, y1[:, 0], y2[:, 0], y1[:, 1], y2[:, 1], y_p, z_q, z_r], -1)
    return new, torch.stack([u_g, v_g, w_g], -1), torch.stack([p_g, q_g, r_g], -1)


# ------------------------------------------------------------------------------ configuration / state
@dataclass
class TurbulenceConfig:
    """Dryden turbulence settings; exactly one of ``severity``, ``w20`` or ``sigma_u`` sets W20.

    severity: a MIL name (very_light, light, moderate, severe). w20: W20 in m/s.
    sigma_u: sigma_u in m/s at ``reference_height`` m (W20 solved from the spec at that height;
    100 m when None).
    external_noise: both backends read the samples from ``Turbulence.noise`` [N, 6] (written by the
    caller before each step) instead of drawing them: used to compare backends on the same noise.
    """

    severity: str | None = None
    w20: float | None = None
    sigma_u: float | None = None
    reference_height: float | None = None
    external_noise: bool = False

    def resolve_w20(self) -> float:
        """W20 in m/s."""
        given = [k for k in ("severity", "w20", "sigma_u") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ValueError(f"give one of severity, w20 or sigma_u, not {given}")
        if self.w20 is not None:
            return severity_w20(float(self.w20))
        if self.sigma_u is not None:
            height = 100.0 if self.reference_height is None else self.reference_height
            return w20_for_sigma_u(self.sigma_u, height)
        return severity_w20(self.severity or "light")


def w20_for_sigma_u(sigma_u: float, height: float) -> float:
    """W20 (m/s) whose sigma_u at ``height`` m equals ``sigma_u`` m/s (bisection, float64)."""
    if not sigma_u >= 0.0:
        raise ValueError(f"sigma_u must be >= 0, got {sigma_u}")
    h = torch.tensor([float(height)], dtype=torch.float64)
    lo, hi = 0.0, 1.0
    while float(dryden_scales(h, torch.tensor([hi], dtype=torch.float64))[1][0, 0]) < sigma_u:
        hi *= 2.0
        if hi > 1e4:
            raise ValueError(f"sigma_u = {sigma_u} m/s is out of reach at {height} m")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if float(dryden_scales(h, torch.tensor([mid], dtype=torch.float64))[1][0, 0]) < sigma_u:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def turbulence_config(spec: object) -> TurbulenceConfig | None:
    """None / False / "off" / "none" -> None; a severity name or a TurbulenceConfig -> config."""
    if spec is None or spec is False or (isinstance(spec, str) and spec.lower() in ("off", "none")):
        return None
    if isinstance(spec, TurbulenceConfig):
        return spec
    if isinstance(spec, str):
        severity_w20(spec)
        return TurbulenceConfig(severity=spec)
    raise TypeError(f"turbulence must be None, a severity name or a TurbulenceConfig, got {spec!r}")


class Turbulence:
    """Per-env Dryden state held by the Simulator beside the integrated state vector.

    filter: [N, 8] normalised filter states (zeroed by a reset of the row). w20: [N] m/s, per-env
    severity (domain randomisation writes it by mask; 0 turns a row's gusts off). noise: [N, 6] the
    samples of the last step (or the injected ones with ``external_noise``). rng: int32 [2] (seed,
    step counter) of the Warp streams ``wp.rand_init``.
    """

    def __init__(self, config: TurbulenceConfig, num_envs: int, device: torch.device, dtype: torch.dtype,
                 seed: int):
        self.config = config
        self.external_noise = bool(config.external_noise)
        self.filter = torch.zeros(num_envs, NUM_FILTER_STATES, device=device, dtype=dtype)
        self.w20 = torch.full((num_envs,), config.resolve_w20(), device=device, dtype=dtype)
        self.noise = torch.zeros(num_envs, NUM_NOISE, device=device, dtype=dtype)
        self.rng = torch.zeros(2, dtype=torch.int32, device=device)
        self.reseed(seed)

    def reseed(self, seed: int) -> None:
        """Restart the Warp noise streams from ``seed`` (the torch backend uses the sim generator)."""
        self.rng[0] = int(seed) % (2**31 - 1)
        self.rng[1] = 0

    def reset(self, mask: torch.Tensor | None) -> None:
        """Zero the filter states of the rows in ``mask`` [N] bool (all when None)."""
        if mask is None:
            self.filter.zero_()
        else:
            self.filter.masked_fill_(mask[:, None], 0.0)


# ---------------------------------------------------------------------------------------- warp twins
Vec8 = vector_type(NUM_FILTER_STATES)
Vec6 = vector_type(NUM_NOISE)
Vec11 = vector_type(len(HIGH_ALTITUDE_FT))
if wp is not None:
    _HIGH_FT = wp.constant(Vec11(*HIGH_ALTITUDE_FT))
    _HIGH_LIGHT = wp.constant(Vec11(*HIGH_ALTITUDE_SIGMA_FPS[0]))
    _HIGH_MODERATE = wp.constant(Vec11(*HIGH_ALTITUDE_SIGMA_FPS[1]))
    _HIGH_SEVERE = wp.constant(Vec11(*HIGH_ALTITUDE_SIGMA_FPS[2]))


@warp_struct
class DrydenScalesWp:
    """Scale lengths (m) and intensities (m/s) for (u, v, w)."""

    length: wp.vec3
    sigma: wp.vec3


@warp_struct
class DrydenStepWp:
    """New filter states, gust velocity (m/s) and gust rate (rad/s) of one env."""

    filt: Vec8
    gust_velocity: wp.vec3
    gust_rate: wp.vec3


@warp_func
def _high_altitude_sigma_wp(h_ft: float, w20_kt: float) -> float:
    """Twin of :func:`_high_altitude_sigma` (ft/s)."""
    h = wp.clamp(h_ft, _HIGH_FT[0], _HIGH_FT[10])
    light = float(0.0)  # noqa: UP018 (a mutable Warp local)
    moderate = float(0.0)  # noqa: UP018 (a mutable Warp local)
    severe = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for k in range(10):
        lo = _HIGH_FT[k]
        hi = _HIGH_FT[k + 1]
        if (h >= lo and h < hi) or (k == 9 and h >= hi):
            t = wp.clamp((h - lo) / (hi - lo), 0.0, 1.0)
            light = _HIGH_LIGHT[k] * (1.0 - t) + _HIGH_LIGHT[k + 1] * t
            moderate = _HIGH_MODERATE[k] * (1.0 - t) + _HIGH_MODERATE[k + 1] * t
            severe = _HIGH_SEVERE[k] * (1.0 - t) + _HIGH_SEVERE[k + 1] * t
    u = w20_kt / 15.0
    c1 = wp.max(1.0 - wp.abs(u - 1.0), 0.0)
    c2 = wp.max(1.0 - wp.abs(u - 2.0), 0.0)
    c3 = wp.max(1.0 - wp.abs(u - 3.0), 0.0)
    if u > 3.0:
        c3 = u / 3.0
    return c1 * light + c2 * moderate + c3 * severe


@warp_func
def dryden_scales_wp(height: float, w20: float) -> DrydenScalesWp:
    """Twin of :func:`dryden_scales` for one env."""
    h = wp.max(height / FT, 10.0)
    h_low = wp.min(h, 1000.0)
    d = 0.177 + 0.000823 * h_low
    sigma_w_low = 0.1 * w20
    out = DrydenScalesWp()
    if h <= 1000.0:
        l_uv = h_low / wp.pow(d, 1.2) * FT
        sigma_uv = sigma_w_low / wp.pow(d, 0.4)
        out.length = wp.vec3(l_uv, l_uv, h_low * FT)
        out.sigma = wp.vec3(sigma_uv, sigma_uv, sigma_w_low)
    else:
        sigma_high = FT * _high_altitude_sigma_wp(wp.max(h, 2000.0), w20 / KT)
        f = wp.clamp((h - 1000.0) / 1000.0, 0.0, 1.0)
        length = (1000.0 + 750.0 * f) * FT
        sigma = sigma_w_low + f * (sigma_high - sigma_w_low)
        out.length = wp.vec3(length, length, length)
        out.sigma = wp.vec3(sigma, sigma, sigma)
    return out


@warp_func
def one_minus_exp_wp(x: float) -> float:
    """Twin of :func:`one_minus_exp`."""
    if x < 0.05:
        return x * (1.0 - x / 2.0 * (1.0 - x / 3.0 * (1.0 - x / 4.0 * (1.0 - x / 5.0))))
    return 1.0 - wp.exp(-x)


@warp_func
def _gamma3_wp(x: float) -> float:
    """Twin of :func:`_gamma3`."""
    if x < 1.0:
        inner = float(1.0)  # noqa: UP018 (a mutable Warp local)
        for j in range(8):
            inner = 1.0 + x / float(11 - j) * inner
        return wp.exp(-x) * x * x * x / 6.0 * inner
    return 1.0 - wp.exp(-x) * (1.0 + x + 0.5 * x * x)


@warp_func
def critically_damped_update_wp(y: wp.vec2, eta: wp.vec2, s: float) -> wp.vec2:
    """Twin of :func:`critically_damped_update`."""
    e = wp.exp(-s)
    x = 2.0 * s
    ex = wp.exp(-x)
    l11 = wp.sqrt(_gamma3_wp(x))
    l21 = 0.5 * x * x * ex / wp.max(l11, 1.0e-30)
    l22 = wp.sqrt(wp.max(one_minus_exp_wp(x) + ex * x * (1.0 - 0.5 * x) - l21 * l21, 0.0))
    es = e * s
    return wp.vec2(e * y[0] + es * (y[0] + y[1]) + l11 * eta[0],
                   e * y[1] - es * (y[0] + y[1]) + l21 * eta[0] + l22 * eta[1])


@warp_func
def _lag_with_hold_wp(z: float, w0: float, w1: float, r: float) -> float:
    """Twin of :func:`_lag_with_hold`."""
    om = one_minus_exp_wp(r)
    return (1.0 - om) * z + om * w0 + (w1 - w0) * (1.0 - om / r)


@warp_func
def dryden_step_wp(filt: Vec8, noise: Vec6, gust_velocity: wp.vec3, w20: float, height: float,
                   airspeed: float, span: float, dt: float) -> DrydenStepWp:
    """Twin of :func:`dryden_step` for one env."""
    sc = dryden_scales_wp(height, w20)
    v = wp.max(airspeed, MIN_TURBULENCE_AIRSPEED)
    s_u = v * dt / sc.length[0]
    y_u = wp.exp(-s_u) * filt[0] + wp.sqrt(one_minus_exp_wp(2.0 * s_u)) * noise[0]
    y_v = critically_damped_update_wp(wp.vec2(filt[1], filt[2]), wp.vec2(noise[1], noise[2]),
                                      v * dt / sc.length[1])
    y_w = critically_damped_update_wp(wp.vec2(filt[3], filt[4]), wp.vec2(noise[3], noise[4]),
                                      v * dt / sc.length[2])
    r_p = dt * wp.pi * v / (4.0 * span)
    y_p = wp.exp(-r_p) * filt[5] + wp.sqrt(one_minus_exp_wp(2.0 * r_p)) * noise[5]
    u_g = sc.sigma[0] * y_u
    v_g = sc.sigma[1] * (0.5 * y_v[0] + _SQRT3_2 * y_v[1])
    w_g = sc.sigma[2] * (0.5 * y_w[0] + _SQRT3_2 * y_w[1])
    z_q = _lag_with_hold_wp(filt[6], gust_velocity[2], w_g, r_p)
    z_r = _lag_with_hold_wp(filt[7], gust_velocity[1], v_g, r_p * (4.0 / 3.0))
    sigma_p = (wp.sqrt(0.1) * wp.pi * wp.pow(wp.pi / (4.0 * span), 1.0 / 6.0) * sc.sigma[2]
               / (wp.sqrt(span) * wp.pow(sc.length[2], 1.0 / 3.0)))
    out = DrydenStepWp()
    out.filt = Vec8(y_u, y_v[0], y_v[1], y_w[0], y_w[1], y_p, z_q, z_r)
    out.gust_velocity = wp.vec3(u_g, v_g, w_g)
    out.gust_rate = wp.vec3(sigma_p * y_p, -(w_g - z_q) * (wp.pi / (4.0 * span)),
                            (v_g - z_r) * (wp.pi / (3.0 * span)))
    return out
