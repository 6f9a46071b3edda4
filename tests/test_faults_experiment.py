"""Faults of ``falcon-rl experiment``, its runner and its cell cache, and of the shared output-folder check,
found by trying, one case per row and variant:

1. the workers of ``--workers N`` die with the sweep's process, however it is killed;
2. the cache is keyed on the settings, not on how ``--out`` is spelt or where it lies;
3. a full disk is one line, exit 1, no temporary, earlier outputs intact; an error ends the cells in
   flight at once;
4. a malformed-but-JSON cell file is a one-line warning and a recomputed cell; a folder at a cell file's
   name is refused in one line before anything runs;
5. concurrent writability checks of one folder do not collide;
6. an ``--out`` too long for the files written under it is refused up front;
7. every output has the permissions of an ordinary new file.

The studies' cell function is replaced by a toy (:func:`toy_altitude`), so a sweep takes a moment.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

import falcon_rl.experiment.studies  # noqa: F401  (registers the studies' cell functions first)
from falcon_rl.cli import main
from falcon_rl.commands._common import UsageError, output_dir, output_file
from falcon_rl.experiment.cache import CellCache
from falcon_rl.experiment.cells import CELL_FUNCTIONS, Cell

#: Cells the toy cell function ran in this process.
CALLS: list[Cell] = []
STUDY = ("altitude", "--airframes", "navion", "--controllers", "lqr")


def toy_altitude(cell: Cell) -> dict:
    """A stand-in for the altitude study's cell function: a summary and nothing to draw."""
    CALLS.append(cell)
    return {"summary": {"survival": 1.0, "rmse_m": 0.1 * int(cell.param_dict["episodes"])}}


@pytest.fixture(autouse=True)
def toy_study(monkeypatch):
    monkeypatch.setitem(CELL_FUNCTIONS, "altitude", f"{__name__}:toy_altitude")
    CALLS.clear()


def experiment(*args: str) -> tuple[int, str]:
    """(exit code, stderr without the progress bar's lines) of ``falcon-rl experiment ARGS --json`` run
    here."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        code = main(["experiment", *args, "--json"])
    lines = err.getvalue().replace("\r", "\n").splitlines()
    return code, "\n".join(line for line in lines if line.strip() and not line.startswith("cells"))


def outputs(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ---- 1. workers die with their parent
PARENT_WITH_POOL = """
import sys, time
sys.path.insert(0, {folder!r})
from falcon_rl.experiment.runners import worker_pool
from sleeper import mark_and_sleep
with worker_pool(2) as pool:
    calls = [pool.submit(mark_and_sleep, {folder!r}) for _ in range(2)]
    time.sleep(120)
"""
PARENT_WITH_WATCHER = """
import subprocess, sys, time
child = "import os, sys, time; sys.path.insert(0, {folder!r}); from sleeper import mark_and_sleep; " \\
        "from falcon_rl.experiment.runners import watch_parent; watch_parent(os.getppid(), 0.1); " \\
        "mark_and_sleep({folder!r})"
children = [subprocess.Popen([sys.executable, "-c", child]) for _ in range(2)]
time.sleep(120)
"""
SLEEPER = """
import os, pathlib, time
from tqdm import tqdm
def mark_and_sleep(folder):
    with tqdm(total=1, disable=True):  # as a cell's progress bar would
        pathlib.Path(folder, f"pid-{os.getpid()}").touch()
        time.sleep(60)
