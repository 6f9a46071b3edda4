"""The sea surface: sea states, wave spectra and a random-phase directional wave field per env.

Sea state (WMO / Douglas code) -> significant wave height range Hs (m); the field is drawn at the
range's middle unless Hs is given:

    code   0    1        2          3           4           5         6
    Hs     0    0-0.1    0.1-0.5    0.5-1.25    1.25-2.5    2.5-4     4-6

Spectra of the surface elevation, one-sided in angular frequency w (m^2 s / rad):

    Pierson-Moskowitz (wind U at 19.5 m):  S(w) = a g^2 w^-5 exp(-b (w0 / w)^4),  a = 8.1e-3,
                                           b = 0.74, w0 = g / U  (fully developed: Hs = 0.21 U^2 / g,
                                           Tp = 5.0 sqrt(Hs))
    the same from Hs and Tp (DNV-RP-C205 3.5.5):  S_PM(w) = 5/16 Hs^2 wp^4 w^-5 exp(-5/4 (wp / w)^4),
                                           wp = 2 pi / Tp
    JONSWAP:                               S_J(w) = A_gamma S_PM(w) gamma^r,
                                           r = exp(-(w - wp)^2 / (2 s^2 wp^2)),
                                           A_gamma = 1 - 0.287 ln gamma,  s = 0.07 (w <= wp) or 0.09,
                                           gamma = 3.3 by default (1: Pierson-Moskowitz)

with Tp = 5.0 sqrt(Hs) (fully developed) unless given. Directional spreading about the mean wave
direction theta0 (the direction the waves travel toward, from north, rad):

    D(theta) = Gamma(1 + n/2) / (sqrt(pi) Gamma(1/2 + n/2)) cos^n(theta - theta0),  |theta - theta0| < pi/2

(n = 2 by default; n = 0 with ``spreading=None``: long-crested waves along theta0).

The field is a sum of K Airy components in deep water (dispersion w^2 = g k), each with its own
frequency, direction and random phase drawn per env from the env's generator:

    eta(n, e, t) = sum_k a_k cos(k_k (n cos theta_k + e sin theta_k) - w_k t + phi_k)
    a_k = sqrt(2 S(w_k) dw)

The K frequencies split [w_lo, w_hi] = [0.5, 5] wp into equal bins, one frequency drawn uniformly in
each (so a field does not repeat after 2 pi / dw), and each component's direction is drawn from D by
its inverse distribution: the record at a point then has variance sum a_k^2 / 2 = m0 and
Hs = 4 sqrt(m0), and its spectrum is S. eta is positive up, from the mean water level, in the NED
frame's horizontal coordinates (north n, east e, m); ``SeaSurface`` evaluates eta, d(eta)/dt and the
air's potential flow over the waves, decaying with height h above them as exp(-k h).
The Warp twins (``sea_elevation_wp``, ``sea_elevation_rate_wp``, ``sea_air_velocity_wp``) evaluate
the same sums for one env over :class:`SeaFieldWp`, zero-copy views of a float32 ``SeaSurface``
(:func:`sea_field_views`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..constants import G0
from ._warp import warp_func, warp_struct, wp

#: Significant wave height range (low, high) of each WMO sea-state code 0-6, m.
SEA_STATE_HS: tuple[tuple[float, float], ...] = (
    (0.0, 0.0), (0.0, 0.1), (0.1, 0.5), (0.5, 1.25), (1.25, 2.5), (2.5, 4.0), (4.0, 6.0))
#: Pierson-Moskowitz constants (wind at 19.5 m).
PM_ALPHA = 8.1e-3
PM_BETA = 0.74
#: Fully developed Pierson-Moskowitz: Tp = PM_PERIOD_FACTOR sqrt(Hs) (s, Hs in m).
PM_PERIOD_FACTOR = 5.0
#: JONSWAP peak-width parameters below and above the peak, and the default peak enhancement.
JONSWAP_SIGMA = (0.07, 0.09)
JONSWAP_GAMMA = 3.3
#: Frequency band of the sampled components, in units of the peak frequency.
BAND = (0.5, 5.0)


def sea_state_height(code: int) -> float:
    """The significant wave height Hs (m) a sea-state code 0-6 draws: the middle of its range."""
    if not (isinstance(code, int) and not isinstance(code, bool) and 0 <= code < len(SEA_STATE_HS)):
        raise ValueError(f"sea state must be an int code 0-{len(SEA_STATE_HS) - 1}, got {code!r}")
    low, high = SEA_STATE_HS[code]
    return 0.5 * (low + high)


def fully_developed_period(significant_height: float) -> float:
    """Tp (s) of a fully developed Pierson-Moskowitz sea of significant height Hs (m): 5.0 sqrt(Hs)."""
    return PM_PERIOD_FACTOR * math.sqrt(significant_height)


def pierson_moskowitz_wind(omega: torch.Tensor, wind_speed: float) -> torch.Tensor:
    """S(w) [like ``omega``] of the Pierson-Moskowitz spectrum of wind speed U (m/s, at 19.5 m)."""
    w0 = G0 / wind_speed
    return PM_ALPHA * G0**2 * omega**-5 * torch.exp(-PM_BETA * (w0 / omega) ** 4)


def jonswap(omega: torch.Tensor, significant_height: float, peak_period: float,
            gamma: float = JONSWAP_GAMMA) -> torch.Tensor:
    """S(w) [like ``omega``] of the JONSWAP spectrum of Hs (m) and Tp (s) (DNV-RP-C205; gamma = 1 is the
    Pierson-Moskowitz spectrum of Hs and Tp)."""
    wp = 2.0 * math.pi / peak_period
    pm = 5.0 / 16.0 * significant_height**2 * wp**4 * omega**-5 * torch.exp(-1.25 * (wp / omega) ** 4)
    if gamma == 1.0:
        return pm
    sigma = torch.where(omega <= wp, JONSWAP_SIGMA[0], JONSWAP_SIGMA[1])
    r = torch.exp(-((omega - wp) ** 2) / (2.0 * sigma**2 * wp**2))
    return (1.0 - 0.287 * math.log(gamma)) * pm * gamma**r


@dataclass(frozen=True)
class SeaState:
    """A sea: Hs (m), Tp (s), the mean direction the waves travel toward (rad from north), the cos^n
    spreading exponent n (None: long-crested) and the JONSWAP gamma (1: Pierson-Moskowitz)."""

    significant_height: float
    peak_period: float
    direction: float = 0.0
    spreading: float | None = 2.0
    gamma: float = JONSWAP_GAMMA

    @classmethod
    def from_code(cls, code: int, direction: float = 0.0, spreading: float | None = 2.0,
                  gamma: float = JONSWAP_GAMMA) -> SeaState:
        """The sea of WMO code 0-6: Hs at the middle of its range, Tp fully developed."""
        hs = sea_state_height(code)
        return cls(hs, fully_developed_period(hs) if hs > 0 else 1.0, direction, spreading, gamma)

    def __post_init__(self) -> None:
        for name in ("significant_height", "peak_period", "direction", "gamma"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"sea {name} must be a finite number, got {value!r}")
        if self.significant_height < 0 or self.peak_period <= 0 or self.gamma < 1:
            raise ValueError(f"sea needs significant_height >= 0, peak_period > 0 and gamma >= 1, got "
                             f"{self.significant_height!r}, {self.peak_period!r}, {self.gamma!r}")
        if self.spreading is not None and not (math.isfinite(self.spreading) and self.spreading >= 0):
            raise ValueError(f"sea spreading must be None or a number >= 0, got {self.spreading!r}")

    @property
    def peak_frequency(self) -> float:
        """wp = 2 pi / Tp, rad/s."""
        return 2.0 * math.pi / self.peak_period

    def spectrum(self, omega: torch.Tensor) -> torch.Tensor:
        """S(w) [like ``omega``], m^2 s / rad."""
        return jonswap(omega, self.significant_height, self.peak_period, self.gamma)


def spreading_directions(u: torch.Tensor, mean: float, exponent: float | None) -> torch.Tensor:
    """Directions [like ``u``] drawn from the cos^n spreading about ``mean`` by inverting its
    distribution at the uniforms ``u`` in [0, 1) (tabulated on 2,049 points); ``exponent`` None: all
    along ``mean``."""
    if exponent is None:
        return torch.full_like(u, mean)
    grid = torch.linspace(-math.pi / 2, math.pi / 2, 2049, dtype=torch.float64)
    density = torch.cos(grid).clamp_min(0.0) ** exponent
    cdf = torch.cat([torch.zeros(1, dtype=torch.float64),
                     torch.cumsum(0.5 * (density[1:] + density[:-1]) * (grid[1] - grid[0]), 0)])
    cdf = cdf / cdf[-1]
    index = torch.searchsorted(cdf, u.to(torch.float64).contiguous()).clamp(1, len(grid) - 1)
    lo, hi = cdf[index - 1], cdf[index]
    fraction = (u.to(torch.float64) - lo) / (hi - lo).clamp_min(1e-300)
    angle = grid[index - 1] + fraction * (grid[index] - grid[index - 1])
    return (mean + angle).to(u.dtype)


@dataclass
class SeaSurface:
    """K Airy components of N envs' wave fields (each [N, K]): amplitude a (m), wavenumber k (rad/m),
    frequency w (rad/s), direction (cos, sin) of travel and phase phi (rad)."""

    amplitude: torch.Tensor
    wavenumber: torch.Tensor
    frequency: torch.Tensor
    direction_cos: torch.Tensor
    direction_sin: torch.Tensor
    phase: torch.Tensor

    def _argument(self, north: torch.Tensor, east: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        """k (n cos + e sin) - w t + phi, [N, P, K] for points [N, P] (or [N]) and a time that is a scalar,
        one per env [N] or one per point [N, P]."""
        north, east = _points(north), _points(east)
        time = torch.as_tensor(time, dtype=self.frequency.dtype, device=self.frequency.device)
        if time.dim() == 1:
            time = time[:, None, None]
        elif time.dim() == 2:
            time = time[..., None]
        travel = (north[..., None] * self.direction_cos[:, None]
                  + east[..., None] * self.direction_sin[:, None])
        return (self.wavenumber[:, None] * travel - self.frequency[:, None] * time
                + self.phase[:, None])

    def elevation(self, north: torch.Tensor, east: torch.Tensor, time: torch.Tensor | float) -> torch.Tensor:
        """eta (m, up from the mean level) at points ``north``, ``east`` ([N] or [N, P], m) at ``time``
        (s: a scalar, [N], or [N, P] one per point): [N] or [N, P]."""
        eta = (self.amplitude[:, None] * torch.cos(self._argument(north, east, time))).sum(-1)
        return _per_env(eta, north)

    def elevation_rate(self, north: torch.Tensor, east: torch.Tensor, time: torch.Tensor | float
                       ) -> torch.Tensor:
        """d(eta)/dt (m/s) at the points and time of :meth:`elevation`, same shape."""
        speed = (self.amplitude * self.frequency)[:, None]
        rate = (speed * torch.sin(self._argument(north, east, time))).sum(-1)
        return _per_env(rate, north)

    def air_velocity(self, north: torch.Tensor, east: torch.Tensor, height: torch.Tensor,
                     time: torch.Tensor | float) -> torch.Tensor:
        """NED velocity (m/s) of the air's potential flow over the waves at ``height`` (m, clamped at 0)
        above the mean level (points [N] -> [N, 3], [N, P] -> [N, P, 3]): each component's a w exp(-k h)
        (-cos along the travel, sin up)."""
        argument = self._argument(north, east, time)
        decay = (self.amplitude * self.frequency)[:, None] * torch.exp(
            -self.wavenumber[:, None] * _points(height).clamp_min(0.0)[..., None])
        along = -decay * torch.cos(argument)
        velocity = torch.stack([(along * self.direction_cos[:, None]).sum(-1),
                                (along * self.direction_sin[:, None]).sum(-1),
                                -(decay * torch.sin(argument)).sum(-1)], dim=-1)
        return _per_env(velocity, north)

    @property
    def variance(self) -> torch.Tensor:
        """[N] the elevation's variance at a point over a long record: sum a_k^2 / 2 (= m0)."""
        return 0.5 * (self.amplitude**2).sum(-1)


