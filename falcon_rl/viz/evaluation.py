"""Figures of the evaluation protocols (PNG, Agg)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import torch

from ..evaluation.protocols import ProtocolResult
from ._figure import save_figure


def plot_altitude(result: ProtocolResult, path: Path, shown: int = 10) -> Path:
    """Achieved vs commanded altitude for ``shown`` episodes, the error band over all episodes,
    elevator and throttle traces."""
    tr = result.traces["altitude"]["next"]
    t = tr["state", "time"][0].cpu()
    height, target = tr["state", "height"].cpu(), tr["task", "target_altitude"].cpu()
    reference = tr["task", "reference_altitude"].cpu()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7))
    ax = axes[0, 0]
    for i in range(min(shown, height.shape[0])):
        ax.plot(t, height[i], color=f"C{i % 10}", lw=1.2)
        ax.plot(t, reference[i], color=f"C{i % 10}", lw=0.8, ls="--")
    ax.set(title="achieved (solid) vs reference (dashed)", xlabel="time (s)", ylabel="height (m)")
    ax = axes[0, 1]
    err = height - target
    q = torch.quantile(err, torch.tensor([0.05, 0.5, 0.95]), dim=0)
    ax.fill_between(t, q[0], q[2], alpha=0.3, label="5-95 %")
    ax.plot(t, q[1], label="median")
    ax.axhspan(-1, 1, color="g", alpha=0.1, label="+-1 m capture band")
    ax.set(title=f"altitude error, all {height.shape[0]} episodes", xlabel="time (s)", ylabel="h - h* (m)")
    ax.set_ylim(-20, 20)
    ax.legend(fontsize=8)
    surfaces, throttle = tr["state", "surface_position"].cpu(), tr["state", "throttle"].cpu()
    for i in range(min(shown, height.shape[0])):
        axes[1, 0].plot(t, torch.rad2deg(surfaces[i, :, 0]), color=f"C{i % 10}", lw=0.8)
        axes[1, 1].plot(t, throttle[i, :, 0], color=f"C{i % 10}", lw=0.8)
    axes[1, 0].set(xlabel="time (s)", ylabel="elevator (deg)")
    axes[1, 1].set(xlabel="time (s)", ylabel="throttle")
    for a in axes.flat:
        a.grid(alpha=0.3)
    s = result.summary
    fig.suptitle(f"{result.controller} on {result.airframe}: survival {s['survival']:.2f}, "
                 f"acquisition {s['acquisition']:.2f}, RMSE {s['rmse_m']:.3g} m")
    return save_figure(fig, path)


def plot_attitude(result: ProtocolResult, path: Path) -> Path:
    """The attitude protocol's figure of one result: :func:`plot_bank_facets` of it alone."""
    return plot_bank_facets([result], path)


def plot_bank_facets(results: list[ProtocolResult], path: Path) -> Path:
    """Rows: maneuvers; columns: controllers. Commanded (dashed) vs achieved bank, +-8.6 deg band."""
    maneuvers = list(results[0].traces)
    fig, axes = plt.subplots(len(maneuvers), len(results), figsize=(4.2 * len(results), 2.4 * len(maneuvers)),
                             squeeze=False, sharex="row")
    for col, r in enumerate(results):
        for row, name in enumerate(maneuvers):
            ax = axes[row, col]
            tr = r.traces[name]["next"]
            t = tr["state", "time"][0].cpu()
            cmd = torch.rad2deg(tr["task", "bank_command"][0].cpu())
            ax.fill_between(t, cmd - 8.6, cmd + 8.6, color="0.85")
            ax.plot(t, cmd, "k--", lw=1)
            ax.plot(t, torch.rad2deg(tr["state", "euler"][0, :, 0].cpu()), lw=1.2)
            rmse = r.summary.get(f"{name}/bank_rmse_deg", math.nan)
            band = r.summary.get(f"{name}/bank_time_in_band", math.nan)
            ax.set_title(f"{r.controller} / {name}: {rmse:.2f} deg, {band:.2f} in band", fontsize=9)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel("bank (deg)")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    return save_figure(fig, path, dpi=100)
