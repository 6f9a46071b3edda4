"""Rewards as named terms: every built-in task's reward is the sum of its named, weighted and signed
terms, the same in its torch step and its fused Warp step; the env reports their means per env-step
(``reward_term_means``) and the recipes log them as ``reward/<term>``."""

from __future__ import annotations

import csv

import pytest
import torch

from falcon_rl import make_env
from falcon_rl.envs.tasks import task_names
from falcon_rl.recipes import algorithm

TOL = {"rtol": 1e-5, "atol": 1e-5}
EXPECTED = {"altitude": ("altitude", "airspeed", "pitch_rate", "smoothness", "capture", "survival",
                         "overshoot", "energy_rate"),
            "climb_descend": ("altitude", "airspeed", "pitch_rate", "smoothness", "capture", "survival",
                              "overshoot", "energy_rate"),
            "attitude": ("bank", "climb", "airspeed", "energy", "smoothness"),
            "path_following": ("cross_track", "course", "altitude", "energy", "smoothness"),
            "trajectory": ("position", "velocity", "energy", "smoothness")}


def steps(env, count: int) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
    """(rewards [N] per step, term values [N, K] per step) over ``count`` steps of random actions."""
    generator = torch.Generator().manual_seed(0)
    rewards, terms = [], []
    env.reset_tensors()
    for _ in range(count):
        action = torch.rand(env.config.num_envs, env.task.action_dim, generator=generator) * 2 - 1
        step = env.step_tensors(action.to(env.sim.dtype))
        rewards.append(step.reward.clone())
        terms.append(env.task.reward_term_values.clone())
        done = (step.reason > 0) | step.truncated
        if bool(done.any()):
            env.reset_tensors(done)
    return rewards, terms


@pytest.mark.parametrize("task", list(EXPECTED))
def test_the_reward_is_the_sum_of_its_named_terms_in_the_fused_and_the_torch_step(task: str) -> None:
    assert set(EXPECTED) <= set(task_names())
    envs = {fused: make_env(task, "volantex_ranger", num_envs=4, seed=1, episode_seconds=2.0, fused=fused)
            for fused in (True, False)}
    assert envs[True].task.fused_stepper() is not None
    assert envs[True].task.reward_terms == EXPECTED[task]
    runs = {fused: steps(env, 50) for fused, env in envs.items()}
    for fused, (rewards, terms) in runs.items():
        for reward, values in zip(rewards, terms, strict=True):
            assert values.shape == (4, len(EXPECTED[task]))
            torch.testing.assert_close(values.sum(-1), reward, **TOL,
                                       msg=lambda m, f=fused: f"fused={f}: {m}")
    for a, b in zip(runs[True][1], runs[False][1], strict=True):  # the same terms both ways
        torch.testing.assert_close(a, b, **TOL)
    assert any(bool((values != 0).all(0).any()) for values in runs[True][1])


def test_reward_term_means_average_each_term_per_env_step_and_start_over() -> None:
    env = make_env("altitude", "volantex_ranger", num_envs=3, seed=2, lean=True)
    env.reset()
    values = []
    for _ in range(7):
        env.rand_step()
        values.append(env.task.reward_term_values.clone())
    means = env.reward_term_means()
    assert list(means) == list(EXPECTED["altitude"])
    expected = torch.stack(values).mean((0, 1))
    torch.testing.assert_close(torch.tensor(list(means.values())), expected, rtol=1e-5, atol=1e-6)
    assert means["survival"] == pytest.approx(env.task.config.survival_bonus)
    assert env.reward_term_means() == {}  # started over: no step since
    torch.testing.assert_close(env.task.reward_term_sums, torch.zeros_like(env.task.reward_term_sums))


def test_the_recipes_log_each_reward_term(tmp_path) -> None:
    recipe = algorithm("ppo")
    cfg = recipe.make_config("altitude", num_envs=8, rollout_steps=8, epochs=1, minibatches=2, frames=128,
                             out=str(tmp_path / "ppo"), final_eval_episodes=0, progress=False,
                             checkpoint_every=10**9, logger="csv")
    recipe.train(cfg)
    logged = {path.stem: path for path in (tmp_path / "ppo" / "logs").rglob("*.csv")
              if path.parent.name == "reward"}
    assert set(logged) == set(EXPECTED["altitude"]), sorted(logged)
    rows = list(csv.reader(logged["survival"].open()))
    assert rows and float(rows[-1][-1]) == pytest.approx(cfg.env_options.get("survival_bonus", 1.0))


def test_the_full_env_publishes_each_term_beside_the_reward() -> None:
    from torchrl.envs.utils import check_env_specs

    env = make_env("attitude", "volantex_ranger", num_envs=3, seed=4)
    check_env_specs(env, seed=0)
    td = env.reset()
    assert set(td["reward_terms"].keys()) == set(EXPECTED["attitude"])
    assert all(not value.any() for value in td["reward_terms"].values())  # a reset has no transition
    rollout = env.rollout(6)
    terms = rollout["next", "reward_terms"]
    assert terms[EXPECTED["attitude"][0]].shape == (3, 6, 1)
    total = sum(terms[name] for name in EXPECTED["attitude"])
    torch.testing.assert_close(total, rollout["next", "reward"], **TOL)
    assert "reward_terms" not in make_env("attitude", num_envs=1, lean=True).reset().keys()  # noqa: SIM118
