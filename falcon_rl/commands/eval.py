"""``falcon-rl eval``: score a controller on a task's evaluation protocol.

    falcon-rl eval --task climb_descend --controller lqr --episodes 20
    falcon-rl eval --task path_following --controller trim --seconds 20 --json
    falcon-rl eval --task altitude --controller runs/ppo_altitude/policy.pt

Tasks, their controllers, protocols and figures come from the task registry (``TaskSpec``); a
controller that does not apply to the task, or a policy of another task, exits 2 with a one-line reason.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..envs.maneuvers import MANEUVERS
from ._common import UsageError, emit

NAME = "eval"
HELP = "evaluate a controller (the task's baselines: lqr | mppi | trim, or a policy file) on its protocol"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..envs.tasks import task_names

    parser.add_argument("--controller", required=True,
                        help="a baseline of the task (lqr, mppi, trim where they apply), ppo or a policy")
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default="volantex_ranger")
    parser.add_argument("--episodes", type=int, default=20, help="episodes (attitude: per maneuver)")
    parser.add_argument("--maneuvers", default=None,
                        help=f"comma list of {','.join(MANEUVERS)} (protocols that fly maneuvers: attitude)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backend", choices=["torch", "warp"], default="torch")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seconds", type=float, default=None,
                        help="episode length, s (default: the protocol's; attitude: cuts each maneuver)")
    parser.add_argument("--out", default="runs/eval", help="folder for report.md, results.json, PNGs")


def _protocol_options(args: argparse.Namespace, protocol) -> dict:
    """Options of the protocol call beyond the common ones: --maneuvers where the protocol takes it."""
    import inspect

    if args.maneuvers is None:
        return {}
    if "maneuvers" not in inspect.signature(protocol).parameters:
        raise UsageError(f"--maneuvers does not apply to the {args.task} protocol")
    maneuvers = tuple(m for m in args.maneuvers.split(",") if m)
    unknown = set(maneuvers) - set(MANEUVERS)
    if unknown or not maneuvers:
        raise UsageError(f"unknown maneuvers {sorted(unknown)}; choose from {list(MANEUVERS)}")
    return {"maneuvers": maneuvers}


def run(args: argparse.Namespace) -> int:
    from ..envs.tasks import task_spec
    from ..evaluation.controllers import baseline_names, make_controller
    from ..evaluation.report import result_document, write_report

    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seconds is not None and args.seconds <= 0:
        raise UsageError(f"--seconds must be > 0, got {args.seconds}")
    spec = task_spec(args.task)
    protocol = spec.protocol_function()
    options = _protocol_options(args, protocol)
    baseline = args.controller in baseline_names()
    if baseline:
        spec.controller(args.controller)  # one-line ValueError naming the task's controllers
    label = args.controller if baseline else Path(args.controller).stem
    out = Path(args.out)
    result = protocol(args.airframe, label, lambda env: make_controller(args.controller, env),
                      episodes=args.episodes, seed=args.seed, backend=args.backend, device=args.device,
                      episode_seconds=args.seconds, **options)
    plot = spec.figure_function()
    out.mkdir(parents=True, exist_ok=True)
    figures = [] if plot is None else [plot(result, out / f"{args.task}_{args.airframe}_{label}.png")]
    report = write_report([result], out, figures, f"{label} on {args.airframe}: {args.task} protocol")
    doc = {**result_document(result), "report": str(report), "figure": str(figures[0]) if figures else None}
    emit(args, doc, report.read_text() + f"\nreport: {report}")
    return 0
