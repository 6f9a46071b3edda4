"""Physical constants and unit conversions, SI, defined once for the whole package.

This module imports nothing, so that every layer can use it: ``airframe`` (below ``physics``),
``physics`` (``physics.constants`` is this module), the tasks, the baselines, ``derive`` and
``validation``. Values marked "ISA" are those of the US Standard Atmosphere 1976 at sea level.
"""

from __future__ import annotations

import math

# ---------------------------------------------------------------------------------- gravity, air
#: Standard gravity, m/s^2.
G0 = 9.80665
#: ISA sea-level temperature, K.
T0 = 288.15
#: ISA sea-level pressure, Pa.
P0 = 101_325.0
#: ISA sea-level density, kg/m^3 (the standard's rounded value; P0 / (R_AIR T0) = 1.2249992).
RHO0 = 1.225
#: Specific gas constant of dry air, J/(kg K): R* / M0 as in the 1976 standard (287.0531).
R_AIR = 8.31432 / 0.0289644
#: ISA tropospheric temperature lapse rate, K/m.
LAPSE = -0.0065
#: Ratio of specific heats of air.
GAMMA = 1.4

# ---------------------------------------------------------------------------------- unit conversions
#: Radians per degree.
DEG = math.pi / 180.0
#: Metres per foot.
FT = 0.3048
#: Metres per inch.
IN = 0.0254
#: Metres per second per knot.
KT = 1852.0 / 3600.0
#: Kilograms per pound-mass (JSBSim weights in lbs are pounds-mass at standard gravity).
LBM = 0.45359237
#: Kilograms per slug (= LBM G0 / FT, kept to the last digit JSBSim's tables were checked with).
SLUG = 14.593902937206364
#: kg m^2 per slug ft^2.
SLUG_FT2 = SLUG * FT**2
#: Newtons per pound-force (1 slug ft/s^2).
LBF = SLUG * FT

__all__ = ["DEG", "FT", "G0", "GAMMA", "IN", "KT", "LAPSE", "LBF", "LBM", "P0", "RHO0", "R_AIR", "SLUG",
           "SLUG_FT2", "T0"]
