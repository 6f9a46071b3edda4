"""``falcon-rl experiment``: the paper's four studies, and the physics ablation.

    falcon-rl experiment all --scale quick                     # the four studies, both airframes
    falcon-rl experiment altitude --controllers ppo,lqr --seeds 3 --scale paper
    falcon-rl experiment maneuvers --runner ray --ray-address auto
    falcon-rl experiment sea-state --scale quick                # sea skimming over sea states 0-5
    falcon-rl experiment landing --scale quick                  # landings with ground effect on and off
    falcon-rl experiment ablation --tasks altitude,attitude --airframe volantex_ranger \\
        --controllers lqr,ppo --episodes 20 --out runs/ablation

The studies (altitude, maneuvers, ground-effect, robustness; ``all``) run as one sweep of cells, one
per study x airframe x controller x training seed x MPPI draw, cached under ``--out``/cells: a killed
sweep resumes where it stopped and a changed cell reruns alone (``falcon_rl.experiment``).
``sea-state`` (not in ``all``) flies the sea-skimming protocol at 0.25 b over sea states 0-5 per airframe
and controller (the altimeter LQR; PPO where a policy exists); ``landing`` (not in ``all``) flies the
landing protocol from the same starts with ground effect on and off (``tecs-flare``). Each study writes
``--out``/<study>/report.md, tables.tex (the paper's layout), results.json and its figures. ``--scale
quick`` is a smoke run with shipped policies and one seed; ``paper`` the paper's sizes. Learned rows
without a shipped policy are trained with ``--train`` and otherwise left empty.

``ablation``:
For each task and controller, the task's protocol on the full model and on one arm per phenomenon
(ideal actuators, no throttle lag, constant density, no rate damping, no propeller torque, no ground
effect; ``falcon_rl.evaluation.ablation``). Writes report.md (a table per task: the headline metric,
its change against the full model and survival per arm and controller), results.json and ablation.png
(bars of the change).

Every output is written atomically (``falcon_rl.atomic_files``): a full disk ends the command with one
line (exit 1) and leaves earlier outputs intact.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..atomic_files import write_atomic
from ..defaults import DEFAULT_AIRFRAME
from ._common import (
    add_flight_arguments,
    check_controller,
    check_device,
    comma_list,
    emit,
    output_dir,
    positive_int,
    use_threads,
)

NAME = "experiment"
HELP = ("the paper's studies (altitude, maneuvers, ground-effect, robustness, all), the sea-state and "
        "landing studies and the physics ablation")
#: The paper's four studies (``all``), then the studies of falcon-rl's own.
STUDY_ACTIONS = ("altitude", "maneuvers", "ground-effect", "robustness")
OWN_STUDIES = ("sea-state", "landing")
ACTIONS = (*STUDY_ACTIONS, *OWN_STUDIES, "all", "ablation")
#: The files ``experiment ablation`` writes under --out.
ABLATION_FILES = ("ablation.png", "report.md", "results.json")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=ACTIONS,
                        help="a study, all four of the paper, sea-state, landing, or ablation (one "
                             "phenomenon simplified at a time)")
    parser.add_argument("--airframes", default=None,
                        help="studies: comma list of airframes (default airship_v7,volantex_ranger)")
    parser.add_argument("--scale", choices=("quick", "paper"), default="quick",
                        help="studies: quick (shipped policies, one seed) or paper (the paper's sizes)")
    parser.add_argument("--seeds", type=positive_int, default=None,
                        help="studies: how many training seeds (0 .. N-1) the learned rows fly "
                             "(default: the scale's)")
    parser.add_argument("--train", action="store_true",
                        help="studies: train the learned policies that do not ship (long)")
    parser.add_argument("--runner", choices=("local", "ray"), default="local",
                        help="studies: run cells in local processes or as Ray tasks")
    parser.add_argument("--workers", type=positive_int, default=1, help="studies: parallel cells")
    parser.add_argument("--ray-address", default=None,
                        help="studies, --runner ray: a cluster address or 'auto' (default: a local Ray)")
    parser.add_argument("--tasks", default="altitude,attitude", help="ablation: comma list of tasks")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME,
                        help="ablation: shipped name or path to a JSON file")
    parser.add_argument("--controllers", default=None,
                        help="comma list (ablation default lqr: the tasks' baselines, ppo, policy files; "
                             "studies default: each study's, from ppo, sac, td3, lqr, mppi, tecs-flare)")
    parser.add_argument("--episodes", type=positive_int, default=None,
                        help="episodes per cell or arm (default: the scale's; ablation 20; attitude: per "
                             "maneuver)")
    add_flight_arguments(parser, "episode length, s (default: each protocol's own)", None,
                         "output folder (default runs/experiment, ablation runs/ablation)")


def _parse(args: argparse.Namespace) -> tuple[list[str], dict[str, str], str, Path]:
    """(tasks, controller -> label, airframe name, output folder) of the flags; UsageError for a bad one,
    before any env is built."""
    from ..airframe import load_airframe
    from ..envs.tasks import task_names

    tasks = comma_list(args.tasks, "--tasks", tuple(task_names()))
    controllers = comma_list("lqr" if args.controllers is None else args.controllers, "--controllers")
    check_device(args.device)
    airframe = load_airframe(args.airframe).name
    labels = {}
    for task in tasks:
        for name in controllers:
            labels[name] = check_controller(name, task, args.airframe, "--controllers")
    return tasks, labels, airframe, output_dir(args.out or "runs/ablation", files=ABLATION_FILES)


def run(args: argparse.Namespace) -> int:
    use_threads(args)
    if args.action != "ablation":
        from ._studies import run_studies

        check_device(args.device)
        args.out = args.out or "runs/experiment"
        studies = list(STUDY_ACTIONS) if args.action == "all" else [args.action]
        document, text = run_studies(args, studies)
        emit(args, document, text + f"\noutputs: {args.out}")
        return 0
    return run_ablation_command(args)


def run_ablation_command(args: argparse.Namespace) -> int:
    """``experiment ablation``: the protocols on the full model and on one arm per phenomenon."""
    from ..evaluation.ablation import ablation_document, ablation_markdown, run_ablation
    from ..evaluation.controllers import make_controller
    from ..viz.ablation import plot_ablation

    tasks, labels, airframe, out = _parse(args)
    results = []
    for task in tasks:
        for name, label in labels.items():
            results.append(run_ablation(task, args.airframe, label,
                                        lambda env, name=name: make_controller(name, env),
                                        episodes=args.episodes or 20, seed=args.seed,
                                        backend=args.backend,
                                        device=args.device, episode_seconds=args.seconds))
    figure = plot_ablation(results, out / ABLATION_FILES[0])
    table = ablation_markdown(results)
    settings = {"episodes": args.episodes or 20, "seed": args.seed, "backend": args.backend,
                "device": args.device, "seconds": args.seconds}
    report = write_atomic(out / ABLATION_FILES[1], f"# Ablation on {airframe}\n\nSettings: "
                          f"{json.dumps(settings)}\n\n{table}\n![ablation]({figure.name})\n")
    document = {"settings": settings, "results": ablation_document(results), "report": str(report),
                "figure": str(figure)}
    write_atomic(out / ABLATION_FILES[2], json.dumps(document, indent=2, default=float))
    emit(args, document, table + f"\nreport: {report}")
    return 0
