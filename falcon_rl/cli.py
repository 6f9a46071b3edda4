"""``falcon-rl`` command line. Each subcommand lives in ``falcon_rl/commands/<name>.py`` and
exposes ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input with a one-line reason on stderr, 1 with a one-line reason when the
system refuses a file operation (a full disk, a permission taken away mid-run: :func:`system_error`;
outputs are written atomically, so earlier ones stay intact and no temporary is left). What the
subcommands share (:class:`UsageError`, :func:`emit`) lives in :mod:`falcon_rl.commands._common`, below
this module.

Start-up stays light: the command modules import torch, TorchRL and Warp inside ``run`` (and inside
``add_arguments`` where their options need the registries), and the parser adds the arguments of the
one subcommand being run only, so ``falcon-rl --help`` and ``--version`` import none of them.
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
import textwrap
from collections.abc import Sequence
from types import ModuleType

from . import __version__
from . import commands as _commands_pkg
from .commands._common import UsageError, emit, one_line

DESCRIPTION = ("falcon-rl: a TorchRL-native simulator and control-learning benchmark for fixed-wing "
               "aircraft flying near the ground. It trims airframes, tabulates ground effect, trains PPO, "
               "SAC and TD3, and scores policies and classical baselines (LQR, MPPI, trim) on the tasks' "
               "protocols.")

EPILOG = """typical commands:
  falcon-rl airframes                                  list the shipped airframes
  falcon-rl trim --airframe navion --airspeed 50       trim straight and level flight
  falcon-rl ge-table --airframe volantex_ranger        ground effect on the trim thrust
  falcon-rl eval --task altitude --controller lqr      score a controller on a task's protocol
  falcon-rl train ppo --task altitude                  train a policy (then eval --controller PATH)
  falcon-rl demo                                       the main job on embedded defaults

'falcon-rl COMMAND --help' lists the options of a command."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one printable line on stderr and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"{self.prog}: error: {one_line(message)}", file=sys.stderr)
        raise SystemExit(2)


def command_modules() -> dict[str, ModuleType]:
    """Subcommand name -> its module, for every public module of :mod:`falcon_rl.commands`."""
    modules = {}
    for info in sorted(pkgutil.iter_modules(_commands_pkg.__path__), key=lambda m: m.name):
        if not info.name.startswith("_"):
            module = importlib.import_module(f"{_commands_pkg.__name__}.{info.name}")
            modules[module.NAME] = module
    return modules


def _selected(argv: Sequence[str], names: set[str]) -> str | None:
    """The subcommand ``argv`` runs: its first word that is not an option (the top-level options take no
    values), when it names one."""
    word = next((a for a in argv if not a.startswith("-")), None)
    return word if word in names else None


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``falcon-rl`` parser. With ``argv``, only the subcommand that ``argv`` runs gets its arguments
    (describing some of them imports the task registry); without, every subcommand does."""
    modules = command_modules()
    selected = None if argv is None else _selected(argv, set(modules))
    parser = _Parser(prog="falcon-rl", description=textwrap.fill(DESCRIPTION, 88), epilog=EPILOG,
                     formatter_class=argparse.RawDescriptionHelpFormatter)  # keeps the epilog's layout
    parser.add_argument("--version", action="version", version=f"falcon-rl {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND", title="commands",
                                parser_class=_Parser)
    for name, module in modules.items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        if argv is None or name == selected:
            p.add_argument("--json", action="store_true", help="print one JSON document on stdout")
            module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def _known_errors() -> tuple[type[BaseException], ...]:
    """What bad input raises, printed as one line with exit code 2: :class:`UsageError` and the other
    ``ValueError`` s (invalid airframe, geometry and policy files, and the registries naming their valid
    choices), and :class:`TrimError` (no trim at the requested condition; only once its module is loaded,
    so that start-up does not import torch). Anything else is a bug and keeps its traceback."""
    trim = sys.modules.get("falcon_rl.physics.trim")
    return (ValueError,) if trim is None else (ValueError, trim.TrimError)


def _stdout_gone() -> int:
    """stdout's reader went away (``falcon-rl airframes --json | head``): stop quietly with exit code 0,
    with stdout pointed at the null device so that the interpreter's last flush does not complain."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # an in-process capture has no file descriptor
        pass
    return 0


def system_error(error: OSError) -> str:
    """One line for an ``OSError`` of the system (``No space left on device: 'runs/x/policy.pt'``)."""
    reason = error.strerror or one_line(error)
    return one_line(f"{reason}: {str(error.filename)!r}" if error.filename is not None else reason)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``falcon-rl`` with ``argv`` (default: the process arguments); returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        try:
            args = build_parser(argv).parse_args(argv)
        except SystemExit as exc:  # --help and --version (0), or an argparse error already printed (2)
            sys.stdout.flush()
            return 0 if exc.code is None else exc.code if isinstance(exc.code, int) else 2
        try:
            code = int(args._run(args) or 0)
        except _known_errors() as exc:
            print(f"falcon-rl {args.command}: error: {one_line(exc)}", file=sys.stderr)
            return 2
        except BrokenPipeError:
            raise
        except OSError as exc:
            print(f"falcon-rl {args.command}: error: {system_error(exc)}", file=sys.stderr)
            return 1
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        return _stdout_gone()
    except KeyboardInterrupt:
        print("falcon-rl: interrupted", file=sys.stderr)
        return 130


__all__ = ["DESCRIPTION", "EPILOG", "UsageError", "build_parser", "command_modules", "emit", "main",
           "system_error"]


if __name__ == "__main__":
    raise SystemExit(main())
