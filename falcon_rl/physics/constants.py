"""Physical constants and unit conversions (SI): the package-level :mod:`falcon_rl.constants`.

They live at the package root so that ``airframe`` (imported by ``physics``) can use them without
importing the flight model; this module is the name the physics code imports them by.
"""

from __future__ import annotations

from ..constants import DEG, FT, G0, GAMMA, IN, KT, LAPSE, LBF, LBM, P0, R_AIR, RHO0, SLUG, SLUG_FT2, T0

__all__ = ["DEG", "FT", "G0", "GAMMA", "IN", "KT", "LAPSE", "LBF", "LBM", "P0", "RHO0", "R_AIR", "SLUG",
           "SLUG_FT2", "T0"]
