"""Training recipes end to end on tiny configs: checkpoints, resume, atomic writes, export, CLI, and
the shipped policies."""

from __future__ import annotations

import json

import pytest
import torch

import falcon_rl
from falcon_rl.cli import main
from falcon_rl.policies import available, load_policy, read_policy, shipped_policy
from falcon_rl.policies.format import atomic_save
from falcon_rl.recipes import algorithm
from falcon_rl.recipes.checkpoint import load_checkpoint, load_replay, replay_state
from falcon_rl.recipes.common import RunningNorm

TINY = {"ppo": {"num_envs": 8, "rollout_steps": 8, "epochs": 1, "minibatches": 2},
        "sac": {"num_envs": 8, "rollout_steps": 8, "updates_per_batch": 2, "batch_size": 16,
                "init_random_frames": 32, "buffer_size": 1000, "critic_cells": (16,), "cells": (16,)},
        "td3": {"num_envs": 8, "rollout_steps": 8, "updates_per_batch": 2, "batch_size": 16,
                "init_random_frames": 32, "buffer_size": 1000, "critic_cells": (16,), "cells": (16,)}}


def tiny(name: str, tmp_path, frames: int, **kw):
    recipe = algorithm(name)
    options = {**TINY[name], "frames": frames, "out": str(tmp_path / name), "final_eval_episodes": 0,
               "progress": False, "checkpoint_every": 10**9, **kw}
    return recipe, recipe.make_config("altitude", **options)


@pytest.mark.parametrize("name", ["ppo", "sac", "td3"])
def test_recipe_trains_checkpoints_and_resumes(name, tmp_path):
    recipe, cfg = tiny(name, tmp_path, frames=128)
    first = recipe.train(cfg)
    assert first["frames"] == 128 and first["updates"] > 0
    doc = load_checkpoint(tmp_path / name / "checkpoint.pt")  # weights_only=True inside
    assert doc["counters"]["frames"] == 128 and doc["algorithm"] == name
    iterations = doc["counters"]["iterations"]
    # "kill" after the first run, then resume to twice the frames: the counters continue
    cfg.resume, cfg.frames = True, 256
    second = recipe.train(cfg)
    assert second["frames"] == 256
    assert second["iterations"] == 2 * iterations
    assert second["updates"] > first["updates"]
    assert load_checkpoint(tmp_path / name / "checkpoint.pt")["counters"]["frames"] == 256
    assert (tmp_path / name / "policy.pt").exists() and (tmp_path / name / "policy.ts").exists()
    assert list((tmp_path / name / "logs").rglob("*.csv"))


@pytest.mark.parametrize(("given", "expected"), [("auto", -2.0), (-3.5, -3.5)])
def test_sac_target_entropy_reaches_the_loss(given, expected, tmp_path, monkeypatch):
    """``target_entropy``: "auto" is minus the action count (2 on altitude), a number is used as given."""
    from falcon_rl.recipes import sac

    losses = []

    class Spy(sac.SACLoss):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            losses.append(self)

    monkeypatch.setattr(sac, "SACLoss", Spy)
    recipe, cfg = tiny("sac", tmp_path, frames=64, target_entropy=given)
    recipe.train(cfg)
    assert len(losses) == 1 and float(losses[0].target_entropy) == expected


def test_resume_restores_weights_and_rng(tmp_path):
    recipe, cfg = tiny("ppo", tmp_path, frames=64)
    recipe.train(cfg)
    doc = torch.load(tmp_path / "ppo" / "checkpoint.pt", weights_only=True)
    assert set(doc["modules"]) == {"actor", "critic"} and "optimizer" in doc["optimizers"]
    assert {"torch", "numpy", "python", "env", "sim"} <= set(doc["rng"]) and doc["norm"]["count"] > 0
    assert doc["format"] == 2 and isinstance(doc["sha256"], str)


@pytest.mark.parametrize("name", ["sac", "td3"])
def test_resume_restores_the_replay_buffer(name, tmp_path):
    recipe, cfg = tiny(name, tmp_path, frames=128)
    recipe.train(cfg)
    first = load_checkpoint(tmp_path / name / "checkpoint.pt")["replay"]
    assert first["size"] == 128 and first["data"]["observation"].shape[0] == 128
    cfg.resume, cfg.frames = True, 256
    recipe.train(cfg)
    second = load_checkpoint(tmp_path / name / "checkpoint.pt")["replay"]
    assert second["size"] == 256  # the saved 128 transitions came back, then 128 new ones
    for key in ("observation", "action", ("next", "reward"), ("next", "observation")):
        key = key if isinstance(key, tuple) else (key,)
        old, new = first["data"], second["data"]
        for part in key:
            old, new = old[part], new[part]
        assert torch.equal(new[:128], old)
        assert not torch.equal(new[128:], old)


def test_replay_round_trip_keeps_the_writer_cursor():
    from tensordict import TensorDict
    from torchrl.data import LazyTensorStorage, ReplayBuffer

    def make():
        return ReplayBuffer(storage=LazyTensorStorage(10), batch_size=4)

    rb = make()
    rb.extend(TensorDict({"x": torch.arange(13.0)}, [13]))  # wrapped: slots 0-2 hold 10-12
    state = torch.load(_saved(replay_state(rb)), weights_only=True)
    copy = make()
    assert load_replay(copy, state) == 10
    assert torch.equal(copy[:]["x"], rb[:]["x"])
    for buffer in (rb, copy):
        buffer.extend(TensorDict({"x": torch.tensor([99.0])}, [1]))
    assert torch.equal(copy[:]["x"], rb[:]["x"]) and copy[:]["x"][3] == 99.0


