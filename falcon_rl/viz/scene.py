"""A cheap 3D flight view: one RGB frame of one or more aircraft over a ground grid or the sea.

:class:`FrameRenderer` projects everything itself (a pinhole camera) and draws flat 2D collections on one
Agg canvas that it keeps and reuses, so a 480x360 frame costs a few milliseconds of NumPy and one Agg
draw (mplot3d is an order of magnitude slower; the sea's wave mesh adds ~15 ms at 480x360). It holds no
global state (no pyplot figure manager), so several renderers may live side by side, e.g. one per
Gymnasium env.

Scene: a ground plane (height 0, a grid of "nice" spacing) under a sky, or over the sea (``sea``, a
:class:`~.sea.SeaField`) the sea: the mean level to the horizon under an animated wave mesh, the
elevation of the field at the frame's time on a grid of rays even on the screen (:func:`.sea.sea_mesh`),
flat-shaded by slope, crests lighter and troughs darker; each aircraft as a glyph
(:mod:`.glyph`) rotated by its attitude quaternion (body FRD to NED) and drawn back to front (painter's
algorithm), flat-shaded by the angle of each panel to a light from above; its shadow on the ground (on
the waves over the sea) and a drop line; optional trails coloured by bank angle on a diverging colormap
over +-:data:`BANK_RANGE_DEG` (blue: left bank, red: right bank); a HUD line per aircraft (time, height,
bank), and the sea state over the sea.

Camera: looking at the centre of the aircraft's bounding box from ``camera_elevation_deg`` above the
horizontal, from behind the mean heading of the aircraft (a chase view; or from a fixed azimuth), at the
distance where the sphere around all aircraft and their glyphs fills the view. It depends on the
current frame only, so a frame is a pure function of the inputs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import torch
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from ..airframe import Airframe, load_airframe
from ..physics.rotations import rotation_matrix
from .glyph import Glyph, aircraft_glyph
from .sea import SeaField, sea_mesh

#: Trails are coloured by bank angle over +-BANK_RANGE_DEG degrees.
BANK_RANGE_DEG = 50.0
#: Diverging colormap of the bank angle (blue left, red right).
BANK_CMAP = "coolwarm"
_SKY = (0.80, 0.88, 0.96)
_GROUND = (0.78, 0.83, 0.72)
_GRID = (0.55, 0.62, 0.50)
_SEA_TROUGH = np.array([0.05, 0.22, 0.38])
_SEA_CREST = np.array([0.42, 0.64, 0.76])
#: Pixels across a cell of the wave mesh (at the bottom of the screen; rows are even on the screen).
_SEA_CELL_PX = 10
_LIGHT = np.array([0.35, 0.25, -1.0]) / np.linalg.norm([0.35, 0.25, -1.0])  # NED, towards the light
_MAX_HUD_LINES = 4
#: Colour levels of a trail over +-BANK_RANGE_DEG (about 3 degrees a level).
_TRAIL_LEVELS = 33


def bank_colors(bank_rad: np.ndarray) -> np.ndarray:
    """RGBA colours [N, 4] of bank angles [N] rad on :data:`BANK_CMAP` over +-:data:`BANK_RANGE_DEG`."""
    norm = Normalize(-BANK_RANGE_DEG, BANK_RANGE_DEG, clip=True)
    return matplotlib.colormaps[BANK_CMAP](norm(np.degrees(np.asarray(bank_rad, dtype=np.float64))))


def _numpy(value: Any, name: str, last: int) -> np.ndarray:
    """``value`` (array or tensor) as a float64 [E, last] array; [last] is read as E = 1."""
    if isinstance(value, torch.Tensor):
        value = value.detach().cpu().numpy()
    array = np.asarray(value, dtype=np.float64)
    if array.ndim == 1:
        array = array[None]
    if array.ndim != 2 or array.shape[1] != last or array.shape[0] == 0:
        raise ValueError(f"{name} must be [E, {last}], got shape {tuple(np.shape(value))}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} holds NaN or infinite values")
    return array


def _nice_step(length: float) -> float:
    """The 1-2-5 number nearest above ``length``."""
    exponent = 10.0 ** math.floor(math.log10(max(length, 1e-9)))
    for factor in (1.0, 2.0, 5.0, 10.0):
        if factor * exponent >= length:
            return factor * exponent
    return 10.0 * exponent


def _clip_polygon_near(poly: np.ndarray, near: float) -> np.ndarray:
    """Sutherland-Hodgman: the part of camera-space polygon [K, 3] with depth (column 2) >= near."""
    out: list[np.ndarray] = []
    count = len(poly)
    for i in range(count):
        a, b = poly[i], poly[(i + 1) % count]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (near - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out) if out else np.zeros((0, 3))


def _clip_segments_near(a: np.ndarray, b: np.ndarray,
                        near: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-space segments a, b [N, 3] clipped to depth >= near: (a', b', kept mask [N])."""
    keep = (a[:, 2] >= near) | (b[:, 2] >= near)
    a, b = a.copy(), b.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (near - a[:, 2]) / (b[:, 2] - a[:, 2])
    cut_a = keep & (a[:, 2] < near)
    cut_b = keep & (b[:, 2] < near)
    a[cut_a] = a[cut_a] + t[cut_a, None] * (b[cut_a] - a[cut_a])
    b[cut_b] = a[cut_b] + t[cut_b, None] * (b[cut_b] - a[cut_b])
    return a, b, keep


