"""The sea for the viewers: :class:`SeaField`, one aircraft's wave field (the K Airy components of
``physics.sea.SeaSurface``), evaluated with NumPy by the same sum as ``SeaSurface.elevation``::

    eta(n, e, t) = sum_k a_k cos(k_k (n cos_k + e sin_k) - w_k t + phi_k)    (m, up from the mean level)

with n north and e east (m, NED about the origin) and t the aircraft's own clock (s). A recording over
the sea (:class:`~falcon_rl.recording.Recording`, ``rec.sea``) holds these fields; :func:`recorded_sea`
reads the one an aircraft flies over at a frame and :func:`scene_sea` the one a scene of several
aircraft draws (the first aircraft over the sea). Summary numbers for captions and exports: the
significant wave height Hs = 4 sqrt(sum a^2 / 2), the peak period (of the strongest component), the
mean direction of travel and the WMO sea-state code whose Hs range holds Hs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..physics.sea import SEA_STATE_HS
from ..recording import SEA_COMPONENTS, Recording


@dataclass(frozen=True)
class SeaField:
    """K Airy components, each a [K] float64 array: amplitude a (m), wavenumber k (rad/m), frequency w
    (rad/s), direction of travel (cos, sin) from north and phase phi (rad)."""

    amplitude: np.ndarray
    wavenumber: np.ndarray
    frequency: np.ndarray
    direction_cos: np.ndarray
    direction_sin: np.ndarray
    phase: np.ndarray

    def __post_init__(self) -> None:
        arrays = [np.asarray(getattr(self, name), dtype=np.float64).reshape(-1) for name in SEA_COMPONENTS]
        if len({len(a) for a in arrays}) != 1 or len(arrays[0]) == 0:
            raise ValueError(f"a sea field needs [K] components of one length K >= 1, got "
                             f"{[len(a) for a in arrays]}")
        for name, array in zip(SEA_COMPONENTS, arrays, strict=True):
            object.__setattr__(self, name, array)

    @classmethod
    def from_components(cls, components: np.ndarray) -> SeaField:
        """From [6, K] rows in :data:`~falcon_rl.recording.SEA_COMPONENTS` order."""
        return cls(*np.asarray(components, dtype=np.float64))

    @classmethod
    def from_surface(cls, surface: Any, env: int) -> SeaField:
        """Env ``env``'s row of a ``physics.sea.SeaSurface`` ([N, K] tensors)."""
        return cls(*(getattr(surface, name)[env].detach().cpu().numpy() for name in SEA_COMPONENTS))

    @property
    def num_components(self) -> int:
        """K."""
        return int(self.amplitude.shape[0])

    def elevation(self, north: Any, east: Any, time: float, resolution: Any = None) -> np.ndarray:
        """eta (m, up) at the points ``north``, ``east`` (m, broadcast together to [...]) at ``time`` (s):
        [...]. ``resolution`` (m, broadcast like the points; None: the exact sum) is the spacing of a
        mesh sampling the field there: components shorter than two spacings are left out and those
        between two and four faded in, so that a coarse mesh does not alias the short waves."""
        north, east = np.broadcast_arrays(np.asarray(north, np.float64), np.asarray(east, np.float64))
        travel = north[..., None] * self.direction_cos + east[..., None] * self.direction_sin  # [..., K]
        argument = self.wavenumber * travel - self.frequency * float(time) + self.phase
        amplitude = np.broadcast_to(self.amplitude, argument.shape)
        if resolution is not None:
            wavelength = 2.0 * math.pi / np.maximum(self.wavenumber, 1e-12)
            spacing = np.broadcast_to(np.asarray(resolution, np.float64), north.shape)[..., None]
            amplitude = amplitude * np.clip(0.5 * wavelength / np.maximum(spacing, 1e-12) - 1.0, 0.0, 1.0)
        return (amplitude * np.cos(argument)).sum(-1)

    @property
    def variance(self) -> float:
        """m0 = sum a^2 / 2 (m^2), the elevation's variance at a point over a long record."""
        return float(0.5 * np.sum(self.amplitude**2))

    @property
    def significant_height(self) -> float:
        """Hs = 4 sqrt(m0), m."""
        return 4.0 * math.sqrt(self.variance)

    @property
    def peak_period(self) -> float:
        """2 pi / w of the strongest component (s; the spectrum's peak, the bins being equal); inf when
        calm."""
        if not np.any(self.amplitude > 0):
            return math.inf
        return 2.0 * math.pi / float(self.frequency[int(np.argmax(self.amplitude))])

    @property
    def mean_direction_deg(self) -> float:
        """The energy-weighted mean direction the waves travel toward, deg clockwise from north [0, 360)."""
        energy = self.amplitude**2
        north, east = float(energy @ self.direction_cos), float(energy @ self.direction_sin)
        return math.degrees(math.atan2(east, north)) % 360.0

    @property
    def sea_state(self) -> int:
        """The WMO sea-state code 0-6 whose significant-height range holds :attr:`significant_height`
        (6 above its range)."""
        hs = self.significant_height
        if hs <= 0.0:
            return 0
        return next((code for code, (_, high) in enumerate(SEA_STATE_HS) if code and hs <= high),
                    len(SEA_STATE_HS) - 1)

    def describe(self) -> str:
        """One line: the sea state, Hs, Tp, direction and K (no commas)."""
        period = self.peak_period
        tp = f"Tp {period:.1f} s" if math.isfinite(period) else "calm"
        return (f"WMO sea state {self.sea_state} (Hs {self.significant_height:.2f} m; {tp}; waves toward "
                f"{self.mean_direction_deg:.0f} deg; {self.num_components} components)")


