"""``falcon-rl eval``: score a controller on a task's evaluation protocol.

    falcon-rl eval --task climb_descend --controller lqr --episodes 20
    falcon-rl eval --task path_following --controller trim --seconds 20 --json
    falcon-rl eval --task altitude --controller runs/ppo_altitude/policy.pt

Tasks, their controllers, protocols and figures come from the task registry (``TaskSpec``); a
controller that does not apply to the task, or a policy of another task, exits 2 with a one-line reason
before any env is built.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import (
    UsageError,
    add_flight_arguments,
    check_controller,
    check_device,
    comma_list,
    emit,
    inside,
    nonnegative_int,
    output_dir,
    positive_int,
    use_threads,
)

NAME = "eval"
HELP = "evaluate a controller (the task's baselines: lqr | mppi | trim, or a policy file) on its protocol"


def controllers_help() -> str:
    """The --controller help: every registered task's controllers (read from the task registry)."""
    from ..envs.tasks import TASK_SPECS

    per_task = "; ".join(f"{name}: {', '.join(sorted(spec.controllers))}"
                         for name, spec in TASK_SPECS.items())
    return (f"a controller of the task ({per_task}), ppo, sac or td3 (the shipped policy of that algorithm, "
            "task and airframe; see --policy-seed) or the path of a policy file (policy.pt of "
            "'falcon-rl train')")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..envs.maneuvers import MANEUVERS
    from ..envs.tasks import task_names

    parser.add_argument("--controller", required=True, help=controllers_help())
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default="volantex_ranger", help="shipped name or path to a JSON file")
    parser.add_argument("--policy-seed", type=nonnegative_int, default=0,
                        help="with ppo, sac or td3: the training seed of the shipped policy (default 0)")
    parser.add_argument("--episodes", type=positive_int, default=20, help="episodes (attitude: per maneuver)")
    parser.add_argument("--maneuvers", default=None,
                        help=f"comma list of {','.join(MANEUVERS)} (protocols that fly maneuvers: attitude)")
    add_flight_arguments(parser, "episode length, s (default: the protocol's; attitude: cuts each maneuver)",
                         "runs/eval", "folder for report.md, results.json, PNGs")


def _protocol_options(args: argparse.Namespace, protocol) -> dict:
    """Options of the protocol call beyond the common ones: --maneuvers where the protocol takes it."""
    import inspect

    from ..envs.maneuvers import MANEUVERS

    if args.maneuvers is None:
        return {}
    if "maneuvers" not in inspect.signature(protocol).parameters:
        raise UsageError(f"--maneuvers does not apply to the {args.task} protocol")
    maneuvers = comma_list(args.maneuvers, "--maneuvers", tuple(MANEUVERS))
    return {"maneuvers": tuple(maneuvers)}


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..envs.tasks import task_spec

    check_device(args.device)
    use_threads(args)
    airframe = load_airframe(args.airframe)
    spec = task_spec(args.task)
    protocol = spec.protocol_function()
    options = _protocol_options(args, protocol)
    label = check_controller(args.controller, args.task, args.airframe, policy_seed=args.policy_seed)
    out = output_dir(args.out)
    figure = inside(out, f"{args.task}_{airframe.name}_{label}.png", "figure name")
    title = f"{label} on {airframe.name}: {args.task} protocol"
    return _evaluate(args, spec, options, label, title, figure)


def _evaluate(args: argparse.Namespace, spec, options: dict, label: str, title: str, figure: Path) -> int:
    """Run the protocol, write the report and the figure next to it, print (the inputs are checked)."""
    from ..evaluation.controllers import make_controller
    from ..evaluation.report import result_document, write_report

    result = spec.protocol_function()(args.airframe, label,
                                      lambda env: make_controller(args.controller, env, args.policy_seed),
                      episodes=args.episodes, seed=args.seed, backend=args.backend, device=args.device,
                      episode_seconds=args.seconds, **options)
    plot = spec.figure_function()
    figures = [] if plot is None else [plot(result, figure)]
    report = write_report([result], figure.parent, figures, title)
    doc = {**result_document(result), "report": str(report), "figure": str(figures[0]) if figures else None}
    emit(args, doc, report.read_text() + f"\nreport: {report}")
    return 0

