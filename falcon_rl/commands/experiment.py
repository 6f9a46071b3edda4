"""``falcon-rl experiment ablation``: score controllers with each physical phenomenon simplified in turn.

    falcon-rl experiment ablation --tasks altitude,attitude --airframe volantex_ranger \\
        --controllers lqr,ppo --episodes 20 --out runs/ablation

For each task and controller, the task's protocol on the full model and on one arm per phenomenon
(ideal actuators, no throttle lag, constant density, no rate damping, no propeller torque, no ground
effect; ``falcon_rl.evaluation.ablation``). Writes report.md (a table per task: the headline metric,
its change against the full model and survival per arm and controller), results.json and ablation.png
(bars of the change).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ._common import (
    add_flight_arguments,
    check_controller,
    check_device,
    comma_list,
    emit,
    output_dir,
    positive_int,
)

NAME = "experiment"
HELP = "experiments over the benchmark's protocols: 'ablation' (each phenomenon simplified in turn)"
ACTIONS = ("ablation",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS, help="ablation: one phenomenon simplified at a time")
    parser.add_argument("--tasks", default="altitude,attitude", help="comma list of tasks")
    parser.add_argument("--airframe", default="volantex_ranger", help="shipped name or path to a JSON file")
    parser.add_argument("--controllers", default="lqr",
                        help="comma list: the tasks' baselines (lqr, mppi, trim), ppo, policy files")
    parser.add_argument("--episodes", type=positive_int, default=20,
                        help="episodes per arm (attitude: per maneuver)")
    add_flight_arguments(parser, "episode length, s (default: each protocol's own)", "runs/ablation",
                         "output folder")


def _parse(args: argparse.Namespace) -> tuple[list[str], dict[str, str], str, Path]:
    """(tasks, controller -> label, airframe name, output folder) of the flags; UsageError for a bad one,
    before any env is built."""
    from ..airframe import load_airframe
    from ..envs.tasks import task_names

    tasks = comma_list(args.tasks, "--tasks", tuple(task_names()))
    controllers = comma_list(args.controllers, "--controllers")
    check_device(args.device)
    airframe = load_airframe(args.airframe).name
    labels = {}
    for task in tasks:
        for name in controllers:
            labels[name] = check_controller(name, task, args.airframe, "--controllers")
    return tasks, labels, airframe, output_dir(args.out)


def run(args: argparse.Namespace) -> int:
    from ..evaluation.ablation import ablation_document, ablation_markdown, run_ablation
    from ..evaluation.controllers import make_controller
    from ..viz.ablation import plot_ablation

    tasks, labels, airframe, out = _parse(args)
    results = []
    for task in tasks:
        for name, label in labels.items():
            results.append(run_ablation(task, args.airframe, label,
                                        lambda env, name=name: make_controller(name, env),
                                        episodes=args.episodes, seed=args.seed, backend=args.backend,
                                        device=args.device, episode_seconds=args.seconds))
    figure = plot_ablation(results, out / "ablation.png")
    table = ablation_markdown(results)
    settings = {"episodes": args.episodes, "seed": args.seed, "backend": args.backend, "device": args.device,
                "seconds": args.seconds}
    report = out / "report.md"
    report.write_text(f"# Ablation on {airframe}\n\nSettings: {json.dumps(settings)}\n\n{table}\n"
                      f"![ablation]({figure.name})\n")
    document = {"settings": settings, "results": ablation_document(results), "report": str(report),
                "figure": str(figure)}
    (out / "results.json").write_text(json.dumps(document, indent=2, default=float))
    emit(args, document, table + f"\nreport: {report}")
    return 0
