"""The experiment's figures, drawn from the cells' cached results (``falcon_rl.experiment``):
the altitude study's grid, the faceted bank tracking of the maneuvers study and its 3D track renders.
Each takes {(airframe, controller): result} of one replicate (the first seed and draw), where a result
is a cell's cached document with its ``traces``."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from ..recording import Recording
from ._figure import save_figure
from .track import plot_tracks

Results = Mapping[tuple[str, str], Mapping[str, Any]]
#: Bank tolerance band of the maneuvers study, deg (the paper's +-8.6 deg).
BANK_TOLERANCE_DEG = 8.6


def _grid(rows: list[str], cols: list[str], width: float, height: float) -> tuple[plt.Figure, np.ndarray]:
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(width * len(cols), height * len(rows)),
                             squeeze=False)
    return fig, axes


def _traced(results: Results) -> dict[tuple[str, str], Mapping[str, Any]]:
    """The results that have traces (cells without a policy have none)."""
    return {key: value for key, value in results.items() if value.get("traces")}


def plot_altitude_study(results: Results, path: str | Path) -> Path | None:
    """Rows: airframes; columns: controllers. Achieved (solid) vs reference (dashed) height of up to
    ten episodes, and the 5-95 % band of h - h* over all episodes on a twin axis. None when no cell has
    traces."""
    traced = _traced(results)
    if not traced:
        return None
    airframes = list(dict.fromkeys(a for a, _ in traced))
    controllers = list(dict.fromkeys(c for _, c in traced))
    fig, axes = _grid(airframes, controllers, 3.6, 2.8)
    for (airframe, controller), result in traced.items():
        ax = axes[airframes.index(airframe), controllers.index(controller)]
        tr = result["traces"]
        time = np.asarray(tr["time"])
        for i, (height, reference) in enumerate(zip(tr["height"], tr["reference"], strict=False)):
            ax.plot(time, height, color=f"C{i % 10}", lw=1.0)
            ax.plot(time, reference, color=f"C{i % 10}", lw=0.7, ls="--")
        summary = result["summary"]
        ax.set_title(f"{airframe} / {controller}\nRMSE {summary.get('rmse_m', math.nan):.3g} m, "
                     f"surv. {summary.get('survival', math.nan):.2f}", fontsize=9)
        ax.set(xlabel="time (s)", ylabel="height (m)")
        ax.grid(alpha=0.3)
    for ax in axes.flat:
        if not ax.has_data():
            ax.set_axis_off()
    fig.suptitle("Altitude acquisition and hold: achieved (solid) vs reference (dashed)")
    return save_figure(fig, path)


def plot_bank_facets_study(results: Results, airframe: str, path: str | Path) -> Path | None:
    """Rows: maneuvers; columns: controllers (one airframe). Commanded (dashed) vs achieved bank with
    the +-8.6 deg band; each panel reports the bank RMSE. None when no cell of ``airframe`` has traces."""
    traced = {c: r for (a, c), r in _traced(results).items() if a == airframe}
    if not traced:
        return None
    maneuvers = list(next(iter(traced.values()))["traces"])
    controllers = list(traced)
    fig, axes = _grid(maneuvers, controllers, 3.4, 2.2)
    for col, (controller, result) in enumerate(traced.items()):
        for row, maneuver in enumerate(maneuvers):
            ax = axes[row, col]
            tr = result["traces"].get(maneuver)
            if tr is None:
                ax.set_axis_off()
                continue
            time = np.asarray(tr["time"])
            command, bank = np.degrees(tr["bank_command"]), np.degrees(tr["bank"])
            ax.fill_between(time, command - BANK_TOLERANCE_DEG, command + BANK_TOLERANCE_DEG, color="0.88")
            ax.plot(time, command, "k--", lw=0.9)
            ax.plot(time, bank, color="C0", lw=1.1)
            rmse = result["summary"].get(f"{maneuver}/bank_rmse_deg", math.nan)
            ax.set_title(f"{controller}: {maneuver}, RMSE {rmse:.2f} deg", fontsize=9)
            ax.set(xlabel="time (s)", ylabel="bank (deg)")
            ax.grid(alpha=0.3)
    fig.suptitle(f"Bank tracking on {airframe}: commanded (dashed), achieved (solid), "
                 f"+-{BANK_TOLERANCE_DEG} deg")
    return save_figure(fig, path)


def maneuver_recordings(results: Results, controller: str) -> dict[tuple[str, str], Recording]:
    """{(airframe, maneuver): Recording} of ``controller``'s traced maneuvers (for :func:`plot_tracks`)."""
    out = {}
    for (airframe, name), result in _traced(results).items():
        if name != controller:
            continue
        for maneuver, tr in result["traces"].items():
            time = np.asarray(tr["time"], dtype=np.float64)
            keep = np.concatenate([[True], np.diff(time) > 0])  # one frame per time
            fields = {"position_ned": np.asarray(tr["position_ned"], np.float32)[keep, None],
                      "quaternion": np.asarray(tr["quaternion"], np.float32)[keep, None]}
            out[(airframe, maneuver)] = Recording(time[keep], fields, {"airframe": airframe})
    return out


def plot_maneuver_tracks(results: Results, controller: str, path: str | Path) -> Path | None:
    """The paper's track renders (rows airframes, columns maneuvers, coloured by bank) of
    ``controller``; None when it has no traced cell."""
    recordings = maneuver_recordings(results, controller)
    return plot_tracks(recordings, path) if recordings else None


