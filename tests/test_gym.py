"""The single-aircraft Gymnasium wrapper: registration, env_checker, horizon and TimeLimit, seeding,
the action contract, the tensor-core path against TorchRL's step, and a short Stable-Baselines3 PPO
run."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

import falcon_rl  # noqa: F401  (registers falcon_rl/<Task>-v0)
from falcon_rl.envs.gym import GYM_IDS, VECTOR_ENTRY_POINT, CoreAircraftEnv
from falcon_rl.envs.tasks import TERMINATION_CODE

#: Five env steps per episode (10 ms control).
SHORT = {"decimation": 1, "episode_seconds": 0.05}


@pytest.mark.parametrize("env_id", sorted(GYM_IDS.values()))
def test_registered_envs_pass_check_env_and_time_limit_is_the_horizon(env_id: str) -> None:
    env = gym.make(env_id, airframe="volantex_ranger")
    check_env(env.unwrapped, skip_render_check=True)
    spec = gym.spec(env_id)
    assert spec.vector_entry_point == VECTOR_ENTRY_POINT
    assert isinstance(env, gym.wrappers.TimeLimit)
    assert spec.max_episode_steps == env.get_wrapper_attr("_max_episode_steps")
    assert spec.max_episode_steps == env.unwrapped.env.max_episode_steps  # the env's own horizon


def test_core_aircraft_env_spaces_and_step() -> None:
    env = CoreAircraftEnv("altitude", "navion", **SHORT)
    assert env.observation_space.shape == (11,) and env.action_space.shape == (2,)
    assert env.env.config.backend == "warp"  # the default backend
    obs, info = env.reset(seed=3)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert 12.0 <= abs(info["initial_altitude"] - info["target_altitude"]) <= 18.0
    for step in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert isinstance(reward, float) and not terminated
        assert truncated == (step == 4)
    again, _ = env.reset(seed=3)
    first, _ = CoreAircraftEnv("altitude", "navion", **SHORT).reset(seed=3)
    np.testing.assert_array_equal(again, first)


def _truncation_steps(env: gym.Env, episodes: int = 2) -> list[int]:
    """Steps at which each of ``episodes`` episodes was truncated (zero action, no termination)."""
    ends = []
    for _ in range(episodes):
        env.reset(seed=0)
        for step in range(1, 50):
            _, _, terminated, truncated, _ = env.step(np.zeros(2, np.float32))
            assert not terminated
            if truncated:
                ends.append(step)
                break
    return ends


def test_time_limit_and_env_horizon_end_the_episode_at_the_smaller() -> None:
    assert _truncation_steps(gym.make("falcon_rl/Altitude-v0", **SHORT)) == [5, 5]  # env horizon 5 < 600
    assert _truncation_steps(gym.make("falcon_rl/Altitude-v0", max_episode_steps=3, **SHORT)) == [3, 3]


def test_seed_none_is_fresh_entropy_and_a_seed_is_reproducible() -> None:
    first, second = CoreAircraftEnv("altitude"), CoreAircraftEnv("altitude")
    assert first.build_seed != second.build_seed
    assert first.reset()[1]["initial_altitude"] != second.reset()[1]["initial_altitude"]
    actions = [np.array([0.1 * k, -0.05 * k], np.float32) for k in range(4)]
    runs = []
    for env in (first, second):
        obs, _ = env.reset(seed=21)
        runs.append([obs] + [env.step(action)[0] for action in actions])
    np.testing.assert_array_equal(np.stack(runs[0]), np.stack(runs[1]))


def test_seed_reseeds_the_robustness_transforms() -> None:
    options = {"sensors": "mild", "obs_delay_ms": (0.0, 100.0), "randomize": True}
    runs = []
    for build_seed in (1, 2):
        env = CoreAircraftEnv("altitude", "volantex_ranger", seed=build_seed, **options)
        obs, _ = env.reset(seed=9)
        runs.append([obs] + [env.step(np.full(2, 0.1, np.float32))[0] for _ in range(3)])
    np.testing.assert_array_equal(np.stack(runs[0]), np.stack(runs[1]))


@pytest.mark.parametrize("action", [np.zeros(1, np.float32), np.zeros((1, 2), np.float32),
                                    np.zeros(3, np.float32), np.zeros(2, bool), np.zeros(2, np.complex64),
                                    np.zeros(2, np.int64), np.array(["a", "b"]), [None, None]],
                         ids=["one-column", "batched", "three", "bool", "complex", "int", "str", "object"])
def test_wrong_actions_are_refused_before_anything_moves(action: object) -> None:
    env, twin = CoreAircraftEnv("altitude", seed=0), CoreAircraftEnv("altitude", seed=0)
    env.reset(seed=4)
    twin.reset(seed=4)
    with pytest.raises(ValueError, match="action") as refused:
        env.step(action)
    assert "\n" not in str(refused.value)
    good = np.array([0.3, -0.2], np.float32)
    np.testing.assert_array_equal(env.step(good)[0], twin.step(good)[0])


def assert_identical(fast: object, slow: object, where: str = "") -> None:
    """``fast`` and ``slow`` hold the same values with the same types: dicts with the same keys in the
    same order, arrays of one dtype and shape with equal entries (and no NaN or Inf in a float one),
    Python scalars of one type, sequences item by item."""
    assert type(fast) is type(slow), f"{where}: {type(fast).__name__} != {type(slow).__name__}"
    if isinstance(fast, dict):
        assert list(fast) == list(slow), f"{where}: keys {list(fast)} != {list(slow)}"
        for key in fast:
            assert_identical(fast[key], slow[key], f"{where}[{key!r}]")
    elif isinstance(fast, list | tuple):
        assert len(fast) == len(slow), f"{where}: {len(fast)} != {len(slow)} items"
        for index, (a, b) in enumerate(zip(fast, slow, strict=True)):
            assert_identical(a, b, f"{where}[{index}]")
    elif isinstance(fast, np.ndarray):
        assert (fast.dtype, fast.shape) == (slow.dtype, slow.shape), f"{where}: {fast.dtype} {fast.shape} " \
                                                                       f"!= {slow.dtype} {slow.shape}"
        if fast.dtype == object:
            assert_identical(list(fast), list(slow), where)
        else:
            np.testing.assert_array_equal(fast, slow, err_msg=where, strict=True)
            assert fast.dtype.kind != "f" or np.isfinite(fast).all(), f"{where}: not finite"
    else:
        assert fast == slow, f"{where}: {fast!r} != {slow!r}"


def _single_action(rng: np.random.Generator, step: int) -> np.ndarray:
    """Step ``step``'s action: uniform in [-1.5, 1.5] (float64 on even steps), full up elevator from
    step 40 (an alpha stall within 20 steps), a NaN at step 3 and infinities at step 4."""
    action = rng.uniform(-1.5, 1.5, 2)
    if step >= 40:
        action[0] = 1.0
    if step == 3:
        action[1] = np.nan
    if step == 4:
        action[:] = (np.inf, -np.inf)
    return action if step % 2 == 0 else action.astype(np.float32)


@pytest.mark.parametrize("options", [{}, {"lean": True}, {"backend": "torch", "dtype": torch.float64}],
                         ids=["default", "lean", "torch-float64"])
def test_tensor_core_steps_exactly_as_torchrl_step(options: dict) -> None:
    """The fast path (the env's tensor core) and TorchRL's step, side by side from one seed: the same
    observations, rewards, flags and infos (types included) through truncations, an alpha stall, a
    NaN action, a NaN state (its entries zeroed), infinite actions, reseeded and unseeded resets."""
    fast = CoreAircraftEnv("altitude", "navion", seed=3, episode_seconds=1.5, **options)  # 30 steps
    slow = CoreAircraftEnv("altitude", "navion", seed=3, episode_seconds=1.5, fast_path=False, **options)
    assert fast.core is not None and slow.core is None
    rng, reasons = np.random.default_rng(0), []
    assert_identical(fast.reset(seed=11), slow.reset(seed=11), "reset")
    for step in range(65):
        action = _single_action(rng, step)
        if step == 10:
            for env in (fast, slow):
                env.env.sim.x[0] = float("nan")
        result = fast.step(action)
        assert_identical(result, slow.step(action), f"step {step}")
        if result[2] or result[3]:
            reasons.append(result[4]["termination_reason"])
            seed = None if step % 2 else step
            assert_identical(fast.reset(seed=seed), slow.reset(seed=seed), f"reset after step {step}")
    assert {0, TERMINATION_CODE["non_finite"], TERMINATION_CODE["alpha_stall"]} <= set(reasons)


def test_robustness_options_step_through_torchrl() -> None:
    assert CoreAircraftEnv("altitude", seed=0, sensors="mild").core is None  # a TransformedEnv
    assert CoreAircraftEnv("altitude", seed=0).core is not None


@pytest.mark.slow
def test_stable_baselines3_ppo_trains() -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("falcon_rl/Altitude-v0", airframe="volantex_ranger")
    model = sb3.PPO("MlpPolicy", env, n_steps=1024, batch_size=256, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=2048)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
