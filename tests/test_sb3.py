"""The Stable-Baselines3 VecEnv adapter over one batched simulator: SB3's checks and conventions
(terminal_observation, TimeLimit.truncated, seed), attributes and methods, the tensor-core path
against TorchRL's, and a short PPO run."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest
import torch

sb3 = pytest.importorskip("stable_baselines3")

from stable_baselines3.common.env_checker import check_env  # noqa: E402
from stable_baselines3.common.monitor import Monitor  # noqa: E402
from stable_baselines3.common.vec_env import VecMonitor  # noqa: E402
from test_gym import assert_identical  # noqa: E402

import falcon_rl  # noqa: E402, F401  (registers falcon_rl/<Task>-v0)
from falcon_rl.envs.gym import GYM_IDS  # noqa: E402
from falcon_rl.envs.gym.sb3 import FalconSB3VecEnv  # noqa: E402
from falcon_rl.envs.gym.vector import FalconVectorEnv  # noqa: E402
from falcon_rl.envs.tasks import TERMINATION_CODE  # noqa: E402

#: Five env steps per episode (10 ms control).
SHORT = {"decimation": 1, "episode_seconds": 0.05}


@pytest.mark.parametrize("env_id", sorted(GYM_IDS.values()))
def test_sb3_env_checker_accepts_the_single_env(env_id: str) -> None:
    check_env(gym.make(env_id, airframe="volantex_ranger"), warn=True)


def test_adapter_follows_sb3_conventions_and_matches_the_gym_vector_env() -> None:
    venv = FalconSB3VecEnv.make("altitude", num_envs=3, seed=1, **SHORT)
    twin = FalconVectorEnv(3, "altitude", seed=1, **SHORT)
    assert venv.num_envs == 3 and venv.observation_space.shape == (11,) and venv.action_space.shape == (2,)
    venv.seed(7)
    obs = venv.reset()
    np.testing.assert_array_equal(obs, twin.reset(seed=7)[0])
    actions = np.full((3, 2), 0.1, np.float32)
    for step in range(5):
        obs, reward, done, infos = venv.step(actions)
        expected, expected_reward, _, truncated, info = twin.step(actions)
        assert obs.dtype == reward.dtype == np.float32 and done.dtype == np.bool_ and len(infos) == 3
        np.testing.assert_array_equal(obs, expected)
        np.testing.assert_array_equal(reward, expected_reward.astype(np.float32))
        assert done.tolist() == truncated.tolist() == [step == 4] * 3
        assert [i["TimeLimit.truncated"] for i in infos] == [step == 4] * 3
    for row, sb3_info in enumerate(infos):  # the done step: obs is already the next episode's first
        np.testing.assert_array_equal(sb3_info["terminal_observation"], info["final_obs"][row])
        assert not np.array_equal(sb3_info["terminal_observation"], obs[row])


def test_seed_applies_at_the_next_reset_and_none_continues_the_stream() -> None:
    venv = FalconSB3VecEnv.make("altitude", num_envs=2, info_keys=("initial_altitude",))
    assert venv.seed(4) == [4, 4]  # one seed for the batch
    venv.reset()
    first = [info["initial_altitude"] for info in venv.reset_infos]
    venv.reset()  # no seed: continues the stream
    assert [info["initial_altitude"] for info in venv.reset_infos] != first
    venv.seed(4)
    venv.reset()
    assert [info["initial_altitude"] for info in venv.reset_infos] == first


def test_info_keys_attributes_and_methods() -> None:
    venv = FalconSB3VecEnv.make("altitude", num_envs=4, seed=0, info_keys=("altitude_error",))
    venv.reset()
    _, _, _, infos = venv.step(np.zeros((4, 2), np.float32))
    assert all(isinstance(info["altitude_error"], float) for info in infos)
    assert venv.get_attr("max_episode_steps", indices=[0, 2]) == [venv.venv.max_episode_steps] * 2
    assert venv.get_attr("render_mode") == [None] * 4
    assert venv.has_attr("single_action_space") and not venv.has_attr("no_such_attribute")
    assert venv.env_is_wrapped(Monitor) == [False] * 4
    with pytest.raises(ValueError, match="whole batch"):
        venv.set_attr("max_episode_steps", 3, indices=[1])
    with pytest.raises(ValueError, match="whole batch"):
        venv.env_method("reset", indices=0)
    venv.set_attr("label", "fleet")
    assert venv.get_attr("label") == ["fleet"] * 4
    results = venv.env_method("reset", seed=3)
    assert len(results) == 4 and results[0][0].shape == (4, 11)
    with pytest.raises(KeyError, match="altitude_errr"):
        FalconSB3VecEnv.make("altitude", num_envs=1, seed=0, info_keys=("altitude_errr",)).reset()


def test_wrong_actions_are_refused() -> None:
    venv = FalconSB3VecEnv.make("altitude", num_envs=4, seed=0)
    venv.reset()
    for actions in (np.zeros((4, 1), np.float32), np.zeros((4, 2), bool), np.zeros((4, 2), np.complex64)):
        with pytest.raises(ValueError, match="actions"):
            venv.step(actions)


@pytest.mark.parametrize("info_keys", [(), ("altitude_error", "termination_reason")], ids=["bare", "keys"])
def test_tensor_core_adapter_steps_exactly_as_the_torchrl_path(info_keys: tuple[str, ...]) -> None:
    """Fast path and TorchRL path side by side from one seed: the same obs, rewards, dones, infos
    (terminal_observation, TimeLimit.truncated, task entries) and reset_infos through truncations,
    alpha stalls, a NaN action, a NaN state, and a reseeded reset."""
    fast = FalconSB3VecEnv.make("altitude", num_envs=4, airframe="navion", info_keys=info_keys, seed=2,
                                episode_seconds=1.0)
    slow = FalconSB3VecEnv.make("altitude", num_envs=4, airframe="navion", info_keys=info_keys, seed=2,
                                episode_seconds=1.0,
                                fast_path=False)
    assert fast.venv.core is not None and slow.venv.core is None
    rng, reasons = np.random.default_rng(3), set()
    for step in range(45):
        if step in (0, 30):
            for venv in (fast, slow):
                venv.seed(step)
            assert_identical(fast.reset(), slow.reset(), "reset")
        if step == 12:
            for venv in (fast, slow):
                venv.venv.env.sim.x[3] = float("nan")
        actions = rng.uniform(-1.2, 1.2, (4, 2)).astype(np.float32)
        actions[2, 0] = 1.0  # full up elevator: alpha stalls
        actions[1, 1] = np.nan if step == 5 else actions[1, 1]
        fast.step_async(actions)
        slow.step_async(actions)
        result = fast.step_wait()
        assert_identical(result, slow.step_wait(), f"step {step}")
        assert_identical(fast.reset_infos, slow.reset_infos, f"reset_infos {step}")
        terminal = [info for info in result[3] if "terminal_observation" in info]
        reasons |= {info.get("termination_reason", -1) for info in terminal}
        assert len(terminal) == int(result[2].sum())
    if info_keys:
        assert {0, TERMINATION_CODE["alpha_stall"], TERMINATION_CODE["non_finite"]} <= reasons


@pytest.fixture
def one_torch_thread() -> Iterator[None]:
    """One torch thread for SB3's small networks (two spin against the simulator's on a busy 2-core
    machine and make a short run 10-20x slower)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.mark.usefixtures("one_torch_thread")
