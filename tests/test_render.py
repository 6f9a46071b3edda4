"""render() of the Gymnasium envs and the TorchRL pixels transform: frames from the same renderer as
the animations; an env made without a render mode builds no view."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs

import falcon_rl
from falcon_rl.envs.gym.render import display_available
from falcon_rl.viz.pixels import FlightPixels


def level_then_banked(env: gymnasium.Env, steps: int) -> tuple[np.ndarray, np.ndarray]:
    env.reset(seed=0)
    level = env.render()
    for _ in range(steps):
        env.step(np.array([0.0, 0.4, 0.0, 0.6], np.float32))
    return level, env.render()


def test_rgb_array_frames():
    env = gymnasium.make("falcon_rl/Attitude-v0", airframe="volantex_ranger", render_mode="rgb_array")
    assert env.metadata["render_fps"] == pytest.approx(20.0)
    level, banked = level_then_banked(env, 20)
    for frame in (level, banked):
        assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8
    assert (level != banked).mean() > 0.01
    env.close()


def test_unrendered_env_builds_no_view():
    env = gymnasium.make("falcon_rl/Attitude-v0", airframe="volantex_ranger")
    env.reset(seed=0)
    assert env.unwrapped._renderer is None
    with pytest.warns(UserWarning, match="without render_mode"):
        assert env.render() is None


def test_render_mode_errors(monkeypatch):
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        gymnasium.make("falcon_rl/Altitude-v0", airframe="volantex_ranger", render_mode="ascii")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if not display_available():
        with pytest.raises(ValueError, match="needs a display"):
            gymnasium.make("falcon_rl/Altitude-v0", airframe="volantex_ranger", render_mode="human")
    with pytest.raises(ValueError, match="at most 16 are rendered"):
        gymnasium.make_vec("falcon_rl/Altitude-v0", num_envs=17, render_mode="rgb_array")


def test_vector_env_renders_each_sub_env():
    env = gymnasium.make_vec("falcon_rl/Attitude-v0", num_envs=2, airframe="volantex_ranger",
                             render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.array([[0.0, 0.5, 0.0, 0.6], [0.0, -0.5, 0.0, 0.6]], np.float32))
    frames = env.render()
    assert len(frames) == 2 and all(f.shape == (360, 480, 3) for f in frames)
    assert (frames[0] != frames[1]).mean() > 0.01  # banked left and right
    env.close()


def test_torchrl_pixels():
    env = TransformedEnv(falcon_rl.make_env("attitude", "volantex_ranger", num_envs=2, seed=0),
                         FlightPixels(96, 72))
    check_env_specs(env)
    rollout = env.rollout(5, lambda td: td.set("action", torch.zeros(2, 4)))
    assert rollout["next", "pixels"].shape == (2, 5, 72, 96, 3)
    assert rollout["next", "pixels"].dtype == torch.uint8
    assert rollout["pixels"].float().std() > 0
    env.close()
