"""ISA / US Standard Atmosphere 1976: troposphere (0-11 km) and the isothermal layer above.

Geometric altitude is converted to geopotential altitude H = r0 z / (r0 + z) first. The model
switch ``constant_density`` (``switches.ModelSwitches(atmosphere="constant")``) replaces the density
by its sea-level value RHO_SEA_LEVEL = P0 / (R T0) at every height (:func:`model_density`).
"""

from __future__ import annotations

import torch

from ._warp import warp_func, wp
from .constants import G0, GAMMA, LAPSE, P0, R_AIR, T0

R_EARTH = 6_356_766.0  # m, geopotential Earth radius
H_TROPOPAUSE = 11_000.0  # m geopotential
T_TROPOPAUSE = T0 + LAPSE * H_TROPOPAUSE  # 216.65 K
P_TROPOPAUSE = P0 * (T_TROPOPAUSE / T0) ** (-G0 / (R_AIR * LAPSE))  # 22,632 Pa
_PRESSURE_EXPONENT = -G0 / (R_AIR * LAPSE)
RHO_SEA_LEVEL = P0 / (R_AIR * T0)  # 1.225 kg/m^3


def isa(altitude_m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """ISA state at geometric altitude.

    Args:
        altitude_m: [...] geometric altitude above mean sea level, m (valid up to 20 km).

    Returns:
        (temperature K, pressure Pa, density kg/m^3, speed of sound m/s), each shaped like the input.
    """
    h = altitude_m.clamp(-1_000.0, 20_000.0)
    geopotential = R_EARTH * h / (R_EARTH + h)
    tropo = geopotential <= H_TROPOPAUSE
    temperature = torch.where(tropo, T0 + LAPSE * geopotential,
                              torch.full_like(geopotential, T_TROPOPAUSE))
    p_tropo = P0 * (temperature / T0) ** (-G0 / (R_AIR * LAPSE))
    p_strato = P_TROPOPAUSE * torch.exp(-G0 * (geopotential - H_TROPOPAUSE) / (R_AIR * T_TROPOPAUSE))
    pressure = torch.where(tropo, p_tropo, p_strato)
    density = pressure / (R_AIR * temperature)
    sound = torch.sqrt(GAMMA * R_AIR * temperature)
    return temperature, pressure, density, sound


def isa_density(altitude_m: torch.Tensor) -> torch.Tensor:
    """Density only, kg/m^3, shaped like ``altitude_m``."""
    return isa(altitude_m)[2]


def model_density(altitude_m: torch.Tensor, constant_density: torch.Tensor) -> torch.Tensor:
    """[N] kg/m^3: ISA density at ``altitude_m`` [N], or RHO_SEA_LEVEL where the int32 switch
    ``constant_density`` [N] is set."""
    density = isa_density(altitude_m)
    return torch.where(constant_density != 0, RHO_SEA_LEVEL, density)


@warp_func
def isa_density_wp(altitude_m: float) -> float:
    """Density kg/m^3 at geometric altitude, m (twin of :func:`isa_density`)."""
    h = wp.clamp(altitude_m, -1000.0, 20000.0)
    geopotential = R_EARTH * h / (R_EARTH + h)
    temperature = T_TROPOPAUSE
    pressure = float(0.0)  # noqa: UP018 (a mutable Warp local)
    if geopotential <= H_TROPOPAUSE:
        temperature = T0 + LAPSE * geopotential
        pressure = P0 * wp.pow(temperature / T0, _PRESSURE_EXPONENT)
    else:
        pressure = P_TROPOPAUSE * wp.exp(-G0 * (geopotential - H_TROPOPAUSE) / (R_AIR * T_TROPOPAUSE))
    return pressure / (R_AIR * temperature)


@warp_func
def model_density_wp(altitude_m: float, constant_density: int) -> float:
    """Twin of :func:`model_density` for one env."""
    if constant_density != 0:
        return RHO_SEA_LEVEL
    return isa_density_wp(altitude_m)
