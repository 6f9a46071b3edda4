"""``falcon-rl train``: train PPO, SAC or TD3 on a task with the recipe's per-task defaults.

    falcon-rl train ppo --task altitude --airframe volantex_ranger --out runs/ppo_altitude
    falcon-rl train ppo --task altitude --out runs/ppo_altitude --resume      # continue a killed run
    falcon-rl train ppo --task altitude --out runs/ppo_altitude --resume-if-present   # job scripts
    falcon-rl train ppo --task altitude --stop-when "survival>=1,acquisition>=0.95,rmse_m<=0.5"

Writes ``checkpoint.pt`` (resumable), ``policy.pt`` (for ``falcon-rl eval --controller PATH``),
``policy.ts`` (TorchScript), ``summary.json`` and logs under ``--out``. The same flags and ``--seed``
give bit-identical weights, and a killed run resumed with ``--resume`` ends where the uninterrupted
run would. ``--resume`` needs ``<out>/checkpoint.pt`` of the same algorithm, task, airframe, networks,
seed, backend and device (``falcon_rl.recipes.checkpoint.IDENTITY_FIELDS``); a missing, corrupt or
mismatched checkpoint exits 2 with one line naming it. Bad flags and ``--set`` values (types, ranges,
an unknown field, a device this machine lacks, an unwritable ``--out``) exit 2 before anything runs.

``--stop-when`` stops at the first validation (``--eval-every``, ``eval_episodes`` episodes) that meets
every condition *and* whose weights meet them again on ``confirm_episodes`` confirmation episodes (100
by default, on seeds of their own: neither the validation's nor the final test's); a confirmation that
misses one lets training go on (``falcon_rl.recipes.selection``). The run ships the confirmed weights.

One run per ``--out``: a run locks ``<out>/.lock`` for its whole life (released when it ends or its
process dies), and a second run into the folder meanwhile exits 2 with one line naming it. A run whose
ended training episodes are all non-finite (termination reason "non_finite") exits 2 with one line and
exports no policy; a refused file operation (a full disk) exits 1 with one line, leaving the earlier
outputs whole and no temporary file (``falcon_rl.recipes.runner``).
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import math

from ..defaults import BATCH_BACKENDS, DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ._common import (
    UsageError,
    check_device,
    emit,
    nonnegative_int,
    output_dir,
    positive_int,
)

NAME = "train"
HELP = "train PPO, SAC or TD3 on a task (checkpoints, policy export, final evaluation)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("algorithm", choices=["ppo", "sac", "td3"])
    parser.add_argument("--task", default="altitude", help="altitude, attitude (or another task)")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--envs", type=positive_int, default=None,
                        help="parallel envs (default: the recipe's)")
    parser.add_argument("--frames", type=positive_int, default=None,
                        help="total env steps (default: the recipe's)")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--backend", choices=BATCH_BACKENDS, default=DEFAULT_BACKEND,
                        help="simulator backend (default warp, the fastest; torch: the reference)")
    parser.add_argument("--seed", type=nonnegative_int, default=0)
    parser.add_argument("--out", default=None, help="output folder (default runs/<alg>_<task>_<airframe>)")
    resume = parser.add_mutually_exclusive_group()
    resume.add_argument("--resume", action="store_const", const=True, default=False,
                        help="continue from <out>/checkpoint.pt (an error when there is none)")
    resume.add_argument("--resume-if-present", dest="resume", action="store_const", const="auto",
                        help="continue from <out>/checkpoint.pt when it exists, else start a new run")
    parser.add_argument("--logger", choices=["csv", "tensorboard", "wandb", "none"], default="csv")
    parser.add_argument("--eval-every", type=nonnegative_int, default=None,
                        help="frames between validations (0: only the final evaluation); with the "
                             "recipe field keep_best the best validated snapshot is shipped")
    parser.add_argument("--stop-when", default=None, metavar="CONDITIONS",
                        help="stop at the first validation meeting every condition, e.g. "
                             "\"survival>=1,acquisition>=0.95,rmse_m<=0.5\" (the task protocol's metrics, "
                             "averaged over its cases), once confirm_episodes more episodes (--set; default "
                             "100, seeds of their own) meet them too; otherwise training goes on. Needs "
                             "validations (--eval-every)")
    parser.add_argument("--eval-episodes", type=nonnegative_int, default=None,
                        help="episodes of the final evaluation")
    parser.add_argument("--threads", type=positive_int, default=None, help="torch CPU threads (default 1)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                        help="override a recipe field (Python literal), e.g. --set batch_size=512 "
                             "--set 'env_options={\"decimation\": 5}' (merged into the recipe's "
                             "env_options); repeatable")


def parse_overrides(items: list[str]) -> dict:
    """``["field=value", ...]`` -> {field: literal value} (a bare word stays a string)."""
    overrides = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise UsageError(f"--set takes FIELD=VALUE, got {item!r}")
        try:
            value = ast.literal_eval(text)
        except (ValueError, SyntaxError, MemoryError, RecursionError):
            value = text
        overrides[name.strip()] = tuple(value) if isinstance(value, list) else value
    return overrides


def _config(recipe, args: argparse.Namespace, out: str, overrides: dict):
    """The recipe's config for the task: its defaults, the flags, then the ``--set`` fields, checked
    (types, ranges, device, a writable output folder) before anything runs."""
    from ..recipes.checks import check_config

    flags = {"airframe": args.airframe, "num_envs": args.envs, "frames": args.frames, "device": args.device,
             "backend": args.backend, "seed": args.seed, "out": out, "resume": args.resume,
             "logger": args.logger, "eval_every": args.eval_every, "final_eval_episodes": args.eval_episodes,
             "threads": args.threads, "progress": not args.no_progress and not args.json,
             "stop_when": args.stop_when}
    try:
        cfg = recipe.make_config(args.task, **{**flags, **overrides})
    except TypeError as exc:  # an unknown --set field
        raise UsageError(str(exc)) from None
    try:
        check_config(cfg)
    except ValueError as exc:
        raise UsageError(f"--set {exc}" if str(exc).split()[0] in overrides else str(exc)) from None
    check_device(cfg.device, "--device")
    if cfg.out is not None:
        output_dir(cfg.out, "--out")
    return cfg


def run(args: argparse.Namespace) -> int:
    from ..recipes import algorithm
    from ..recipes.runner import release_run_folder

    if args.logger in ("tensorboard", "wandb") and importlib.util.find_spec(args.logger) is None:
        raise UsageError(f"--logger {args.logger} needs the {args.logger} package "
                         f"(pip install {args.logger})")
    recipe = algorithm(args.algorithm)
    out = args.out or f"runs/{args.algorithm}_{args.task}_{args.airframe}"
    cfg = _config(recipe, args, out, parse_overrides(args.set))
    try:
        summary = recipe.train(cfg)
    finally:
        release_run_folder(cfg.out)  # a run that raised still holds its folder
    summary["config"] = cfg.to_dict()
    lines = [f"{args.algorithm} on {args.task} / {args.airframe}: {summary['frames']:,} frames in "
             f"{summary['wall_seconds']:.0f} s ({summary['env_steps_per_s']:,.0f} env-steps/s "
             "incl. learning)"]
    if "solved" in summary:
        solved = summary["solved"]
        lines.append("stop_when not met" if solved is None else
                     f"stop_when met at {solved['frames']:,} frames, {solved['wall_seconds']:.0f} s")
    for key in ("policy", "torchscript", "checkpoint"):
        if key in summary:
            lines.append(f"{key}: {summary[key]}")
    if summary.get("eval"):
        lines.append(f"evaluation ({summary['eval_episodes']} episodes): " + ", ".join(
            f"{k} {v:.3g}" for k, v in summary["eval"].items() if not math.isnan(v)))
    summary["eval"] = summary.get("eval") and {k: (None if isinstance(v, float) and math.isnan(v) else v)
                                               for k, v in summary["eval"].items()}
    emit(args, summary, "\n".join(lines))
    return 0
