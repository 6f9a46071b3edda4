"""``falcon-rl ge-table``: trim thrust with and without ground effect against h/b."""

from __future__ import annotations

import argparse

from ._common import MAX_AIRSPEED, bounded_float, emit, inside, output_dir

NAME = "ge-table"
HELP = "ground-effect thrust table (trim on/off and lifting-line theory at h/b 0.25..6) + PNG"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--airframe", required=True, help="shipped name or path to a JSON file")
    parser.add_argument("--airspeed", type=bounded_float(0.0, MAX_AIRSPEED, "m/s"), default=None,
                        help="m/s (default: cruise)")
    parser.add_argument("--ground-effect", choices=["induced", "paper"], default="induced",
                        help="the correction of the 'on' column: induced drag only (default) or the paper's "
                             "whole-drag form")
    parser.add_argument("--out", default="runs/ge-table", help="folder for the PNG (default runs/ge-table)")


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..evaluation.ground_effect_trim import format_table, ground_effect_table, rows_as_dicts
    from ..viz.ground_effect import plot_ground_effect

    airframe = load_airframe(args.airframe)
    figure = inside(output_dir(args.out), f"{airframe.name}.png", "airframe name")
    rows = ground_effect_table(airframe, args.airspeed, model=args.ground_effect)
    png = plot_ground_effect({airframe.name: rows}, figure)
    doc = {"airframe": airframe.name, "ground_effect": args.ground_effect,
           "airspeed_mps": args.airspeed or airframe.envelope.cruise_speed,
           "rows": rows_as_dicts(rows), "plot": str(png)}
    emit(args, doc, format_table(airframe.name, rows) + f"\n\nplot: {png}")
    return 0
