"""``falcon-rl validate jsbsim``: cross-validate an airframe against its JSBSim export."""

from __future__ import annotations

import argparse

from ._common import MAX_HEIGHT, UsageError, bounded_float, comma_list, emit, output_dir

NAME = "validate"
HELP = "cross-simulator validation: fly an airframe and its JSBSim export, print r and RMSE per channel"

#: Ground-effect settings and excitations (the keys of ``validation.jsbsim_compare``'s GE_SETTINGS and
#: its EXCITATIONS; tests/test_bad_inputs_cli.py checks that they agree).
GROUND_EFFECT = ("off", "on", "both")
EXCITATIONS = ("trim", "doublet")
_height = bounded_float(0.0, MAX_HEIGHT, "m")


def _heights(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated heights, each in (0, MAX_HEIGHT] m."""
    values = tuple(_height(v.strip()) for v in text.split(",") if v.strip())
    if not values:
        raise argparse.ArgumentTypeError(f"expected comma-separated heights in m, got {text!r}")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", choices=["jsbsim"], help="simulator to compare against")
    parser.add_argument("--airframe", required=True, help="shipped name or path to a JSON file")
    parser.add_argument("--heights", type=_heights, default=(1.0, 10.0, 100.0),
                        help="initial CG heights, m, comma-separated (default 1,10,100)")
    parser.add_argument("--duration", type=bounded_float(0.0, 3600.0, "s"), default=10.0,
                        help="seconds per run (default 10)")
    parser.add_argument("--ground-effect", default="off,on,both",
                        help="settings: off (both off), on (falcon-rl only, as in the paper), "
                             "both (JSBSim export with the same correction); default off,on,both")
    parser.add_argument("--excitation", default="trim,doublet",
                        help="trim (zero-input free flight) and/or doublet (elevator); default both")
    parser.add_argument("--doublet-amplitude", type=bounded_float(0.0, 1.0), default=0.05,
                        help="elevator doublet amplitude, normalised command units (default 0.05)")
    parser.add_argument("--all-channels", action="store_true",
                        help="also print the other channels (alpha, beta, attitude, rates, u v w, position)")
    parser.add_argument("--out", default="runs/validate", help="folder for the PNGs and the JSBSim export")


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe

    airframe = load_airframe(args.airframe)
    ground_effect = tuple(comma_list(args.ground_effect, "--ground-effect", GROUND_EFFECT))
    excitation = tuple(comma_list(args.excitation, "--excitation", EXCITATIONS))
    try:
        import jsbsim  # noqa: F401
    except ImportError as exc:
        raise UsageError("the jsbsim package is not installed: pip install 'falcon-rl[jsbsim]'") from exc
    out = output_dir(args.out)
    return _validate(args, airframe, out, ground_effect, excitation)


def _validate(args: argparse.Namespace, airframe, out, ground_effect: tuple[str, ...],
              excitation: tuple[str, ...]) -> int:
    """Fly, compare, plot and print (the inputs are checked)."""
    from ..validation.jsbsim_compare import HEADLINE, Doublet, validate_jsbsim
    from ..validation.jsbsim_fly import CHANNELS
    from ..validation.jsbsim_report import format_table, plot_overlays

    doublet = Doublet(amplitude=args.doublet_amplitude)
    results = validate_jsbsim(airframe, out / "jsbsim", args.heights, ground_effect, excitation,
                              args.duration, doublet=doublet, progress=True)
    plots = plot_overlays(results, out)
    doc = {"airframe": airframe.name, "target": "jsbsim", "duration_s": args.duration, "dt_s": 0.01,
           "doublet": {"amplitude": doublet.amplitude, "start_s": doublet.start, "width_s": doublet.width},
           "jsbsim_aircraft": str(out / "jsbsim" / "aircraft" / airframe.name / f"{airframe.name}.xml"),
           "rows": [r.row() for r in results], "plots": [str(p) for p in plots]}
    text = format_table(results)
    if args.all_channels:
        text += "\n\n" + format_table(results, [c for c in CHANNELS if c not in HEADLINE])
    emit(args, doc, text + f"\n\nJSBSim aircraft: {doc['jsbsim_aircraft']}\nplots: {out}/")
    return 0
