"""``falcon-rl airframe derive GEOMETRY``: derive an airframe JSON from a geometry source file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ._common import UsageError, emit

NAME = "airframe"
HELP = "airframe tools: 'derive' an airframe JSON from a geometry source with AeroSandbox"
ACTIONS = ("derive",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS, help="derive: sweep, fit and write the airframe JSON")
    parser.add_argument("geometry", help="geometry source file, e.g. airframes/geometry/navion.json")
    parser.add_argument("--out", default=None, help="airframe JSON to write (default: airframes/NAME.json "
                                                    "beside the geometry folder)")
    parser.add_argument("--plot", default=None,
                        help="PNG of sweep vs fit (default: runs/derive/NAME_fit.png)")


def run(args: argparse.Namespace) -> int:
    geometry = Path(args.geometry)
    if not geometry.is_file():
        raise UsageError(f"geometry file not found: {geometry}")
    try:
        from ..derive.build import derive_airframe
        from ..derive.plots import plot_fit
        from ..derive.writer import write_airframe
        derived = derive_airframe(geometry)
    except ImportError as exc:
        raise UsageError(str(exc)) from exc
    doc = derived.document
    out = Path(args.out) if args.out else geometry.resolve().parent.parent / f"{doc['name']}.json"
    write_airframe(doc, out)
    png = plot_fit(derived, args.plot or Path("runs/derive") / f"{doc['name']}_fit.png")
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
