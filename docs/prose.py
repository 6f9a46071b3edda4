"""Render the package's docstrings, plain prose with a few reST habits, as Markdown for the site.

The code's docstrings are prose, not Google or NumPy sections. What Markdown would get wrong:

- Sphinx roles, ``:class:`~falcon_rl.envs.FixedWingEnv``` -> a cross-reference to the API page when
  the target is rendered somewhere on the site, else plain code (``<autoref ... optional>``: an
  unresolved optional reference is not a warning);
- reST simple tables (``====  ====`` borders) -> Markdown tables (continuation lines joined);
- an indented block right after a line ending in ``:`` -> a code block (reST's literal block);
- a first sentence wrapped over lines -> one line (the API summary tables show the first line);
- ``h*``, ``V_a*`` (a starred symbol) -> an escaped star, not the start of emphasis; ``<Task>`` ->
  text, not an HTML tag.

Everything else passes through unchanged. Used by the griffe extension (``griffe_prose.py``) for the
API reference and by the env cards (``gen_env_cards.py``) for the task definitions.
"""

from __future__ import annotations

import html
import re
from collections.abc import Callable

#: name as written in a role (leading dots for relative names) -> identifier of the object, or None.
Resolver = Callable[[str], "str | None"]

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|obj|exc|const|type):`(?P<target>[^`]+)`")
CODE_SPAN = re.compile(r"(?P<ticks>`+)(?P<code>.+?)(?P=ticks)")
TOKEN = re.compile(f"{ROLE.pattern}|{CODE_SPAN.pattern}")
BORDER = re.compile(r"^ *=+( +=+)+ *$")
FENCE = re.compile(r"^ *(```|~~~)")
#: Google-style sections whose block lists entries ("name: text"; "a, b: text" for several names).
ENTRY_SECTION = re.compile(r"^ *(Args|Arguments|Parameters|Params|Keyword Args|Keyword Arguments|"
                           r"Other Parameters|Attributes|Raises|Warns):\s*$")
#: Google-style sections whose block is prose.
PROSE_SECTION = re.compile(r"^ *(Returns|Yields|Receives|Notes?|Warnings?|Deprecated):\s*$")
ENTRY = re.compile(r"^(?P<names>[A-Za-z_*][\w.*]*(?:, *[A-Za-z_*][\w.*]*)*(?: *\([^)]*\))?): +(?P<text>.*)$")
STARRED = re.compile(r"(?<=[\w)\]}])\*")
TAG_OPEN = re.compile(r"<(?=[A-Za-z/!?])")


def autoref(identifier: str, title: str) -> str:
    """An optional cross-reference: a link when ``identifier`` is rendered on the site, else the title."""
    return (f'<autoref identifier="{html.escape(identifier, quote=True)}" optional>'
            f"<code>{html.escape(title)}</code></autoref>")


def _role(target: str, resolve: Resolver | None) -> str:
    target = target.strip()
    short = target.startswith("~")
    name = target.lstrip("~")
    shown = name.lstrip(".")
    if short:
        shown = shown.rsplit(".", 1)[-1]
    identifier = (resolve(name) if resolve is not None else None) or name.lstrip(".")
    return autoref(identifier, shown)


def _text(segment: str, in_table: bool) -> str:
    segment = STARRED.sub(r"\\*", segment)
    segment = TAG_OPEN.sub("&lt;", segment)
    if in_table:
        segment = segment.replace("|", r"\|")
    return segment


def inline(line: str, resolve: Resolver | None = None, in_table: bool = False) -> str:
    """One line of prose: roles to references, code spans kept, the rest escaped where needed."""
    out, position = [], 0
    for match in TOKEN.finditer(line):
        out.append(_text(line[position:match.start()], in_table))
        if match["target"] is not None:
            out.append(_role(match["target"], resolve))
        else:
            out.append(match.group(0))
        position = match.end()
    out.append(_text(line[position:], in_table))
    return "".join(out)


def _columns(border: str) -> list[int]:
    """Start columns of a simple table's columns, from its border line."""
    return [m.start() for m in re.finditer(r"=+", border)]


def _cells(line: str, starts: list[int]) -> list[str]:
    bounds = [*starts[1:], None]
    return [line[start:end].strip() if len(line) > start else ""
            for start, end in zip(starts, bounds, strict=True)]


