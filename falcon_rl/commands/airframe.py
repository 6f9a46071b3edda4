"""``falcon-rl airframe derive GEOMETRY``: derive an airframe JSON from a geometry source file."""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from ._common import UsageError, emit, inside, output_file, printable

NAME = "airframe"
HELP = "airframe tools: 'derive' an airframe JSON from a geometry source with AeroSandbox"
ACTIONS = ("derive",)

#: What reading a malformed geometry file can raise besides GeometryError (a ValueError): the file cannot
#: be read or decoded, nests too deep, or holds values of the wrong JSON type where the loader indexes them.
_MALFORMED = (OSError, UnicodeDecodeError, RecursionError, TypeError, KeyError, AttributeError, IndexError)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS, help="derive: sweep, fit and write the airframe JSON")
    parser.add_argument("geometry", help="geometry source file, e.g. airframes/geometry/navion.json")
    parser.add_argument("--out", default=None, help="airframe JSON to write (default: airframes/NAME.json "
                                                    "beside the geometry folder)")
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
