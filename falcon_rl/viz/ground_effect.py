"""Figure: trim-thrust change against h/b, measured and lifting-line theory, per airframe."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ..evaluation.ground_effect_trim import GroundEffectRow
from ._figure import save_figure


def plot_ground_effect(tables: dict[str, list[GroundEffectRow]], path: str | Path) -> Path:
    """Write a PNG of delta-thrust % vs h/b (log x), one colour per airframe."""
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=130)
    for i, (name, rows) in enumerate(tables.items()):
        color = f"C{i}"
        x = [r.h_over_b for r in rows]
        ax.plot(x, [r.delta_percent for r in rows], "o-", color=color, label=f"{name}: trim")
        ax.plot(x, [r.theory_percent for r in rows], "s--", color=color, alpha=0.6,
                label=f"{name}: theory (fixed $C_L$)")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xscale("log")
    ticks = sorted({r.h_over_b for rows in tables.values() for r in rows})
    ax.set_xticks(ticks, [f"{t:g}" for t in ticks])
    ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
    ax.set_xlabel("height over span h/b")
    ax.set_ylabel("trim thrust change with ground effect (%)")
    ax.set_title("Ground effect: thrust demand in level flight at cruise speed")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return save_figure(fig, path, dpi=100)
