"""``falcon-rl ge-table``: trim thrust with and without ground effect against h/b."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..airframe import load_airframe
from ..evaluation.ground_effect_table import format_table, ground_effect_table, rows_as_dicts
from ..viz.ground_effect import plot_ground_effect
from ._common import UsageError, emit

NAME = "ge-table"
HELP = "ground-effect thrust table (trim on/off and lifting-line theory at h/b 0.25..6) + PNG"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--airframe", required=True, help="shipped name or path to a JSON file")
    parser.add_argument("--airspeed", type=float, default=None, help="m/s (default: cruise)")
    parser.add_argument("--ground-effect-model", choices=["induced", "paper"], default="induced")
    parser.add_argument("--out", default="runs/ge-table", help="folder for the PNG")


def run(args: argparse.Namespace) -> int:
    airframe = load_airframe(args.airframe)
    if args.airspeed is not None and not args.airspeed > 0:
        raise UsageError(f"--airspeed must be > 0, got {args.airspeed}")
    rows = ground_effect_table(airframe, args.airspeed, model=args.ground_effect_model)
    png = plot_ground_effect({airframe.name: rows}, Path(args.out) / f"{airframe.name}.png")
    doc = {"airframe": airframe.name, "ground_effect_model": args.ground_effect_model,
           "airspeed_mps": args.airspeed or airframe.envelope.cruise_speed,
           "rows": rows_as_dicts(rows), "plot": str(png)}
    emit(args, doc, format_table(airframe.name, rows) + f"\n\nplot: {png}")
    return 0
