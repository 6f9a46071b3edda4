"""CLI reference page, rendered at build time from ``falcon_rl.cli.build_parser()``.

Every (sub)command's ``--help`` as argparse prints it, nested subcommands included, at a fixed width
and without colour, so the page is what a user sees and changes only when the parser does.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from contextlib import contextmanager

from prose import inline

#: Help text width (argparse reads $COLUMNS): a terminal's, and what fits the page's code blocks.
WIDTH = 80


@contextmanager
def _plain_terminal() -> Iterator[None]:
    saved = {key: os.environ.get(key) for key in ("COLUMNS", "NO_COLOR", "FORCE_COLOR", "PYTHON_COLORS")}
    os.environ.update(COLUMNS=str(WIDTH), NO_COLOR="1", PYTHON_COLORS="0")
    os.environ.pop("FORCE_COLOR", None)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, argparse.ArgumentParser]]:
    """(name, one-line help, parser) of each subcommand of ``parser``, in the parser's order (aliases
    once)."""
    found, seen = [], set()
    for action in parser._actions:  # argparse keeps subcommands only here
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
        for name, sub in action.choices.items():
            if id(sub) in seen:
                continue
            seen.add(id(sub))
            found.append((name, helps.get(name, "") or sub.description or "", sub))
    return found


def _walk(parser: argparse.ArgumentParser, path: tuple[str, ...]
          ) -> Iterator[tuple[tuple[str, ...], str, argparse.ArgumentParser]]:
    for name, summary, sub in subcommands(parser):
        yield (*path, name), summary, sub
        yield from _walk(sub, (*path, name))


def _anchor(path: tuple[str, ...]) -> str:
    return "-".join(path).replace("_", "-")


def render_cli(parser: argparse.ArgumentParser | None = None) -> str:
    """Markdown of the CLI reference: the top-level help, a table of the subcommands, then each one's
    help, depth first."""
    if parser is None:
        from falcon_rl.cli import build_parser

        parser = build_parser()
    prog = parser.prog
    with _plain_terminal():
        commands = list(_walk(parser, ()))
        top = parser.format_help()
        helps = [sub.format_help() for _, _, sub in commands]
    lines = ["# Command line", "",
             f"`{prog}` is installed with the package (`pip install -e .`; also "
             f"`python -m falcon_rl.cli`). This page is generated from the parser at build time: each "
             "block is the command's `--help`.", "",
             "```text", top.rstrip(), "```", "",
             "| command | what it does |", "|---|---|"]
    for path, summary, _ in commands:
        title = " ".join((prog, *path))
        lines.append(f"| [`{title}`](#{_anchor(path)}) | {inline(summary, in_table=True)} |")
    for (path, summary, _), text in zip(commands, helps, strict=True):
        level = "#" * min(len(path) + 1, 6)
        lines += ["", f"{level} `{' '.join((prog, *path))}` {{#{_anchor(path)}}}", ""]
        if summary:
            lines += [inline(summary[:1].upper() + summary[1:] + ("" if summary.endswith(".") else ".")), ""]
        lines += ["```text", text.rstrip(), "```"]
    return "\n".join(lines) + "\n"
