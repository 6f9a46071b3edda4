"""Run a sweep of cells through a :class:`~.cache.CellCache`: cached cells are read back, the others run
here, in worker processes or on Ray, and each result is written to the cache (by this process) as soon
as its cell finishes, so a killed sweep loses only the cells in flight.

- ``runner="local"``, ``workers=1``: one cell after the other in this process;
- ``runner="local"``, ``workers>1``: a ``concurrent.futures.ProcessPoolExecutor`` of ``workers``
  processes started with the spawn context;
- ``runner="ray"``: one Ray task per cell on the cluster at ``ray_address``, or on a local Ray instance
  with ``num_cpus=workers`` (Ray is an optional extra: ``pip install 'falcon-rl[distributed]'``).

Every cell runs through :func:`~.cells.run_cell`, which seeds the global generators from the cell, so all
runners give the same numbers. The cell function's "module:attribute" is looked up here and sent with
the cell, together with this process's ``sys.path``, so functions registered at run time (a test's, a
script's) resolve in the workers too. A cell that raises does not stop the sweep: after it,
:class:`CellsFailedError` names the failed cells in one line (the finished ones are cached).
"""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import multiprocessing
import sys
from collections.abc import Iterable, Sequence
from typing import Any

from tqdm import tqdm

from .cache import CellCache
from .cells import Cell, cell_reference, run_cell

RUNNERS = ("local", "ray")
RAY_HINT = "pip install 'falcon-rl[distributed]'"


class CellsFailedError(RuntimeError):
    """Some cells of a sweep raised; ``failures`` maps each to its error line, ``results`` holds the
    results of the others (cached)."""

    def __init__(self, failures: dict[Cell, str], results: dict[str, dict[str, Any]], total: int):
        self.failures = failures
        self.results = results
        names = "; ".join(f"{cell.label()} ({error})" for cell, error in failures.items())
        super().__init__(f"{len(failures)} of {total} cells failed: {names}")


def _execute(cell: Cell, reference: str, paths: Sequence[str], threads: int = 1) -> tuple[bool, Any]:
    """Worker side: (True, result) or (False, "Type: message") of ``cell`` on ``threads`` torch threads,
    never raising."""
    for path in paths:
        if path not in sys.path:
            sys.path.append(path)
    try:
        return True, run_cell(cell, reference, threads)
    except Exception as error:  # a failed cell is reported, the sweep goes on
        return False, _error_line(error)


def _error_line(error: BaseException) -> str:
    """``"Type: first line of the message"``."""
    lines = str(error).strip().splitlines()
    return f"{type(error).__name__}: {lines[0]}" if lines else type(error).__name__


def import_ray() -> Any:
    """The ``ray`` module, or a one-line ImportError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise ImportError(f"runner 'ray' needs Ray, which is not installed: {RAY_HINT}") from None
    return ray


def _check(runner: str, workers: int) -> None:
    if runner not in RUNNERS:
        raise ValueError(f"runner must be one of {RUNNERS}, got {runner!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an int >= 1, got {workers!r}")


def run_cells(cells: Iterable[Cell], cache: CellCache, runner: str = "local", workers: int = 1,
              ray_address: str | None = None, progress: bool = True, threads: int = 1
              ) -> dict[str, dict[str, Any]]:
    """Results of ``cells`` (cell key -> result): cached ones read back, the others run (see the module
    docstring) on ``threads`` torch CPU threads each and cached as each finishes. Raises
    :class:`CellsFailedError` after the sweep when some cells raised, and ValueError for a bad runner or
    worker count or a study without a cell function."""
    _check(runner, workers)
    unique = list({cell.key(): cell for cell in cells}.items())
    references = {cell.study: cell_reference(cell.study) for _, cell in unique}  # fail before any run
    results: dict[str, dict[str, Any]] = {}
    todo: list[tuple[str, Cell]] = []
    for key, cell in unique:
        cached = cache.get(cell)
        if cached is None:
            todo.append((key, cell))
        else:
            results[key] = cached
    failures: dict[Cell, str] = {}
    bar = tqdm(total=len(unique), initial=len(results), desc="cells", unit="cell", disable=not progress,
               leave=False)

    def finish(key: str, cell: Cell, outcome: tuple[bool, Any]) -> None:
        ok, value = outcome
        if ok:
            cache.put(cell, value)
            results[key] = value
        else:
            failures[cell] = value
            bar.set_postfix(failed=len(failures))
        bar.update(1)

    paths = list(sys.path)
    try:
        if not todo:
            pass
        elif runner == "ray":
            _run_ray(todo, references, paths, workers, ray_address, finish, threads)
        elif workers == 1:
            for key, cell in todo:
                bar.set_description(f"cells ({cell.label()})")
                finish(key, cell, _execute(cell, references[cell.study], (), threads))
        else:
            _run_processes(todo, references, paths, workers, finish, threads)
    finally:
        bar.close()
    if failures:
        raise CellsFailedError(failures, results, len(unique))
    return results


def _run_processes(todo: list[tuple[str, Cell]], references: dict[str, str], paths: list[str], workers: int,
                   finish: Any, threads: int = 1) -> None:
    """Run ``todo`` on a spawn-context process pool, finishing each cell as it completes."""
    context = multiprocessing.get_context("spawn")
    with futures.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=context) as pool:
        pending = {pool.submit(_execute, cell, references[cell.study], paths, threads): (key, cell)
                   for key, cell in todo}
        try:
            for future in futures.as_completed(pending):
                key, cell = pending[future]
                try:
                    outcome = future.result()
                except Exception as error:  # the worker died (e.g. killed): the cell failed
                    outcome = (False, _error_line(error))
                finish(key, cell, outcome)
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def _run_ray(todo: list[tuple[str, Cell]], references: dict[str, str], paths: list[str], workers: int,
             address: str | None, finish: Any, threads: int = 1) -> None:
    """Run ``todo`` as Ray tasks (one per cell), finishing each cell as it completes."""
    ray = import_ray()
    started_here = not ray.is_initialized()
    if started_here:
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
        else:
            ray.init(address=address, logging_level="ERROR")
    pending: dict[Any, tuple[str, Cell]] = {}
    try:
        remote = ray.remote(num_cpus=1, max_retries=0)(_execute)
        pending = {remote.remote(cell, references[cell.study], paths, threads): (key, cell)
                   for key, cell in todo}
        waiting = list(pending)
        while waiting:
            done, waiting = ray.wait(waiting, num_returns=1)
            for ref in done:
                key, cell = pending[ref]
                try:
                    outcome = ray.get(ref)
                except Exception as error:  # the worker died or the task could not run
                    outcome = (False, _error_line(error))
                finish(key, cell, outcome)
    except BaseException:  # interrupted: stop the cells in flight (the finished ones are cached)
        for ref in pending:
            with contextlib.suppress(Exception):  # already finished or gone
                ray.cancel(ref, force=True)
        raise
    finally:
        if started_here:
            ray.shutdown()


__all__ = ["RUNNERS", "CellsFailedError", "import_ray", "run_cells"]
