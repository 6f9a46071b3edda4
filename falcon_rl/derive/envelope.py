"""Flight envelope of a derived airframe, computed on the fitted model itself.

- stall: V_s = sqrt(2 W / (rho S C_L,max)) with C_L,max of the clean AeroBuildup sweep;
- cruise: the geometry file's cruise speed (its source is stated there);
- max: the top level speed the model trims at full throttle (bisection on ``trim_level``), capped
  at 2.5 x cruise;
- max bank: acos(1 / n) at the load factor that keeps 1.2 V_s margin at cruise,
  n = (V_cruise / (1.2 V_s))^2, capped by the geometry file's operational limit;
- climb-rate limit: excess-power climb at cruise, (T_max - T_trim) V / W, capped by the geometry
  file's figure.
"""

from __future__ import annotations

import math
from typing import Any

from ..airframe import Airframe
from ..physics.trim import TrimError, trim_level
from .geometry import GeometrySpec
from .propulsion import full_throttle_thrust

HEIGHT = 100.0  # m, out of ground effect (ground effect off anyway)


def _trims(airframe: Airframe, speed: float) -> bool:
    try:
        trim_level(airframe, speed, HEIGHT, ground_effect=False)
    except TrimError:
        return False
    return True


def max_level_speed(airframe: Airframe, cruise: float, cap: float) -> float:
    """Highest speed (m/s, 0.1 m/s resolution) at which level trim needs throttle <= 1."""
    if _trims(airframe, cap):
        return cap
    lo, hi = cruise, cap
    while hi - lo > 0.05:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _trims(airframe, mid) else (lo, mid)
    return math.floor(lo * 10) / 10


def envelope(airframe: Airframe, spec: GeometrySpec, stall: float) -> tuple[dict[str, Any], dict[str, str]]:
    """Envelope block of the airframe document and the notes that explain it."""
    cruise = spec.cruise_speed
    caps = spec.raw["envelope"]
    vmax = max_level_speed(airframe, cruise, 2.5 * cruise)
    trim = trim_level(airframe, cruise, HEIGHT, ground_effect=False)
    rho = _density(float(trim.height[0]))
    t_max = sum(full_throttle_thrust(m.disk_area, m.thrust_coefficient, m.discharge_speed, cruise, rho)
                for m in airframe.motors)
    climb = (t_max - float(trim.thrust[0])) * cruise / airframe.weight
    n = (cruise / (1.2 * stall)) ** 2
    bank_stall = math.acos(min(1.0, 1.0 / n)) if n > 1 else 0.2
    bank = min(math.radians(caps["max_bank_deg"]), bank_stall)
    out = {"stall_speed_mps": round(stall, 2), "cruise_speed_mps": cruise, "max_speed_mps": vmax,
           "max_bank_rad": round(bank, 4),
           "climb_rate_limit_mps": round(min(caps["climb_rate_limit_mps"], climb), 2)}
    notes = {"envelope": (
        f"stall from C_L,max of the sweep; max {vmax} m/s = top level speed the model trims at full throttle "
        f"(cap 2.5 x cruise); bank min({caps['max_bank_deg']} deg cap, {math.degrees(bank_stall):.1f} deg "
        f"at 1.2 V_s margin); climb min({caps['climb_rate_limit_mps']} m/s cap, {climb:.2f} m/s excess-power "
        f"climb at cruise)")}
    return out, notes


def _density(height: float) -> float:
    import torch

    from ..physics.atmosphere import isa_density

    return float(isa_density(torch.tensor(height, dtype=torch.float64)))
