"""Geometry source files (``airframes/geometry/<name>.json``): load and check them.

A geometry file describes the airframe the way a three-view and a data sheet do; ``derive`` turns it
into an airframe JSON (schema v1). Axes are AeroSandbox *geometry* axes: x aft, y toward the right
wing tip, z up, origin at an arbitrary datum (the nose). Lengths in m, angles in degrees.

Top-level fields (all required unless marked optional):

- ``name``, ``display_name``, ``description``
- ``reference``: ``cg_m`` [3] (datum axes), ``airspeed_mps`` (analysis speed and Reynolds number),
  ``altitude_m``, ``cruise_speed_mps``, optional ``tail_dynamic_pressure_ratio`` (default 0.9)
- ``wings[]``: ``name``, ``role`` (``main`` | ``horizontal_tail`` | ``vertical_tail``),
  ``symmetric``, ``panels`` (spanwise strips per side), ``sections[]`` (``xyz_le_m``, ``chord_m``,
  ``twist_deg``, ``airfoil`` NACA name), ``control_surfaces[]`` (``kind`` elevator | aileron |
  rudder, ``span_fraction`` [start, end] of the wing's span, ``hinge_chord_fraction``)
- ``fuselages[]``: ``name``, ``stations[]`` (``x_m``, ``z_m``, ``width_m``, ``height_m``)
- ``mass``: ``mass_kg`` and the inertia ``ixx_kg_m2`` ... or ``radii_of_gyration``
  (``rx``, ``ry``, ``rz`` as fractions of span, length, mean of both: Roskam's non-dimensional radii)
  with ``length_m``
- ``propulsion``: see :mod:`falcon_rl.derive.propulsion`
- ``actuators``: ``elevator_deg``, ``aileron_deg``, ``rudder_deg`` (deflection limits)
- ``envelope``: ``max_bank_deg`` (structural/operational cap), ``climb_rate_limit_mps`` (cap)
- ``provenance``: ``sources`` [str], ``notes`` {field: where the number came from}
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..airframe import read_json_strictly

ROLES = ("main", "horizontal_tail", "vertical_tail")
SURFACE_KINDS = ("elevator", "aileron", "rudder")


class GeometryError(ValueError):
    """A geometry source file is malformed; the message names the file and the field."""


@dataclass(frozen=True)
class Section:
    xyz_le: tuple[float, float, float]
    chord: float
    twist_deg: float
    airfoil: str


@dataclass(frozen=True)
class ControlSurface:
    kind: str
    span_fraction: tuple[float, float]
    hinge_chord_fraction: float


@dataclass(frozen=True)
class Wing:
    name: str
    role: str
    symmetric: bool
    panels: int
    sections: tuple[Section, ...]
    control_surfaces: tuple[ControlSurface, ...]

    @property
    def span(self) -> float:
        """Tip-to-tip span (projected on y for horizontal surfaces, height for vertical ones)."""
        axis = 2 if self.role == "vertical_tail" else 1
        tip = abs(self.sections[-1].xyz_le[axis])
        return 2.0 * tip if self.symmetric else abs(tip - abs(self.sections[0].xyz_le[axis]))

    @property
    def area(self) -> float:
        """Planform area from the trapezoids between sections (both sides if symmetric)."""
        axis = 2 if self.role == "vertical_tail" else 1
        half = sum(abs(b.xyz_le[axis] - a.xyz_le[axis]) * 0.5 * (a.chord + b.chord)
                   for a, b in zip(self.sections[:-1], self.sections[1:], strict=True))
        return (2.0 if self.symmetric else 1.0) * half


@dataclass(frozen=True)
class FuselageStation:
    x: float
    z: float
    width: float
    height: float


@dataclass(frozen=True)
class Fuselage:
    name: str
    stations: tuple[FuselageStation, ...]


@dataclass(frozen=True)
class GeometrySpec:
    """A parsed geometry source; ``raw`` keeps the document for the sections used as-is."""

    path: Path
    name: str
    display_name: str
    description: str
    cg: tuple[float, float, float]
    airspeed: float
    altitude: float
    cruise_speed: float
    tail_q_ratio: float
    wings: tuple[Wing, ...]
    fuselages: tuple[Fuselage, ...]
    raw: dict[str, Any]

    @property
    def main_wing(self) -> Wing:
        return next(w for w in self.wings if w.role == "main")


def _need(doc: dict, key: str, where: str, path: Path) -> Any:
    if key not in doc:
        raise GeometryError(f"{path}: field '{where}{key}': missing required field")
    return doc[key]


def _vec3(value: Any, where: str, path: Path) -> tuple[float, float, float]:
    if not (isinstance(value, list) and len(value) == 3 and all(isinstance(v, int | float) for v in value)):
        raise GeometryError(f"{path}: field '{where}': expected a list of 3 numbers")
    return float(value[0]), float(value[1]), float(value[2])


def _wing(doc: dict, i: int, path: Path) -> Wing:
    where = f"wings[{i}]."
    role = _need(doc, "role", where, path)
    if role not in ROLES:
        raise GeometryError(f"{path}: field '{where}role': must be one of {list(ROLES)}, got {role!r}")
    sections = tuple(
        Section(_vec3(_need(s, "xyz_le_m", f"{where}sections[{j}].", path), f"{where}sections[{j}]", path),
                float(_need(s, "chord_m", f"{where}sections[{j}].", path)),
                float(s.get("twist_deg", 0.0)), str(_need(s, "airfoil", f"{where}sections[{j}].", path)))
        for j, s in enumerate(_need(doc, "sections", where, path)))
    if len(sections) < 2:
        raise GeometryError(f"{path}: field '{where}sections': needs at least 2 sections")
    surfaces = []
    for j, c in enumerate(doc.get("control_surfaces", [])):
        kind = _need(c, "kind", f"{where}control_surfaces[{j}].", path)
        lo, hi = _need(c, "span_fraction", f"{where}control_surfaces[{j}].", path)
        if kind not in SURFACE_KINDS or not 0.0 <= lo < hi <= 1.0:
            raise GeometryError(f"{path}: field '{where}control_surfaces[{j}]': kind in "
                                f"{list(SURFACE_KINDS)} and 0 <= start < end <= 1 required")
        hinge = float(_need(c, "hinge_chord_fraction", f"{where}control_surfaces[{j}].", path))
        surfaces.append(ControlSurface(kind, (float(lo), float(hi)), hinge))
    return Wing(str(_need(doc, "name", where, path)), role, bool(_need(doc, "symmetric", where, path)),
                int(doc.get("panels", 6)), sections, tuple(surfaces))


def _fuselage(doc: dict, i: int, path: Path) -> Fuselage:
    where = f"fuselages[{i}]."
    stations = tuple(FuselageStation(float(s["x_m"]), float(s.get("z_m", 0.0)), float(s["width_m"]),
                                     float(s["height_m"]))
                     for s in _need(doc, "stations", where, path))
    return Fuselage(str(_need(doc, "name", where, path)), stations)


def load_geometry(path: str | Path) -> GeometrySpec:
    """Parse a geometry source file; raises :class:`GeometryError` naming file and field."""
    path = Path(path)
    if not path.is_file():
        raise GeometryError(f"{path}: geometry file not found")
    doc = read_json_strictly(path, GeometryError, "geometry")  # strict UTF-8 JSON: no duplicates, NaN
    if not isinstance(doc, dict):
        raise GeometryError(f"{path}: a geometry file is one JSON object, got {type(doc).__name__}")
    for key in ("name", "reference", "wings", "mass", "propulsion", "actuators", "envelope", "provenance"):
        _need(doc, key, "", path)
    ref = doc["reference"]
    wings = tuple(_wing(w, i, path) for i, w in enumerate(doc["wings"]))
    if sum(w.role == "main" for w in wings) != 1:
        raise GeometryError(f"{path}: field 'wings': exactly one wing needs role 'main'")
    kinds = {c.kind for w in wings for c in w.control_surfaces}
    if kinds != set(SURFACE_KINDS):
        raise GeometryError(f"{path}: field 'wings': needs elevator, aileron and rudder surfaces, has "
                            f"{sorted(kinds)}")
    return GeometrySpec(
        path=path, name=str(doc["name"]), display_name=str(doc.get("display_name", doc["name"])),
        description=str(doc.get("description", "")),
        cg=_vec3(_need(ref, "cg_m", "reference.", path), "reference.cg_m", path),
        airspeed=float(_need(ref, "airspeed_mps", "reference.", path)),
        altitude=float(ref.get("altitude_m", 0.0)),
        cruise_speed=float(_need(ref, "cruise_speed_mps", "reference.", path)),
        tail_q_ratio=float(ref.get("tail_dynamic_pressure_ratio", 0.9)),
        wings=wings, fuselages=tuple(_fuselage(f, i, path) for i, f in enumerate(doc.get("fuselages", []))),
        raw=doc,
    )
