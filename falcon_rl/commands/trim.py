"""``falcon-rl trim``: straight-and-level trim of an airframe at an airspeed and height."""

from __future__ import annotations

import argparse

from ._common import MAX_AIRSPEED, MAX_HEIGHT, bounded_float, emit

NAME = "trim"
HELP = "trim straight and level flight: alpha, elevator, throttle, thrust, drag, C_L, C_D, C_Di"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--airframe", required=True, help="shipped name or path to a JSON file")
    parser.add_argument("--airspeed", type=bounded_float(0.0, MAX_AIRSPEED, "m/s"), default=None,
                        help="m/s (default: cruise)")
    parser.add_argument("--height", type=bounded_float(0.0, MAX_HEIGHT, "m"), default=100.0,
                        help="m above ground (default 100)")
    parser.add_argument("--ground-effect", choices=["induced", "paper", "off"], default="induced",
                        help="the Phillips-Hunsaker correction of the induced drag only (default), the "
                             "paper's whole-drag form, or none")


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..physics.trim import trim_level

    airframe = load_airframe(args.airframe)
    airspeed = airframe.envelope.cruise_speed if args.airspeed is None else args.airspeed
    ge = False if args.ground_effect == "off" else args.ground_effect
    row = trim_level(airframe, airspeed, args.height, ground_effect=ge).row(0)
    doc = {"airframe": airframe.name, "ground_effect": ge or "off", **row}
    text = "\n".join(f"{k:<26}{v:.6g}" if isinstance(v, float) else f"{k:<26}{v}"
                     for k, v in doc.items())
    emit(args, doc, text)
    return 0
