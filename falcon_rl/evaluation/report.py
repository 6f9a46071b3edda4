"""Tables of protocol results in the paper's layout: markdown for people, JSON for programs."""

from __future__ import annotations

import json
import math
from pathlib import Path

from .protocols import ProtocolResult

ALTITUDE_COLUMNS = (("survival", "Surv."), ("acquisition", "Acq."), ("rmse_m", "RMSE (m)"),
                    ("settling_time_s", "t_s (s)"), ("overshoot_m", "Over. (m)"))
ATTITUDE_COLUMNS = (("bank_rmse_deg", "bank RMSE (deg)"), ("bank_time_in_band", "in band"),
                    ("climb_rate_rmse_mps", "hdot RMSE (m/s)"), ("airspeed_rmse_mps", "V RMSE (m/s)"),
                    ("survival", "Surv."))


def _fmt(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "---"
    return f"{value:.3g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.1e}"


def altitude_table(results: list[ProtocolResult]) -> str:
    """| Airframe | Alg. | n | Surv. | Acq. | RMSE (m) | t_s (s) | Over. (m) | plan time |"""
    head = "| Airframe | Alg. | n | " + " | ".join(h for _, h in ALTITUDE_COLUMNS) + " | s / control step |"
    lines = [head, "|" + "---|" * (len(ALTITUDE_COLUMNS) + 4)]
    for r in results:
        cells = [_fmt(r.summary.get(k, math.nan)) for k, _ in ALTITUDE_COLUMNS]
        lines.append(f"| {r.airframe} | {r.controller} | {r.settings['episodes']} | " + " | ".join(cells)
                     + f" | {r.seconds_per_control_step:.2e} |")
    return "\n".join(lines)


def attitude_table(results: list[ProtocolResult]) -> str:
    """One row per airframe, controller and maneuver."""
    head = "| Airframe | Alg. | Maneuver | " + " | ".join(h for _, h in ATTITUDE_COLUMNS) + " |"
    lines = [head, "|" + "---|" * (len(ATTITUDE_COLUMNS) + 3)]
    for r in results:
        for name in r.settings["maneuvers"]:  # type: ignore[union-attr]
            cells = [_fmt(r.summary.get(f"{name}/{k}", math.nan)) for k, _ in ATTITUDE_COLUMNS]
            lines.append(f"| {r.airframe} | {r.controller} | {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def result_document(result: ProtocolResult) -> dict:
    """JSON-ready summary: the table's fields by name plus the settings that produced them."""
    return {"task": result.task, "airframe": result.airframe, "controller": result.controller,
            **{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in result.summary.items()},
            "seconds_per_control_step": result.seconds_per_control_step, "settings": result.settings}


def write_report(results: list[ProtocolResult], out: Path, figures: list[Path], title: str) -> Path:
    """Write ``report.md`` and ``results.json`` under ``out``; returns the markdown path."""
    out.mkdir(parents=True, exist_ok=True)
    altitude = [r for r in results if r.task == "altitude"]
    attitude = [r for r in results if r.task == "attitude"]
    lines = [f"# {title}", ""]
    if altitude:
        lines += ["## Altitude acquisition and hold", "", altitude_table(altitude), ""]
    if attitude:
        lines += ["## Attitude maneuvers", "", attitude_table(attitude), ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    report = out / "report.md"
    report.write_text("\n".join(lines) + "\n")
    (out / "results.json").write_text(json.dumps([result_document(r) for r in results], indent=2,
                                                 default=str))
    return report
