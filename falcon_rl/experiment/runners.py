"""Run a sweep of cells through a :class:`~.cache.CellCache`: cached cells are read back, the others run
here, in worker processes or on Ray, and each result is written to the cache (by this process) as soon
as its cell finishes, so a killed sweep loses only the cells in flight.

- ``runner="local"``, ``workers=1``: one cell after the other in this process;
- ``runner="local"``, ``workers>1``: a ``concurrent.futures.ProcessPoolExecutor`` of ``workers``
  processes started with the spawn context (:func:`worker_pool`). The workers die with this process,
  however it ends (SIGKILL included: :func:`die_with_parent`), and an error here (a full disk writing
  a result) or Ctrl-C ends the cells in flight at once instead of waiting for them;
- ``runner="ray"``: one Ray task per cell on the cluster at ``ray_address``, or on a local Ray instance
  with ``num_cpus=workers`` (Ray is an optional extra: ``pip install 'falcon-rl[distributed]'``).

Every cell runs through :func:`~.cells.run_cell`, which seeds the global generators from the cell, so all
runners give the same numbers. The cell function's "module:attribute" is looked up here and sent with
the cell, together with this process's ``sys.path``, so functions registered at run time (a test's, a
script's) resolve in the workers too. A cell that raises does not stop the sweep: after it,
:class:`CellsFailedError` names the failed cells in one line (the finished ones are cached). A full disk
(or quota) is the exception: every later cell would fail the same way, so its ``OSError`` stops the
sweep (local runner) and reaches the caller as it is.
"""

from __future__ import annotations

import concurrent.futures as futures
import contextlib
import ctypes
import errno
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Iterable, Sequence
from typing import Any

from tqdm import tqdm

from .cache import CellCache
from .cells import Cell, cell_reference, run_cell

RUNNERS = ("local", "ray")
RAY_HINT = "pip install 'falcon-rl[distributed]'"
#: ``prctl`` option of Linux: the signal a process gets when the thread that started it ends.
PR_SET_PDEATHSIG = 1
#: How often a worker without ``prctl`` looks whether its parent is still there, s.
PARENT_POLL_SECONDS = 0.5
#: ``errno`` values of a full disk or quota: such an error in a cell stops the sweep.
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


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
    raising only the ``OSError`` of a full disk (:func:`_disk_full`)."""
    for path in paths:
        if path not in sys.path:
            sys.path.append(path)
    try:
        return True, run_cell(cell, reference, threads)
    except Exception as error:  # a failed cell is reported, the sweep goes on
        if _disk_full(error):
            raise
        return False, _error_line(error)


def _disk_full(error: BaseException) -> bool:
    """Whether ``error`` is the ``OSError`` of a full disk or quota (:data:`DISK_FULL`)."""
    return isinstance(error, OSError) and error.errno in DISK_FULL


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


def _parent_death_signal(signum: int) -> bool:
    """Ask Linux to send ``signum`` to this process when its parent ends; False where ``prctl`` is not
    available (other systems)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0) == 0
    except (OSError, AttributeError):  # no C library or no prctl in it
        return False


def watch_parent(parent: int, interval: float = PARENT_POLL_SECONDS) -> threading.Thread:
    """Start a daemon thread that ends this process (exit code 1) once its parent process is no longer
    ``parent`` (it ended, and the process was handed to another); returns the thread."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(interval)
        os._exit(1)

    thread = threading.Thread(target=watch, name="falcon-rl-watch-parent", daemon=True)
    thread.start()
    return thread


def die_with_parent(parent: int) -> None:
    """Worker initializer: end this worker when ``parent`` (the sweep's process, its pid) ends, however it
    ends. On Linux the kernel sends SIGKILL (``prctl(PR_SET_PDEATHSIG)``: nothing in a worker needs
    cleaning up, its results are written by the parent); elsewhere :func:`watch_parent` polls. A parent
    that ended before this ran is caught by the check that follows. (Linux signals when the *thread*
    that started the worker ends: the pool's workers are started by the thread that submits the cells,
    which waits for them.)"""
    if not _parent_death_signal(signal.SIGKILL):
        watch_parent(parent)
    if os.getppid() != parent:
        os._exit(1)


def _start_worker(parent: int) -> None:
    """Initializer of a :func:`worker_pool` worker: :func:`die_with_parent`, and a thread lock for tqdm's
    bars (its default, a multiprocessing lock, is reported as leaked by the resource tracker when the
    worker is terminated)."""
    die_with_parent(parent)
    tqdm.set_lock(threading.RLock())


@contextlib.contextmanager
def worker_pool(workers: int) -> Any:
    """A spawn-context ``ProcessPoolExecutor`` of ``workers`` processes that die with this one
    (:func:`die_with_parent`). Leaving the block by an exception (an error finishing a cell, Ctrl-C)
    cancels the queued calls and terminates the workers (the processes this one started while the pool
    was open), so the calls in flight end at once."""
    context = multiprocessing.get_context("spawn")
    before = set(multiprocessing.active_children())
    pool = futures.ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_start_worker,
                                       initargs=(os.getpid(),))
    try:
        yield pool
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        for process in set(multiprocessing.active_children()) - before:
            process.terminate()
        raise
    finally:
        pool.shutdown(wait=True)


def _run_processes(todo: list[tuple[str, Cell]], references: dict[str, str], paths: list[str], workers: int,
                   finish: Any, threads: int = 1) -> None:
    """Run ``todo`` on a :func:`worker_pool`, finishing each cell as it completes."""
    with worker_pool(min(workers, len(todo))) as pool:
        pending = {pool.submit(_execute, cell, references[cell.study], paths, threads): (key, cell)
                   for key, cell in todo}
        for future in futures.as_completed(pending):
            key, cell = pending[future]
            try:
                outcome = future.result()
            except Exception as error:  # the worker died (e.g. killed): the cell failed
                if _disk_full(error):
                    raise
                outcome = (False, _error_line(error))
            finish(key, cell, outcome)


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


__all__ = ["RUNNERS", "CellsFailedError", "die_with_parent", "import_ray", "run_cells", "watch_parent",
           "worker_pool"]
