"""Tables of protocol results in the paper's layout: markdown for people, JSON for programs.

Any registered task renders the same way: one section per task (its ``TaskSpec.title``), one column
per ``TaskSpec.metrics`` entry, one row per result, or per result and case for protocols whose
summary keys read "<case>/<metric>" (the attitude maneuvers).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..atomic_files import write_atomic
from ..envs.tasks import TASK_SPECS, Metric
from .protocols import ProtocolResult


def _fmt(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "---"
    return f"{value:.3g}" if abs(value) >= 1e-3 or value == 0 else f"{value:.1e}"


def cases(result: ProtocolResult) -> list[str]:
    """The "<case>/" prefixes of ``result.summary`` in order of appearance ([""] when it has none)."""
    found = [key.split("/", 1)[0] for key in result.summary if "/" in key]
    return list(dict.fromkeys(found)) or [""]


def _columns(results: list[ProtocolResult]) -> tuple[Metric, ...]:
    """The task's metric columns; for an unregistered task, every metric of the first result."""
    spec = TASK_SPECS.get(results[0].task)
    if spec is not None and spec.metrics:
        return spec.metrics
    case = cases(results[0])[0]
    prefix = f"{case}/" if case else ""
    return tuple(Metric(key[len(prefix):], key[len(prefix):]) for key in results[0].summary
                 if key.startswith(prefix))


def task_table(results: list[ProtocolResult]) -> str:
    """| Airframe | Alg. | [Case |] n | <metrics> | s / control step | for results of one task."""
    columns = _columns(results)
    with_cases = any(cases(r) != [""] for r in results)
    head = ["Airframe", "Alg.", *(["Case"] if with_cases else []), "n", *(m.header for m in columns),
            "s / control step"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        for case in cases(r):
            prefix = f"{case}/" if case else ""
            cells = [_fmt(r.summary.get(prefix + m.key, math.nan)) for m in columns]
            lines.append("| " + " | ".join([r.airframe, r.controller, *([case] if with_cases else []),
                                            str(r.settings.get("episodes", "")), *cells,
                                            f"{r.seconds_per_control_step:.2e}"]) + " |")
    return "\n".join(lines)


def result_document(result: ProtocolResult) -> dict:
    """JSON-ready summary: the table's fields by name plus the settings that produced them."""
    return {"task": result.task, "airframe": result.airframe, "controller": result.controller,
            **{k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in result.summary.items()},
            "seconds_per_control_step": result.seconds_per_control_step, "settings": result.settings}


def write_report(results: list[ProtocolResult], out: Path, figures: list[Path], title: str) -> Path:
    """Write ``report.md`` (a section per task, in order of first appearance) and ``results.json``
    under ``out``, each atomically; returns the markdown path."""
    lines = [f"# {title}", ""]
    for task in dict.fromkeys(r.task for r in results):
        spec = TASK_SPECS.get(task)
        heading = spec.title if spec is not None else task
        lines += [f"## {heading}", "", task_table([r for r in results if r.task == task]), ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    report = write_atomic(out / "report.md", "\n".join(lines) + "\n")
    documents = [result_document(r) for r in results]
    write_atomic(out / "results.json", json.dumps(documents, indent=2, default=str))
    return report
