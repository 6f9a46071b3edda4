"""``falcon-rl validate jsbsim``: cross-validate an airframe against its JSBSim export."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..airframe import load_airframe
from ._common import UsageError, emit

NAME = "validate"
HELP = "cross-simulator validation: fly an airframe and its JSBSim export, print r and RMSE per channel"


def _floats(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from exc
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def _names(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", choices=["jsbsim"], help="simulator to compare against")
    parser.add_argument("--airframe", required=True, help="shipped name or path to a JSON file")
    parser.add_argument("--heights", type=_floats, default=(1.0, 10.0, 100.0),
                        help="initial CG heights, m, comma-separated (default 1,10,100)")
    parser.add_argument("--duration", type=float, default=10.0, help="seconds per run (default 10)")
    parser.add_argument("--ground-effect", type=_names, default=("off", "on", "both"),
                        help="settings: off (both off), on (falcon-rl only, as in the paper), "
                             "both (JSBSim export with the same correction); default off,on,both")
    parser.add_argument("--excitation", type=_names, default=("trim", "doublet"),
                        help="trim (zero-input free flight) and/or doublet (elevator); default both")
    parser.add_argument("--doublet-amplitude", type=float, default=0.05,
                        help="elevator doublet amplitude, normalised command units (default 0.05)")
    parser.add_argument("--all-channels", action="store_true",
                        help="also print the other channels (alpha, beta, attitude, rates, u v w, position)")
    parser.add_argument("--out", default="runs/validate", help="folder for the PNGs and the JSBSim export")


def run(args: argparse.Namespace) -> int:
    from ..validation.jsbsim_compare import EXCITATIONS, GE_SETTINGS, HEADLINE, Doublet, validate_jsbsim
    from ..validation.jsbsim_fly import CHANNELS
    from ..validation.jsbsim_report import format_table, plot_overlays

    airframe = load_airframe(args.airframe)
    if not args.duration > 0:
        raise UsageError(f"--duration must be > 0, got {args.duration}")
    if any(not h > 0 for h in args.heights):
        raise UsageError(f"--heights must be > 0, got {list(args.heights)}")
    bad = [g for g in args.ground_effect if g not in GE_SETTINGS]
    if bad or not args.ground_effect:
        raise UsageError(f"--ground-effect takes {list(GE_SETTINGS)}, got {list(args.ground_effect)}")
    bad = [e for e in args.excitation if e not in EXCITATIONS]
    if bad or not args.excitation:
        raise UsageError(f"--excitation takes {list(EXCITATIONS)}, got {list(args.excitation)}")
    if not 0 < args.doublet_amplitude <= 1:
        raise UsageError(f"--doublet-amplitude must be in (0, 1], got {args.doublet_amplitude}")
    try:
        import jsbsim  # noqa: F401
    except ImportError as exc:
        raise UsageError("the jsbsim package is not installed: pip install 'falcon-rl[jsbsim]'") from exc
    out = Path(args.out)
    doublet = Doublet(amplitude=args.doublet_amplitude)
    results = validate_jsbsim(airframe, out / "jsbsim", args.heights, args.ground_effect, args.excitation,
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
