"""Faults found by trying ``falcon-rl train``, one test (parametrized over its cases) per row:

1. ``--stop-when`` met on the 16-episode validation must be confirmed on more episodes of other seeds
   before the run stops (a run stopped at RMSE <= 0.5 m had tested 0.504 m); a failed confirmation
   trains on, and a solved run ships the confirmed weights.
2. Two runs into one ``--out``: the second is refused in one line while the first holds the folder's
   lock, and removes nothing of it; the lock goes when its holder's process dies.
3. A full disk while writing any output: one line, exit 1, no temporary left, earlier outputs intact.
4. A run whose episodes all end "non_finite": one line, exit 2, no policy exported.

The evaluations of row 1 are faked (their numbers are the test's); the runs are a few 8-env batches.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
import torch
from torchrl.envs import Transform

from falcon_rl import atomic_files
from falcon_rl.cli import main
from falcon_rl.policies import read_policy
from falcon_rl.recipes import runner
from falcon_rl.recipes.checkpoint import load_checkpoint
from falcon_rl.recipes.evaluate import EVAL_SEED
from falcon_rl.recipes.runner import LOCK_FILE, OUTPUT_FILES, lock_run_folder, release_run_folder
from falcon_rl.recipes.selection import CONFIRMATION_SEED, VALIDATION_SEED

sys.path.insert(0, str(Path(__file__).parent))
from test_training_reproducible import train_argv


def cli(argv: list[str], capsys) -> tuple[int, list[str]]:
    """Exit code and stderr lines (without Warp's start-up notice) of ``falcon-rl argv`` in-process."""
    code = main([str(a) for a in argv])
    return code, [line for line in capsys.readouterr().err.strip().splitlines() if "Warp" not in line]


# ------------------------------------------------------------------ row 1: a stop the test keeps
STOP = ("--eval-every", "64", "--stop-when", "survival>=1,rmse_m<=0.5", "--set", "eval_episodes=16")


def fake_evaluate(validations: list[float], confirmations: list[float], calls: list[tuple[int, int]]):
    """An ``evaluate`` whose validations and confirmations report the next RMSE of their list (the
    last one repeating) with survival 1; it records (seed offset, episodes) of every call."""
    rmse = {VALIDATION_SEED: iter(validations), CONFIRMATION_SEED: iter(confirmations)}
    last = {VALIDATION_SEED: validations[-1], CONFIRMATION_SEED: confirmations[-1], EVAL_SEED: 0.45}

    def evaluate(net, cfg, label, episodes, seed_offset=EVAL_SEED, **options):
        calls.append((seed_offset, episodes))
        value = next(rmse[seed_offset], last[seed_offset]) if seed_offset in rmse else last[seed_offset]
        return SimpleNamespace(summary={"survival": 1.0, "acquisition": 1.0, "rmse_m": value})

    return evaluate


#: (case, validation RMSEs, confirmation RMSEs, extra flags, frames trained, frames solved or None,
#: confirmations flown). The altitude recipe keeps its best snapshot: the last weights are validated too.
STOP_CASES = [
    ("confirmation fails: trains on", [0.40], [0.504], (), 256, None, 4),  # 64, 128, 192, the last
    ("confirmation passes: stops", [0.40], [0.48], (), 64, 64, 1),
    ("keep_best ships the confirmed weights", [0.30, 0.45], [0.60, 0.48], ("--set", "keep_best=True"),
     128, 128, 2),
    ("confirm_episodes=0: the validation alone", [0.40], [0.60], ("--set", "confirm_episodes=0"), 64, 64, 0),
]


@pytest.mark.parametrize("case, validations, confirmations, extra, frames, solved_at, confirmed",
                         STOP_CASES, ids=[c[0] for c in STOP_CASES])
def test_row1_stop_when_is_confirmed_on_other_episodes(tmp_path, monkeypatch, case, validations,
                                                       confirmations, extra, frames, solved_at, confirmed):
    calls: list[tuple[int, int]] = []
    monkeypatch.setattr(runner, "evaluate", fake_evaluate(validations, confirmations, calls))
    out = tmp_path / "run"
    assert main(train_argv("ppo", out, 256, *STOP, *extra)) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == frames
    assert [c for c in calls if c[0] == CONFIRMATION_SEED] == [(CONFIRMATION_SEED, 100)] * confirmed
    if solved_at is None:
        assert summary["solved"] is None
        return
    assert summary["solved"]["frames"] == solved_at
    assert summary["solved"]["confirmation"] == (None if not confirmed else
                                                 {"survival": 1.0, "acquisition": 1.0, "rmse_m": 0.48})
    assert read_policy(out / "policy.pt")[1]["frames"] == solved_at  # the confirmed weights
    assert load_checkpoint(out / "checkpoint.pt")["extra"]["solved"] == summary["solved"]


def test_row1_a_resumed_run_solved_without_confirmation_trains_on(tmp_path, monkeypatch):
    monkeypatch.setattr(runner, "evaluate", fake_evaluate([0.40], [0.60], []))
    out = tmp_path / "run"
    assert main(train_argv("ppo", out, 256, *STOP, "--set", "confirm_episodes=0")) == 0
    assert json.loads((out / "summary.json").read_text())["solved"]["frames"] == 64
    assert main(train_argv("ppo", out, 256, *STOP, "--resume")) == 0  # now confirmed on 100 episodes
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 256 and summary["solved"] is None


# ------------------------------------------------------------------ row 2: one run per folder
HOLD = ("import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT); "
        "fcntl.flock(fd, fcntl.LOCK_EX); os.write(fd, str(os.getpid()).encode()); "
        "print('locked', flush=True); sys.stdin.read()")
TRY = ("import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)\n"
       "try:\n    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)\nexcept BlockingIOError:\n    sys.exit(3)")


def hold_lock(folder: Path) -> subprocess.Popen:
    """Another process holding ``folder``'s run lock, as a run would, until its stdin closes."""
    folder.mkdir(parents=True, exist_ok=True)
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(folder / LOCK_FILE)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "locked"
    return holder


def test_row2_a_second_run_into_a_held_folder_is_refused_and_removes_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    holder = hold_lock(out)
    in_flight = out / ".policy.pt.abc123.tmp"  # the holder's write under way
    in_flight.write_bytes(b"half a policy")
    try:
        code, err = cli(train_argv("ppo", out, 64), capsys)
        assert code == 2 and len(err) == 1
        assert str(out) in err[0] and "another training run" in err[0] and f"process {holder.pid}" in err[0]
        assert in_flight.exists() and not any((out / name).exists() for name in OUTPUT_FILES)
    finally:
        holder.communicate("")  # the holder's process ends: the system drops its lock
    code, err = cli(train_argv("ppo", out, 64), capsys)
    assert code == 0 and not in_flight.exists() and (out / "policy.pt").exists()


def test_row2_the_lock_is_held_between_processes_until_released(tmp_path):
    def other_process_locks() -> bool:
        return subprocess.run([sys.executable, "-c", TRY, str(tmp_path / LOCK_FILE)]).returncode == 0

    lock_run_folder(tmp_path)
    try:
        assert not other_process_locks()
        lock_run_folder(tmp_path)  # this process again (a run of it that raised): takes it over
        assert not other_process_locks()
    finally:
        release_run_folder(tmp_path)
    assert other_process_locks()


# ------------------------------------------------------------------ row 3: a full disk
class FullDiskFor:
    """``os`` for :mod:`falcon_rl.atomic_files` in which writing a temporary of ``name`` fails with
    ENOSPC, as on a full disk (everything else is the real ``os``)."""

    def __init__(self, name: str):
        self.name = name

    def __getattr__(self, attribute: str):
        return getattr(os, attribute)

    def fdopen(self, descriptor: int, *args, **kwargs):
        stream = os.fdopen(descriptor, *args, **kwargs)
        target = Path(os.readlink(f"/proc/self/fd/{descriptor}")).name
        return _Refusing(stream) if target.startswith(atomic_files.temporary_prefix(self.name)) else stream


class _Refusing:
    """A file whose writes fail as on a full disk."""

    def __init__(self, stream):
        self.stream = stream

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.stream.close()

    def write(self, data: bytes) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A tiny PPO run's finished folder (resuming it only writes its outputs again)."""
    out = tmp_path_factory.mktemp("finished") / "run"
    assert main(train_argv("ppo", out, 64)) == 0
    return out


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="names open files through /proc")
@pytest.mark.parametrize("name", OUTPUT_FILES)
def test_row3_a_full_disk_is_one_line_and_leaves_earlier_outputs_whole(finished_run, tmp_path, monkeypatch,
                                                                       capsys, name):
    out = tmp_path / "run"
    shutil.copytree(finished_run, out)
    before = {path.name: path.read_bytes() for path in out.iterdir() if path.is_file()}
    monkeypatch.setattr(atomic_files, "os", FullDiskFor(name))
    code, err = cli([*train_argv("ppo", out, 64), "--resume"], capsys)
    assert code == 1 and len(err) == 1 and "No space left on device" in err[0]
    assert not list(out.glob("*.tmp")) and not list(out.glob(".*.tmp"))
    assert (out / name).read_bytes() == before[name]  # the file being written keeps its earlier content
    load_checkpoint(out / "checkpoint.pt")
    read_policy(out / "policy.pt")
    torch.jit.load(str(out / "policy.ts"))
    json.loads((out / "summary.json").read_text())


