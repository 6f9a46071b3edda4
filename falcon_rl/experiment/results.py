"""Tables of an experiment in the paper's layout (markdown for people, LaTeX for the paper) and its
``results.json`` for programs.

A table has label columns (by default airframe and controller) and one column per metric; each entry is
"mean ± std" of the replicates (and "[ci_low, ci_high]" with ``ci=True``), or ``--`` where no replicate
gave a value (an empty :class:`~.statistics.Aggregate`, a missing metric).

``results.json`` (written by :func:`write_results`, built by :func:`experiment_document`)::

    {
      "format": "falcon-rl-experiment/1",
      "created": "2025-01-01T00:00:00+00:00",                 # ISO-8601, UTC
      "version": {"falcon_rl": "0.1.0", "commit": "<40 hex>" | null},
      "settings": {...},                                       # free-form JSON: what the sweep ran with
      "cells": [                                               # one per replicate (per seed and draw)
        {"key": "<32 hex>", "study": str, "task": str, "airframe": str, "controller": str,
         "seed": int, "draw": int, "params": {name: value},
         "locations": {name: path},                            # only when the cell has any
         "status": "finished" | "failed", "error": str | null,
         "summary": {metric: float | null}, "seconds": float | null}
      ],
      "aggregates": [                                          # one per table entry (cells but seed, draw)
        {"study": str, "task": str, "airframe": str, "controller": str, "params": {name: value},
         "replicates": ["<key>", ...], "missing": ["<key>", ...],
         "metrics": {metric: {"mean": float | null, "std": float | null, "n": int, "n_excluded": int,
                              "ci_low": float | null, "ci_high": float | null, "iqm": float | null,
                              "empty": bool}}}
      ]
    }

Non-finite numbers are written as null (standard JSON). ``std`` is the sample deviation (ddof=1), the
interval a 95 % percentile bootstrap of the mean, ``iqm`` the interquartile mean (see
:mod:`.statistics`); ``n`` counts the finite values, ``n_excluded`` the others.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from .cache import write_json_atomic
from .cells import Cell, code_version, jsonable
from .statistics import Aggregate, CellGroup, group_cells

RESULTS_FORMAT = "falcon-rl-experiment/1"
#: Text of an entry without a value.
EMPTY = "--"
_LATEX_SPECIAL = {"\\": r"\textbackslash{}", "&": r"\&", "%": r"\%", "$": r"\$", "#": r"\#", "_": r"\_",
                  "{": r"\{", "}": r"\}", "~": r"\textasciitilde{}", "^": r"\textasciicircum{}"}


@dataclass(frozen=True)
class Column:
    """A metric column: ``key`` in the aggregates, ``header`` shown (unit included), ``digits`` after
    the decimal point."""

    key: str
    header: str
    digits: int = 2


@dataclass(frozen=True)
class Row:
    """A table row: its label texts (one per label column) and metric -> Aggregate (or a plain number,
    or None for an empty entry)."""

    labels: tuple[str, ...]
    values: Mapping[str, Aggregate | float | None]


def _columns(columns: Sequence[Column | str]) -> list[Column]:
    if not columns:
        raise ValueError("a table needs at least one column")
    return [c if isinstance(c, Column) else Column(str(c), str(c)) for c in columns]


def rows_from_groups(groups: Iterable[CellGroup], labels: Sequence[str] = ("airframe", "controller")
                     ) -> list[Row]:
    """One row per group, labelled by the group's ``labels`` fields (a parameter name picks its value)."""
    rows = []
    for group in groups:
        params = dict(group.params)
        texts = []
        for name in labels:
            if hasattr(group, name) and name != "params":
                texts.append(str(getattr(group, name)))
            elif name in params:
                texts.append(str(params[name]))
            else:
                raise ValueError(f"row label {name!r} is neither a cell field nor a parameter")
        rows.append(Row(tuple(texts), dict(group.aggregates)))
    return rows


def latex_escape(text: str) -> str:
    """``text`` with LaTeX's special characters escaped (underscores included)."""
    return "".join(_LATEX_SPECIAL.get(char, char) for char in text)


def format_value(value: Aggregate | float | None, digits: int = 2, ci: bool = False, latex: bool = False
                 ) -> str:
    """"mean ± std" (and " [low, high]" with ``ci``) of an aggregate of several replicates, the number
    alone for one replicate (as the paper writes its LQR rows) or a float, ``--`` for an empty
    aggregate, a non-finite number or None."""
    if value is None or (isinstance(value, Aggregate) and value.empty):
        return EMPTY
    if isinstance(value, Aggregate) and value.n == 1:
        value = value.mean
    if not isinstance(value, Aggregate):
        number = float(value)
        if not math.isfinite(number):
            return EMPTY
        return f"${number:.{digits}f}$" if latex else f"{number:.{digits}f}"
    pm = r" \pm " if latex else " ± "
    text = f"{value.mean:.{digits}f}{pm}{value.std:.{digits}f}"
    text = f"${text}$" if latex else text
    if ci:
        interval = f"[{value.ci_low:.{digits}f}, {value.ci_high:.{digits}f}]"
        text += rf" {{\scriptsize ${interval}$}}" if latex else f" {interval}"
    return text