"""


def alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie waiting for a reaper counts as ended)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


@pytest.mark.parametrize(("parent", "signum"), [
    (PARENT_WITH_POOL, signal.SIGKILL), (PARENT_WITH_POOL, signal.SIGTERM),
    (PARENT_WITH_WATCHER, signal.SIGKILL),  # the portable fallback, where prctl is missing
], ids=["pool-sigkill", "pool-sigterm", "watcher-sigkill"])
def test_workers_die_with_their_parent(parent: str, signum: int, tmp_path: Path) -> None:
    (tmp_path / "sleeper.py").write_text(SLEEPER)
    process = subprocess.Popen([sys.executable, "-c", parent.format(folder=str(tmp_path))],
                               stderr=subprocess.DEVNULL)  # the killed parent's resource tracker speaks
    workers: list[int] = []
    try:
        deadline = time.monotonic() + 60
        while len(workers) < 2 and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.1)
            workers = [int(p.name[4:]) for p in tmp_path.glob("pid-*")]
        assert len(workers) == 2, "the workers did not start"
        process.send_signal(signum)
        process.wait(10)
        deadline = time.monotonic() + 5
        while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [pid for pid in workers if alive(pid)], "workers outlived their parent"
    finally:
        process.kill()
        for pid in workers:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


# ---- 2. the cache is keyed on the settings
@pytest.mark.parametrize("second", ["relative", "moved"])
def test_the_same_settings_into_another_spelling_of_out_recompute_nothing(second: str, tmp_path: Path,
                                                                          monkeypatch) -> None:
    first = tmp_path / "a1"
    assert experiment(*STUDY, "--out", str(first))[0] == 0
    assert len(CALLS) == 1
    if second == "moved":
        first = first.rename(tmp_path / "moved")
    monkeypatch.chdir(tmp_path)
    assert experiment(*STUDY, "--out", first.name)[0] == 0
    assert len(CALLS) == 1, "a cell was recomputed"


@pytest.mark.parametrize("controllers", ["lqr", "ppo"])
def test_cell_keys_leave_out_the_policies_folder(controllers: str, tmp_path: Path) -> None:
    from falcon_rl.cli import build_parser
    from falcon_rl.commands._studies import study_cells

    def keys(out: str) -> list[str]:
        argv = ["experiment", "altitude", "--controllers", controllers, "--seeds", "2", "--out", out]
        args = build_parser(argv).parse_args(argv)
        cells = study_cells(args, ["altitude"], Path(out))["altitude"]
        assert all(dict(c.locations)["policies"] == str(Path(out) / "policies") for c in cells)
        return [cell.key() for cell in cells]

    assert keys(str(tmp_path / "a1")) == keys("a1") == keys(str(tmp_path / "elsewhere" / "b2"))


def test_a_cache_file_of_the_earlier_key_is_still_read(tmp_path: Path) -> None:
    cell = Cell.make("altitude", "altitude", "navion", "lqr", 0, 0, {"episodes": 1},
                     {"policies": "x/policies"})
    cache = CellCache(tmp_path)
    cache.put(cell.legacy(), {"summary": {"rmse_m": 0.5}})  # as earlier versions wrote it
    assert cell.legacy().key() != cell.key()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert cache.get(cell)["summary"] == {"rmse_m": 0.5}


# ---- 3. a full disk
@pytest.fixture
def full_disk(monkeypatch):
    """``full_disk(name)``: from now on, syncing a file whose name contains ``name`` fails as a full disk
    does (every atomic write syncs its temporary before moving it into place)."""
    if not Path("/proc/self/fd").is_dir():
        pytest.skip("needs /proc/self/fd to tell which file is synced")
    real_fsync = os.fsync

    def arm(name: str) -> None:
        def fsync(fd: int) -> None:
            if name in os.readlink(f"/proc/self/fd/{fd}"):
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            real_fsync(fd)
        monkeypatch.setattr(os, "fsync", fsync)
    return arm


@pytest.mark.parametrize("target", ["report.md", "tables.tex"])
def test_a_full_disk_is_one_line_and_leaves_earlier_outputs(target: str, tmp_path: Path, full_disk) -> None:
    assert experiment(*STUDY, "--out", str(tmp_path))[0] == 0
    before = outputs(tmp_path)
    full_disk(target)
    code, err = experiment(*STUDY, "--episodes", "3", "--out", str(tmp_path))  # a new cell, new tables
    assert code == 1 and len(err.splitlines()) == 1 and "No space left on device" in err, err
    after = outputs(tmp_path)
    assert after[f"altitude/{target}"] == before[f"altitude/{target}"]
    assert not [name for name in after if name.endswith(".tmp")]


def disk_full_altitude(cell: Cell) -> dict:
    """A cell function that finds the disk full (e.g. while it trains a policy)."""
    CALLS.append(cell)
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "policies/ppo/checkpoint.pt")


@pytest.mark.parametrize("workers", ["1", "2"])
def test_a_full_disk_inside_a_cell_stops_the_sweep_in_one_line(workers: str, tmp_path: Path,
                                                               monkeypatch) -> None:
    monkeypatch.setitem(CELL_FUNCTIONS, "altitude", f"{__name__}:disk_full_altitude")
    code, err = experiment("altitude", "--airframes", "navion,volantex_ranger", "--controllers", "lqr",
                           "--workers", workers, "--out", str(tmp_path))
    assert code == 1 and len(err.splitlines()) == 1, err
    assert err.endswith("No space left on device: 'policies/ppo/checkpoint.pt'"), err
    assert len(CALLS) == (1 if workers == "1" else 0)  # in-process: the second cell never ran
    assert not list(tmp_path.rglob("*.tmp")) and not (tmp_path / "altitude").exists()


PARENT_FAILING = """
import sys, time
sys.path.insert(0, {folder!r})
from falcon_rl.experiment.runners import worker_pool
from sleeper import mark_and_sleep
start = time.monotonic()
try:
    with worker_pool(2) as pool:
        calls = [pool.submit(mark_and_sleep, {folder!r}) for _ in range(2)]
        while len(list(__import__("pathlib").Path({folder!r}).glob("pid-*"))) < 2:
            time.sleep(0.05)
        raise OSError(28, "No space left on device")
except OSError:
    print(time.monotonic() - start)
