"""The sea in a Tacview export (:func:`falcon_rl.viz.acmi.write_acmi`) of a recording over the sea.

Tacview draws no waves, so the export writes what it can show and keeps what it cannot:

- the global ``Comments`` name the sea (WMO sea state, Hs, Tp, direction of travel:
  :meth:`~.sea.SeaField.describe`) and the formula of the elevation;
- each aircraft's ``AGL`` is its clearance above the water (``surface_clearance``) rather than its
  height above the mean level;
- under each aircraft over its sea, a marker object (``Type=Sea+Sensor``, a buoy; id
  ``FIRST_SEA_ID + e``, ``Parent`` the aircraft) rides the water surface under the aircraft's CG (its
  altitude is the mean level plus the elevation there), with the static properties ``SeaState``,
  ``WaveHeight`` (Hs, m) and ``WaveField``, the field's K components as text (:func:`wave_field_text`;
  Tacview keeps unknown properties in its raw telemetry), and ``WaveClock`` (s, the aircraft's own clock,
  the field's t, where it differs from the frame time). It is removed while the aircraft flies over the
  ground and written anew when its field changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..recording import SEA_COMPONENTS, Recording
from .geodesy import ReferencePoint, ned_to_geodetic
from .sea import SeaField, over_sea, recorded_sea, sea_clock

#: The id of the sea marker under aircraft ``e`` is ``FIRST_SEA_ID + e`` (written in hex).
FIRST_SEA_ID = 0x100101
#: Object type of the sea markers (a buoy: Tacview's "sonobuoy" tags).
SEA_MARKER_TYPE = "Sea+Sensor"


def wave_field_text(field: SeaField) -> str:
    """``field``'s components as one text property value: ``a|k|w|cos|sin|phi`` per component (m, rad/m,
    rad/s, -, -, rad; 9 significant digits, exact for float32), components separated by ``;``."""
    rows = np.stack([getattr(field, name) for name in SEA_COMPONENTS], axis=1)  # [K, 6]
    return ";".join("|".join(f"{value:.9g}" for value in row) for row in rows)


def parse_wave_field(text: str) -> SeaField:
    """The :class:`SeaField` of a ``WaveField`` value (:func:`wave_field_text`); ValueError when malformed."""
    rows = [component.split("|") for component in text.split(";")]
    if not rows or any(len(row) != len(SEA_COMPONENTS) for row in rows):
        raise ValueError(f"a WaveField needs {len(SEA_COMPONENTS)} values per component, got {text[:60]!r}")
    return SeaField.from_components(np.array(rows, dtype=np.float64).T)


def sea_comments(rec: Recording) -> str | None:
    """The global comment naming the sea of ``rec`` (each distinct description once), None without a sea."""
    seen: dict[str, None] = {}
    for env in range(rec.num_envs if rec.has_sea else 0):
        changes = np.flatnonzero(np.diff(rec["sea_field"][:, env], prepend=-2) != 0)
        over = [k for k in range(rec.num_frames) if over_sea(rec, k, env)]
        for frame in sorted(set(changes.tolist()) | set(over[:1])):
            field = recorded_sea(rec, int(frame), env)
            if field is not None:
                seen[field.describe()] = None
    if not seen:
        return None
    return ("Flight over the sea: " + " / ".join(seen) + ". eta(n e t) = sum a cos(k (n cos + e sin) - w t + "
            "phi); the WaveField property of the marker under each aircraft lists its components "
            "(a|k|w|cos|sin|phi).")


@dataclass
class SeaTrack:
    """The marker under aircraft ``env``: ``field`` [T] the index of the wave field it is over (-1: over the
    ground), ``fields`` {index: :class:`SeaField`}, its ``lat``, ``lon`` (deg) and ``alt`` (m) [T], and
    ``clock`` [T] s (the field's time) or None when it is the frame time."""

    env: int
    field: np.ndarray
    fields: dict[int, SeaField]
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    clock: np.ndarray | None


def sea_tracks(rec: Recording, reference: ReferencePoint, frame_time: np.ndarray) -> list[SeaTrack]:
    """The markers of the aircraft of ``rec`` that fly over their sea in some frame (none without a sea),
    in a file whose frames are at ``frame_time`` [T] s. The water's elevation under the CG is the recorded
    ``surface_elevation`` where recorded, else the field's at the aircraft's clock."""
    tracks: list[SeaTrack] = []
    if not rec.has_sea:
        return tracks
    ned = np.asarray(rec["position_ned"], dtype=np.float64)
    for env in range(rec.num_envs):
        over = np.array([over_sea(rec, k, env) for k in range(rec.num_frames)])
        if not over.any():
            continue
        index = np.where(over, rec["sea_field"][:, env], -1).astype(np.int64)
        fields: dict[int, SeaField] = {}
        for i in np.unique(index[over]).tolist():
            field = recorded_sea(rec, int(np.argmax(index == i)), env)
            assert field is not None  # the frame is over the sea
            fields[i] = field
        clock = np.array([sea_clock(rec, k, env) for k in range(rec.num_frames)])
        if rec.has("surface_elevation") and np.all(np.isfinite(rec["surface_elevation"][over, env])):
            eta = np.asarray(rec["surface_elevation"][:, env], dtype=np.float64)
        else:
            north, east = ned[:, env, 0], ned[:, env, 1]
            eta = np.array([0.0 if i < 0 else fields[int(i)].elevation(north[k], east[k], clock[k])
                            for k, i in enumerate(index)])
        water = np.stack([ned[:, env, 0], ned[:, env, 1], -np.where(over, eta, 0.0)], axis=-1)
        lat, lon, alt = ned_to_geodetic(reference, water)
        same = np.allclose(clock, frame_time, rtol=0.0, atol=1e-6)
        tracks.append(SeaTrack(env, index, fields, lat, lon, alt, None if same else clock))
    return tracks


__all__ = ["FIRST_SEA_ID", "SEA_MARKER_TYPE", "SeaTrack", "parse_wave_field", "sea_comments",
           "sea_tracks", "wave_field_text"]
