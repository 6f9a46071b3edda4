"""``falcon-rl eval``: score a controller on a task's evaluation protocol.

    falcon-rl eval --task climb_descend --controller lqr --episodes 20
    falcon-rl eval --task path_following --controller trim --seconds 20 --json
    falcon-rl eval --task altitude --controller runs/ppo_altitude/policy.pt

Tasks, their controllers, protocols and figures come from the task registry (``TaskSpec``); a
controller that does not apply to the task, or a policy of another task, exits 2 with a one-line reason
before any env is built.

Each run gets its own folder: without ``--out``, a new ``runs/eval/TASK-CONTROLLER-AIRFRAME-UTCTIME``
(``-2``, ``-3``, ... when two runs start in the same second); a ``--out`` that already holds a report
is refused in one line unless ``--force``. Where the report went is said on stderr (and in the JSON).
"""

from __future__ import annotations

import argparse
import re
import sys
from datetime import datetime, timezone
from pathlib import Path

from ..defaults import DEFAULT_AIRFRAME
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
#: The folder under which each run without --out gets its own.
RUNS_FOLDER = Path("runs/eval")
#: The report of a run (next to results.json and the figure); a --out holding one is not overwritten.
REPORT_NAME = "report.md"
#: Characters of the task, controller and airframe names kept in a run's folder name.
MAX_PART_CHARACTERS = 40
#: Most same-second runs of the same task, controller and airframe that get a folder each.
MAX_SAME_SECOND_RUNS = 1000


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
    from ..physics.wind import SEVERITY_W20_KT

    parser.add_argument("--controller", required=True, help=controllers_help())
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME, help="shipped name or path to a JSON file")
    parser.add_argument("--policy-seed", type=nonnegative_int, default=0,
                        help="with ppo, sac or td3: the training seed of the shipped policy (default 0)")
    parser.add_argument("--episodes", type=positive_int, default=20, help="episodes (attitude: per maneuver)")
    parser.add_argument("--maneuvers", default=None,
                        help=f"comma list of {','.join(MANEUVERS)} (protocols that fly maneuvers: attitude)")
    parser.add_argument("--sea-state", type=int, choices=range(7), default=None, metavar="{0..6}",
                        help="WMO sea state the protocol flies over (protocols over the sea: sea_skimming; "
                             "default its own, 3)")
    parser.add_argument("--clearance", type=float, default=None,
                        help="commanded clearance in spans (sea_skimming; default 0.25)")
    parser.add_argument("--turbulence", choices=tuple(SEVERITY_W20_KT), default=None,
                        help="Dryden turbulence the episodes fly in (MIL severity; default: the protocol's, "
                             "none)")
    add_flight_arguments(parser, "episode length, s (default: the protocol's; attitude: cuts each maneuver)",
                         None, "folder for report.md, results.json and the figure (default: a new folder per "
                         f"run, {RUNS_FOLDER}/TASK-CONTROLLER-AIRFRAME-UTCTIME); one that already holds a "
                         "report is refused unless --force")
    parser.add_argument("--force", action="store_true", help="replace the report of an earlier run in --out")


def _protocol_options(args: argparse.Namespace, protocol) -> dict:
    """Options of the protocol call beyond the common ones, where the protocol takes them: --maneuvers,
    --sea-state, --clearance and --turbulence (UsageError naming the flag otherwise)."""
    import inspect
    import math

    from ..envs.maneuvers import MANEUVERS

    parameters = inspect.signature(protocol).parameters
    options: dict = {}
    for flag, name, value in (("--maneuvers", "maneuvers", args.maneuvers),
                              ("--sea-state", "sea_state", args.sea_state),
                              ("--clearance", "clearance", args.clearance)):
        if value is None:
            continue
        if name not in parameters:
            raise UsageError(f"{flag} does not apply to the {args.task} protocol")
        options[name] = value
    if args.turbulence is not None:
        takes_options = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
        if not (takes_options or "turbulence" in parameters):
            raise UsageError(f"--turbulence does not apply to the {args.task} protocol")
        options["turbulence"] = args.turbulence
    if "maneuvers" in options:
        options["maneuvers"] = tuple(comma_list(args.maneuvers, "--maneuvers", tuple(MANEUVERS)))
    clearance = options.get("clearance")
    if clearance is not None and not (math.isfinite(clearance) and 0.0 < clearance <= 2.0):
        raise UsageError(f"--clearance must be a number of spans in (0, 2], got {clearance!r}")
    return options


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
    figure_name = inside(Path(), f"{args.task}_{airframe.name}_{label}.png", "figure name").name
    out = given_folder(args.out, args.force) if args.out is not None else run_folder(
        RUNS_FOLDER, (args.task, label, airframe.name))
    figure = out / figure_name
    title = f"{label} on {airframe.name}: {args.task} protocol"
    try:
        return _evaluate(args, spec, options, label, title, figure)
    except BaseException:
        if args.out is None and not any(out.iterdir()):  # the run's own folder, left empty: not kept
            out.rmdir()
        raise


def given_folder(path: str, force: bool) -> Path:
    """``--out`` as a writable folder, refused (UsageError) when it holds the report of an earlier run and
    ``force`` is not set."""
    out = output_dir(path)
    if (out / REPORT_NAME).exists() and not force:
        raise UsageError(f"--out {path!r} already holds the {REPORT_NAME} of an earlier run: add --force to "
                         "replace it, or leave --out out for a new folder per run")
    return out


def run_folder(root: Path, parts: tuple[str, ...], now: datetime | None = None) -> Path:
    """A new folder ``root/PART-PART-...-UTCTIME`` (``now``, default the current time, as
    ``20250101T120000Z``) for one run, created here; ``-2``, ``-3``, ... are added when the name is taken
    (two runs in the same second). Characters other than letters, digits, ``_`` and ``.`` in a part
    become ``_``, and a part keeps its first :data:`MAX_PART_CHARACTERS` (a long policy file name)."""
    stamp = (now or datetime.now(timezone.utc)).strftime("%Y%m%dT%H%M%SZ")
    cleaned = (re.sub(r"[^A-Za-z0-9_.]+", "_", p)[:MAX_PART_CHARACTERS].strip(".") or "_" for p in parts)
    name = "-".join([*cleaned, stamp])
    output_dir(root, "the default --out folder")
    for attempt in range(1, MAX_SAME_SECOND_RUNS + 1):
        folder = root / (name if attempt == 1 else f"{name}-{attempt}")
        try:
            folder.mkdir()
        except FileExistsError:
            continue
        return folder
    raise UsageError(f"{str(root)!r} already holds {MAX_SAME_SECOND_RUNS} folders named {name}[-N]: "
                     "give --out")


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
    print(f"eval: report in {report}", file=sys.stderr)
    emit(args, doc, report.read_text())
    return 0

