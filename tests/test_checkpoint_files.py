"""Checkpoint and policy files that cannot be used are refused with one line naming the file (exit 2
through the CLI), never run pickled code, and never suggest loading them unsafely; the train command's
bad flags likewise; SAC checkpoints grow with the replay fill, not with its capacity."""

from __future__ import annotations

import os
import pickle
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
import torch

from falcon_rl.cli import main
from falcon_rl.policies import HERE, available, read_policy
from falcon_rl.policies.format import LEGACY_FORMATS, content_digest, read_document, seal
from falcon_rl.recipes.checkpoint import load_checkpoint

#: Flags of the tiny PPO run every checkpoint case resumes (the fixture trains with the same ones).
COMMON = ("--envs", "8", "--frames", "64", "--eval-episodes", "0", "--no-progress", "--logger", "none")
PPO = (*COMMON, "--set", "rollout_steps=8", "--set", "epochs=1", "--set", "minibatches=2")


def cli(argv: list[str], capsys) -> tuple[int, list[str]]:
    """Exit code and stderr lines of ``falcon-rl argv`` run in-process."""
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A tiny PPO run's folder: checkpoint.pt, policy.pt, policy.ts."""
    out = tmp_path_factory.mktemp("trained") / "ppo"
    assert main(["train", "ppo", "--out", str(out), *PPO]) == 0
    return out


class Evil:
    """Unpickling runs ``touch <marker>`` (were it ever unpickled with code allowed)."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def _flip_in(path: Path, tensor: torch.Tensor) -> None:
    """Flip one bit of ``tensor``'s bytes where they are stored in the file at ``path``."""
    data = bytearray(path.read_bytes())
    at = bytes(data).find(tensor.numpy().tobytes())
    assert at >= 0
    data[at + 5] ^= 0x10
    path.write_bytes(bytes(data))


def _flipped(path: Path, source: Path, marker: Path) -> None:
    """A copy of ``source`` with one bit of the actor's first weight flipped."""
    shutil.copy(source, path)
    doc = torch.load(source, weights_only=True)
    _flip_in(path, doc["mlp"]["0.weight"] if "mlp" in doc else doc["modules"]["actor"]["mlp.0.weight"])


def _huge(path: Path, source: Path, cells: list[int] | None = None) -> None:
    """A sealed policy file whose declared network would need ~160 GB (or has ``cells``)."""
    doc = read_document(source, "policy")
    doc = {k: v for k, v in doc.items() if k != "sha256"}
    doc["arch"] = {**doc["arch"], "cells": cells or [200_000, 200_000]}
    torch.save(seal(doc), path)


def _legacy_bad_shapes(path: Path, source: Path) -> None:
    """A legacy (format /1, no checksum) policy whose weights do not match its declared network."""
    doc = read_document(source, "policy")
    doc = {k: v for k, v in doc.items() if k != "sha256"}
    doc["format"] = LEGACY_FORMATS[0]
    doc["mlp"]["0.weight"] = doc["mlp"]["0.weight"][:, :3].clone()
    torch.save(doc, path)


def _edited(path: Path, source: Path) -> None:
    """A checkpoint whose weights were edited after sealing (the checksum is kept)."""
    doc = torch.load(source, weights_only=True)
    doc["modules"]["actor"]["mlp.0.weight"] += 1.0
    torch.save(doc, path)


def _legacy_other_shapes(path: Path, source: Path) -> None:
    """A legacy (format 1, no checksum) checkpoint whose actor has another first layer than its config
    says: caught by the shape check after the networks are built."""
    doc = torch.load(source, weights_only=True)
    doc = {**{k: v for k, v in doc.items() if k != "sha256"}, "format": 1}
    doc["modules"]["actor"]["mlp.0.weight"] = doc["modules"]["actor"]["mlp.0.weight"][:, :3].clone()
    torch.save(doc, path)


@dataclass(frozen=True)
class Case:
    """One bad file: ``write(path, source, marker)`` makes it from the trained run's file ``source``;
    ``target``: where it is given (a policy to ``eval``, a checkpoint to ``train --resume``)."""

    name: str
    target: str
    write: Callable[[Path, Path, Path], None] | None
    reason: str
    args: tuple[str, ...] = ()
    command: str = "ppo"


