"""``falcon-rl experiment altitude|maneuvers|ground-effect|robustness|all``: the paper's studies as one
sweep of cached cells (``falcon_rl.experiment``), then per study a folder with report.md,
tables.tex (the paper's layout), results.json and the figures."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from ._common import UsageError, comma_list, output_dir


def scale_of(args: argparse.Namespace) -> Any:
    """The scale of ``--scale`` with ``--seeds``, ``--episodes`` and ``--seconds`` applied."""
    from ..experiment.studies import SCALES

    scale = SCALES[args.scale]
    if args.seeds is not None:
        scale = replace(scale, seeds=tuple(range(args.seeds)))
    if args.episodes is not None:
        n = args.episodes
        scale = replace(scale, learned_episodes=n, baseline_episodes=n, mppi_episodes=n, maneuver_episodes=n,
                        mppi_maneuver_episodes=n, ge_episodes=n, robustness_episodes=n)
    if args.seconds is not None:
        scale = replace(scale, maneuver_seconds=args.seconds, robustness_seconds=args.seconds)
    return scale


def study_cells(args: argparse.Namespace, studies: list[str], out: Path) -> dict[str, list]:
    """{study: its cells} of the flags (UsageError for an unknown airframe or controller)."""
    from ..airframe import load_airframe
    from ..experiment.studies import AIRFRAMES, CONTROLLERS, STUDY_CONTROLLERS
    from ..experiment.studies import study_cells as cells_of

    airframes = tuple(load_airframe(a).name for a in comma_list(args.airframes or ",".join(AIRFRAMES),
                                                                  "--airframes"))
    scale = scale_of(args)
    options = {"backend": args.backend, "policies": str(out / "policies"), "train": bool(args.train)}
    asked = (None if args.controllers is None
             else tuple(comma_list(args.controllers, "--controllers", CONTROLLERS)))
    return {study: cells_of(study, airframes, asked or STUDY_CONTROLLERS[study], scale, options)
            for study in studies}


def run_studies(args: argparse.Namespace, studies: list[str]) -> tuple[dict[str, Any], str]:
    """Run the sweep (cached cells skipped), write every study's outputs; (document, text)."""
    from ..experiment import CellCache, CellsFailedError, run_cells

    out = output_dir(args.out)
    per_study = study_cells(args, studies, out)
    cells = [cell for cells in per_study.values() for cell in cells]
    failures: dict = {}
    try:
        results = run_cells(cells, CellCache(out / "cells"), runner=args.runner, workers=args.workers,
                            ray_address=args.ray_address, threads=args.threads)
    except CellsFailedError as error:
        results, failures = error.results, error.failures
    except ImportError as error:  # the Ray extra is missing
        raise UsageError(str(error)) from None
    documents, texts = {}, []
    for study, study_cells_ in per_study.items():
        document, text = write_study(study, study_cells_, results, failures, out / study, args)
        documents[study] = document
        texts.append(text)
    failed = [f"{cell.label()}: {error}" for cell, error in failures.items()]
    text = "\n\n".join(texts) + (f"\n\nfailed cells ({len(failed)}):\n" + "\n".join(failed) if failed else "")
    return {"studies": documents, "failed": failed, "out": str(out)}, text


def write_study(study: str, cells: list, results: dict, failures: dict, folder: Path,
                args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    """report.md, tables.tex, results.json and the figures of one study; (summary document, text)."""
    from ..experiment import (
        experiment_document,
        group_cells,
        latex_table,
        markdown_table,
        rows_from_groups,
        write_results,
    )
    from ..experiment.study_tables import STUDY_TABLES

    folder.mkdir(parents=True, exist_ok=True)
    groups = group_cells(cells, results)
    settings = {"study": study, "scale": args.scale, "runner": args.runner, "backend": args.backend}
    results_path = write_results(folder / "results.json",
                                 experiment_document(settings, cells, results, failures, groups))
    sections, latex = [f"# {study}: {args.scale} scale", ""], []
    for table in STUDY_TABLES[study]:
        rows = rows_from_groups(groups, table.labels)
        sections += [f"## {table.title}", "", markdown_table(rows, table.columns, table.headers), ""]
        latex.append(latex_table(rows, table.columns, table.title, f"tab:{study}-{table.name}",
                                 table.headers))
    status = _statuses(cells, results)
    if status:
        sections += ["## Cells without a result", "", *status, ""]
    figures = study_figures(study, cells, results, folder)
    sections += [f"![{p.stem}]({p.name})" for p in figures]
    report = folder / "report.md"
    report.write_text("\n".join(sections) + "\n")
    (folder / "tables.tex").write_text("\n\n".join(latex) + "\n")
    document = {"report": str(report), "results": str(results_path), "tables": str(folder / "tables.tex"),
                "figures": [str(p) for p in figures], "cells": len(cells),
                "finished": sum(cell.key() in results for cell in cells)}
    return document, "\n".join(sections[2:])


def _statuses(cells: list, results: dict) -> list[str]:
    """One line per cell whose result carries a status (e.g. "no policy")."""
    lines = []
    for cell in cells:
        status = results.get(cell.key(), {}).get("status")
        if status:
            lines.append(f"- {cell.airframe} / {cell.controller} (seed {cell.seed}, draw {cell.draw}): "
                         f"{status}")
    return lines


def first_replicates(cells: list, results: dict) -> dict[tuple[str, str], dict]:
    """{(airframe, controller): result} of each group's first finished replicate."""
    out: dict[tuple[str, str], dict] = {}
    for cell in cells:
        result = results.get(cell.key())
        if result is not None and (cell.airframe, cell.controller) not in out:
            out[(cell.airframe, cell.controller)] = result
    return out


def study_figures(study: str, cells: list, results: dict, folder: Path) -> list[Path]:
    """The study's figures from the cached traces (those it has)."""
    from ..viz import experiment as figures

    shown = first_replicates(cells, results)
    written: list[Path | None] = []
    if study == "altitude":
        written.append(figures.plot_altitude_study(shown, folder / "altitude.png"))
    elif study == "maneuvers":
        for airframe in dict.fromkeys(a for a, _ in shown):
            written.append(figures.plot_bank_facets_study(shown, airframe, folder / f"bank_{airframe}.png"))
        controllers = [c for c in ("ppo", "lqr", "mppi", "sac", "td3") if any(k[1] == c for k in shown)]
        if controllers:
            written.append(figures.plot_maneuver_tracks(shown, controllers[0], folder / "tracks.png"))
    elif study == "ground-effect":
        written.append(figures.plot_ground_effect_study(shown, folder / "ground_effect.png"))
    elif study == "robustness":
        written.append(figures.plot_robustness_study(shown, folder / "robustness.png"))
    return [p for p in written if p is not None]
