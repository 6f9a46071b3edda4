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

from ._common import UsageError, emit

NAME = "experiment"
HELP = "experiments over the benchmark's protocols: 'ablation' (each phenomenon simplified in turn)"
ACTIONS = ("ablation",)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS, help="ablation: one phenomenon simplified at a time")
    parser.add_argument("--tasks", default="altitude,attitude", help="comma list of tasks")
    parser.add_argument("--airframe", default="volantex_ranger")
    parser.add_argument("--controllers", default="lqr",
                        help="comma list: the tasks' baselines (lqr, mppi, trim), ppo, policy files")
    parser.add_argument("--episodes", type=int, default=20, help="episodes per arm (attitude: per maneuver)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--backend", choices=["torch", "warp"], default="warp")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--seconds", type=float, default=None,
                        help="episode length, s (default: each protocol's own)")
    parser.add_argument("--out", default="runs/ablation", help="output folder")


def _parse(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    from ..envs.tasks import task_names, task_spec
    from ..evaluation.controllers import baseline_names
    from ..policies import shipped_policy

    tasks = [t for t in args.tasks.split(",") if t]
    controllers = [c for c in args.controllers.split(",") if c]
    unknown = sorted(set(tasks) - set(task_names()))
    if not tasks or unknown:
        raise UsageError(f"--tasks: unknown {unknown}; tasks: {task_names()}")
    if not controllers:
        raise UsageError("--controllers must name at least one controller")
    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    if args.seconds is not None and args.seconds <= 0:
        raise UsageError(f"--seconds must be > 0, got {args.seconds}")
    for task in tasks:
        spec = task_spec(task)
        for name in controllers:
            if name in baseline_names() and name not in spec.controllers:
                raise UsageError(f"controller {name!r} does not apply to task {task!r}; its controllers: "
                                 f"{sorted(spec.controllers)}")
            if name == "ppo":
                shipped_policy(task, args.airframe)  # ValueError naming the shipped policies
            elif name not in baseline_names() and not Path(name).is_file():
                raise UsageError(f"controller {name!r} is neither a baseline nor a policy file")
    return tasks, controllers


def run(args: argparse.Namespace) -> int:
    from ..evaluation.ablation import ablation_document, ablation_markdown, run_ablation
    from ..evaluation.controllers import baseline_names, make_controller
    from ..viz.ablation import plot_ablation

    tasks, controllers = _parse(args)
    results = []
    for task in tasks:
        for name in controllers:
            label = name if name in baseline_names() or name == "ppo" else Path(name).stem
            results.append(run_ablation(task, args.airframe, label,
                                        lambda env, name=name: make_controller(name, env),
                                        episodes=args.episodes, seed=args.seed, backend=args.backend,
                                        device=args.device, episode_seconds=args.seconds))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    figure = plot_ablation(results, out / "ablation.png")
    table = ablation_markdown(results)
    settings = {"episodes": args.episodes, "seed": args.seed, "backend": args.backend, "device": args.device,
                "seconds": args.seconds}
    report = out / "report.md"
    report.write_text(f"# Ablation on {args.airframe}\n\nSettings: {json.dumps(settings)}\n\n{table}\n"
                      f"![ablation]({figure.name})\n")
    document = {"settings": settings, "results": ablation_document(results), "report": str(report),
                "figure": str(figure)}
    (out / "results.json").write_text(json.dumps(document, indent=2, default=float))
    emit(args, document, table + f"\nreport: {report}")
    return 0
