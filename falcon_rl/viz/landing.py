"""The landing protocol's figure (PNG, Agg): the approaches against the glide path, the flare, and where
and how hard each touched down."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ..evaluation.landing import LATERAL_LIMIT, LONGITUDINAL_LIMIT, SINK_LIMIT
from ..evaluation.protocols import ProtocolResult
from ._figure import save_figure


def plot_landing(result: ProtocolResult, path: Path, shown: int = 8) -> Path:
    """Left: height against the distance to the aim point for ``shown`` episodes with the glide path
    (dashed); middle: the last 60 m (the flare), wheel height; right: the touchdowns' positions coloured by
    sink rate, with the limits' box."""
    tr = result.traces["landing"]["next"]
    done = tr["done"].reshape(tr["done"].shape[0], -1).cpu().bool()
    alive = (done.long().cumsum(-1) - done.long()) == 0  # the first episode of each row
    north = tr["state", "position_ned"][..., 0].cpu()
    height, glide = tr["state", "height"].cpu(), tr["task", "glide_path_height"].cpu()
    wheels = tr["task", "wheel_height"].cpu()
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(14, 4.5))
    for i in range(min(shown, north.shape[0])):
        keep = alive[i]
        left.plot(north[i][keep], height[i][keep], color=f"C{i % 10}", lw=1.0)
        left.plot(north[i][keep], glide[i][keep], color=f"C{i % 10}", lw=0.7, ls="--")
        near = keep & (north[i] > -60.0)
        middle.plot(north[i][near], wheels[i][near], color=f"C{i % 10}", lw=1.0)
    for ax in (left, middle):
        ax.axhline(0.0, color="0.3", lw=1.2)
        ax.axvline(0.0, color="0.6", lw=0.8, ls=":")
    left.set(title="approach: height (solid) and glide path (dashed)", xlabel="north of the aim point (m)",
             ylabel="height (m)")
    middle.set(title="flare: wheels above the surface", xlabel="north of the aim point (m)",
               ylabel="wheel height (m)")
    m = result.episodes
    touched = m["touchdown"].cpu()
    points = right.scatter(m["longitudinal_m"].cpu()[touched], m["lateral_m"].cpu()[touched],
                           c=m["sink_rate_mps"].cpu()[touched], cmap="viridis", vmin=0.0, vmax=2 * SINK_LIMIT)
    fig.colorbar(points, ax=right, label="sink rate at touchdown (m/s)")
    right.add_patch(plt.Rectangle((-LONGITUDINAL_LIMIT, 0.0), 2 * LONGITUDINAL_LIMIT, LATERAL_LIMIT,
                                  fill=False, ec="k", lw=1.0, ls="--"))
    right.set(title="touchdowns (box: the limits)", xlabel="past the aim point (m)",
              ylabel="|lateral offset| (m)")
    for ax in (left, middle, right):
        ax.grid(alpha=0.3)
    s = result.summary
    fig.suptitle(f"{result.controller} on {result.airframe}: {100 * s['landed_within_limits']:.0f} % within "
                 f"the limits, sink {s['sink_rate_mps']:.2f} m/s, float {s['float_m']:.0f} m")
    fig.tight_layout()
    return save_figure(fig, path)


__all__ = ["plot_landing"]