def _check_rows(rows: Sequence[Row], label_headers: Sequence[str]) -> None:
    for row in rows:
        if len(row.labels) != len(label_headers):
            raise ValueError(f"row {row.labels!r} has {len(row.labels)} labels for {len(label_headers)} "
                             f"label columns")


def markdown_table(rows: Sequence[Row], columns: Sequence[Column | str],
                   label_headers: Sequence[str] = ("Airframe", "Alg."), ci: bool = False) -> str:
    """| <label headers> | <column headers> | with one line per row (entries: :func:`format_value`)."""
    columns = _columns(columns)
    _check_rows(rows, label_headers)
    head = [*label_headers, *(c.header for c in columns)]
    lines = ["| " + " | ".join(head) + " |",
             "|" + "---|" * len(label_headers) + "---:|" * len(columns)]
    for row in rows:
        entries = [format_value(row.values.get(c.key), c.digits, ci) for c in columns]
        lines.append("| " + " | ".join([*row.labels, *entries]) + " |")
    return "\n".join(lines)


def latex_table(rows: Sequence[Row], columns: Sequence[Column | str], caption: str, label: str,
                label_headers: Sequence[str] = ("Airframe", "Alg."), ci: bool = False) -> str:
    """A booktabs ``table`` (``\\toprule``/``\\midrule``/``\\bottomrule``; needs ``\\usepackage{booktabs}``):
    label columns left-aligned, metrics centred; the first label is written where it changes, with a
    ``\\midrule`` between its blocks (the paper's airframe blocks); text escaped, empty entries ``--``."""
    columns = _columns(columns)
    _check_rows(rows, label_headers)
    spec = "l" * len(label_headers) + "c" * len(columns)
    head = [latex_escape(h) for h in label_headers] + [latex_escape(c.header) for c in columns]
    lines = [r"\begin{table}[t]", r"\centering", rf"\caption{{{latex_escape(caption)}}}",
             rf"\label{{{label}}}", rf"\begin{{tabular}}{{{spec}}}", r"\toprule", " & ".join(head) + r" \\",
             r"\midrule"]
    previous: str | None = None
    for index, row in enumerate(rows):
        labels = [latex_escape(text) for text in row.labels]
        if labels and previous is not None and row.labels[0] == previous:
            labels[0] = ""
        elif labels and index > 0:
            lines.append(r"\midrule")
        previous = row.labels[0] if row.labels else None
        entries = [format_value(row.values.get(c.key), c.digits, ci, latex=True) for c in columns]
        lines.append(" & ".join([*labels, *entries]) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", r"\end{table}"]
    return "\n".join(lines)


def experiment_document(settings: Mapping[str, Any], cells: Sequence[Cell], results: Mapping[str, Mapping],
                        failures: Mapping[Cell, str] | None = None,
                        groups: Sequence[CellGroup] | None = None) -> dict[str, Any]:
    """The ``results.json`` document (module docstring) of ``cells`` with ``results`` (key -> result),
    the ``failures`` (cell -> error line) and the aggregates (:func:`~.statistics.group_cells` of the
    cells unless ``groups`` are given)."""
    failures = dict(failures or {})
    rows, seen = [], set()
    for cell in cells:
        key = cell.key()
        if key in seen:
            continue
        seen.add(key)
        result = results.get(key)
        rows.append({"key": key, **cell.to_dict(), "status": "finished" if result is not None else "failed",
                     "error": failures.get(cell, None if result is not None else "no result"),
                     "summary": dict(result["summary"]) if result is not None else {},
                     "seconds": result.get("seconds") if result is not None else None})
    groups = group_cells(cells, results) if groups is None else groups
    return {"format": RESULTS_FORMAT, "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "version": code_version(), "settings": dict(settings), "cells": rows,
            "aggregates": [group.to_dict() for group in groups]}


def write_results(path: str | Path, document: Mapping[str, Any]) -> Path:
    """Write ``document`` (a ``results.json`` document, see the module docstring) to ``path`` atomically
    as standard JSON (non-finite numbers as null); returns the path."""
    if document.get("format") != RESULTS_FORMAT:
        raise ValueError(f"results document format must be {RESULTS_FORMAT!r}, "
                         f"got {document.get('format')!r}")
    missing = [name for name in ("settings", "cells", "aggregates") if name not in document]
    if missing:
        raise ValueError(f"results document lacks {missing}")
    return write_json_atomic(Path(path), jsonable(document))


__all__ = ["EMPTY", "RESULTS_FORMAT", "Column", "Row", "experiment_document", "format_value", "latex_escape",
           "latex_table", "markdown_table", "rows_from_groups", "write_results"]
