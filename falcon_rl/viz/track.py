"""The maneuver figure: a grid of still 3D flight tracks, one row per airframe and one column per
maneuver, each track coloured by bank angle over +-50 degrees (one shared colorbar, degrees) with a few
attitude glyphs (:mod:`.glyph`) along it. Axes in metres: north, east, height; the east axis runs
right to left, so the view is the true, unmirrored geometry. The glyphs are enlarged so that each spans
:data:`GLYPH_FRACTION` of the largest track extent of its panel (never shrunk); the scale is printed in
the panel."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from ..airframe import AirframeError, load_airframe
from ..physics.rotations import rotation_matrix
from ..recording import Recording
from ._figure import save_figure
from .animation import bank_angles
from .glyph import aircraft_glyph
from .scene import BANK_CMAP, BANK_RANGE_DEG

#: A glyph spans this share of its panel's largest track extent (when that enlarges it).
GLYPH_FRACTION = 0.12
#: Tracks are drawn through at most this many points.
MAX_TRACK_POINTS = 2000


def _plot_coords(ned: np.ndarray) -> np.ndarray:
    """NED [..., 3] -> plot coordinates (north, east, height) [..., 3]."""
    return np.stack([ned[..., 0], ned[..., 1], -ned[..., 2]], axis=-1)


def _draw_panel(ax: plt.Axes, rec: Recording, airframe_name: str, glyphs_per_track: int,
                norm: Normalize) -> None:
    """One 3D panel: every aircraft of ``rec`` with its bank-coloured track and glyphs."""
    position = np.asarray(rec["position_ned"], dtype=np.float64)  # [T, E, 3]
    quaternion = np.asarray(rec["quaternion"], dtype=np.float64)
    bank = np.degrees(bank_angles(rec))
    points = _plot_coords(position)
    low, high = points.reshape(-1, 3).min(0), points.reshape(-1, 3).max(0)
    extent = float(max((high - low).max(), 1e-3))
    airframe = load_airframe(airframe_name)
    scale = max(1.0, GLYPH_FRACTION * extent / airframe.geometry.span)
    glyph = aircraft_glyph(airframe, scale)
    cmap = matplotlib.colormaps[BANK_CMAP]
    pad = 0.05 * extent + glyph.extent
    # Equal metres on every axis, each axis at least a quarter of the longest (a level track stays 3D).
    ranges = np.maximum(high - low + 2 * pad, 0.25 * (extent + 2 * pad))
    centre = 0.5 * (low + high)
    lo, hi = centre - ranges / 2, centre + ranges / 2
    floor = lo[2]  # the ground track is drawn on the panel's floor
    stride = max(1, math.ceil(rec.num_frames / MAX_TRACK_POINTS))
    for e in range(rec.num_envs):
        path = points[::stride, e]
        shade = bank[::stride, e]
        if len(path) >= 2:
            segments = np.stack([path[:-1], path[1:]], axis=1)
            ax.add_collection3d(Line3DCollection(segments, colors=cmap(norm(0.5 * (shade[1:] + shade[:-1]))),
                                                 linewidths=1.6))
        ax.plot(path[:, 0], path[:, 1], np.full(len(path), floor), color="0.6", lw=0.6, alpha=0.6)
        frames = np.linspace(0, rec.num_frames - 1, glyphs_per_track).round().astype(int)
        rotations = rotation_matrix(torch.from_numpy(quaternion[frames, e])).numpy()
        for frame, rot in zip(frames, rotations, strict=True):
            polys = [_plot_coords(p @ rot.T + position[frame, e]) for p in glyph.polygons]
            ax.add_collection3d(Poly3DCollection(polys, facecolors=glyph.colors, edgecolors="0.15",
                                                 linewidths=0.3, alpha=0.95))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])  # east runs right to left: an unmirrored view
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(tuple(ranges / ranges.max()))
    ax.set_xlabel("north (m)", fontsize=7, labelpad=-2)
    ax.set_ylabel("east (m)", fontsize=7, labelpad=-2)
    ax.set_zlabel("height (m)", fontsize=7, labelpad=-2)
    ax.tick_params(labelsize=6, pad=0)
    for axis, share in zip((ax.xaxis, ax.yaxis, ax.zaxis), ranges / ranges.max(), strict=True):
        axis.set_major_locator(MaxNLocator(max(2, round(5 * share)), min_n_ticks=2))
    if scale > 1.0:
        ax.text2D(0.98, 0.98, f"glyph x{scale:.0f}", transform=ax.transAxes, fontsize=6, color="0.3",
                  ha="right", va="top")


def plot_tracks(recordings: Mapping[tuple[str, str], Recording], path: str | Path,
                glyphs_per_track: int = 4) -> Path:
    """Write the maneuver figure (PNG) to ``path`` and return it.

    ``recordings``: {(airframe name, maneuver name): Recording}; rows are the airframes and columns the
    maneuvers, in first-seen order; a missing pair leaves its panel blank. Positions in m (NED in the
    recordings, drawn as north, east, height); bank colour over +-BANK_RANGE_DEG degrees.
    ``glyphs_per_track``: attitude glyphs along each track (evenly spaced in time, first and last
    frame included; 0 for none)."""
    if not isinstance(recordings, Mapping) or not recordings:
        raise ValueError("recordings must be a non-empty {(airframe, maneuver): Recording} mapping")
    for key, rec in recordings.items():
        if not (isinstance(key, tuple) and len(key) == 2 and all(isinstance(k, str) for k in key)):
            raise ValueError(f"recordings keys must be (airframe, maneuver) name pairs, got {key!r}")
        if not isinstance(rec, Recording):
            raise ValueError(f"recordings[{key!r}] must be a Recording, got {type(rec).__name__}")
    if isinstance(glyphs_per_track, bool) or not isinstance(glyphs_per_track, int) or glyphs_per_track < 0:
        raise ValueError(f"glyphs_per_track must be a non-negative integer, got {glyphs_per_track!r}")
    airframes = list(dict.fromkeys(a for a, _ in recordings))
    maneuvers = list(dict.fromkeys(m for _, m in recordings))
    names: dict[str, str] = {}
    for name in airframes:
        try:
            names[name] = load_airframe(name).display_name
        except AirframeError as error:
            raise ValueError(f"recordings name an unknown airframe {name!r} ({error})") from None

    rows, cols = len(airframes), len(maneuvers)
    fig = plt.figure(figsize=(3.3 * cols + 0.8, 3.0 * rows + 0.3))
    grid = fig.add_gridspec(rows, cols + 1, width_ratios=[1.0] * cols + [0.05])
    norm = Normalize(-BANK_RANGE_DEG, BANK_RANGE_DEG, clip=True)
    for i, airframe in enumerate(airframes):
        for j, maneuver in enumerate(maneuvers):
            ax = fig.add_subplot(grid[i, j], projection="3d")
            ax.view_init(elev=25, azim=-130)
            rec = recordings.get((airframe, maneuver))
            title = maneuver if i == 0 else ""
            if j == 0:
                title = f"{names[airframe]}\n{title}" if title else names[airframe]
            ax.set_title(title, fontsize=9)
            if rec is None:
                ax.set_axis_off()
                ax.text2D(0.5, 0.5, "no recording", transform=ax.transAxes, ha="center", color="0.5")
                continue
            _draw_panel(ax, rec, airframe, glyphs_per_track, norm)
    cax = fig.add_subplot(grid[:, -1])
    fig.colorbar(ScalarMappable(norm=norm, cmap=BANK_CMAP), cax=cax, label="bank angle (deg)",
                 extend="both")
    return save_figure(fig, path)