def _per_env(values: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """``values`` [N, P, ...] as [N, ...] when the points were one per env ([N]), else as they are."""
    return values[:, 0] if torch.as_tensor(points).dim() == 1 else values


def _points(values: torch.Tensor) -> torch.Tensor:
    """[N, P] from [N] (one point per env) or [N, P]."""
    values = torch.as_tensor(values)
    return values[:, None] if values.dim() == 1 else values


def sample_sea(sea: SeaState, num_envs: int, generator: torch.Generator, components: int = 128,
               device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32) -> SeaSurface:
    """A wave field per env of ``sea`` with ``components`` (>= 64) Airy components: frequencies drawn in
    equal bins of [0.5, 5] wp, directions from the spreading, phases uniform; draws from ``generator``
    (its device) in the order frequency jitter, direction, phase, each [N, K]. A flat sea (Hs = 0) has
    zero amplitudes."""
    if components < 64:
        raise ValueError(f"a sea needs at least 64 components, got {components}")
    shape, kw = (num_envs, components), {"generator": generator, "device": generator.device,
                                         "dtype": torch.float64}
    jitter, spread, phase = torch.rand(shape, **kw), torch.rand(shape, **kw), torch.rand(shape, **kw)
    lo, hi = BAND[0] * sea.peak_frequency, BAND[1] * sea.peak_frequency
    width = (hi - lo) / components
    omega = lo + (torch.arange(components, dtype=torch.float64, device=generator.device) + jitter) * width
    amplitude = torch.sqrt(2.0 * sea.spectrum(omega) * width)
    if sea.significant_height == 0.0:
        amplitude = torch.zeros_like(amplitude)
    theta = spreading_directions(spread, sea.direction, sea.spreading)
    out = {"amplitude": amplitude, "wavenumber": omega**2 / G0, "frequency": omega,
           "direction_cos": torch.cos(theta), "direction_sin": torch.sin(theta),
           "phase": 2.0 * math.pi * phase}
    return SeaSurface(**{name: value.to(device=device, dtype=dtype) for name, value in out.items()})


# ---------------------------------------------------------------------------------------- warp twins
@warp_struct
class SeaFieldWp:
    """A ``SeaSurface``'s [N, K] float32 tensors as Warp arrays (zero-copy views)."""

    amplitude: wp.array2d(dtype=wp.float32)
    wavenumber: wp.array2d(dtype=wp.float32)
    frequency: wp.array2d(dtype=wp.float32)
    direction_cos: wp.array2d(dtype=wp.float32)
    direction_sin: wp.array2d(dtype=wp.float32)
    phase: wp.array2d(dtype=wp.float32)


def sea_field_views(surface: SeaSurface) -> SeaFieldWp:
    """:class:`SeaFieldWp` viewing ``surface``'s tensors (float32, contiguous; they must outlive the
    launches that read the views)."""
    views = SeaFieldWp()
    for name in ("amplitude", "wavenumber", "frequency", "direction_cos", "direction_sin", "phase"):
        tensor = getattr(surface, name)
        if tensor.dtype != torch.float32 or not tensor.is_contiguous():
            raise ValueError(f"a sea field's Warp views need contiguous float32 tensors, {name} is "
                             f"{tensor.dtype}")
        setattr(views, name, wp.from_torch(tensor))
    return views


@warp_func
def sea_argument_wp(sea: SeaFieldWp, i: int, k: int, north: float, east: float, time: float) -> float:
    """k_k (n cos theta_k + e sin theta_k) - w_k t + phi_k of env i's component k."""
    travel = north * sea.direction_cos[i, k] + east * sea.direction_sin[i, k]
    return sea.wavenumber[i, k] * travel - sea.frequency[i, k] * time + sea.phase[i, k]


@warp_func
def sea_elevation_wp(sea: SeaFieldWp, i: int, north: float, east: float, time: float) -> float:
    """eta (m, up) of env i at (``north``, ``east``) and ``time`` (twin of ``SeaSurface.elevation``)."""
    eta = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for k in range(sea.amplitude.shape[1]):
        eta += sea.amplitude[i, k] * wp.cos(sea_argument_wp(sea, i, k, north, east, time))
    return eta


@warp_func
def sea_elevation_rate_wp(sea: SeaFieldWp, i: int, north: float, east: float, time: float) -> float:
    """d(eta)/dt (m/s) of env i (twin of ``SeaSurface.elevation_rate``)."""
    rate = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for k in range(sea.amplitude.shape[1]):
        argument = sea_argument_wp(sea, i, k, north, east, time)
        rate += sea.amplitude[i, k] * sea.frequency[i, k] * wp.sin(argument)
    return rate


@warp_func
def sea_air_velocity_wp(sea: SeaFieldWp, i: int, north: float, east: float, height: float,
                        time: float) -> wp.vec3:
    """NED velocity (m/s) of the air's potential flow over env i's waves at ``height`` (m) above the mean
    level (twin of ``SeaSurface.air_velocity``)."""
    along_n = float(0.0)  # noqa: UP018 (a mutable Warp local)
    along_e = float(0.0)  # noqa: UP018
    up = float(0.0)  # noqa: UP018
    h = wp.max(height, 0.0)
    for k in range(sea.amplitude.shape[1]):
        argument = sea_argument_wp(sea, i, k, north, east, time)
        decay = sea.amplitude[i, k] * sea.frequency[i, k] * wp.exp(-sea.wavenumber[i, k] * h)
        along = -decay * wp.cos(argument)
        along_n += along * sea.direction_cos[i, k]
        along_e += along * sea.direction_sin[i, k]
        up += decay * wp.sin(argument)
    return wp.vec3(along_n, along_e, -up)


__all__ = [
    "BAND",
    "JONSWAP_GAMMA",
    "PM_PERIOD_FACTOR",
    "SEA_STATE_HS",
    "SeaFieldWp",
    "SeaState",
    "SeaSurface",
    "fully_developed_period",
    "jonswap",
    "pierson_moskowitz_wind",
    "sample_sea",
    "sea_air_velocity_wp",
    "sea_elevation_rate_wp",
    "sea_elevation_wp",
    "sea_field_views",
    "sea_state_height",
    "spreading_directions",
]