# ------------------------------------------------------------------ row 4: every episode non-finite
class NaNActions(Transform):
    """Hands the env a NaN action at every step: every env ends its episode "non_finite" at once (the
    policy's own actions, in the batch, stay finite)."""

    def __init__(self):
        super().__init__(in_keys_inv=["action"], out_keys_inv=["action"])

    def _inv_apply_transform(self, action: torch.Tensor) -> torch.Tensor:
        return torch.full_like(action, float("nan"))


@pytest.mark.parametrize("name", ["ppo", "sac"])
def test_row4_a_run_whose_episodes_all_end_non_finite_fails_and_exports_nothing(tmp_path, monkeypatch,
                                                                                  capsys, name):
    from falcon_rl.recipes import algorithm, common

    def broken_env(cfg, *args, **kwargs):
        env = common.make_train_env(cfg, *args, **kwargs)
        env.insert_transform(0, NaNActions())
        return env

    monkeypatch.setattr(algorithm(name), "make_train_env", broken_env)
    out = tmp_path / "run"
    code, err = cli(train_argv(name, out, 256, "--eval-episodes", "4"), capsys)
    assert code == 2 and len(err) == 1
    assert "ended non-finite" in err[0] and "no policy exported" in err[0]
    assert not any((out / file).exists() for file in OUTPUT_FILES)