def over_sea(rec: Recording, frame: int, env: int) -> bool:
    """Whether aircraft ``env`` flies over its sea in frame ``frame`` of ``rec``: the recording has a wave
    field for the frame and its ``over_water`` field (where recorded; else a non-zero amplitude) says so."""
    if not rec.has_sea or int(rec["sea_field"][frame, env]) < 0:
        return False
    if rec.has("over_water"):
        return bool(rec["over_water"][frame, env] != 0)
    return bool(np.any(rec.sea["amplitude"][int(rec["sea_field"][frame, env]), env] > 0))


def recorded_sea(rec: Recording, frame: int, env: int) -> SeaField | None:
    """The wave field aircraft ``env`` flies over in frame ``frame`` of ``rec`` (None: over the ground)."""
    if not over_sea(rec, frame, env):
        return None
    index = int(rec["sea_field"][frame, env])
    return SeaField(*(rec.sea[name][index, env] for name in SEA_COMPONENTS))


def sea_clock(rec: Recording, frame: int, env: int) -> float:
    """The clock (s) of aircraft ``env``'s wave field in frame ``frame``: its ``sim_time`` where recorded,
    else the recording's ``time``."""
    if rec.has("sim_time") and np.isfinite(rec["sim_time"][frame, env]):
        return float(rec["sim_time"][frame, env])
    return float(rec.time[frame])


def scene_sea(rec: Recording, frame: int) -> tuple[SeaField, float] | None:
    """The sea a scene of all of ``rec``'s aircraft draws in frame ``frame`` (the wave field and clock of the
    first aircraft over the sea; one scene draws one field), or None when none is over the sea."""
    for env in range(rec.num_envs):
        field = recorded_sea(rec, frame, env)
        if field is not None:
            return field, sea_clock(rec, frame, env)
    return None





def sea_mesh(field: SeaField, time: float, eye: np.ndarray, world_to_cam: np.ndarray, focal: float,
             width: int, height: int, far: float, columns: int = 64, rows: int = 48,
             margin: float = 8.0) -> np.ndarray | None:
    """The wave mesh a pinhole camera sees (a projective grid): vertices [rows + 1, columns + 1, 3] NED (m)
    of the sea ``field`` at ``time``, where the rays of a grid of pixels even on the screen (``margin``
    pixels beyond its edges, up to the horizon or the ``far`` m range) meet the mean level, lifted to the
    elevation there (short components faded out where the mesh is coarse, :meth:`SeaField.elevation`).
    The camera: ``eye`` [3] NED, ``world_to_cam`` [3, 3] rows (right, up, forward), ``focal`` pixels, the
    screen ``width`` x ``height``. None when the eye is not above the mean level or sees no water."""
    if eye[2] >= -1e-3:
        return None
    right, up, forward = world_to_cam
    above = -float(eye[2])
    v = np.linspace((-margin - 0.5 * height) / focal, (0.5 * height + margin) / focal, 512)
    down = v * up[2] + forward[2]  # the rays' NED z along the screen's centre column
    reach = np.where(down > 1e-9, above * np.sqrt(1.0 + v**2) / np.maximum(down, 1e-9), np.inf)
    visible = np.flatnonzero(reach <= far)
    if len(visible) < 2:
        return None
    u = np.linspace((-margin - 0.5 * width) / focal, (0.5 * width + margin) / focal, columns + 1)
    v = np.linspace(v[visible[0]], v[visible[-1]], rows + 1)
    rays = u[None, :, None] * right + v[:, None, None] * up + forward  # [rows + 1, columns + 1, 3]
    along = np.minimum(above / np.maximum(rays[..., 2], 1e-9), far)  # to the mean level (z = 0)
    points = eye + along[..., None] * rays
    points[..., 2] = -field.elevation(points[..., 0], points[..., 1], time, resolution=_spacing(points))
    return points


def _spacing(points: np.ndarray) -> np.ndarray:
    """[R, C] the larger distance from each point of a grid [R, C, 3] to its next neighbour along either
    axis (the last row and column take their neighbour's)."""
    rows = np.linalg.norm(np.diff(points, axis=0), axis=-1)
    columns = np.linalg.norm(np.diff(points, axis=1), axis=-1)
    return np.maximum(np.concatenate([rows, rows[-1:]], 0), np.concatenate([columns, columns[:, -1:]], 1))

__all__ = ["SeaField", "over_sea", "recorded_sea", "scene_sea", "sea_clock", "sea_mesh"]
