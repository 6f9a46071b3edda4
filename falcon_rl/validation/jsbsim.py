"""JSBSim cross-validation: the public entry points.

    from falcon_rl.validation.jsbsim import export_aircraft, validate_jsbsim
    path = export_aircraft(load_airframe("navion"), "out")        # out/aircraft/navion/navion.xml
    results = validate_jsbsim(load_airframe("navion"), "out")     # one CaseResult per case

See ``jsbsim_export`` (the aircraft model), ``jsbsim_fly`` (running both simulators: planet,
atmosphere, timing), ``jsbsim_compare`` (cases and metrics) and ``jsbsim_report`` (tables, PNGs).
"""

from __future__ import annotations

from .jsbsim_compare import EXCITATIONS, GE_SETTINGS, HEADLINE, Case, CaseResult, Doublet, validate_jsbsim
from .jsbsim_export import export_aircraft
from .jsbsim_fly import CHANNELS, EARTH_RADIUS, PLANET_RADIUS, Trajectory, fly_falcon, fly_jsbsim
from .jsbsim_report import format_table, plot_overlays

__all__ = [
    "CHANNELS", "EARTH_RADIUS", "EXCITATIONS", "GE_SETTINGS", "HEADLINE", "PLANET_RADIUS", "Case",
    "CaseResult", "Doublet", "Trajectory", "export_aircraft", "fly_falcon", "fly_jsbsim", "format_table",
    "plot_overlays", "validate_jsbsim",
]
