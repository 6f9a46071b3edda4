"""Regenerate navion_nelson.json: Nelson's published Navion derivatives, as a reference set.

The shipped ``navion.json`` is derived from geometry (``falcon-rl airframe derive``); this file keeps
the textbook derivative set beside it for validation against Nelson's worked examples (modes, trim).
Run: python airframes/sources/make_nelson_navion.py  (writes ../navion_nelson.json). Every number
below names its source or the estimate behind it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

OUT = Path(__file__).resolve().parent.parent
DEG = math.pi / 180.0
FT = 0.3048
SLUGFT2 = 1.3558179483314  # kg m^2
RHO0 = 1.225


def polar_terms(cl0: float, cla: float, cd_parasite: float, k: float) -> list[dict]:
    """C_D = C_Dp + k (C_L0 + C_La alpha)^2 expanded into monomials in alpha."""
    return [
        {"coef": round(cd_parasite + k * cl0**2, 6)},
        {"coef": round(2 * k * cl0 * cla, 6), "alpha": 1},
        {"coef": round(k * cla**2, 6), "alpha": 2},
    ]


def momentum_constants(static_thrust: float, speed: float, thrust_at_speed: float,
                       disk_area: float) -> tuple[float, float]:
    """k_m, C_p of T = 1/2 rho S_p C_p k_m (k_m - V) at full throttle from two thrust points."""
    k_m = speed / (1.0 - thrust_at_speed / static_thrust)
    c_p = 2.0 * static_thrust / (RHO0 * disk_area * k_m**2)
    return k_m, c_p


def surface(limit_deg: float) -> dict:
    # Paper, "Actuators": servo-driven surfaces are second order, omega_n = 10 rad/s, zeta = 1/sqrt2.
    return {"order": 2, "natural_frequency_rad_s": 10.0, "damping_ratio": round(1 / math.sqrt(2), 6),
            "limits_rad": [round(-limit_deg * DEG, 6), round(limit_deg * DEG, 6)]}


def navion() -> dict:
    span, area, chord = 33.4 * FT, 184 * FT**2, 5.7 * FT
    cl0, cla = 0.41, 4.44
    # Nelson lists C_Da = 0.33 at C_L0: with C_D = C_Dp + k C_L^2, k = C_Da / (2 C_L0 C_La).
    k = 0.33 / (2 * cl0 * cla)
    cdp = 0.05 - k * cl0**2
    oswald = 1.0 / (math.pi * (span**2 / area) * k)
    # Piston engine: 205 hp (Continental E-185/IO-470 class), 2.13 m propeller. Static thrust from
    # the momentum disk with figure of merit 0.75; cruise thrust from power available with
    # propeller efficiency 0.80 at 53.64 m/s.
    power = 205 * 745.7
    disk = math.pi * (2.13 / 2) ** 2
    static = (2 * RHO0 * disk) ** (1 / 3) * (0.75 * power) ** (2 / 3)
    k_m, c_p = momentum_constants(static, 53.64, 0.80 * power / 53.64, disk)
    return {
        "schema_version": 1,
        "name": "navion_nelson",
        "display_name": "North American Navion (Nelson's derivatives)",
        "description": "Four-seat piston single; Nelson's textbook stability-derivative set (reference for "
                       "the geometry-derived navion).",
        "geometry": {
            "wing_area_m2": round(area, 4), "span_m": round(span, 4), "mean_chord_m": round(chord, 4),
            "aspect_ratio": round(span**2 / area, 4), "taper_ratio": 0.54,
            "wing_quarter_chord_m": [0.0, 0.0, 0.3],
        },
        "mass": {"mass_kg": round(2750 * 0.45359237, 2),
                 "ixx_kg_m2": round(1048 * SLUGFT2, 1), "iyy_kg_m2": round(3000 * SLUGFT2, 1),
                 "izz_kg_m2": round(3530 * SLUGFT2, 1), "ixz_kg_m2": 0.0},
        "aero": {
            "oswald_efficiency": round(oswald, 4),
            "alpha_range_rad": [round(-10 * DEG, 5), round(20 * DEG, 5)],
            "beta_range_rad": [round(-20 * DEG, 5), round(20 * DEG, 5)],
            "alpha_stall_rad": round(15 * DEG, 5),
            "coefficients": {
                "CL": {"terms": [{"coef": cl0}, {"coef": cla, "alpha": 1},
                                 {"coef": 0.355, "elevator": 1}], "rates": {"q": 3.8}},
                "CD": {"terms": polar_terms(cl0, cla, cdp, k)},
                "CY": {"terms": [{"coef": -0.564, "beta": 1}, {"coef": 0.157, "rudder": 1}]},
                "Cl": {"terms": [{"coef": -0.074, "beta": 1}, {"coef": 0.134, "aileron": 1},
                                 {"coef": 0.107, "rudder": 1}],
                       "rates": {"p": -0.41, "r": 0.107}},
                "Cm": {"terms": [{"coef": -0.683, "alpha": 1}, {"coef": -0.923, "elevator": 1}],
                       "rates": {"q": -9.96 - 4.36}},
                "Cn": {"terms": [{"coef": 0.071, "beta": 1}, {"coef": 0.0035, "aileron": 1},
                                 {"coef": -0.072, "rudder": 1}],
                       "rates": {"p": -0.0575, "r": -0.125}},
            },
        },
        "propulsion": {"motors": [{
            "name": "engine", "position_m": [1.8, 0.0, 0.0], "thrust_axis": [1.0, 0.0, 0.0],
            "spin": 1, "disk_area_m2": round(disk, 4), "thrust_coefficient": round(c_p, 5),
            "discharge_speed_mps": round(k_m, 3), "torque_coefficient": 0.0,
            "torque_speed_constant_rad_s": 0.0, "time_constant_s": 3.0, "powerplant": "piston"}]},
        "actuators": {"elevator": surface(20), "aileron": surface(15), "rudder": surface(15)},
        "envelope": {"stall_speed_mps": 27.5, "cruise_speed_mps": 53.64, "max_speed_mps": 62.0,
                     "max_bank_rad": round(60 * DEG, 5), "climb_rate_limit_mps": 3.8},
        "provenance": {
            "method": "published stability derivatives, converted to falcon-rl sign conventions",
            "sources": [
                "Nelson, Flight Stability and Automatic Control, 2nd ed., App. B (data from Teper 1969)",
                "Navion POH (stall 53 kt clean, Vne 144 kt, climb 750 ft/min)",
            ],
            "notes": {
                "reference_condition": "sea level, u0 = 176 ft/s = 53.64 m/s, alpha measured from the "
                                       "reference body axis, so C_L0 = W/(qS) = 0.41 and C_m0 = 0",
                "Cm.rates.q": "C_mq + C_m_alphadot = -9.96 - 4.36 (alpha_dot ~ q in the short period);"
                              " the model has no alpha_dot state",
                "CD": "parabolic polar C_Dp + k C_L^2 with k from Nelson's C_Da = 0.33 at C_L0",
                "Cl.aileron": "Nelson's C_lda = -0.134 and C_nda = -0.0035 use the opposite aileron sign;"
                              " both flipped so that positive aileron rolls right",
                "taper_ratio": "estimate from the planform (root 7.2 ft, tip 3.9 ft)",
                "wing_quarter_chord_m": "low wing: quarter chord about 0.3 m below the CG (estimate)",
                "propulsion": f"static thrust {static:.0f} N (momentum disk, FM 0.75), "
                              f"{0.8 * power / 53.64:.0f} N at 53.64 m/s (eta 0.8, 205 hp)",
                "time_constant_s": "piston powerplant class: 3 s throttle lag (paper)",
                "actuators": "surfaces: paper defaults (2nd order, 10 rad/s, 0.707; +-20/15/15 deg)",
                "envelope": "stall 27.5 m/s = POH 53 kt (C_L,max 1.57 at 15 deg); max 62 m/s is the "
                            "model's top level speed at full throttle (Nelson's C_D0 = 0.05 is high)",
            },
        },
    }


def main() -> None:
    for doc in (navion(),):
        path = OUT / f"{doc['name']}.json"
        path.write_text(json.dumps(doc, indent=2) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
