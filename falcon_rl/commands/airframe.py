"""``falcon-rl airframe derive GEOMETRY``: derive an airframe JSON from a geometry source file;
``falcon-rl airframe import-jsbsim NAME|PATH``: import a JSBSim aircraft as an airframe JSON."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from ._common import UsageError, emit, inside, output_file, printable

NAME = "airframe"
HELP = ("airframe tools: 'derive' an airframe JSON from a geometry source with AeroSandbox; 'import-jsbsim' "
        "a JSBSim aircraft")
ACTIONS = ("derive", "import-jsbsim")

#: What reading a malformed geometry file can raise besides GeometryError (a ValueError): the file cannot
#: be read or decoded, nests too deep, or holds values of the wrong JSON type where the loader indexes them.
_MALFORMED = (OSError, UnicodeDecodeError, RecursionError, TypeError, KeyError, AttributeError, IndexError)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS, help="derive: sweep, fit and write the airframe JSON; "
                                                        "import-jsbsim: read a JSBSim aircraft")
    parser.add_argument("geometry", help="derive: geometry source file, e.g. airframes/geometry/navion.json; "
                                         "import-jsbsim: JSBSim model name (c172p) or aircraft XML path")
    parser.add_argument("--out", default=None, help="airframe JSON to write (default: airframes/NAME.json "
                                                    "beside the geometry folder; import-jsbsim: NAME.json)")
    parser.add_argument("--plot", default=None,
                        help="PNG of sweep vs fit (default: runs/derive/NAME_fit.png)")


def _geometry_name(path: Path) -> str:
    """The airframe name of geometry file ``path`` (validated without AeroSandbox), else UsageError."""
    from ..derive.geometry import load_geometry

    try:
        name = load_geometry(path).name
    except _MALFORMED as exc:
        raise UsageError(f"{path}: malformed geometry file ({type(exc).__name__}: {exc})") from None
    if printable(name) != name:
        raise UsageError(f"{path}: field 'name': contains control characters: {printable(name)}")
    inside(Path("."), f"{name}.json", f"{path}: field 'name'")
    return name


def run(args: argparse.Namespace) -> int:
    if args.action == "import-jsbsim":
        return import_jsbsim_command(args)
    geometry = Path(args.geometry)
    if not geometry.is_file():
        raise UsageError(f"geometry file not found: {geometry}")
    name = _geometry_name(geometry)
    out = output_file(args.out or geometry.resolve().parent.parent / f"{name}.json", "--out")
    plot = output_file(args.plot or Path("runs/derive") / f"{name}_fit.png", "--plot")
    if importlib.util.find_spec("aerosandbox") is None:
        raise UsageError("deriving an airframe needs AeroSandbox: pip install 'falcon-rl[derive]'")
    try:
        from ..derive.build import derive_airframe
        from ..derive.plots import plot_fit
        from ..derive.writer import write_airframe
        derived = derive_airframe(geometry)
    except ImportError as exc:
        raise UsageError(str(exc)) from exc
    doc = derived.document
    write_airframe(doc, out)
    png = plot_fit(derived, plot)
    print(f"wrote {out} and {png}", file=sys.stderr)
    residuals = doc["provenance"]["fit"]["residuals"]
    summary = {"airframe": doc["name"], "out": str(out), "plot": str(png), "envelope": doc["envelope"],
               "fit_residuals": residuals}
    lines = [f"{doc['name']}: wrote {out}", f"plot: {png}", "fit (rms held-out / data range):"]
    lines += [f"  {k:<3} {v['rms_held_out']:.3g} / {v['data_range']:.3g}  orders {v['orders']}"
              for k, v in residuals.items()]
    lines += [f"envelope: {doc['envelope']}"]
    emit(args, summary, "\n".join(lines))
    return 0


def import_jsbsim_command(args: argparse.Namespace) -> int:
    """Import, validate with the airframe reader, write and summarise."""
    import json

    if importlib.util.find_spec("jsbsim") is None:
        raise UsageError("importing a JSBSim aircraft needs the jsbsim package: "
                         "pip install 'falcon-rl[jsbsim]'")
    from ..airframe import AirframeError, parse_airframe
    from ..validation.jsbsim_import import JSBSimImportError
    from ..validation.jsbsim_import_build import import_jsbsim

    source = str(args.geometry)
    stem = Path(source).stem if source.endswith(".xml") else source
    out = output_file(args.out or f"{stem}.json", "--out")
    try:
        imported = import_jsbsim(source, name=out.stem)
        parse_airframe(imported.document, out)
    except (JSBSimImportError, AirframeError) as exc:
        raise UsageError(str(exc)) from None
    out.write_text(json.dumps(imported.document, indent=1) + "\n")
    report = imported.report
    summary = {"airframe": imported.document["name"], "out": str(out), "jsbsim_model": report["model"],
               "terms": len(report["terms"]), "omitted": report["omitted"],
               "envelope": imported.document["envelope"]}
    lines = [f"{out.stem}: wrote {out} ({len(report['terms'])} table terms, thrust map from JSBSim's engine)"]
    lines += [f"  {r['name']:<32} {r['output']:<3} axes {r.get('axes')} x {r.get('multiply')}  rms error "
              f"{r['rms_error']:.2g} of {r['rms_coefficient']:.2g}" for r in report["terms"]]
    lines += [f"  left out: {r['name']} ({r['reason']})" for r in report["omitted"]]
    emit(args, summary, "\n".join(lines))
    return 0
