"""Tables (the reference paper's layout) and overlay figures of JSBSim cross-validation runs."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from .jsbsim_compare import HEADLINE, CaseResult
from .jsbsim_fly import CHANNELS

GE_LABEL = {"off": "GE off", "on": "GE on (falcon-rl only)", "both": "GE on (both)"}
TITLE = {"altitude": "Altitude", "pitch_rate": "Pitch rate", "airspeed": "Airspeed"}
DEG = 57.29577951308232
PLOTTED = (("altitude", 1.0, "altitude (m)"), ("pitch_rate", DEG, "pitch rate (deg/s)"),
           ("airspeed", 1.0, "airspeed (m/s)"), ("alpha", DEG, "alpha (deg)"))
#: The panels of an imported airframe's comparison (``jsbsim_model_compare``).
PLOTTED_MODEL = (*PLOTTED, ("roll_rate", DEG, "roll rate (deg/s)"), ("phi", DEG, "bank (deg)"))


def _cell(metrics: dict[str, float | None], unit: str) -> str:
    r = "   -   " if metrics["r"] is None else f"{metrics['r']:.5f}"
    return f"{r} ({metrics['rmse']:.1e} {unit})"


def format_table(results: Sequence[CaseResult], channels: Sequence[str] = HEADLINE,
                 attribute: str = "metrics") -> str:
    """One block per (airframe, excitation): rows are 'h0 = .. m, GE ..', cells 'r (RMSE unit)' of each
    result's ``attribute`` ("metrics", or "response" where it was flown). r is '-' where a channel stays
    constant (zero-input flight from trim)."""
    blocks = []
    keys = dict.fromkeys((r.airframe, r.case.excitation) for r in results)
    for airframe, excitation in keys:
        rows = [r for r in results if (r.airframe, r.case.excitation) == (airframe, excitation)]
        width = max(len(_condition(r)) for r in rows) + 2
        head = "Condition".ljust(width) + "".join(TITLE.get(c, c).ljust(27) for c in channels)
        lines = [f"{airframe}: {excitation}, Pearson r (RMSE) falcon-rl vs JSBSim, "
                 f"{rows[0].falcon.time[-1]:g} s", head, "-" * len(head.rstrip())]
        for r in rows:
            cells = "".join(_cell(getattr(r, attribute)[c], CHANNELS[c]).ljust(27) for c in channels)
            flag = f"  [min altitude {r.min_altitude:.2f} m: below ground]" if r.min_altitude <= 0 else ""
            lines.append(_condition(r).ljust(width) + cells.rstrip() + flag)
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def _condition(r: CaseResult) -> str:
    return f"h0 = {r.case.height:g} m, {GE_LABEL[r.case.ground_effect]}"


def plot_overlays(results: Sequence[CaseResult], directory: str | Path,
                  plotted: Sequence[tuple[str, float, str]] = PLOTTED) -> list[Path]:
    """One PNG per (airframe, excitation, height): the ``plotted`` channels (name, scale, label; default
    altitude, pitch rate, airspeed and alpha) of both simulators (falcon-rl solid, JSBSim dashed), one
    colour per ground-effect setting."""
    out = []
    groups = dict.fromkeys((r.airframe, r.case.excitation, r.case.height) for r in results)
    for airframe, excitation, height in groups:
        rows = [r for r in results if (r.airframe, r.case.excitation, r.case.height) ==
                (airframe, excitation, height)]
        rows_n = (len(plotted) + 1) // 2
        fig, axes = plt.subplots(rows_n, 2, figsize=(10, 3.2 * rows_n), dpi=110, sharex=True)
        for i, r in enumerate(rows):
            for ax, (name, scale, label) in zip(axes.flat, plotted, strict=False):
                ax.plot(r.falcon.time, r.falcon.channels[name] * scale, color=f"C{i}", lw=1.4,
                        label=f"falcon-rl, {GE_LABEL[r.case.ground_effect]}")
                ax.plot(r.jsbsim.time, r.jsbsim.channels[name] * scale, color=f"C{i}", lw=1.2, ls="--",
                        label=f"JSBSim, {GE_LABEL[r.case.ground_effect]}")
                ax.set_ylabel(label)
                ax.grid(True, alpha=0.3)
        for ax in axes[-1]:
            ax.set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7)
        fig.suptitle(f"{airframe}: {excitation} from trim at h0 = {height:g} m")
        fig.tight_layout()
        label = re.sub(r"[^A-Za-z0-9.]+", "_", excitation)  # "elevator 50 m/s" -> "elevator_50_m_s"
        path = Path(directory) / f"{airframe}_{label}_h{height:g}m.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path)
        plt.close(fig)
        out.append(path)
    return out