def test_ppo_trains_on_the_batched_adapter() -> None:
    venv = VecMonitor(FalconSB3VecEnv.make("altitude", num_envs=64, airframe="volantex_ranger", seed=0,
                                           decimation=5, episode_seconds=1.0))
    model = sb3.PPO("MlpPolicy", venv, n_steps=16, batch_size=256, n_epochs=2, seed=0, device="cpu")
    before = [p.detach().clone() for p in model.policy.parameters()]
    model.learn(total_timesteps=4096)
    assert model.num_timesteps >= 4096
    after = [p.detach() for p in model.policy.parameters()]
    assert any(not np.array_equal(a.numpy(), b.numpy()) for a, b in zip(before, after, strict=True))
    assert len(model.ep_info_buffer) > 0 and all(ep["l"] <= 20 for ep in model.ep_info_buffer)
    actions, _ = model.predict(venv.reset(), deterministic=True)
    assert actions.shape == (64, 2) and np.all(np.abs(actions) <= 1.0)


def test_missing_stable_baselines3_is_one_clear_import_error(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in [name for name in sys.modules if name.split(".")[0] == "stable_baselines3"]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.delitem(sys.modules, "falcon_rl.envs.gym.sb3")
    with pytest.raises(ImportError, match="needs stable-baselines3: pip install stable-baselines3") as error:
        importlib.import_module("falcon_rl.envs.gym.sb3")
    assert "\n" not in str(error.value)
