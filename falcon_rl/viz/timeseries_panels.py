"""The layout engine of the time-domain panels (:mod:`.timeseries`): a panel is a list of :class:`Row`
of :class:`Plot` of :class:`Line`, each line one quantity [T, E] already in display units, drawn
against the recording's time [T] for every aircraft.

Two layouts of the same panel:

- overlaid (default): one axes per plot (rows x plots), one colour per aircraft, the line style tells
  the lines of a plot apart (e.g. commanded dashed, achieved solid); at most
  :data:`MAX_AIRCRAFT_PER_FIGURE` aircraft, so that the colours stay distinguishable;
- faceted: one column per aircraft, every plot of a row drawn in the same axes, one colour per plot.

Also here: :data:`QUANTITIES`, the recorded or derived quantities the panels draw and task references
are matched to, and the checks of the arguments the public functions share (aircraft indices, output
formats).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch
from matplotlib.lines import Line2D

from ..constants import DEG
from ..physics.rotations import body_to_ned, quaternion_to_euler
from ..recording import Recording
from ._figure import save_figure

#: Most aircraft drawn in one figure (overlaid: ten colours of the default cycle, eight stay readable;
#: faceted: eight columns). ``envs=None`` draws the first ones; naming more raises ValueError.
MAX_AIRCRAFT_PER_FIGURE = 8
#: Output formats the panels are written in (the file suffix, without the dot).
SUPPORTED_FORMATS: tuple[str, ...] = ("png", "svg", "pdf")
#: Inches per axes column and per row of a panel.
_COLUMN_WIDTH, _ROW_HEIGHT = 3.6, 2.2
_DPI = 100
#: Smallest y range drawn as such; a narrower one (a constant trace) is widened by +-1.
_MIN_Y_SPAN = 1e-9


@dataclass(frozen=True)
class Line:
    """One quantity of every aircraft: ``values`` [T, E] in display units, drawn in ``style``."""

    label: str
    values: np.ndarray
    style: str = "-"


@dataclass(frozen=True)
class Plot:
    """One axes (overlaid layout): the lines of one quantity, e.g. commanded and achieved elevator."""

    title: str
    lines: tuple[Line, ...]


@dataclass(frozen=True)
class Row:
    """Plots sharing a y label with its unit, e.g. "angle (deg)": roll, pitch and yaw."""

    ylabel: str
    plots: tuple[Plot, ...]


def row_of(ylabel: str, plots: Iterable[Plot | None]) -> Row | None:
    """A :class:`Row` of the ``plots`` that exist (None: a field absent from the recording), or None."""
    present = tuple(plot for plot in plots if plot is not None and plot.lines)
    return Row(ylabel, present) if present else None


def plot_of(title: str, lines: Iterable[Line | None]) -> Plot | None:
    """A :class:`Plot` of the ``lines`` that exist, or None when none does."""
    present = tuple(line for line in lines if line is not None)
    return Plot(title, present) if present else None


# ------------------------------------------------------------------------------- recorded quantities
def as_float(values: np.ndarray) -> np.ndarray:
    """``values`` as float64."""
    return np.asarray(values, dtype=np.float64)


def _euler(rec: Recording) -> np.ndarray:
    """[T, E, 3] rad roll, pitch, yaw (recorded, else from the quaternion); yaw unwrapped in time."""
    if rec.has("euler"):
        euler = as_float(rec["euler"]).copy()
    else:
        euler = quaternion_to_euler(torch.from_numpy(as_float(rec["quaternion"]))).numpy()
    euler[..., 2] = unwrap_in_time(euler[..., 2])
    return euler


def unwrap_in_time(angle: np.ndarray) -> np.ndarray:
    """``angle`` [T, E] rad without its 2 pi jumps along T; NaN frames (an aircraft not recorded
    then) stay NaN and do not spoil the frames after them."""
    out = angle.copy()
    for column in np.ndindex(angle.shape[1:]):
        values = out[(slice(None), *column)]
        finite = np.isfinite(values)
        values[finite] = np.unwrap(values[finite])
    return out


def _velocity_ned(rec: Recording) -> np.ndarray | None:
    """[T, E, 3] m/s inertial velocity in NED (recorded, else rotated from the body velocity)."""
    if rec.has("velocity_ned"):
        return as_float(rec["velocity_ned"])
    if rec.has("velocity_body"):
        q, v = (torch.from_numpy(as_float(rec[name])) for name in ("quaternion", "velocity_body"))
        return body_to_ned(q.reshape(-1, 4), v.reshape(-1, 3)).reshape(v.shape).numpy()
    return None


def recorded(name: str) -> Callable[[Recording], np.ndarray | None]:
    """The extractor of the field ``name`` (float64 [T, E, ...], None when absent)."""
    return lambda rec: as_float(rec[name]) if rec.has(name) else None


@dataclass(frozen=True)
class Quantity:
    """A recorded or derived quantity: ``extract(rec)`` gives [T, E] (or [T, E, C] with ``components``
    naming C) in SI units, or None when the recording lacks it; times ``scale`` it is in ``unit``."""

    label: str
    unit: str
    extract: Callable[[Recording], np.ndarray | None]
    scale: float = 1.0
    components: tuple[str, ...] = ()

    def line(self, rec: Recording, component: int | None = None, label: str = "", style: str = "-"
             ) -> Line | None:
        """The :class:`Line` [T, E] of this quantity (of ``component`` of a vector one), or None."""
        values = self.extract(rec)
        if values is not None and component is not None:
            values = values[..., component] if values.ndim == 3 and component < values.shape[2] else None
        if values is None or values.ndim != 2:
            return None
        return Line(label, values * self.scale, style)


#: Quantities the panels draw and task references are matched to, by name.
QUANTITIES: dict[str, Quantity] = {
    "position_ned": Quantity("position NED", "m", recorded("position_ned"),
                             components=("north", "east", "down")),
    "height": Quantity("height", "m", lambda r: as_float(r["height"]) if r.has("height")
                       else -as_float(r["position_ned"][..., 2])),
    "euler": Quantity("Euler angle", "deg", _euler, 1 / DEG, ("roll", "pitch", "yaw")),
    "roll": Quantity("roll", "deg", lambda r: _euler(r)[..., 0], 1 / DEG),
    "pitch": Quantity("pitch", "deg", lambda r: _euler(r)[..., 1], 1 / DEG),
    "yaw": Quantity("yaw", "deg", lambda r: _euler(r)[..., 2], 1 / DEG),
    "velocity_ned": Quantity("velocity NED", "m/s", _velocity_ned, components=("north", "east", "down")),
    "velocity_body": Quantity("velocity body", "m/s", recorded("velocity_body"), components=("u", "v", "w")),
    "airspeed": Quantity("airspeed", "m/s", recorded("airspeed")),
    "ground_speed": Quantity("ground speed", "m/s", lambda r: None if (v := _velocity_ned(r)) is None
                             else np.linalg.norm(v, axis=-1)),
    "climb_rate": Quantity("climb rate", "m/s", lambda r: None if (v := _velocity_ned(r)) is None
                           else -v[..., 2]),
    "course": Quantity("course", "deg", lambda r: None if (v := _velocity_ned(r)) is None
                       else unwrap_in_time(np.arctan2(v[..., 1], v[..., 0])), 1 / DEG),
    "alpha": Quantity("alpha", "deg", recorded("alpha"), 1 / DEG),
    "beta": Quantity("beta", "deg", recorded("beta"), 1 / DEG),
    "angular_rate_body": Quantity("body rate", "deg/s", recorded("angular_rate_body"), 1 / DEG,
                                  ("p", "q", "r")),
}

# ---------------------------------------------------------------------------------------- arguments
def check_recording(rec: Recording) -> None:
    """Raise ValueError for a recording without frames or without aircraft."""
    if rec.num_frames == 0 or rec.num_envs == 0:
        raise ValueError(f"empty recording ({rec.num_frames} frames of {rec.num_envs} aircraft)")


def select_aircraft(rec: Recording, envs: Sequence[int] | None) -> Recording:
    """The recording of the aircraft ``envs`` (indices into E; None: the first
    :data:`MAX_AIRCRAFT_PER_FIGURE`); ValueError for an empty recording or a bad index list."""
    check_recording(rec)
    if envs is None:
        envs = range(min(rec.num_envs, MAX_AIRCRAFT_PER_FIGURE))
    index = list(envs)
    if not index:
        raise ValueError("envs is empty: name at least one aircraft")
    for env in index:
        if isinstance(env, bool) or not isinstance(env, int | np.integer) or not 0 <= env < rec.num_envs:
            raise ValueError(f"unknown aircraft index {env!r}: the recording has {rec.num_envs} aircraft")
    if len(set(index)) != len(index):
        raise ValueError(f"envs names an aircraft twice: {index}")
    if len(index) > MAX_AIRCRAFT_PER_FIGURE:
        raise ValueError(f"{len(index)} aircraft asked, a figure shows at most {MAX_AIRCRAFT_PER_FIGURE}")
    return rec if index == list(range(rec.num_envs)) else rec.select(int(e) for e in index)


def check_formats(formats: Iterable[str]) -> tuple[str, ...]:
    """The ``formats`` (file suffixes without the dot), once each; ValueError for an unknown one."""
    if isinstance(formats, str):
        formats = (formats,)
    chosen = tuple(dict.fromkeys(f.lower().lstrip(".") for f in formats))
    if not chosen:
        raise ValueError(f"no output format given, choose from {', '.join(SUPPORTED_FORMATS)}")
    for fmt in chosen:
        if fmt not in SUPPORTED_FORMATS:
            raise ValueError(f"unknown format {fmt!r}, choose from {', '.join(SUPPORTED_FORMATS)}")
    return chosen


def check_path(path: str | Path) -> Path:
    """``path`` as a Path; ValueError when its suffix is not one of :data:`SUPPORTED_FORMATS`."""
    path = Path(path)
    check_formats((path.suffix or "(none)",))
    return path


# ---------------------------------------------------------------------------------------- drawing
def _labels(rec: Recording) -> list[str]:
    labels = list(rec.meta.get("labels") or [])
    return [labels[e] if e < len(labels) else f"aircraft {e}" for e in range(rec.num_envs)]


def _title(rec: Recording, name: str) -> str:
    keys = ("airframe", "task", "controller")
    parts = [f"{key} {rec.meta[key]}" for key in keys if rec.meta.get(key)]
    return f"{name}: " + ", ".join(parts) if parts else name


def _draw_overlaid(rec: Recording, rows: Sequence[Row]) -> plt.Figure:
    columns = max(len(row.plots) for row in rows)
    fig, axes = plt.subplots(len(rows), columns, figsize=(_COLUMN_WIDTH * columns, _ROW_HEIGHT * len(rows)),
                             squeeze=False)
    for r, row in enumerate(rows):
        for c in range(columns):
            ax = axes[r, c]
            if c >= len(row.plots):
                ax.set_visible(False)
                continue
            plot = row.plots[c]
            for line in plot.lines:
                for env in range(rec.num_envs):
                    ax.plot(rec.time, line.values[:, env], color=f"C{env}", ls=line.style, lw=1.1)
            ax.set(title=plot.title, ylabel=row.ylabel)
            handles = [Line2D([], [], color=f"C{env}", label=label)
                       for env, label in enumerate(_labels(rec))] if r == c == 0 else []
            if len({line.style for line in plot.lines}) > 1:
                handles += [Line2D([], [], color="0.3", ls=line.style, label=line.label)
                            for line in plot.lines]
            if handles:
                ax.legend(handles=handles, fontsize=7, loc="best")
            if all(c >= len(below.plots) for below in rows[r + 1:]):
                ax.set_xlabel("time (s)")
    return fig


def _draw_faceted(rec: Recording, rows: Sequence[Row]) -> plt.Figure:
    columns = rec.num_envs
    fig, axes = plt.subplots(len(rows), columns, figsize=(_COLUMN_WIDTH * columns, _ROW_HEIGHT * len(rows)),
                             squeeze=False, sharex=True)
    for r, row in enumerate(rows):
        for env in range(columns):
            ax = axes[r, env]
            for p, plot in enumerate(row.plots):
                for line in plot.lines:
                    label = f"{plot.title} {line.label}".strip() if len(plot.lines) > 1 else plot.title
                    ax.plot(rec.time, line.values[:, env], color=f"C{p}", ls=line.style, lw=1.1, label=label)
            ax.set(ylabel=row.ylabel if env == 0 else "")
            if env == 0:
                ax.legend(fontsize=7, loc="best")
    for env, label in enumerate(_labels(rec)):
        axes[0, env].set_title(label)
        axes[-1, env].set_xlabel("time (s)")
    return fig


def render(rec: Recording, rows: Sequence[Row | None], name: str, facet: bool = False) -> plt.Figure | None:
    """The figure of the present ``rows`` (None when no row is present): time (s) on x, the aircraft
    overlaid in colours or, with ``facet``, one column each; the suptitle names ``name`` and the
    recording's airframe, task and controller when known."""
    present = [row for row in rows if row is not None]
    if not present:
        return None
    fig = _draw_faceted(rec, present) if facet else _draw_overlaid(rec, present)
    for ax in fig.axes:
        ax.grid(alpha=0.3)
        low, high = ax.get_ylim()
        if high - low < _MIN_Y_SPAN:  # a constant trace: show its value, not rounding noise
            ax.set_ylim(low - 1.0, high + 1.0)
    fig.suptitle(_title(rec, name))
    return fig


def write(fig: plt.Figure, paths: Sequence[Path]) -> list[Path]:
    """Lay out ``fig`` and write it to every path of ``paths`` (the suffix picks the format); the first
    through ``save_figure``, which lays the figure out and closes it (a closed figure still saves)."""
    first = save_figure(fig, paths[0], dpi=_DPI)
    for path in paths[1:]:
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=_DPI)
    return [first, *paths[1:]]
