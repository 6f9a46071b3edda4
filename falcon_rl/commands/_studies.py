"""``falcon-rl experiment altitude|maneuvers|ground-effect|robustness|all``: the paper's studies as one
sweep of cached cells (``falcon_rl.experiment``), then per study a folder with report.md,
tables.tex (the paper's layout), results.json and the figures. Every file is written atomically
(:mod:`falcon_rl.atomic_files`): a full disk stops the command with one line and leaves the earlier
outputs as they were. ``--out`` is checked before anything runs: writable, and short enough for the
longest file the sweep writes under it (:func:`study_outputs`)."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

from ..atomic_files import write_atomic
from ._common import UsageError, comma_list, output_dir

#: The files of each study's folder besides its figures.
STUDY_FILES = ("report.md", "tables.tex", "results.json")
#: The figures each study draws (``{airframe}``: one per airframe).
STUDY_FIGURES = {"altitude": ("altitude.png",), "maneuvers": ("bank_{airframe}.png", "tracks.png"),
                 "ground-effect": ("ground_effect.png",), "robustness": ("robustness.png",),
                 "sea-state": ("sea_state.png",), "landing": ("landing.png",)}
#: Characters allowed for the name of a training metric's log file (``logs/<run>/scalars/<metric>.csv``).
METRIC_NAME_ALLOWANCE = 32


def scale_of(args: argparse.Namespace) -> Any:
    """The scale of ``--scale`` with ``--seeds``, ``--episodes`` and ``--seconds`` applied."""
    from ..experiment.studies import SCALES

    scale = SCALES[args.scale]
    if args.seeds is not None:
        scale = replace(scale, seeds=tuple(range(args.seeds)))
    if args.episodes is not None:
        n = args.episodes
        scale = replace(scale, learned_episodes=n, baseline_episodes=n, mppi_episodes=n, maneuver_episodes=n,
                        mppi_maneuver_episodes=n, ge_episodes=n, robustness_episodes=n, sea_episodes=n,
                        sea_mppi_episodes=n, landing_episodes=n)
    if args.seconds is not None:
        scale = replace(scale, maneuver_seconds=args.seconds, robustness_seconds=args.seconds,
                        sea_seconds=args.seconds)
    return scale


def study_cells(args: argparse.Namespace, studies: list[str], out: Path) -> dict[str, list]:
    """{study: its cells} of the flags (UsageError for an unknown airframe or controller)."""
    from ..airframe import load_airframe
    from ..experiment.studies import AIRFRAMES, CONTROLLERS, STUDY_CONTROLLERS
    from ..experiment.studies import study_cells as cells_of

    airframes = tuple(load_airframe(a).name for a in comma_list(args.airframes or ",".join(AIRFRAMES),
                                                                  "--airframes"))
    scale = scale_of(args)
    options = {"backend": args.backend, "train": bool(args.train)}
    locations = {"policies": str(out / "policies")}  # where, not what: not in the cells' keys
    asked = (None if args.controllers is None
             else tuple(comma_list(args.controllers, "--controllers", CONTROLLERS)))
    return {study: cells_of(study, airframes, asked or STUDY_CONTROLLERS[study], scale, options, locations)
            for study in studies}


def study_outputs(per_study: dict[str, list], out: Path) -> list[str]:
    """The files the sweep of ``per_study`` writes under ``out``, relative to it: the cell files, each
    study's files and figures, and the policy files (with ``--train``, also the logs) of the learned
    cells (for the up-front length check of ``--out``)."""
    from ..experiment.studies import LEARNED, policy_folder

    files = []
    for study, cells in per_study.items():
        files += [f"cells/{cell.key()}.json" for cell in cells[:1]]
        files += [f"{study}/{name}" for name in STUDY_FILES]
        files += [f"{study}/{name.format(airframe=cell.airframe)}" for cell in cells
                  for name in STUDY_FIGURES[study]]
        files += [str(policy_folder(cell).relative_to(out) / name) for cell in cells
                  if cell.controller in LEARNED for name in _training_files(cell)]
    return files


def _training_files(cell: Any) -> list[str]:
    """The files of learned ``cell``'s policy folder: those its training writes (with --train; the metric
    logs' names allowed :data:`METRIC_NAME_ALLOWANCE` characters), else the policy file it reads."""
    if not cell.param_dict.get("train"):
        return ["policy.pt"]
    from ..recipes.runner import OUTPUT_FILES

    run = f"{cell.controller}_{cell.task}_{cell.airframe}"
    return [*OUTPUT_FILES, f"logs/{run}/scalars/{'x' * METRIC_NAME_ALLOWANCE}.csv"]


def run_studies(args: argparse.Namespace, studies: list[str]) -> tuple[dict[str, Any], str]:
    """Check ``--out``, run the sweep (cached cells skipped), write every study's outputs; (document,
    text)."""
    from ..experiment import CellCache, CellsFailedError, run_cells

    per_study = study_cells(args, studies, Path(args.out))
    out = output_dir(args.out, files=study_outputs(per_study, Path(args.out)))
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
    from ..experiment.study_layouts import STUDY_TABLES

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
    report = write_atomic(folder / "report.md", "\n".join(sections) + "\n")
    write_atomic(folder / "tables.tex", "\n\n".join(latex) + "\n")
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
    names = STUDY_FIGURES[study]
    written: list[Path | None] = []
    if study == "altitude":
        written.append(figures.plot_altitude_study(shown, folder / names[0]))
    elif study == "maneuvers":
        for airframe in dict.fromkeys(a for a, _ in shown):
            written.append(figures.plot_bank_facets_study(shown, airframe,
                                                          folder / names[0].format(airframe=airframe)))
        controllers = [c for c in ("ppo", "lqr", "mppi", "sac", "td3") if any(k[1] == c for k in shown)]
        if controllers:
            written.append(figures.plot_maneuver_tracks(shown, controllers[0], folder / names[1]))
    elif study == "ground-effect":
        written.append(figures.plot_ground_effect_study(shown, folder / names[0]))
    elif study == "robustness":
        written.append(figures.plot_robustness_study(shown, folder / names[0]))
    elif study == "sea-state":
        written.append(figures.plot_sea_state_study(shown, folder / names[0]))
    elif study == "landing":
        written.append(figures.plot_landing_study(shown, folder / names[0]))
    return [p for p in written if p is not None]