def _truncated(p, s, m):
    p.write_bytes(s.read_bytes()[: s.stat().st_size // 2])


FILE_DEFECTS = (
    ("truncated", _truncated, "truncated"),
    ("zero-bytes", lambda p, s, m: p.write_bytes(b""), "empty file"),
    ("random-bytes", lambda p, s, m: p.write_bytes(os.urandom(4096)), "not a torch file"),
    ("text", lambda p, s, m: p.write_text("not a checkpoint\n" * 20), "not a torch file"),
    ("pickled-list", lambda p, s, m: p.write_bytes(pickle.dumps([1, 2, 3])), "plain Python pickle"),
    ("saved-list", lambda p, s, m: torch.save([torch.ones(2)], p), "holds a list"),
    ("malicious-pickle", lambda p, s, m: p.write_bytes(pickle.dumps(Evil(m), protocol=2)), "pickle"),
    ("malicious-torch-file", lambda p, s, m: torch.save({"x": Evil(m)}, p), "pickled Python objects"),
    ("flipped-byte", _flipped, "checksum mismatch"),
    ("torchscript", lambda p, s, m: shutil.copy(s.parent / "policy.ts", p), "TorchScript"),
)
CASES = [
    *(Case(f"{target}-{name}", target, write, reason)
      for target in ("policy", "checkpoint") for name, write, reason in FILE_DEFECTS),
    Case("policy-is-a-checkpoint", "policy", lambda p, s, m: shutil.copy(s.parent / "checkpoint.pt", p),
         "a training checkpoint"),
    Case("policy-huge-layers", "policy", lambda p, s, m: _huge(p, s), "outside the limits"),
    Case("policy-too-many-parameters", "policy", lambda p, s, m: _huge(p, s, [16_384] * 8), "too large"),
    Case("policy-legacy-bad-shapes", "policy", lambda p, s, m: _legacy_bad_shapes(p, s), "do not match"),
    Case("policy-of-another-task", "policy", lambda p, s, m: shutil.copy(s, p), "task",
         ("--task", "attitude")),
    Case("checkpoint-is-a-policy", "checkpoint", lambda p, s, m: shutil.copy(s.parent / "policy.pt", p),
         "a policy file"),
    Case("checkpoint-edited", "checkpoint", lambda p, s, m: _edited(p, s), "checksum mismatch"),
    Case("checkpoint-missing", "checkpoint", None, "no checkpoint to resume"),
    Case("checkpoint-legacy-other-shapes", "checkpoint", lambda p, s, m: _legacy_other_shapes(p, s),
         "other shapes"),
    Case("algorithm-mismatch", "checkpoint", lambda p, s, m: shutil.copy(s, p), "cannot resume it as sac",
         command="sac"),
    Case("network-size-mismatch", "checkpoint", lambda p, s, m: shutil.copy(s, p), "cells",
         ("--set", "cells=(32, 32)")),
    Case("task-mismatch", "checkpoint", lambda p, s, m: shutil.copy(s, p), "task", ("--task", "attitude")),
    Case("airframe-mismatch", "checkpoint", lambda p, s, m: shutil.copy(s, p), "airframe",
         ("--airframe", "navion")),
    Case("seed-mismatch", "checkpoint", lambda p, s, m: shutil.copy(s, p), "seed", ("--seed", "5")),
]


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_bad_files_are_refused_in_one_line(case: Case, trained: Path, tmp_path: Path, capsys):
    marker = tmp_path / "pwned"
    if case.target == "policy":
        path = tmp_path / "bad.pt"
        case.write(path, trained / "policy.pt", marker)
        argv = ["eval", "--controller", path, "--task", "altitude", "--episodes", "1", "--seconds", "1",
                "--backend", "torch", "--out", tmp_path / "eval", *case.args]
    else:
        path = tmp_path / "run" / "checkpoint.pt"
        path.parent.mkdir()
        if case.write is not None:
            case.write(path, trained / "checkpoint.pt", marker)
        flags = PPO if case.command == "ppo" else COMMON
        argv = ["train", case.command, "--out", path.parent, "--resume", *flags, *case.args]
    code, lines = cli(argv, capsys)
    assert code == 2
    assert len(lines) == 1, lines
    assert str(path) in lines[0] and case.reason in lines[0], lines[0]
    assert "weights_only" not in lines[0] and "weights-only" not in lines[0]
    assert not marker.exists()  # no pickled code ran


def test_the_bad_file_cases_are_what_they_claim(trained: Path, tmp_path: Path):
    """The flipped-byte case changes a weight (not padding), and the huge case would need > 100 GB."""
    for case in (c for c in CASES if c.name in ("policy-flipped-byte", "checkpoint-flipped-byte")):
        source = trained / ("policy.pt" if case.target == "policy" else "checkpoint.pt")
        path = tmp_path / f"{case.name}.pt"
        case.write(path, source, tmp_path / "marker")
        with pytest.raises(ValueError, match="checksum mismatch"):
            (read_policy if case.target == "policy" else load_checkpoint)(path)
        flipped = torch.load(path, weights_only=True)
        assert content_digest(flipped) != flipped["sha256"]
    _huge(tmp_path / "huge.pt", trained / "policy.pt")
    cells = torch.load(tmp_path / "huge.pt", weights_only=True)["arch"]["cells"]
    assert 4 * (cells[0] * cells[1]) > 100e9


def test_policy_and_checkpoint_files_are_sealed(trained: Path):
    policy = read_document(trained / "policy.pt", "policy")
    checkpoint = read_document(trained / "checkpoint.pt", "checkpoint")
    for doc in (policy, checkpoint):
        assert doc["sha256"] == content_digest(doc)
    read_policy(trained / "policy.pt")
    assert load_checkpoint(trained / "checkpoint.pt")["counters"]["frames"] == 64


@pytest.mark.parametrize("stem", available())
def test_shipped_policies_load(stem):
    """A shipped file is either of the current format with a verified checksum, or predates the checksum
    (format /1) and loads after the structure checks."""
    path = HERE / f"{stem}.pt"  # sac_ and td3_ files too
    doc = read_document(path, "policy")
    assert doc["format"] in LEGACY_FORMATS or doc["sha256"] == content_digest(doc)
    policy, meta = read_policy(path)
    action = policy(torch.zeros(3, policy.mlp[0].in_features))
    assert action.shape == (3, policy.act_dim) and torch.isfinite(action).all()
    assert stem.split("_", 1)[1].startswith(f"{meta['task']}_")  # <algorithm>_<task>_<airframe>[_seedK]


def test_legacy_checkpoint_resumes(trained: Path, tmp_path: Path, capsys):
    """A format-1 checkpoint (no checksum) of the same run resumes."""
    out = tmp_path / "run"
    out.mkdir()
    doc = torch.load(trained / "checkpoint.pt", weights_only=True)
    torch.save({**{k: v for k, v in doc.items() if k != "sha256"}, "format": 1}, out / "checkpoint.pt")
    code, _ = cli(["train", "ppo", "--out", out, "--resume", *PPO[:2], "--frames", "128", *PPO[4:]], capsys)
    assert code == 0
    assert load_checkpoint(out / "checkpoint.pt")["counters"]["frames"] == 128


def test_resume_if_present_and_stale_temporary_files(tmp_path: Path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    for name in ("checkpoint.pt.tmp", "policy.pt.tmp", "policy.ts.tmp"):
        (out / name).write_bytes(b"half a file")
    assert cli(["train", "ppo", "--out", out, "--resume-if-present", *PPO], capsys)[0] == 0  # new run
    assert not list(out.glob("*.tmp"))
    first = load_checkpoint(out / "checkpoint.pt")["counters"]
    assert first["frames"] == 64
    argv = ["train", "ppo", "--out", out, "--resume-if-present", *PPO[:2], "--frames", "128", *PPO[4:]]
    assert cli(argv, capsys)[0] == 0
    second = load_checkpoint(out / "checkpoint.pt")["counters"]
    assert second["frames"] == 128 and second["iterations"] == 2 * first["iterations"]


NO_CUDA = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is available here")
BAD_FLAGS = [
    (("--set", "rollout_steps=0"), "rollout_steps"),
    (("--eval-every", "-1"), "--eval-every"),
    (("--envs", "9" * 400), "out of range"),
    (("--frames", "0"), "--frames"),
    (("--seed", "-3"), "--seed"),
    (("--threads", "0"), "--threads"),
    (("--out", "/proc/falcon-rl-test"), "writable"),
    (("--set", "no_such_field=1"), "no_such_field"),
    (("--set", "actor_lr=1e999"), "actor_lr must be a finite number"),
    (("--set", "actor_lr=nan"), "actor_lr must be a finite number"),
    (("--set", "critic_lr=-1"), "critic_lr must be > 0"),
    (("--set", "gamma=2"), "gamma"),
    (("--set", "num_envs=True"), "num_envs"),
    (("--set", "batch_size=" + "9" * 400), "batch_size"),
    (("--set", "cells=(100000, 100000)"), "cells"),
    (("--set", "cells=()"), "cells"),
    (("--set", "activation=bogus"), "activation"),
    (("--set", "backend=bogus"), "backend"),
    (("--set", "resume=maybe"), "resume"),
    (("--set", "episode_seconds=0"), "episode_seconds"),
    (("--set", "target_entropy=high"), "target_entropy must be a finite number or 'auto'"),
    (("--set", "target_entropy=nan"), "target_entropy must be a finite number"),
    (("--set", "env_options={'no_such_option': 1}"), "no_such_option"),
    (("--set", "batch_size"), "FIELD=VALUE"),
    (("--resume", "--resume-if-present"), "not allowed"),
    (("--device", "tpu"), "--device"),
    pytest.param(("--device", "cuda"), "CUDA", marks=NO_CUDA),
    pytest.param(("--set", "device=cuda"), "CUDA", marks=NO_CUDA),
]


@pytest.mark.parametrize(("flags", "reason"), BAD_FLAGS,
                         ids=[" ".join((f.values if hasattr(f, "values") else f)[0])[:40] for f in BAD_FLAGS])
def test_train_bad_flags_exit_2_with_one_line(flags, reason, tmp_path: Path, capsys):
    out = [] if "--out" in flags else ["--out", tmp_path / "out"]
    code, lines = cli(["train", "sac", *out, "--envs", "8", "--frames", "64", "--eval-episodes", "0",
                       "--no-progress", "--logger", "none", *flags], capsys)
    assert code == 2
    assert len(lines) == 1 and reason in lines[0], lines
    assert not (tmp_path / "out" / "checkpoint.pt").exists()


def test_sac_checkpoint_grows_with_the_replay_fill(tmp_path: Path, capsys):
    """The replay entry holds the filled transitions only (slicing the storage saved all of it)."""
    sizes, replays = {}, {}
    for frames in (64, 1024):
        out = tmp_path / str(frames)
        assert cli(["train", "sac", "--out", out, "--envs", "8", "--frames", frames, "--eval-episodes", "0",
                    "--no-progress", "--logger", "none", "--set", "buffer_size=200000", "--set",
                    "init_random_frames=10000", "--set", "rollout_steps=8"], capsys)[0] == 0
        sizes[frames] = (out / "checkpoint.pt").stat().st_size
        replays[frames] = load_checkpoint(out / "checkpoint.pt")["replay"]
    row_bytes = sum(t[0].numel() * t.element_size() for t in _tensors(replays[64]["data"]))
    assert replays[64]["size"] == 64 and replays[1024]["size"] == 1024
    assert all(t.shape[0] == 64 for t in _tensors(replays[64]["data"]))
    assert sizes[1024] - sizes[64] >= 0.9 * (1024 - 64) * row_bytes  # the file grows with the fill ...
    assert sizes[64] < 0.1 * 200_000 * row_bytes  # ... and a small fill makes a small file


def _tensors(data: dict):
    for value in data.values():
        yield from (_tensors(value) if isinstance(value, dict) else (value,))
