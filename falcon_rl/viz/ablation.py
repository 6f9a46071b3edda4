"""Bar figure of an ablation study: the change of each task's headline metric per simplified
phenomenon, one panel per task, one bar group per arm, one bar per controller (PNG, Agg)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from ..evaluation.ablation import FULL, AblationResult
from ._figure import save_figure


def plot_ablation(results: list[AblationResult], path: Path) -> Path:
    """Save the figure of ``results`` (from ``run_ablation``) to ``path``; returns the path."""
    tasks = list(dict.fromkeys(r.task for r in results))
    fig, axes = plt.subplots(1, len(tasks), figsize=(6.5 * len(tasks), 4.2), squeeze=False)
    for ax, task in zip(axes[0], tasks, strict=True):
        rows = [r for r in results if r.task == task]
        arms = [arm for arm in rows[0].values if arm != FULL]
        width = 0.8 / len(rows)
        y = np.arange(len(arms))
        for k, r in enumerate(rows):
            changes = [r.change(arm) for arm in arms]
            offsets = y + (k - (len(rows) - 1) / 2) * width
            ax.barh(offsets, changes, height=width,
                    label=f"{r.controller} (full {r.values[FULL]:.3g} {r.unit})")
            for offset, change in zip(offsets, changes, strict=True):
                if not math.isfinite(change):  # no episode survived to be scored
                    ax.text(0.0, offset, f" {r.controller}: every episode lost", va="center", fontsize=7)
        ax.set_yticks(y, arms)
        ax.invert_yaxis()
        ax.axvline(0.0, color="black", lw=0.8)
        ax.set_xlabel(f"change of {rows[0].headline} vs the full model ({rows[0].unit})")
        ax.set_title(f"{task} on {rows[0].airframe}")
        ax.grid(alpha=0.3, axis="x")
        ax.legend(fontsize=8)
    fig.suptitle("ablation: one phenomenon simplified at a time")
    return save_figure(fig, path)
