"""The Gymnasium wrapper: registration, env_checker, and a short Stable-Baselines3 PPO run."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import falcon_rl  # noqa: F401  (registers falcon_rl/<Task>-v0)
from falcon_rl.envs.gym import GYM_IDS, CoreAircraftEnv


@pytest.mark.parametrize("env_id", sorted(GYM_IDS.values()))
def test_registered_envs_pass_check_env(env_id: str) -> None:
    env = gym.make(env_id, airframe="volantex_ranger")
    check_env(env.unwrapped, skip_render_check=True)


def test_core_aircraft_env_spaces_and_step() -> None:
    env = CoreAircraftEnv("altitude", "navion", episode_seconds=0.05)
    assert env.observation_space.shape == (11,) and env.action_space.shape == (2,)
    obs, info = env.reset(seed=3)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert 12.0 <= abs(info["initial_altitude"] - info["target_altitude"]) <= 18.0
    for step in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert isinstance(reward, float) and not terminated
        assert truncated == (step == 4)
    again, _ = env.reset(seed=3)
    first, _ = CoreAircraftEnv("altitude", "navion").reset(seed=3)
    np.testing.assert_array_equal(again, first)


@pytest.mark.slow
def test_stable_baselines3_ppo_trains() -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("falcon_rl/Altitude-v0", airframe="volantex_ranger")
    model = sb3.PPO("MlpPolicy", env, n_steps=1024, batch_size=256, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=2048)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