def plot_ground_effect_study(results: Results, path: str | Path) -> Path | None:
    """Delta T against h/b per airframe: the controllers' Delta T_pi (markers, held bands only), the
    trim-only Delta T (line) and the lifting-line theory (dashed). None without rows."""
    with_rows = {key: value for key, value in results.items() if value.get("rows")}
    if not with_rows:
        return None
    airframes = list(dict.fromkeys(a for a, _ in with_rows))
    fig, axes = plt.subplots(1, len(airframes), figsize=(5.0 * len(airframes), 3.8), squeeze=False)
    drawn: set[str] = set()  # airframes whose trim and theory lines are drawn
    for (airframe, controller), result in with_rows.items():
        ax = axes[0, airframes.index(airframe)]
        rows = result["rows"]
        band = np.array([r["h_over_b"] for r in rows], dtype=float)
        policy = np.array([np.nan if r["delta_percent"] is None else r["delta_percent"] for r in rows], float)
        ax.plot(band, policy, "o", label=f"{controller} (Delta T_pi)")
        if airframe not in drawn:  # the trim-only table's columns, once per airframe
            drawn.add(airframe)
            trim = np.array([np.nan if r["trim_delta_percent"] is None else r["trim_delta_percent"]
                             for r in rows], float)
            theory = np.array([np.nan if r["theory_percent"] is None else r["theory_percent"] for r in rows],
                              float)
            ax.plot(band, trim, "k-", lw=1.0, label="trim (Delta T)")
            ax.plot(band, theory, "k--", lw=0.8, label="lifting-line theory")
        ax.set(xscale="log", xlabel="h/b", ylabel="thrust change (%)", title=airframe)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle("Ground effect on the thrust to hold a height: correction on vs off")
    return save_figure(fig, path)


def plot_robustness_study(results: Results, path: str | Path) -> Path | None:
    """Survival and bank RMSE against severity, one line per (airframe, controller) and one column per
    disturbance family. None without grid rows."""
    with_rows = {key: value for key, value in results.items() if value.get("rows")}
    if not with_rows:
        return None
    families = list(dict.fromkeys(r["family"] for value in with_rows.values() for r in value["rows"]))
    fig, axes = plt.subplots(2, len(families), figsize=(3.6 * len(families), 5.6), squeeze=False)
    for index, ((airframe, controller), result) in enumerate(with_rows.items()):
        for col, family in enumerate(families):
            rows = [r for r in result["rows"] if r["family"] == family]
            levels = [r["level"] for r in rows]
            metrics = (("survival", "survival"), ("bank_rmse_deg", "bank RMSE (deg)"))
            for row, (key, label) in enumerate(metrics):
                ax = axes[row, col]
                values = [np.nan if r.get(key) is None else r[key] for r in rows]
                ax.plot(levels, values, "o-", color=f"C{index}", label=f"{airframe} / {controller}")
                ax.set(ylabel=label, title=family if row == 0 else None)
                if key == "survival":
                    ax.set_ylim(-0.05, 1.05)
                ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("Robustness of the attitude executor (true state)")
    return save_figure(fig, path)


def plot_sea_state_study(results: Results, path: str | Path) -> Path | None:
    """Water-contact rate, clearance RMSE (spans) and power saved against the sea state, one column per
    airframe and one line per controller. None without rows."""
    with_rows = {key: value for key, value in results.items() if value.get("rows")}
    if not with_rows:
        return None
    airframes = list(dict.fromkeys(a for a, _ in with_rows))
    metrics = (("water_contact_rate", "water-contact rate"), ("clearance_rmse_span", "clearance RMSE (b)"),
               ("power_saved", "power saved"))
    fig, axes = plt.subplots(len(metrics), len(airframes), figsize=(4.6 * len(airframes), 7.5), squeeze=False,
                             sharex=True)
    for (airframe, controller), result in with_rows.items():
        rows = result["rows"]
        codes = [r["sea_state"] for r in rows]
        for row, (key, label) in enumerate(metrics):
            ax = axes[row, airframes.index(airframe)]
            values = [np.nan if r.get(key) is None else r[key] for r in rows]
            ax.plot(codes, values, "o-", label=controller)
            ax.set(ylabel=label, title=airframe if row == 0 else None)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("sea state (WMO code)")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Sea skimming at 0.25 b clearance against the sea state")
    return save_figure(fig, path)


def plot_landing_study(results: Results, path: str | Path) -> Path | None:
    """The touchdown's sink rate and the float in ground effect's band, ground effect on against off, one
    group of bars per airframe and controller. None without rows."""
    with_rows = {key: value for key, value in results.items() if value.get("rows")}
    if not with_rows:
        return None
    labels = [f"{airframe}\n{controller}" for airframe, controller in with_rows]
    metrics = (("sink_rate_mps", "sink rate at touchdown (m/s)"), ("float_m", "float from one span (m)"))
    fig, axes = plt.subplots(1, len(metrics), figsize=(5.5 * len(metrics), 4.2), squeeze=False)
    x = np.arange(len(labels))
    for col, (key, label) in enumerate(metrics):
        ax = axes[0, col]
        for offset, (ground_effect, name) in ((-0.2, (True, "ground effect on")), (0.2, (False, "off"))):
            values = [next((np.nan if r.get(key) is None else r[key] for r in result["rows"]
                            if r["ground_effect"] == ground_effect), np.nan) for result in with_rows.values()]
            ax.bar(x + offset, values, width=0.4, label=name)
        ax.set_xticks(x, labels, fontsize=8)
        ax.set(ylabel=label)
        ax.grid(alpha=0.3, axis="y")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("Landing: what ground effect does to the touchdown and the float")
    return save_figure(fig, path)
