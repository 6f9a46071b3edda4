"""``falcon-rl eval``: score a controller on the altitude or attitude protocol."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..cli import UsageError, emit
from ..envs.maneuvers import MANEUVERS

NAME = "eval"
HELP = "evaluate a controller (lqr | mppi | trim | policy file) on the paper's protocols"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--controller", required=True, help="lqr, mppi, trim or a saved policy path")
    parser.add_argument("--task", choices=["altitude", "attitude"], default="altitude")
    parser.add_argument("--airframe", default="volantex_ranger")
    parser.add_argument("--episodes", type=int, default=20, help="altitude episodes (attitude: per maneuver)")
    parser.add_argument("--maneuvers", default=",".join(MANEUVERS), help="comma list (attitude task)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backend", choices=["torch", "warp"], default="torch")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seconds", type=float, default=30.0, help="altitude episode length, s")
    parser.add_argument("--out", default="runs/eval", help="folder for report.md, results.json, PNGs")


def run(args: argparse.Namespace) -> int:
    from ..evaluation.controllers import make_controller
    from ..evaluation.protocols import altitude_protocol, attitude_protocol
    from ..evaluation.report import result_document, write_report
    from ..viz.evaluation import plot_altitude, plot_bank_facets

    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    maneuvers = tuple(m for m in args.maneuvers.split(",") if m)
    unknown = set(maneuvers) - set(MANEUVERS)
    if unknown:
        raise UsageError(f"unknown maneuvers {sorted(unknown)}; choose from {list(MANEUVERS)}")
    label = Path(args.controller).stem if args.controller not in ("lqr", "mppi", "trim") else args.controller
    out = Path(args.out)
    if args.task == "altitude":
        result = altitude_protocol(args.airframe, label, lambda env: make_controller(args.controller, env),
                                   episodes=args.episodes, seed=args.seed, backend=args.backend,
                                   device=args.device, episode_seconds=args.seconds)
        figure = plot_altitude(result, out / f"altitude_{args.airframe}_{label}.png")
    else:
        result = attitude_protocol(args.airframe, label, lambda env: make_controller(args.controller, env),
                                   maneuvers=maneuvers, episodes=args.episodes, seed=args.seed,
                                   backend=args.backend, device=args.device)
        figure = plot_bank_facets([result], out / f"attitude_{args.airframe}_{label}.png")
    report = write_report([result], out, [figure], f"{label} on {args.airframe}: {args.task} protocol")
    doc = {**result_document(result), "report": str(report), "figure": str(figure)}
    emit(args, doc, report.read_text() + f"\nreport: {report}")
    return 0
