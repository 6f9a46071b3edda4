"""``falcon-rl airframes``: the shipped airframes and their key numbers."""

from __future__ import annotations

import argparse

from ._common import emit

NAME = "airframes"
HELP = "list the shipped airframes (span, area, aspect ratio, taper, mass, speeds)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    del parser


def run(args: argparse.Namespace) -> int:
    from ..airframe import list_airframes, load_airframe

    rows = [load_airframe(name).summary() for name in list_airframes()]
    header = (f"{'name':<18}{'span m':>8}{'S m2':>9}{'AR':>7}{'taper':>7}{'mass kg':>10}"
              f"{'Vs':>6}{'Vcruise':>9}{'Vmax':>6}  powerplant")
    lines = [header]
    for r in rows:
        lines.append(f"{r['name']:<18}{r['span_m']:>8.3f}{r['wing_area_m2']:>9.4f}"
                     f"{r['aspect_ratio']:>7.2f}{r['taper_ratio']:>7.2f}{r['mass_kg']:>10.2f}"
                     f"{r['stall_speed_mps']:>6.1f}{r['cruise_speed_mps']:>9.2f}"
                     f"{r['max_speed_mps']:>6.1f}  {r['powerplant']}")
    emit(args, {"airframes": rows}, "\n".join(lines))
    return 0
