"""An aircraft glyph: a flat-panel mesh (wing, tails, fuselage outline) in body FRD metres, sized from
an airframe's reference geometry, for the 3D flight view (:mod:`.scene`) and the track figure
(:mod:`.track`).

The airframe files hold the wing (span ``b``, mean aerodynamic chord ``c``, taper ratio ``lam``, quarter
chord position) but no fuselage or tail. Those are drawn with the proportions of a conventional light
aircraft (about those of the Cirrus SR22, Navion and small UAVs), in multiples of ``b`` and ``c``:

* wing: trapezoid, unswept quarter-chord line through ``wing_quarter_chord``; root chord
  ``c_r = 1.5 c (1 + lam) / (1 + lam + lam^2)`` (the inverse of the mean-aerodynamic-chord formula) and
  tip chord ``lam c_r``;
* fuselage: length :data:`FUSELAGE_LENGTH` ``b``; its nose :data:`NOSE_AHEAD` of that length ahead of
  the wing quarter chord, maximum width :data:`FUSELAGE_WIDTH` of the length; drawn as a top outline
  (body x-y plane) and a side outline (x-z plane);
* tail arm (wing to tail quarter chords) :data:`TAIL_ARM` ``b``;
* horizontal tail: span :data:`HTAIL_SPAN` ``b``, root chord :data:`HTAIL_CHORD` ``c``, taper 0.6;
* vertical tail: height :data:`VTAIL_HEIGHT` ``b``, root chord :data:`VTAIL_CHORD` ``c``, tip chord
  0.55 of the root, its quarter-chord line swept back 30 degrees.

``scale`` enlarges the whole glyph about the CG (1 = true size). A 1.6 m UAV seen on a track of
hundreds of metres is a few pixels wide; a ``scale`` of 10 to 50 keeps its attitude readable. Only the
drawing is scaled, never the positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..airframe import Airframe, load_airframe

#: Fuselage length, in wing spans.
FUSELAGE_LENGTH = 0.72
#: Share of the fuselage length ahead of the wing quarter chord.
NOSE_AHEAD = 0.3
#: Largest fuselage width (and depth), in fuselage lengths.
FUSELAGE_WIDTH = 0.11
#: Tail arm, wing to tail quarter chords, in wing spans.
TAIL_ARM = 0.38
#: Horizontal tail span, in wing spans.
HTAIL_SPAN = 0.33
#: Horizontal tail root chord, in wing mean chords.
HTAIL_CHORD = 0.8
#: Vertical tail height, in wing spans.
VTAIL_HEIGHT = 0.12
#: Vertical tail root chord, in wing mean chords.
VTAIL_CHORD = 1.1

#: Face colour (RGB in [0, 1]) of each part.
ROLE_COLORS: dict[str, tuple[float, float, float]] = {
    "wing": (0.93, 0.93, 0.90),
    "horizontal_tail": (0.85, 0.86, 0.88),
    "vertical_tail": (0.85, 0.20, 0.15),
    "fuselage_top": (0.30, 0.38, 0.55),
    "fuselage_side": (0.25, 0.32, 0.48),
}


@dataclass(frozen=True)
class Glyph:
    """Flat polygons of an aircraft in body FRD metres relative to the CG.

    ``polygons[i]`` is [K_i, 3] (m), ``roles[i]`` names the part (a key of :data:`ROLE_COLORS`) and
    ``colors[i]`` is its RGB face colour in [0, 1]."""

    polygons: tuple[np.ndarray, ...]
    roles: tuple[str, ...]
    colors: tuple[tuple[float, float, float], ...]
    span: float  # m, drawn wing span (airframe span x scale)
    length: float  # m, drawn fuselage length

    @property
    def extent(self) -> float:
        """m, the largest distance of a vertex from the CG (the glyph's bounding radius)."""
        return float(max(np.linalg.norm(p, axis=1).max() for p in self.polygons))

    def vertices(self) -> np.ndarray:
        """All vertices stacked, [sum K_i, 3] m body FRD."""
        return np.concatenate(self.polygons, axis=0)


def _trapezoid(x_qc: float, y0: float, y1: float, c0: float, c1: float, z: float,
               sweep_qc: float = 0.0) -> np.ndarray:
    """A panel in the body x-y plane from span station y0 (chord c0) to y1 (chord c1); its quarter-chord
    line passes x_qc at y0 and moves aft by ``tan(sweep_qc) |y1 - y0|``. [4, 3] m."""
    x1 = x_qc - math.tan(sweep_qc) * abs(y1 - y0)
    return np.array([[x_qc + c0 / 4, y0, z], [x1 + c1 / 4, y1, z],
                     [x1 - 3 * c1 / 4, y1, z], [x_qc - 3 * c0 / 4, y0, z]])


def aircraft_glyph(airframe: Airframe | str | Path, scale: float = 1.0) -> Glyph:
    """The glyph of ``airframe`` (an :class:`Airframe` or a name/path ``load_airframe`` accepts), drawn
    ``scale`` times its true size (> 0; see the module docstring). Polygons in body FRD metres."""
    if not isinstance(airframe, Airframe):
        airframe = load_airframe(airframe)
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number, got {scale!r}")
    g = airframe.geometry
    b, c, lam = g.span, g.mean_chord, g.taper_ratio
    c_root = 1.5 * c * (1 + lam) / (1 + lam + lam * lam)
    c_tip = lam * c_root
    xw, _, zw = g.wing_quarter_chord
    length = FUSELAGE_LENGTH * b
    width = FUSELAGE_WIDTH * length
    x_nose = xw + NOSE_AHEAD * length
    x_tail = x_nose - length
    x_tail_qc = xw - TAIL_ARM * b
    z_tail = zw - 0.25 * width  # tail plane a little above the wing plane

    polygons: list[np.ndarray] = []
    roles: list[str] = []

    def add(poly: np.ndarray, role: str) -> None:
        polygons.append(poly)
        roles.append(role)

    # Fuselage: a top outline (x-y) and a side outline (x-z), tapering to the nose and the tail.
    stations = np.array([0.0, 0.06, 0.18, 0.35, 0.55, 0.8, 1.0])  # from the nose, in lengths
    half = 0.5 * width * np.array([0.25, 0.75, 1.0, 1.0, 0.7, 0.35, 0.15])
    xs = x_nose - stations * length
    top = np.concatenate([np.stack([xs, half, np.full_like(xs, zw)], 1),
                          np.stack([xs[::-1], -half[::-1], np.full_like(xs, zw)], 1)])
    side = np.concatenate([np.stack([xs, np.zeros_like(xs), zw - half * 1.1], 1),
                           np.stack([xs[::-1], np.zeros_like(xs), zw + half[::-1] * 0.9], 1)])
    add(side, "fuselage_side")
    # Wing: two panels (left, right), so that a banked wing shades each half.
    add(_trapezoid(xw, 0.0, b / 2, c_root, c_tip, zw), "wing")
    add(_trapezoid(xw, 0.0, -b / 2, c_root, c_tip, zw), "wing")
    add(top, "fuselage_top")
    # Horizontal tail.
    ht_root = HTAIL_CHORD * c
    ht_half = HTAIL_SPAN * b / 2
    for tip in (ht_half, -ht_half):
        add(_trapezoid(x_tail_qc, 0.0, tip, ht_root, 0.6 * ht_root, z_tail, math.radians(5)),
            "horizontal_tail")
    # Vertical tail in the x-z plane, up is -z.
    vt_root, vt_tip = VTAIL_CHORD * c, 0.55 * VTAIL_CHORD * c
    height = VTAIL_HEIGHT * b
    x_top = x_tail_qc - math.tan(math.radians(30)) * height
    vt = np.array([[x_tail_qc + vt_root / 4, 0.0, z_tail], [x_top + vt_tip / 4, 0.0, z_tail - height],
                   [x_top - 3 * vt_tip / 4, 0.0, z_tail - height],
                   [min(x_tail_qc - 3 * vt_root / 4, x_tail), 0.0, z_tail]])
    add(vt, "vertical_tail")

    scaled = tuple(np.ascontiguousarray(p * scale, dtype=np.float64) for p in polygons)
    return Glyph(polygons=scaled, roles=tuple(roles), colors=tuple(ROLE_COLORS[r] for r in roles),
                 span=b * scale, length=length * scale)
