"""Propulsion identification: momentum-theory constants (S_p, C_p, k_m) per powerplant class.

falcon-rl's thrust at full throttle is T(V) = 1/2 rho S_p C_p k_m (k_m - V): linear in airspeed,
T_0 = 1/2 rho S_p C_p k_m^2 static and zero at V = k_m. Two numbers fix it:

- electric (motor/propeller data): static thrust T_0 from the motor/propeller data and k_m the
  propeller pitch speed at full-throttle rpm (pitch x rpm / 60), where the thrust vanishes;
- piston (rated shaft power P and propeller diameter D): static thrust from the momentum disk,
  T_0 = (2 rho S_p)^(1/3) (FM P)^(2/3) with figure of merit FM, and the power-available thrust
  T_c = eta_p P / V_ref at the reference speed V_ref (cruise); k_m = V_ref / (1 - T_c / T_0).

Motor entries in the geometry file: ``name``, ``position_m`` (datum axes), ``thrust_axis`` (body),
``spin``, ``propeller_diameter_m`` and, for electric motors, ``static_thrust_n``,
``propeller_pitch_m``, ``full_throttle_rpm``; for piston engines ``shaft_power_w``,
``figure_of_merit``, ``propeller_efficiency``. ``time_constant_s`` and ``powerplant`` sit beside
``motors``.
"""

from __future__ import annotations

import math
from typing import Any

from ..constants import RHO0


def momentum_constants(motor: dict[str, Any], powerplant: str, reference_speed: float
                       ) -> tuple[float, float, float, str]:
    """(disk area S_p, C_p, k_m, note) for one motor entry of a geometry file."""
    disk = math.pi * (motor["propeller_diameter_m"] / 2.0) ** 2
    if powerplant == "electric":
        static = float(motor["static_thrust_n"])
        k_m = motor["propeller_pitch_m"] * motor["full_throttle_rpm"] / 60.0
        note = (f"electric: static thrust {static:.3g} N (motor/propeller data), zero thrust at the "
                f"pitch speed k_m = {k_m:.3g} m/s")
    elif powerplant == "piston":
        power = float(motor["shaft_power_w"])
        static = (2.0 * RHO0 * disk) ** (1.0 / 3.0) * (motor["figure_of_merit"] * power) ** (2.0 / 3.0)
        cruise = motor["propeller_efficiency"] * power / reference_speed
        if not cruise < static:
            raise ValueError(f"motor {motor['name']}: power-available thrust {cruise:.0f} N at "
                             f"{reference_speed} m/s exceeds the static thrust {static:.0f} N")
        k_m = reference_speed / (1.0 - cruise / static)
        note = (f"piston: {power / 1e3:.1f} kW shaft; momentum-disk static thrust {static:.0f} N "
                f"(FM {motor['figure_of_merit']}), power-available thrust {cruise:.0f} N at "
                f"{reference_speed:.2f} m/s (eta_p {motor['propeller_efficiency']})")
    else:
        raise ValueError(f"motor {motor['name']}: powerplant must be electric or piston, got {powerplant!r}")
    c_p = 2.0 * static / (RHO0 * disk * k_m**2)
    return disk, c_p, k_m, note


def full_throttle_thrust(disk: float, c_p: float, k_m: float, airspeed: float, rho: float = RHO0) -> float:
    """Thrust of one motor at full throttle (N), clamped at zero beyond k_m."""
    return max(0.0, 0.5 * rho * disk * c_p * k_m * (k_m - airspeed))
