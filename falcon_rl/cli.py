"""``falcon-rl`` command line. Each subcommand lives in ``falcon_rl/commands/<name>.py`` and
exposes ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import sys
from typing import Any

from . import commands as _commands_pkg


class UsageError(ValueError):
    """Bad user input: printed as one line on stderr, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"falcon-rl: error: {message}", file=sys.stderr)
        raise SystemExit(2)


def emit(args: argparse.Namespace, document: Any, text: str) -> None:
    """Print ``document`` as JSON with --json, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(document, indent=2, default=float))
    else:
        print(text)


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


if __name__ == "__main__":
    raise SystemExit(main())