"""


def test_an_error_during_a_pooled_sweep_ends_the_cells_in_flight_quietly(tmp_path: Path) -> None:
    (tmp_path / "sleeper.py").write_text(SLEEPER)
    done = subprocess.run([sys.executable, "-c", PARENT_FAILING.format(folder=str(tmp_path))],
                          capture_output=True, text=True, timeout=60)
    assert float(done.stdout) < 20, "the block waited for the cells in flight"
    assert done.stderr == ""  # e.g. no resource tracker's word of leaked semaphores (tqdm's lock)


# ---- 4. malformed cell files
def _with(document: dict, path: tuple[str, ...], value: object) -> str:
    target = document
    for name in path[:-1]:
        target = target[name]
    target[path[-1]] = value
    return json.dumps(document)


def _survival(text: str) -> object:
    """A damage that writes ``text`` in place of the survival number."""
    return lambda document, _: document.replace('"survival": 1.0', f'"survival": {text}')


MALFORMED = {
    "int-too-long-for-python": _survival("9" * 5000),  # (a warning already before: kept as a guard)
    "int-too-large-for-a-float": _survival("9" * 400),
    "nesting-too-deep": _survival("[" * 100_000 + "]" * 100_000),
    "seconds-a-string": lambda text, doc: _with(doc, ("result", "seconds"), "soon"),
    "status-a-number": lambda text, doc: _with(doc, ("result", "status"), 3),
    "traces-a-list": lambda text, doc: _with(doc, ("result", "traces"), [1, 2]),
}


@pytest.mark.parametrize("damage", list(MALFORMED))
def test_a_malformed_cell_file_is_a_warning_and_the_cell_reruns(damage: str, tmp_path: Path) -> None:
    assert experiment(*STUDY, "--out", str(tmp_path))[0] == 0
    (path,) = (tmp_path / "cells").glob("*.json")
    text = path.read_text()
    path.write_text(MALFORMED[damage](text, json.loads(text)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code, err = experiment(*STUDY, "--out", str(tmp_path))
    assert code == 0, err
    messages = [str(w.message) for w in caught if "cache file" in str(w.message)]
    assert len(messages) == 1 and str(path) in messages[0] and "recomputing altitude/altitude/navion/lqr" \
        in messages[0] and "\n" not in messages[0], messages
    assert len(CALLS) == 2 and json.loads(path.read_text())["result"]["summary"]["survival"] == 1.0


def test_a_folder_at_a_cell_files_name_is_refused_before_anything_runs(tmp_path: Path) -> None:
    assert experiment(*STUDY, "--out", str(tmp_path))[0] == 0
    (path,) = (tmp_path / "cells").glob("*.json")
    path.unlink()
    path.mkdir()
    code, err = experiment(*STUDY, "--out", str(tmp_path))
    assert code == 2 and len(err.splitlines()) == 1 and str(path) in err and "not a file" in err, err
    assert len(CALLS) == 1 and path.is_dir()


# ---- 5. concurrent writability checks
def test_concurrent_writability_checks_do_not_collide(tmp_path: Path) -> None:
    refused: list[str] = []

    def check() -> None:
        for _ in range(250):
            try:
                output_dir(tmp_path)
            except UsageError as error:
                refused.append(str(error))

    threads = [threading.Thread(target=check) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert refused == [] and list(tmp_path.iterdir()) == []


# ---- 6. paths too long for the system
def _long_folder(root: Path, length: int) -> Path:
    """A path of ``length`` characters below ``root`` (components of at most 200), not created."""
    path = str(root)
    while len(path) < length - 201:
        path += "/" + "d" * 200
    return Path(path + "/" + "e" * (length - len(path) - 1))


@pytest.mark.parametrize(("length", "code"), [(4045, 2), (4069, 2), (3900, 0)])
def test_an_out_too_long_for_its_files_is_refused_up_front(length: int, code: int, tmp_path: Path) -> None:
    out = _long_folder(tmp_path, length)
    result, err = experiment(*STUDY, "--out", str(out))
    assert result == code, err
    if code == 2:
        assert len(err.splitlines()) == 1 and "--out" in err and "PATH_MAX 4096" in err, err
        assert CALLS == [] and not out.exists()


def test_an_output_file_name_too_long_for_its_temporary_is_refused(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match=r"--out .* 264 bytes, more than this file system's limit of 255"):
        output_file(tmp_path / ("n" * 250), "--out")


# ---- 7. permissions of the outputs
def test_every_output_has_the_permissions_of_a_new_file(tmp_path: Path) -> None:
    previous = os.umask(0o027)
    try:
        assert experiment(*STUDY, "--out", str(tmp_path))[0] == 0
    finally:
        os.umask(previous)
    modes = {str(p.relative_to(tmp_path)): oct(p.stat().st_mode & 0o777) for p in tmp_path.rglob("*")
             if p.is_file()}
    assert len(modes) == 4 and set(modes.values()) == {oct(0o640)}, modes

