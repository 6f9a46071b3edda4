"""The sea-skimming protocol's figure (PNG, Agg): the flight over the waves and the clearance it held."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ..evaluation.protocols import ProtocolResult
from ._figure import save_figure


def plot_sea_skimming(result: ProtocolResult, path: Path, shown: int = 6) -> Path:
    """Top: the first episode's height over the water under it; bottom left: the altimeter's clearance
    (solid) against the command (dashed) for ``shown`` episodes; bottom right: the lower tip's clearance."""
    tr = result.traces["sea_skimming"]["next"]
    t = tr["state", "time"][0].cpu()
    done = tr["done"].reshape(tr["done"].shape[0], -1).cpu().bool()
    alive = (done.long().cumsum(-1) - done.long()) == 0  # the first episode of each row
    clearance, commanded = tr["task", "clearance"].cpu(), tr["task", "commanded_clearance"].cpu()
    tip = tr["task", "lowest_tip_clearance"].cpu()
    fig = plt.figure(figsize=(11, 7))
    top = fig.add_subplot(2, 1, 1)
    first = alive[0]
    top.fill_between(t[first], tr["task", "surface_elevation"][0].cpu()[first], -10.0, color="#2b6a9a",
                     alpha=0.6, label="water under the aircraft")
    top.plot(t[first], tr["state", "height"][0].cpu()[first], "k", lw=1.2, label="aircraft (CG)")
    low = float(tr["task", "surface_elevation"][0].cpu()[first].min())
    top.set_ylim(low - 0.3, float(tr["state", "height"][0].cpu()[first].max()) + 0.5)
    top.set(title="episode 0 over the waves", xlabel="time (s)", ylabel="height above mean sea level (m)")
    top.legend(fontsize=8, loc="upper right")
    left, right = fig.add_subplot(2, 2, 3), fig.add_subplot(2, 2, 4)
    for i in range(min(shown, clearance.shape[0])):
        keep = alive[i]
        left.plot(t[keep], clearance[i][keep], color=f"C{i % 10}", lw=1.0)
        left.plot(t[keep], commanded[i][keep], color=f"C{i % 10}", lw=0.8, ls="--")
        right.plot(t[keep], tip[i][keep], color=f"C{i % 10}", lw=1.0)
    right.axhline(0.0, color="#2b6a9a", lw=1.5)
    left.set(title="altimeter clearance (solid) vs command (dashed)", xlabel="time (s)",
             ylabel="clearance (m)")
    right.set(title="lower wing tip above the water", xlabel="time (s)", ylabel="clearance (m)")
    for ax in (top, left, right):
        ax.grid(alpha=0.3)
    s, cfg = result.summary, result.settings
    fig.suptitle(f"{result.controller} on {result.airframe}, sea state {cfg.get('sea_state')}: contacts "
                 f"{s['water_contact_rate']:.2f}, RMSE {s['clearance_rmse_span']:.3f} b, power saved "
                 f"{100 * s['power_saved']:.1f} %")
    fig.tight_layout()
    return save_figure(fig, path)


__all__ = ["plot_sea_skimming"]
