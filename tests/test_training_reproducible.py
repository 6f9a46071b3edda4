"""Training reproduces bit for bit: the same seed gives identical weights in separate processes (PPO,
SAC, TD3) and another seed other weights; evaluating during training changes nothing; a run killed
right after a checkpoint and resumed in another process ends with the uninterrupted run's weights,
optimiser states, normaliser and replay buffer."""

from __future__ import annotations

import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from falcon_rl.cli import main
from falcon_rl.recipes.checkpoint import load_checkpoint

REPO = Path(__file__).resolve().parents[1]
NAMES = ("ppo", "sac", "td3")
#: Tiny runs (a few hundred env-steps); 1 s episodes so that envs crash, truncate and reset mid-run.
BASE = ("--envs", "8", "--eval-episodes", "0", "--no-progress", "--logger", "none",
        "--set", "episode_seconds=1.0")
OFF_POLICY = ("--set", "rollout_steps=8", "--set", "updates_per_batch=2", "--set", "batch_size=16",
              "--set", "init_random_frames=32", "--set", "buffer_size=1000", "--set", "cells=(16,)",
              "--set", "critic_cells=(16,)")
TINY = {"ppo": ("--set", "rollout_steps=8", "--set", "epochs=1", "--set", "minibatches=2"),
        "sac": OFF_POLICY, "td3": OFF_POLICY}


def train_argv(name: str, out: Path, frames: int, *extra: str) -> list[str]:
    return ["train", name, "--out", str(out), "--frames", str(frames), *BASE, *TINY[name], *extra]


def run_state(out: Path) -> dict[str, object]:
    """Everything a run learned and will draw from, flattened: the final checkpoint's networks,
    optimisers, normaliser, generators, replay buffer and counters (not the wall clock)."""
    doc = load_checkpoint(out / "checkpoint.pt")
    counters = {k: v for k, v in doc["counters"].items() if k != "wall_seconds"}
    parts = {k: doc[k] for k in ("modules", "optimizers", "norm", "rng", "replay") if k in doc}
    return {**dict(_flat(parts)), ("counters",): counters}


def _flat(tree: dict, prefix: tuple = ()):
    for key, value in tree.items():
        if isinstance(value, dict):
            yield from _flat(value, (*prefix, key))
        else:
            yield (*prefix, key), value


def assert_identical(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    differ = [k for k in a
              if not (torch.equal(a[k], b[k]) if isinstance(a[k], torch.Tensor) else a[k] == b[k])]
    assert not differ, f"{len(differ)} entries differ, e.g. {differ[:3]}"


def _scramble_global_generators() -> None:
    """Leave this process's generators unlike a fresh process's: the run must seed them itself."""
    torch.manual_seed(12345)
    np.random.seed(12345)
    random.seed(12345)


CHILD = """
import sys
from falcon_rl.cli import main
root, argvs = sys.argv[1], sys.argv[2:]
for argv in argvs:
    assert main(argv.replace("ROOT", root).split("|")) == 0
"""


def test_same_seed_same_weights_in_separate_processes(tmp_path: Path):
    argvs = {name: train_argv(name, Path("ROOT") / name, 256) for name in NAMES}
    child = tmp_path / "child"
    subprocess.run([sys.executable, "-c", CHILD, str(child), *("|".join(a) for a in argvs.values())],
                   cwd=REPO, check=True, capture_output=True, timeout=600)
    _scramble_global_generators()
    for name in NAMES:
        assert main(train_argv(name, tmp_path / "here" / name, 256)) == 0
        assert main(train_argv(name, tmp_path / "seed1" / name, 256, "--seed", "1")) == 0
        same, other = run_state(child / name), run_state(tmp_path / "here" / name)
        assert_identical(same, other)
        reseeded = run_state(tmp_path / "seed1" / name)
        actor = [k for k in same if k[:2] == ("modules", "actor") and k[2].startswith("mlp.")]
        assert actor and all(not torch.equal(same[k], reseeded[k]) for k in actor)


def test_evaluating_during_training_changes_no_weight(tmp_path: Path):
    plain, evaluated = tmp_path / "plain", tmp_path / "evaluated"
    assert main(train_argv("ppo", plain, 256)) == 0
    assert main(train_argv("ppo", evaluated, 256, "--eval-every", "64", "--set", "eval_episodes=1",
                           "--set", "eval_seconds=1.0")) == 0
    trained, also_evaluated = run_state(plain), run_state(evaluated)
    assert also_evaluated[("counters",)]["last_eval_frames"] > 0  # the evaluations ran
    del trained[("counters",)], also_evaluated[("counters",)]
    assert_identical(trained, also_evaluated)


KILLED = """
import os, sys
from falcon_rl.recipes import runner

save = runner.TrainingRun.save


def save_then_die(self):
    path = save(self)
    if self.counters.frames < self.cfg.frames:
        os._exit(17)  # killed right after the first periodic checkpoint
    return path


runner.TrainingRun.save = save_then_die
from falcon_rl.cli import main
main(sys.argv[1:])
"""


@pytest.mark.parametrize("name", NAMES)
def test_killed_and_resumed_run_equals_uninterrupted(name: str, tmp_path: Path):
    resumed, uninterrupted = tmp_path / "resumed", tmp_path / "uninterrupted"
    extra = ("--set", "checkpoint_every=128")
    killed = subprocess.run([sys.executable, "-c", KILLED, *train_argv(name, resumed, 384, *extra)],
                            cwd=REPO, capture_output=True, timeout=600)
    assert killed.returncode == 17, killed.stderr.decode()[-2000:]
    assert load_checkpoint(resumed / "checkpoint.pt")["counters"]["frames"] == 128
    (resumed / "checkpoint.pt.tmp").write_bytes(b"half a checkpoint")  # a kill mid-write leaves this
    _scramble_global_generators()
    assert main(train_argv(name, resumed, 384, *extra, "--resume")) == 0
    assert not (resumed / "checkpoint.pt.tmp").exists()
    assert main(train_argv(name, uninterrupted, 384, *extra)) == 0
    state = run_state(resumed)
    assert state[("counters",)]["frames"] == 384 and state[("counters",)]["episodes"] > 0
    assert_identical(state, run_state(uninterrupted))