def _saved(obj):
    import io

    buf = io.BytesIO()
    torch.save(obj, buf)
    buf.seek(0)
    return buf


def test_atomic_save_leaves_no_partial_file(tmp_path, monkeypatch):
    path = tmp_path / "checkpoint.pt"
    atomic_save({"a": torch.ones(3)}, path)

    def broken_save(obj, f, *args, **kwargs):
        f.write(b"half a checkpoint")
        raise KeyboardInterrupt  # a kill in the middle of the write

    monkeypatch.setattr(torch, "save", broken_save)
    with pytest.raises(KeyboardInterrupt):
        atomic_save({"a": torch.zeros(3)}, path)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["checkpoint.pt"]
    assert torch.equal(torch.load(path, weights_only=True)["a"], torch.ones(3))


def test_export_round_trip_gives_the_same_actions(tmp_path):
    recipe, cfg = tiny("ppo", tmp_path, frames=64)
    recipe.train(cfg)
    env = falcon_rl.make_env("altitude", "volantex_ranger", num_envs=5, backend="warp", seed=3)
    td = env.reset()
    module = load_policy(tmp_path / "ppo" / "policy.pt", env)
    scripted = torch.jit.load(str(tmp_path / "ppo" / "policy.ts"))
    action = module(td.clone())["action"]
    assert action.shape == (5, 2) and action.abs().max() <= 1
    torch.testing.assert_close(scripted(td["observation"].float()), action.float())
    _, meta = read_policy(tmp_path / "ppo" / "policy.pt")
    assert meta["task"] == "altitude" and meta["airframe"] == "volantex_ranger"


def test_running_norm_matches_batch_statistics():
    x = torch.randn(1000, 3) * torch.tensor([1.0, 2.0, 0.5]) + 4.0
    norm = RunningNorm(3, min_std=1e-6)
    for chunk in x.split(128):
        norm.update(chunk)
    torch.testing.assert_close(norm.mean, x.mean(0), atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(norm.var, x.var(0, unbiased=False), atol=1e-3, rtol=1e-3)


def test_train_cli_json(tmp_path, capsys):
    out = tmp_path / "cli"
    code = main(["train", "ppo", "--task", "altitude", "--envs", "8", "--frames", "256", "--out", str(out),
                 "--eval-episodes", "0", "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["algorithm"] == "ppo" and doc["frames"] == 256 and doc["env_steps_per_s"] > 0
    assert {"policy", "torchscript", "checkpoint", "config", "wall_seconds", "iterations"} <= set(doc)
    assert doc["config"]["num_envs"] == 8
    assert main(["train", "ppo", "--envs", "0"]) == 2


def test_train_cli_set_overrides_recipe_fields():
    from falcon_rl.commands.train import parse_overrides

    parsed = parse_overrides(["batch_size=512", "cells=[32, 32]", "activation=tanh",
                              'env_options={"decimation": 5}'])
    assert parsed == {"batch_size": 512, "cells": (32, 32), "activation": "tanh",
                      "env_options": {"decimation": 5}}
    assert algorithm("td3").make_config("altitude", **parsed).cells == (32, 32)
    assert main(["train", "td3", "--set", "no_such_field=1"]) == 2
    assert main(["train", "td3", "--set", "batch_size"]) == 2


def test_tensorboard_logger_writes_events_or_says_what_is_missing(tmp_path):
    import importlib.util

    from falcon_rl.recipes.logging import log_scalars, make_logger

    if importlib.util.find_spec("tensorboard") is None:
        with pytest.raises(ImportError, match="pip install tensorboard"):
            make_logger("tensorboard", tmp_path, "run")
        assert main(["train", "ppo", "--logger", "tensorboard", "--out", str(tmp_path / "cli")]) == 2
        pytest.skip("tensorboard is not installed (the clear error is checked)")
    logger = make_logger("tensorboard", tmp_path, "run", {"seed": 0})
    log_scalars(logger, {"train/return": 1.0}, step=1)
    logger.experiment.flush()
    assert list((tmp_path / "logs").rglob("events.out.tfevents.*"))


def _shipped(stem: str) -> tuple[str, str, str, int]:
    """(algorithm, task, airframe, seed) of a shipped policy's file stem."""
    from falcon_rl.envs.tasks import task_names

    algorithm, rest = stem.split("_", 1)
    task = max((t for t in task_names() if rest.startswith(t + "_")), key=len)
    airframe, _, seed = rest[len(task) + 1:].partition("_seed")
    return algorithm, task, airframe, int(seed or 0)


@pytest.mark.parametrize("stem", available())
def test_shipped_policies_load_and_act(stem):
    algorithm, task, airframe, seed = _shipped(stem)
    env = falcon_rl.make_env(task, airframe, num_envs=4, backend="warp", seed=0)
    policy = load_policy(shipped_policy(task, airframe, algorithm, seed), env)
    td = env.reset()
    for _ in range(5):
        td = env.step_mdp(env.step(policy(td)))
    assert torch.isfinite(td["observation"]).all()


def test_unknown_shipped_policy_is_a_clear_error():
    with pytest.raises(ValueError, match="no shipped"):
        shipped_policy("altitude", "no_such_airframe")
