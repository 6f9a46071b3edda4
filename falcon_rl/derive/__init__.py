"""Derive airframe JSON files from geometry sources with AeroSandbox (optional dependency).

Pipeline: :mod:`.geometry` (load the source) -> :mod:`.aerobuildup` (AeroSandbox model in falcon-rl
conventions) -> :mod:`.sweep` (fixed grid) -> :mod:`.fit` (monomial tables, orders on held-out
points) -> :mod:`.propulsion` (momentum constants) -> :mod:`.envelope` (trimmed envelope) ->
:mod:`.build` (document + provenance) -> :mod:`.writer` / :mod:`.plots`.

Importing this package does not import AeroSandbox; only running a sweep does.
"""

from .geometry import GeometryError, load_geometry

__all__ = ["GeometryError", "load_geometry"]
