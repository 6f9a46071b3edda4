"""Includes of the repository's own files into the site's pages, so each idea stays in one file.

A page line

    <!-- include README.md "Physics summary" -->

stands for that section of README.md (the text under the heading, to the next heading of the same or
a higher level; ``""`` names the text before the first section), ``<!-- include FILE -->`` for the
whole file, and a file that is not Markdown comes as a code block. An indented directive (inside an
admonition) indents what it includes. Paths are relative to the repository root. ``hooks.py`` applies
them to every page; a missing file or section is a warning, so the strict build fails on it. Links
and images of an included file that point into ``docs/`` (``](docs/images/x.png)``, or
``](../docs/images/x.png)`` from a file in a folder) are rebased onto
the site (``](images/x.png)``), so README.md and the pages at the site's top level show the same
pictures.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

DIRECTIVE = re.compile(r'^(?P<indent>[ \t]*)<!-- include (?P<path>[^\s"]+)'
                       r'(?: "(?P<section>[^"]*)")? -->[ \t]*$', re.M)
DOCS_LINK = re.compile(r"\]\((?:\.\./)*docs/")
HEADING = re.compile(r"^(#{1,6}) +(.+?) *#*$")
LANGUAGES = {".py": "python", ".sh": "bash", ".json": "json", ".toml": "toml", ".yml": "yaml",
             ".yaml": "yaml"}


def section(text: str, title: str) -> str | None:
    """The body of the section headed ``title`` (None when absent); "" title: the preamble."""
    lines, fence = text.splitlines(), False
    start, level = None, 0
    for index, line in enumerate(lines):
        if line.lstrip().startswith(("```", "~~~")):
            fence = not fence
        match = None if fence else HEADING.match(line)
        if start is None:
            if title == "" and match and len(match.group(1)) == 1:
                start, level = index + 1, 1
            elif match and match.group(2).strip() == title:
                start, level = index + 1, len(match.group(1))
        elif match and len(match.group(1)) <= level + (title == ""):
            return "\n".join(lines[start:index]).strip("\n")
    return None if start is None else "\n".join(lines[start:]).strip("\n")


def included(path: str, title: str | None) -> str:
    """The text ``<!-- include path "title" -->`` stands for; ValueError naming what is missing."""
    target = ROOT / path
    if not target.is_file():
        raise ValueError(f"include of a missing file {path}")
    text = target.read_text(encoding="utf-8")
    if target.suffix.lower() != ".md":
        return f"```{LANGUAGES.get(target.suffix.lower(), 'text')}\n{text.rstrip()}\n```"
    if title is None:
        return DOCS_LINK.sub("](", text.rstrip())
    body = section(text, title)
    if body is None:
        raise ValueError(f'include: {path} has no section "{title}"')
    return DOCS_LINK.sub("](", body)


def expand(markdown: str, warn: Callable[[str], None]) -> str:
    """``markdown`` with its include directives replaced; ``warn`` gets each failure's reason."""

    def replace(match: re.Match) -> str:
        try:
            text = included(match["path"], match["section"])
        except ValueError as error:
            warn(str(error))
            return ""
        return "\n".join(match["indent"] + line if line.strip() else "" for line in text.splitlines())

    return DIRECTIVE.sub(replace, markdown)