class FrameRenderer:
    """Renders frames [height, width, 3] uint8 of E aircraft (see the module docstring).

    ``airframes``: one airframe (drawn for every aircraft) or one per aircraft (Airframe objects or names
    ``load_airframe`` accepts). ``scale`` enlarges the glyphs (see :mod:`.glyph`). ``camera_azimuth_deg``:
    None for the chase view, else the fixed compass direction (deg, 0 north, 90 east) the camera looks
    towards. ``fov_deg``: vertical field of view. ``labels``: HUD names of the aircraft."""

    def __init__(self, airframes: Airframe | str | Path | Sequence[Airframe | str | Path],
                 width: int = 480, height: int = 360, scale: float = 1.0,
                 camera_azimuth_deg: float | None = None, camera_elevation_deg: float = 20.0,
                 fov_deg: float = 50.0, labels: Sequence[str] | None = None, dpi: int = 100) -> None:
        for name, value, low in (("width", width, 16), ("height", height, 16), ("dpi", dpi, 10)):
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        if not 1.0 <= camera_elevation_deg <= 89.0:
            raise ValueError(f"camera_elevation_deg must be in [1, 89], got {camera_elevation_deg!r}")
        if not 5.0 <= fov_deg <= 150.0:
            raise ValueError(f"fov_deg must be in [5, 150], got {fov_deg!r}")
        if camera_azimuth_deg is not None and not math.isfinite(camera_azimuth_deg):
            raise ValueError(f"camera_azimuth_deg must be finite or None, got {camera_azimuth_deg!r}")
        if isinstance(airframes, (Airframe, str, Path)):
            airframes = [airframes]
        if len(airframes) == 0:
            raise ValueError("airframes must name at least one airframe")
        self.airframes = [a if isinstance(a, Airframe) else load_airframe(a) for a in airframes]
        self.glyphs: list[Glyph] = [aircraft_glyph(a, scale) for a in self.airframes]
        self.width, self.height = width, height
        self.scale = float(scale)
        self.camera_azimuth_deg = camera_azimuth_deg
        self.elevation = math.radians(camera_elevation_deg)
        self.fov = math.radians(fov_deg)
        self.focal = 0.5 * height / math.tan(0.5 * self.fov)
        self.labels = list(labels) if labels is not None else None
        # Per glyph: stacked vertices, polygon offsets, body normals, colours.
        self._glyph_data = []
        for glyph in self.glyphs:
            sizes = [len(p) for p in glyph.polygons]
            normals = np.array([np.cross(p[1] - p[0], p[2] - p[0]) for p in glyph.polygons])
            normals /= np.linalg.norm(normals, axis=1, keepdims=True)
            self._glyph_data.append((glyph.vertices(), np.cumsum([0, *sizes]), normals,
                                     np.array(glyph.colors)))

        self.figure = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, facecolor=_SKY)
        self.canvas = FigureCanvasAgg(self.figure)
        ax = self.figure.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_xlim(0, width)
        ax.set_ylim(0, height)
        ax.set_axis_off()
        ax.set_facecolor(_SKY)
        self.axes = ax
        self._ground = PolyCollection([], facecolors=[_GROUND], edgecolors="none", zorder=1)
        self._waves = PolyCollection([], edgecolors="face", linewidths=0.3, zorder=1.5)
        self._grid = LineCollection([], colors=[_GRID], linewidths=0.6, zorder=2)
        self._shadows = PolyCollection([], facecolors=[(0.35, 0.38, 0.33, 0.45)], edgecolors="none", zorder=3)
        self._drops = LineCollection([], colors=[(0.3, 0.3, 0.3, 0.5)], linewidths=0.7, linestyles="--",
                                     zorder=4)
        self._trails = LineCollection([], linewidths=1.8, zorder=5, capstyle="round")
        self._body = PolyCollection([], edgecolors=[(0.1, 0.1, 0.15)], linewidths=0.5, zorder=6)
        for artist in (self._ground, self._waves, self._grid, self._shadows, self._drops, self._trails,
                       self._body):
            ax.add_collection(artist)
        self._hud = ax.text(6, height - 6, "", ha="left", va="top", family="monospace", fontsize=8,
                            zorder=10, bbox={"boxstyle": "round,pad=0.3", "fc": (1, 1, 1, 0.6), "ec": "none"})

    # ----------------------------------------------------------------------------------------- camera
    def _camera(self, position: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(camera position [3] NED m, world-to-camera rows [3, 3] (right, up, forward), distance m)."""
        low, high = position.min(0), position.max(0)
        target = 0.5 * (low + high)
        extent = max(self._glyph_for(e).extent for e in range(len(position)))
        spread = float(np.linalg.norm(position - target, axis=1).max())
        half_fov = 0.5 * min(self.fov, 2 * math.atan(math.tan(0.5 * self.fov) * self.width / self.height))
        distance = (spread + 1.6 * extent) / math.sin(half_fov)
        if self.camera_azimuth_deg is None:
            heading = rotation[:, :2, 0].sum(0)  # summed horizontal nose directions (north, east)
            azimuth = math.atan2(heading[1], heading[0]) if np.hypot(*heading) > 1e-6 else 0.0
        else:
            azimuth = math.radians(self.camera_azimuth_deg)
        ce, se = math.cos(self.elevation), math.sin(self.elevation)
        forward = np.array([ce * math.cos(azimuth), ce * math.sin(azimuth), se])
        right = np.array([-math.sin(azimuth), math.cos(azimuth), 0.0])
        up = np.cross(right, forward)
        return target - distance * forward, np.stack([right, up, forward]), distance

    def _glyph_for(self, env: int) -> Glyph:
        return self.glyphs[env if len(self.glyphs) > 1 else 0]

    def _project(self, cam: np.ndarray) -> np.ndarray:
        """Camera-space points [..., 3] (depth > 0) to pixel coordinates [..., 2] (y up)."""
        depth = cam[..., 2:3]
        return np.array([0.5 * self.width, 0.5 * self.height]) + self.focal * cam[..., :2] / depth

    # ----------------------------------------------------------------------------------------- render
    def render(self, position_ned: Any, quaternion: Any, trails: Sequence[Any] | None = None,
               trail_bank: Sequence[Any] | None = None, time: float | None = None,
               sea: SeaField | None = None, sea_time: float | None = None) -> np.ndarray:
        """One frame [height, width, 3] uint8.

        ``position_ned`` [E, 3] m NED; ``quaternion`` [E, 4] body-to-NED (w, x, y, z) (NumPy arrays or
        CPU tensors; [3] and [4] are read as E = 1). ``trails``: None or one [K, 3] NED path (m) per
        aircraft; ``trail_bank``: None (trails drawn in one colour) or one [K] bank angle (rad) per trail,
        which colours it over +-BANK_RANGE_DEG. ``time``: s, shown on the HUD. ``sea``: None (the flat
        ground) or the wave field to draw at ``sea_time`` (s, its clock; None: ``time`` or 0)."""
        position = _numpy(position_ned, "position_ned", 3)
        quat = _numpy(quaternion, "quaternion", 4)
        envs = len(position)
        if len(quat) != envs:
            raise ValueError(f"quaternion has {len(quat)} rows, position_ned has {envs}")
        if len(self.glyphs) > 1 and len(self.glyphs) != envs:
            raise ValueError(f"the renderer draws {len(self.glyphs)} airframes, got {envs} aircraft")
        norms = np.linalg.norm(quat, axis=1, keepdims=True)
        if np.any(norms < 1e-9):
            raise ValueError("quaternion holds a zero row")
        rotation = rotation_matrix(torch.from_numpy(quat / norms)).numpy()  # [E, 3, 3] body -> NED
        eye, world_to_cam, distance = self._camera(position, rotation)
        near = 0.02 * distance

        def to_cam(points: np.ndarray) -> np.ndarray:
            return (points - eye) @ world_to_cam.T

        clock = float(sea_time if sea_time is not None else time if time is not None else 0.0)
        if sea is None:
            self._waves.set_verts([])
            self._ground.set_facecolor([_GROUND])
            self._draw_ground(eye, world_to_cam, position, distance, near, to_cam)
        else:
            self._draw_sea(eye, world_to_cam, position, distance, near, to_cam, sea, clock)

        def surface(north: np.ndarray, east: np.ndarray) -> np.ndarray:
            """NED z (m) of the surface under the points [P]: the ground, or the sea at its clock."""
            return np.zeros(len(north)) if sea is None else -sea.elevation(north, east, clock)

        # Aircraft, shadows and drop lines.
        faces: list[np.ndarray] = []
        colors: list[np.ndarray] = []
        depths: list[np.ndarray] = []
        shadows: list[np.ndarray] = []
        drops: list[np.ndarray] = []
        for e in range(envs):
            vertices, offsets, normals, base = self._glyph_data[e if len(self.glyphs) > 1 else 0]
            world = vertices @ rotation[e].T + position[e]
            cam = to_cam(world)
            shade = 0.55 + 0.45 * np.abs((normals @ rotation[e].T) @ _LIGHT)
            under = surface(world[:, 0], world[:, 1])
            below = surface(position[e, :1], position[e, 1:2])[0]
            for i in range(len(offsets) - 1):
                poly = cam[offsets[i]:offsets[i + 1]]
                if np.all(poly[:, 2] > near):
                    faces.append(self._project(poly))
                    depths.append(poly[:, 2].mean())
                    colors.append(np.clip(base[i] * shade[i], 0, 1))
                flat = world[offsets[i]:offsets[i + 1]].copy()
                flat[:, 2] = under[offsets[i]:offsets[i + 1]]
                shadow = to_cam(flat)
                if np.all(shadow[:, 2] > near) and position[e, 2] < below:
                    shadows.append(self._project(shadow))
            foot = to_cam(np.array([position[e], [position[e, 0], position[e, 1], below]]))
            if np.all(foot[:, 2] > near) and position[e, 2] < below:
                drops.append(self._project(foot))
        order = np.argsort(-np.asarray(depths)) if depths else []
        self._body.set_verts([faces[i] for i in order])
        self._body.set_facecolor([colors[i] for i in order] if colors else [])
        self._shadows.set_verts(shadows)
        self._drops.set_segments(drops)
        self._draw_trails(trails, trail_bank, envs, near, to_cam)
        self._hud.set_text(self._hud_text(position, rotation, time, sea))
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[..., :3].copy()

    def _draw_ground(self, eye: np.ndarray, world_to_cam: np.ndarray, position: np.ndarray, distance: float,
                     near: float, to_cam: Any) -> None:
        """The ground quad and grid around the aircraft's footprint."""
        height_above = max(-eye[2], 1e-3)
        step = _nice_step(max(distance, height_above) / 3.0)
        centre = np.round(position[:, :2].mean(0) / step) * step
        lines = 12
        half = lines * step
        far = 40.0 * max(distance, height_above)
        quad = np.array([[centre[0] - far, centre[1] - far, 0], [centre[0] + far, centre[1] - far, 0],
                         [centre[0] + far, centre[1] + far, 0], [centre[0] - far, centre[1] + far, 0]])
        ground = _clip_polygon_near(to_cam(quad), near)
        self._ground.set_verts([self._project(ground)] if len(ground) >= 3 else [])
        ticks = np.arange(-lines, lines + 1) * step
        a = np.concatenate([np.stack([centre[0] + ticks, np.full_like(ticks, centre[1] - half)], 1),
                            np.stack([np.full_like(ticks, centre[0] - half), centre[1] + ticks], 1)])
        b = np.concatenate([np.stack([centre[0] + ticks, np.full_like(ticks, centre[1] + half)], 1),
                            np.stack([np.full_like(ticks, centre[0] + half), centre[1] + ticks], 1)])
        zeros = np.zeros((len(a), 1))
        ca, cb, keep = _clip_segments_near(to_cam(np.hstack([a, zeros])), to_cam(np.hstack([b, zeros])), near)
        self._grid.set_segments(np.stack([self._project(ca[keep]), self._project(cb[keep])], 1))

    def _draw_sea(self, eye: np.ndarray, world_to_cam: np.ndarray, position: np.ndarray, distance: float,
                  near: float, to_cam: Any, sea: SeaField, time: float) -> None:
        """The sea: the mean level to the horizon (the ground quad in the sea's colour, no grid) under the
        wave mesh the camera sees at ``time``, its quads drawn back to front."""
        height_above = max(-eye[2], 1e-3)
        far = 40.0 * max(distance, height_above)
        centre = position[:, :2].mean(0)
        quad = np.array([[centre[0] - far, centre[1] - far, 0], [centre[0] + far, centre[1] - far, 0],
                         [centre[0] + far, centre[1] + far, 0], [centre[0] - far, centre[1] + far, 0]])
        level = _clip_polygon_near(to_cam(quad), near)
        self._ground.set_verts([self._project(level)] if len(level) >= 3 else [])
        self._ground.set_facecolor([_sea_colors(np.zeros(1), np.full(1, abs(_LIGHT[2])), 0.0)[0]])
        self._grid.set_segments([])
        columns, rows = max(16, round(self.width / _SEA_CELL_PX)), max(12, round(self.height / _SEA_CELL_PX))
        mesh = sea_mesh(sea, time, eye, world_to_cam, self.focal, self.width, self.height, far=0.5 * far,
                        columns=columns, rows=rows)
        if mesh is None:
            self._waves.set_verts([])
            return
        corners = (mesh[:-1, :-1], mesh[1:, :-1], mesh[1:, 1:], mesh[:-1, 1:])
        quads = np.stack(corners, axis=2).reshape(-1, 4, 3)  # [Q, 4, 3] NED
        cam = to_cam(quads)
        keep = np.all(cam[..., 2] > near, axis=-1)
        quads, cam = quads[keep], cam[keep]
        pixels = self._project(cam)
        outside = ((pixels[..., 0].max(-1) < 0) | (pixels[..., 0].min(-1) > self.width)
                   | (pixels[..., 1].max(-1) < 0) | (pixels[..., 1].min(-1) > self.height))
        quads, cam, pixels = quads[~outside], cam[~outside], pixels[~outside]
        normal = np.cross(quads[:, 2] - quads[:, 0], quads[:, 3] - quads[:, 1])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        colors = _sea_colors(-quads[..., 2].mean(-1), np.abs(normal @ _LIGHT), math.sqrt(sea.variance))
        order = np.argsort(-cam[..., 2].mean(-1))
        self._waves.set_verts(pixels[order])
        self._waves.set_facecolor(colors[order])

    def _draw_trails(self, trails: Sequence[Any] | None, trail_bank: Sequence[Any] | None, envs: int,
                     near: float, to_cam: Any) -> None:
        """Trails as polylines: consecutive segments of one colour level (:data:`_TRAIL_LEVELS` over
        +-BANK_RANGE_DEG) are merged into one path, so a long trail costs a few paths, not one a segment."""
        if trails is None:
            self._trails.set_segments([])
            return
        if len(trails) != envs:
            raise ValueError(f"trails must hold one [K, 3] path per aircraft ({envs}), got {len(trails)}")
        if trail_bank is not None and len(trail_bank) != envs:
            raise ValueError(f"trail_bank must hold one [K] array per trail ({envs}), got {len(trail_bank)}")
        lines: list[np.ndarray] = []
        colors: list[np.ndarray] = []
        for e, trail in enumerate(trails):
            if isinstance(trail, torch.Tensor):
                trail = trail.detach().cpu().numpy()
            path = np.asarray(trail, dtype=np.float64)
            if path.ndim != 2 or path.shape[1] != 3:
                raise ValueError(f"trails[{e}] must be [K, 3], got shape {path.shape}")
            if trail_bank is not None:
                bank = np.asarray(trail_bank[e], dtype=np.float64).reshape(-1)
                if len(bank) != len(path):
                    raise ValueError(
                        f"trail_bank[{e}] has {len(bank)} values, trails[{e}] has {len(path)} points")
            if len(path) < 2:
                continue
            if trail_bank is not None:
                mid = np.clip(np.degrees(0.5 * (bank[1:] + bank[:-1])) / BANK_RANGE_DEG, -1, 1)
                level = np.nan_to_num(np.round((mid + 1) / 2 * (_TRAIL_LEVELS - 1)), nan=0).astype(int)
                palette = bank_colors(np.radians(np.linspace(-BANK_RANGE_DEG, BANK_RANGE_DEG, _TRAIL_LEVELS)))
            else:
                level = np.zeros(len(path) - 1, dtype=int)
                palette = np.array([matplotlib.colormaps["tab10"](e % 10)])
            cam = to_cam(path)
            ca, cb, keep = _clip_segments_near(cam[:-1], cam[1:], near)
            cut_a = ca[:, 2] != cam[:-1, 2]
            cut_b = cb[:, 2] != cam[1:, 2]
            key = np.where(keep, level, -1)
            starts = np.flatnonzero(np.concatenate([[True], (key[1:] != key[:-1]) | cut_a[1:] | cut_b[:-1]]))
            stops = np.append(starts[1:], len(key))
            for i, j in zip(starts, stops, strict=True):
                if key[i] < 0:
                    continue
                lines.append(self._project(np.concatenate([ca[i:i + 1], cb[i:j]])))
                colors.append(palette[key[i]])
        self._trails.set_segments(lines)
        self._trails.set_color(colors if colors else [])

    def _hud_text(self, position: np.ndarray, rotation: np.ndarray, time: float | None,
                  sea: SeaField | None = None) -> str:
        bank = np.degrees(np.arctan2(rotation[:, 2, 1], rotation[:, 2, 2]))
        lines = [f"t {time:7.2f} s"] if time is not None else []
        if sea is not None:
            text = f"sea state {sea.sea_state}  Hs {sea.significant_height:.1f} m"
            lines = [f"{lines[0]}  {text}"] if lines else [text]
        for e in range(min(len(position), _MAX_HUD_LINES)):
            name = f"{self.labels[e][:12]:<12} " if self.labels and e < len(self.labels) else ""
            lines.append(f"{name}h {-position[e, 2]:7.1f} m  bank {bank[e]:+5.0f}\N{DEGREE SIGN}")
        if len(position) > _MAX_HUD_LINES:
            lines.append(f"... {len(position) - _MAX_HUD_LINES} more")
        return "\n".join(lines)

    def close(self) -> None:
        """Release the figure (the renderer is unusable afterwards)."""
        self.figure.clear()


def _sea_colors(height: np.ndarray, lambert: np.ndarray, sigma: float) -> np.ndarray:
    """RGB [Q, 3] of sea panels at ``height`` [Q] m above the mean level (troughs dark, crests light over
    +-2 ``sigma``, the elevation's standard deviation) lit at ``lambert`` [Q] (|cos| of the light to the
    panel's normal; a level panel's is |light z|, slopes turned to the light brighter)."""
    level = np.clip(0.5 + height / (4.0 * sigma), 0.0, 1.0) if sigma > 0 else np.full(len(height), 0.5)
    shade = np.clip(1.0 + 4.0 * (lambert - abs(_LIGHT[2])), 0.6, 1.3)
    return np.clip((_SEA_TROUGH + level[:, None] * (_SEA_CREST - _SEA_TROUGH)) * shade[:, None], 0.0, 1.0)
