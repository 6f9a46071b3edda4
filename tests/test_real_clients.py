"""Clients nobody on this project wrote, used as their own docs say, against the real libraries:
TorchRL's ``GymEnv`` (one env, ``frame_skip``, ``num_envs`` and inside ``ParallelEnv``), Gymnasium's
``check_env`` with its default arguments on a headless machine, ``gymnasium.make`` by id string in a
fresh interpreter that never imported falcon_rl, and CleanRL's continuous-control wrapper stack."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env
from torchrl.envs import GymEnv
from torchrl.envs.utils import check_env_specs

import falcon_rl  # noqa: F401  (registers falcon_rl/<Task>-v0)
from falcon_rl.envs.gym import GYM_IDS

ROOT = Path(__file__).resolve().parents[1]
IDS = sorted(GYM_IDS.values())
#: Ten env steps an episode (20 Hz control), so that episodes end inside a short test.
SHORT = {"episode_seconds": 0.5, "max_episode_steps": 10}


def run_fresh(code: str, folder: Path, timeout: float = 400) -> str:
    """stdout of ``code`` run as a script file by a fresh interpreter (as users run theirs); fails the
    test with its stderr when the interpreter exits non-zero."""
    script = folder / "client.py"
    script.write_text(textwrap.dedent(code))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout


@pytest.mark.parametrize("env_id", IDS)
def test_torchrl_gymenv_builds_every_id_and_passes_its_spec_check(env_id: str) -> None:
    env = GymEnv(env_id)  # TorchRL passes frameskip=1 and drops it on the refusal Python would word
    check_env_specs(env, seed=0)
    rollout = env.rollout(4)
    assert rollout["next", "observation"].shape == (4, *env.observation_spec["observation"].shape)
    assert torch.isfinite(rollout["next", "reward"]).all()


def test_torchrl_gymenv_frame_skip_repeats_the_action_and_sums_the_rewards() -> None:
    skipped, plain = GymEnv("falcon_rl/Altitude-v0", frame_skip=3), GymEnv("falcon_rl/Altitude-v0")
    skipped.set_seed(7)
    plain.set_seed(7)
    action = torch.tensor([0.1, 0.4])
    one = skipped.step(skipped.reset().set("action", action))["next"]
    state, rewards = plain.reset(), []
    for _ in range(3):
        state = plain.step(state.set("action", action))["next"]
        rewards.append(state["reward"])
    torch.testing.assert_close(one["observation"], state["observation"], rtol=0, atol=0)
    torch.testing.assert_close(one["reward"], torch.stack(rewards).sum(0), rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env_with_its_defaults_passes_headless(env_id: str, monkeypatch) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    env = gym.make(env_id)
    assert env.unwrapped.metadata["render_modes"] == ["rgb_array"]  # no window can open here
    check_env(env.unwrapped)  # default arguments: every listed render mode is made and checked
    env.close()


@pytest.mark.parametrize("env_id", IDS)
def test_cleanrl_wrapper_stack_runs_every_id(env_id: str) -> None:
    """CleanRL's ``ppo_continuous_action.py`` env stack, made from an id string (its ``--env-id``)."""
    gamma = 0.99

    def thunk() -> gym.Env:
        env = gym.make(f"falcon_rl:{env_id}", **SHORT)
        env = gym.wrappers.FlattenObservation(env)
        env = gym.wrappers.RecordEpisodeStatistics(env)
        env = gym.wrappers.ClipAction(env)
        env = gym.wrappers.NormalizeObservation(env)
        env = gym.wrappers.TransformObservation(env, lambda obs: np.clip(obs, -10, 10), env.observation_space)
        env = gym.wrappers.NormalizeReward(env, gamma=gamma)
        return gym.wrappers.TransformReward(env, lambda reward: np.clip(reward, -10, 10))

    envs = gym.vector.SyncVectorEnv([thunk for _ in range(2)])
    assert isinstance(envs.single_action_space, gym.spaces.Box)
    obs, _ = envs.reset(seed=1)
    envs.single_action_space.seed(1)
    episodes = []
    for _ in range(12):
        action = np.stack([envs.single_action_space.sample() * 2.0 for _ in range(2)])  # ClipAction's work
        obs, reward, _, _, infos = envs.step(action)
        assert np.isfinite(obs).all() and np.isfinite(reward).all() and np.abs(obs).max() <= 10.0
        if "episode" in infos:
            episodes.extend(infos["episode"]["l"][infos["_episode"]].tolist())
    envs.close()
    assert episodes and max(episodes) <= SHORT["max_episode_steps"]


@pytest.mark.parametrize("prefix", ["", "falcon_rl:"])
def test_gymnasium_make_by_id_string_in_a_fresh_interpreter(prefix: str, tmp_path: Path) -> None:
    """What a tool that takes only an id string does (CleanRL's ``--env-id``, RLlib, a spawned worker):
    the installed start-up file registers the ids when Gymnasium is imported (``falcon_rl_gymnasium_hook``),
    and the ``module:id`` form has Gymnasium import the module itself."""
    out = run_fresh(f"""
        import sys
        import gymnasium
        for env_id in {IDS!r}:
            env = gymnasium.make({prefix!r} + env_id)
            obs, _ = env.reset(seed=0)
            obs, reward, *_ = env.step(env.action_space.sample())
            print(env_id, env.spec.max_episode_steps, obs.shape)
    """, tmp_path)
    assert [line.split()[0] for line in out.splitlines()] == IDS


def test_the_start_up_hook_imports_nothing_until_gymnasium_is_imported(tmp_path: Path) -> None:
    out = run_fresh("""
        import sys
        import falcon_rl_gymnasium_hook
        print(any(type(f).__name__ == "_RegisterAfterGymnasium" for f in sys.meta_path),
              "falcon_rl" in sys.modules, "gymnasium" in sys.modules)
        import json
        print("falcon_rl" in sys.modules)
        import gymnasium
        print("falcon_rl/Altitude-v0" in gymnasium.registry)
    """, tmp_path)
    assert out.split() == ["True", "False", "False", "False", "True"]


def test_torchrl_gymenv_num_envs_and_parallel_env_from_a_script(tmp_path: Path) -> None:
    """``GymEnv(id, num_envs=2)`` (Gymnasium's AsyncVectorEnv) and ``ParallelEnv`` over ``GymEnv``, from a
    user's script with its ``__main__`` guard that never imports falcon_rl: TorchRL starts the workers with
    ``spawn``, and each finds the ids by importing Gymnasium."""
    out = run_fresh("""
        import functools
        from torchrl.envs import GymEnv, ParallelEnv

        if __name__ == "__main__":
            env = GymEnv("falcon_rl/Attitude-v0", num_envs=2)
            print("num_envs", tuple(env.rollout(3)["next", "observation"].shape))
            env.close()
            env = ParallelEnv(2, functools.partial(GymEnv, "falcon_rl/ClimbDescend-v0", frame_skip=2))
            print("parallel", tuple(env.rollout(3)["next", "observation"].shape))
            env.close()
    """, tmp_path)
    assert "num_envs (2, 3, 15)" in out and "parallel (2, 3, 11)" in out
