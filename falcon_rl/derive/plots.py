"""PNG of the AeroBuildup sweep against the fitted tables: one panel per coefficient."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ..constants import DEG
from .build import COEFFICIENTS, Derived
from .fit import evaluate

# (coefficient, sweep group, x column, label): longitudinal against alpha, lateral against beta
PANELS = (("CL", "alpha", 0, "alpha"), ("CD", "alpha", 0, "alpha"), ("Cm", "elevator", 0, "alpha"),
          ("CY", "beta", 1, "beta"), ("Cl", "aileron", 0, "alpha"), ("Cn", "rudder", 0, "alpha"))


def plot_fit(derived: Derived, path: str | Path) -> Path:
    """Sweep points (markers) and fit (lines) per panel; colour = the other swept variable."""
    s, fits = derived.sweep, derived.fits
    fig, axes = plt.subplots(2, 3, figsize=(12, 7), dpi=110)
    for ax, (name, group, col, label) in zip(axes.ravel(), PANELS, strict=True):
        k = COEFFICIENTS.index(name)
        sel = (s.group == group) & ~s.held_out
        other = {"alpha": None, "beta": 0, "elevator": 2, "aileron": 3, "rudder": 4}[group]
        keys = [0.0] if other is None else sorted(set(np.round(s.x[sel, other], 9)))
        for i, key in enumerate(keys):
            rows = sel if other is None else sel & np.isclose(s.x[:, other], key)
            x = s.x[rows]
            order = np.argsort(x[:, col])
            colour = plt.cm.viridis(i / max(1, len(keys) - 1))
            ax.plot(x[order, col] / DEG, s.coefficients[rows, k][order], "o", ms=3, color=colour)
            dense = np.repeat(x[order][:1], 200, axis=0)
            dense[:, col] = np.linspace(x[:, col].min(), x[:, col].max(), 200)
            ax.plot(dense[:, col] / DEG, evaluate(dense, fits[name].terms, fits[name].coefs), "-", lw=1,
                    color=colour, label=None if other is None else f"{group} {key / DEG:+.1f} deg")
        r = fits[name]
        ax.set_title(f"{name}: rms held-out {r.rms_held_out:.2g}", fontsize=9)
        ax.set_xlabel(f"{label} (deg)")
        ax.grid(alpha=0.3)
        if other is not None and len(keys) <= 10:
            ax.legend(fontsize=6)
    fig.suptitle(f"{derived.spec.display_name}: AeroBuildup sweep (markers) vs fitted table (lines)")
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