def simple_table(lines: list[str], start: int, resolve: Resolver | None = None) -> tuple[list[str], int]:
    """Markdown table for the reST simple table whose top border is ``lines[start]``; returns the
    Markdown lines and the index after the table. A line continues the row above when one of its
    cells other than the last is empty (reST: an empty first cell; the tables here also wrap the first
    cell). No closing border: the block is kept verbatim in a text fence."""
    starts = _columns(lines[start])
    borders, rows, header_rows = [start], [], None
    index = start + 1
    while index < len(lines):
        line = lines[index]
        if BORDER.match(line):
            borders.append(index)
            if len(borders) == 2:
                header_rows, rows = rows, []
            if len(borders) == 3:
                break
            index += 1
            continue
        if not line.strip():
            if len(borders) == 2 and rows and (index + 1 >= len(lines) or not lines[index + 1].strip()):
                break
            index += 1
            continue
        cells = _cells(line, starts)
        if rows and any(not cell for cell in cells[:-1]):
            rows[-1] = [f"{old} {new}".strip() for old, new in zip(rows[-1], cells, strict=True)]
        else:
            rows.append(cells)
        index += 1
    if len(borders) < 2:
        return ["```text", *lines[start:index], "```"], index
    end = borders[-1] + 1
    if len(borders) == 2:  # no header: the first row heads the table
        header_rows, rows = header_rows[:1], header_rows[1:]
    header = header_rows[0] if header_rows else [""] * len(starts)
    for extra in (header_rows or [])[1:]:
        header = [f"{old} {new}".strip() for old, new in zip(header, extra, strict=True)]

    def row(cells: list[str]) -> str:
        return "| " + " | ".join(inline(cell, resolve, in_table=True) for cell in cells) + " |"

    table = [row(header), "|" + "|".join("---" for _ in starts) + "|", *(row(cells) for cells in rows)]
    return table, end


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip(" "))


def _section_block(lines: list[str], start: int) -> tuple[list[str], int]:
    """The indented block under the section title ``lines[start]`` and the index after it (empty
    when the next line is not indented under the title)."""
    base, index, block = _indent(lines[start]), start + 1, []
    while index < len(lines) and (not lines[index].strip() or _indent(lines[index]) > base):
        block.append(lines[index])
        index += 1
    while block and not block[-1].strip():
        block.pop()
        index -= 1
    if not block or not block[0].strip():
        return [], start + 1
    return block, index


def google_section(title: str, block: list[str], entries: bool, resolve: Resolver | None) -> list[str]:
    """A Google-style section as a bold title and a list of its entries (or a paragraph): the code
    writes several names per entry ("airspeed, alpha, beta: ...") that a section parser would
    misread, so the entries are shown as written, one item each."""
    out = [f"**{title}**", ""]
    if not entries:
        return [*out, *(inline(line.strip(), resolve) for line in block if line.strip())]
    base = _indent(block[0])
    items: list[str] = []
    for line in block:
        if not line.strip():
            continue
        if _indent(line) > base and items:
            items[-1] += " " + inline(line.strip(), resolve)
            continue
        match = ENTRY.match(line.strip())
        if match:
            names = ", ".join(f"`{name.strip()}`" for name in match["names"].split(","))
            items.append(f"- {names}: {inline(match['text'], resolve)}")
        else:
            items.append("- " + inline(line.strip(), resolve))
    return [*out, *items]


def _join_summary(lines: list[str]) -> list[str]:
    """The first paragraph on one line when it is plain prose: the code wraps its first sentence over
    lines, and the API summaries show a docstring's first line."""
    end = next((i for i, line in enumerate(lines) if not line.strip()), len(lines))
    first = lines[:end]
    plain = all(line.strip() and not line.startswith((" ", "\t")) and not BORDER.match(line)
                and not FENCE.match(line) and not re.match(r"^([-*+] |\d+\. |\||#)", line) for line in first)
    if len(first) < 2 or not plain:
        return lines
    return [" ".join(line.strip() for line in first), *lines[end:]]


def to_markdown(text: str, resolve: Resolver | None = None) -> str:
    """Markdown for a docstring (already dedented, as ``inspect.cleandoc`` leaves it)."""
    lines = _join_summary(text.expandtabs(4).splitlines())
    out: list[str] = []
    in_fence = in_code = False
    previous = ""  # the previous source line, "" when blank

    def blank() -> None:
        if out and out[-1].strip():
            out.append("")

    index = 0
    while index < len(lines):
        line = lines[index]
        if FENCE.match(line):
            in_fence = not in_fence
            out.append(line)
        elif in_fence:
            out.append(line)
        elif not line.strip():
            out.append("")
        elif BORDER.match(line) and not in_code:
            blank()
            table, index = simple_table(lines, index, resolve)
            out.extend(table)
            out.append("")
            previous = ""
            continue
        elif not in_code and (ENTRY_SECTION.match(line) or PROSE_SECTION.match(line)) and \
                _section_block(lines, index)[0]:
            block, end = _section_block(lines, index)
            blank()
            out.extend(google_section(line.strip().rstrip(":"), block, bool(ENTRY_SECTION.match(line)),
                                      resolve))
            out.append("")
            previous, index = "", end
            continue
        elif _indent(line) >= 4 and (in_code or not previous or previous.rstrip().endswith(":")):
            if not in_code:
                blank()
            in_code = True
            out.append(line)
        else:
            if in_code:
                blank()
            in_code = False
            out.append(inline(line, resolve))
        previous = line if line.strip() else ""
        index += 1
    return "\n".join(out)
