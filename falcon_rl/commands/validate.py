"""``falcon-rl validate jsbsim``: cross-validate an airframe against its JSBSim export, or (with
``--jsbsim-model NAME``) an imported airframe against the JSBSim aircraft it came from."""

from __future__ import annotations

import argparse
import importlib.util

from ._common import MAX_HEIGHT, UsageError, bounded_float, comma_list, emit, output_dir

NAME = "validate"
HELP = "cross-simulator validation: fly an airframe and its JSBSim export, print r and RMSE per channel"

#: Ground-effect settings and excitations (the keys of ``validation.jsbsim_compare``'s GE_SETTINGS and
#: its EXCITATIONS; tests/test_bad_inputs_cli.py checks that they agree).
GROUND_EFFECT = ("off", "on", "both")
EXCITATIONS = ("trim", "doublet")
_height = bounded_float(0.0, MAX_HEIGHT, "m")
_speed = bounded_float(0.0, 200.0, "m/s")
MODEL_AIRSPEEDS = (40.0, 45.0, 50.0)
MODEL_HEIGHTS = (10.0, 300.0)


def _heights(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated heights, each in (0, MAX_HEIGHT] m."""
    values = tuple(_height(v.strip()) for v in text.split(",") if v.strip())
    if not values:
        raise argparse.ArgumentTypeError(f"expected comma-separated heights in m, got {text!r}")
    return values


def _speeds(text: str) -> tuple[float, ...]:
    """argparse type: comma-separated airspeeds, each in (0, 200] m/s."""
    values = tuple(_speed(v.strip()) for v in text.split(",") if v.strip())
    if not values:
        raise argparse.ArgumentTypeError(f"expected comma-separated airspeeds in m/s, got {text!r}")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("target", choices=["jsbsim"], help="simulator to compare against")
    parser.add_argument("--airframe", help="shipped name or path to a JSON file (required unless "
                        "--jsbsim-model is given; then default jsbsim_NAME)")
    parser.add_argument("--jsbsim-model", help="fly JSBSim's own aircraft NAME against the imported airframe "
                        "(elevator and aileron doublets and free flight from each model's level trim)")
    parser.add_argument("--airspeeds", type=_speeds, default=MODEL_AIRSPEEDS,
                        help="with --jsbsim-model: trim airspeeds, m/s, comma-separated (default 40,45,50)")
    parser.add_argument("--heights", type=_heights, default=None,
                        help="initial CG heights, m, comma-separated (default 1,10,100; 10,300 with "
                             "--jsbsim-model)")
    parser.add_argument("--duration", type=bounded_float(0.0, 3600.0, "s"), default=None,
                        help="seconds per run (default 10; 20 with --jsbsim-model)")
    parser.add_argument("--dt", type=bounded_float(0.0, 0.05, "s"), default=0.01,
                        help="time step of both simulators, s (default 0.01, the paper's)")
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

    if args.airframe is None and args.jsbsim_model is None:
        raise UsageError("validate jsbsim needs --airframe or --jsbsim-model")
    if args.jsbsim_model is not None:
        return _validate_model(args)
    args.heights = args.heights or (1.0, 10.0, 100.0)
    args.duration = args.duration or 10.0
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
                              args.duration, dt=args.dt, doublet=doublet, progress=True)
    plots = plot_overlays(results, out)
    doc = {"airframe": airframe.name, "target": "jsbsim", "duration_s": args.duration, "dt_s": args.dt,
           "doublet": {"amplitude": doublet.amplitude, "start_s": doublet.start, "width_s": doublet.width},
           "jsbsim_aircraft": str(out / "jsbsim" / "aircraft" / airframe.name / f"{airframe.name}.xml"),
           "rows": [r.row() for r in results], "plots": [str(p) for p in plots]}
    text = format_table(results)
    if args.all_channels:
        text += "\n\n" + format_table(results, [c for c in CHANNELS if c not in HEADLINE])
    emit(args, doc, text + f"\n\nJSBSim aircraft: {doc['jsbsim_aircraft']}\nplots: {out}/")
    return 0


def _validate_model(args: argparse.Namespace) -> int:
    """``--jsbsim-model``: fly JSBSim's aircraft and the imported one, print r and RMSE, write plots."""
    if importlib.util.find_spec("jsbsim") is None:
        raise UsageError("the jsbsim package is not installed: pip install 'falcon-rl[jsbsim]'")
    from ..validation.jsbsim_import import JSBSimImportError, resolve
    from ..validation.jsbsim_model_compare import TARGETS, ModelDoublet, validate_model
    from ..validation.jsbsim_report import PLOTTED_MODEL, format_table, plot_overlays

    try:
        resolve(args.jsbsim_model)
    except JSBSimImportError as exc:
        raise UsageError(str(exc)) from None
    from ..airframe import load_airframe

    airframe = load_airframe(args.airframe or f"jsbsim_{args.jsbsim_model}")
    out = output_dir(args.out)
    heights = args.heights or MODEL_HEIGHTS
    duration = args.duration or 20.0
    doublet = ModelDoublet()
    results, skipped = validate_model(airframe, args.jsbsim_model, out / "jsbsim", args.airspeeds, heights,
                                      duration=duration, dt=args.dt, doublet=doublet)
    plots = plot_overlays(results, out, PLOTTED_MODEL)
    doc = {"airframe": airframe.name, "jsbsim_model": args.jsbsim_model, "duration_s": duration,
           "dt_s": args.dt,
           "doublet": {"amplitude": doublet.amplitude, "start_s": doublet.start, "width_s": doublet.width},
           "targets_r": TARGETS, "rows": [r.row() for r in results], "skipped": skipped,
           "plots": [str(p) for p in plots]}
    text = format_table(results, list(TARGETS))
    answered = [r for r in results if r.response is not None]
    if answered:
        text += "\n\nResponse (each simulator's run minus its own free flight from the same trim):\n"
        text += format_table(answered, list(TARGETS), attribute="response")
    text += "".join(f"\nskipped: {s}" for s in skipped)
    emit(args, doc, text + f"\n\nplots: {out}/")
    return 0
