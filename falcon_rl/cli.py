"""``falcon-rl`` command line. Each subcommand lives in ``falcon_rl/commands/<name>.py`` and
exposes ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input with a one-line reason on stderr. What the subcommands share
(:class:`UsageError`, :func:`emit`) lives in :mod:`falcon_rl.commands._common`, below this module.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from . import commands as _commands_pkg
from .commands._common import UsageError, emit


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"falcon-rl: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="falcon-rl", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    modules = {}
    for info in sorted(pkgutil.iter_modules(_commands_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{_commands_pkg.__name__}.{info.name}")
        p = sub.add_parser(module.NAME, help=module.HELP, description=module.HELP)
        p.add_argument("--json", action="store_true", help="print one JSON document on stdout")
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
        modules[module.NAME] = module
    return parser


def main(argv: list[str] | None = None) -> int:
    from .airframe import AirframeError
    from .physics.trim import TrimError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except (UsageError, AirframeError, TrimError, KeyError, ValueError) as exc:
        message = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"falcon-rl {args.command}: error: {message}", file=sys.stderr)
        return 2


__all__ = ["UsageError", "build_parser", "emit", "main"]


if __name__ == "__main__":
    raise SystemExit(main())
