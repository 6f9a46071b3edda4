"""``falcon-rl demo``: the main job on embedded defaults.

For now (physics core): trim every shipped airframe at cruise, print the ground-effect thrust table
for each and write the figure and a markdown report under ``runs/demo``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from ..airframe import list_airframes, load_airframe
from ..cli import emit
from ..evaluation.ground_effect_table import format_table, ground_effect_table, rows_as_dicts
from ..physics.trim import trim_level
from ..viz.ground_effect import plot_ground_effect

NAME = "demo"
HELP = "run the main job on embedded defaults (trims, ground-effect table, figures in runs/demo)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="runs/demo", help="output folder")


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    trims, tables = {}, {}
    for name in tqdm(list_airframes(), desc="trim + ground-effect table", unit="airframe"):
        airframe = load_airframe(name)
        trims[name] = trim_level(airframe, airframe.envelope.cruise_speed, 100.0).row(0)
        tables[name] = ground_effect_table(airframe)
    png = plot_ground_effect(tables, out / "ground_effect.png")
    lines = ["# falcon-rl demo", "", "## Trim at cruise, 100 m", "",
             "| airframe | V (m/s) | alpha (deg) | elevator (deg) | throttle | thrust (N) | C_L | C_D |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in trims.items():
        lines.append(f"| {name} | {r['airspeed_mps']:.2f} | {r['alpha_deg']:.2f} | "
                     f"{r['elevator_deg']:.2f} | {r['throttle']:.3f} | {r['thrust_n']:.4g} | "
                     f"{r['lift_coefficient']:.3f} | {r['drag_coefficient']:.4f} |")
    lines += ["", "## Ground effect on trim thrust", ""]
    lines += [format_table(name, rows) + "\n" for name, rows in tables.items()]
    lines += [f"![ground effect]({png.name})", ""]
    report = out / "report.md"
    report.write_text("\n".join(lines))
    doc = {"trim": trims, "ge_table": {k: rows_as_dicts(v) for k, v in tables.items()},
           "report": str(report), "plot": str(png)}
    emit(args, doc, "\n".join(lines) + f"\nreport: {report}\nplot: {png}")
    return 0
