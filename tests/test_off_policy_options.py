"""The off-policy recipes' critic options: n-step returns (reward sums, cuts, done flags, the loss's
discount) and layer norm in the critics; both resume only with the checkpoint's own setting."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.objectives.value import TD0Estimator

from falcon_rl.cli import main
from falcon_rl.recipes import algorithm
from falcon_rl.recipes.checkpoint import load_checkpoint
from falcon_rl.recipes.common import STEPS_TO_NEXT, QNet, RunningNorm
from falcon_rl.recipes.off_policy import n_step_transitions

GAMMA = 0.9


def one_env_batch(rewards: list[float], done_at: dict[int, bool]) -> TensorDict:
    """A [1, T] batch whose observation at step t is t, next observation t + 100; ``done_at`` {step:
    terminated} marks episode ends (False: a time-limit truncation)."""
    t = len(rewards)
    obs = torch.arange(t, dtype=torch.float32).reshape(1, t, 1)
    done = torch.zeros(1, t, 1, dtype=torch.bool)
    terminated = torch.zeros(1, t, 1, dtype=torch.bool)
    for step, crash in done_at.items():
        done[0, step] = True
        terminated[0, step] = crash
    return TensorDict({"observation": obs, "action": torch.zeros(1, t, 2),
                       "next": {"observation": obs + 100, "reward": torch.tensor(rewards).reshape(1, t, 1),
                                "done": done, "terminated": terminated}}, batch_size=[1, t])


def test_n_step_sums_rewards_and_cuts_at_episode_and_batch_ends():
    batch = one_env_batch([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], {2: True})
    out = n_step_transitions(batch, GAMMA, 3)
    steps = out[STEPS_TO_NEXT][0].tolist()
    # steps 0-2 end with the crash at step 2; steps 3-6 run to the batch's end (3 at most)
    assert steps == [3, 2, 1, 3, 3, 2, 1]
    reward = out["next", "reward"][0, :, 0]
    torch.testing.assert_close(reward[0], torch.tensor(1 + GAMMA * 2 + GAMMA**2 * 3))
    torch.testing.assert_close(reward[2], torch.tensor(3.0))
    torch.testing.assert_close(reward[4], torch.tensor(5 + GAMMA * 6 + GAMMA**2 * 7))
    # the next observation is the one after the last summed step
    assert out["next", "observation"][0, :, 0].tolist() == [102, 102, 102, 105, 106, 106, 106]
    # the crash ends every window that reaches it: no bootstrap from the terminal observation
    assert out["next", "terminated"][0, :, 0].tolist() == [True, True, True] + [False] * 4
    assert out["next", "done"][0, :, 0].tolist() == [True, True, True] + [False] * 4
    assert torch.equal(batch["next", "reward"][0, :, 0], torch.arange(1.0, 8.0))  # input untouched


def test_n_step_keeps_a_truncation_bootstrapping():
    out = n_step_transitions(one_env_batch([1.0] * 5, {1: False}), GAMMA, 4)
    assert out[STEPS_TO_NEXT][0].tolist() == [2, 1, 3, 2, 1]
    assert out["next", "done"][0, :2, 0].tolist() == [True, True]
    assert not out["next", "terminated"].any()


def test_one_step_is_the_batch_itself():
    batch = one_env_batch([1.0, 2.0], {})
    assert n_step_transitions(batch, GAMMA, 1) is batch


def test_td3_target_discounts_by_the_step_count():
    """The loss's TD(0) target reads the stored step count: r + gamma**k (1 - terminated) Q'."""
    value = nn.Linear(1, 1)
    nn.init.zeros_(value.weight)
    nn.init.constant_(value.bias, 10.0)
    estimator = TD0Estimator(gamma=GAMMA, value_network=TensorDictModule(value, ["observation"],
                                                                         ["state_value"]))
    td = TensorDict({"observation": torch.zeros(2, 1), STEPS_TO_NEXT: torch.tensor([1, 3]),
                     "next": {"observation": torch.zeros(2, 1), "reward": torch.ones(2, 1),
                              "done": torch.zeros(2, 1, dtype=torch.bool),
                              "terminated": torch.zeros(2, 1, dtype=torch.bool)}}, batch_size=[2])
    target = estimator.value_estimate(td)[:, 0]
    torch.testing.assert_close(target, torch.tensor([1 + GAMMA * 10, 1 + GAMMA**3 * 10]))


def test_critic_layer_norm_sits_between_each_hidden_layer_and_its_activation():
    plain = QNet(RunningNorm(3), 3, 2, (8, 8))
    normed = QNet(RunningNorm(3), 3, 2, (8, 8), layer_norm=True)
    kinds = [type(m).__name__ for m in normed.mlp]
    assert kinds == ["Linear", "LayerNorm", "ReLU", "Linear", "LayerNorm", "ReLU", "Linear"]
    assert not any(isinstance(m, nn.LayerNorm) for m in plain.mlp)
    assert normed(torch.randn(4, 3), torch.randn(4, 2)).shape == (4, 1)


TINY = {"num_envs": 8, "rollout_steps": 8, "updates_per_batch": 2, "batch_size": 16, "init_random_frames": 32,
        "buffer_size": 1000, "critic_cells": (16,), "cells": (16,), "final_eval_episodes": 0,
        "progress": False, "checkpoint_every": 10**9}


@pytest.mark.parametrize("name", ["sac", "td3"])
def test_recipes_train_and_resume_with_n_step_and_layer_norm(name, tmp_path):
    recipe = algorithm(name)
    cfg = recipe.make_config("altitude", **TINY, frames=128, out=str(tmp_path / name), n_step=3,
                             critic_layer_norm=True)
    assert recipe.train(cfg)["updates"] > 0
    doc = load_checkpoint(tmp_path / name / "checkpoint.pt")
    steps = doc["replay"]["data"][STEPS_TO_NEXT]
    assert steps.shape == (128,) and set(steps.tolist()) <= {1, 2, 3} and 3 in steps.tolist()
    # the twin critics' first LayerNorm: weight and bias of size 16 at mlp.1
    assert any(k.endswith("mlp.1.weight") and v.shape[-1] == 16 for k, v in doc["modules"]["loss"].items())
    cfg.resume, cfg.frames = True, 256
    assert recipe.train(cfg)["frames"] == 256  # the n-step buffer comes back whole
    cfg.n_step, cfg.frames = 2, 384
    with pytest.raises(Exception, match="n_step=3"):
        recipe.train(cfg)


def test_n_step_beyond_the_rollout_is_refused_in_one_line(capsys):
    assert main(["train", "td3", "--frames", "64", "--set", "n_step=9", "--set", "rollout_steps=4"]) == 2
    err = capsys.readouterr().err.strip()
    assert "n_step (9) must not exceed rollout_steps (4)" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("name", ["sac", "td3"])
def test_anneal_lr_steps_the_actor_and_critics_down_and_leaves_the_temperature(name, tmp_path, monkeypatch):
    """With ``anneal_lr`` the learning rates at each update batch follow 1 - frames / total (floor 5 %)."""
    from falcon_rl.recipes import off_policy

    seen: list[tuple[int, dict[str, float]]] = []
    original = off_policy.anneal_learning_rates

    def spy(cfg, optimizers, frames):
        original(cfg, optimizers, frames)
        seen.append((frames, {k: o.param_groups[0]["lr"] for k, o in optimizers.items()}))

    monkeypatch.setattr(algorithm(name), "anneal_learning_rates", spy)
    recipe = algorithm(name)
    cfg = recipe.make_config("altitude", **TINY, frames=128, out=str(tmp_path / name), anneal_lr=True,
                             actor_lr=1e-3, critic_lr=2e-3)
    recipe.train(cfg)
    assert len(seen) >= 2
    for frames, lrs in seen:
        assert lrs["actor"] == pytest.approx(1e-3 * max(1 - frames / 128, 0.05))
        assert lrs["critic"] == pytest.approx(2e-3 * max(1 - frames / 128, 0.05))
        if name == "sac":
            assert lrs["alpha"] == pytest.approx(cfg.alpha_lr)
    assert seen[-1][1]["actor"] < seen[0][1]["actor"]


def test_without_anneal_lr_the_rates_stay():
    from falcon_rl.recipes import td3
    from falcon_rl.recipes.off_policy import anneal_learning_rates

    cfg = td3.make_config("altitude", frames=100)
    optimizers = {k: torch.optim.Adam([nn.Parameter(torch.zeros(1))], lr=0.1) for k in ("actor", "critic")}
    anneal_learning_rates(cfg, optimizers, 90)
    assert all(o.param_groups[0]["lr"] == 0.1 for o in optimizers.values())
    cfg.anneal_lr = True
    anneal_learning_rates(cfg, optimizers, 90)
    assert optimizers["actor"].param_groups[0]["lr"] == pytest.approx(cfg.actor_lr * 0.1)
