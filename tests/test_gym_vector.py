"""The native batched Gymnasium VectorEnv: make_vec registration, spaces, shapes and dtypes, the
vector info convention, SAME_STEP autoreset (exact), partial resets, seeding, the action contract, and
the tensor-core path against TorchRL's step_and_maybe_reset.

Gymnasium 1.4 ships no vector env checker; its seed and options checks of ``env_checker`` run on the
vector env as they are, and the rest is asserted here.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_reset_options, check_reset_seed_determinism
from gymnasium.vector import AutoresetMode
from test_gym import assert_identical
from torchrl.envs.utils import step_mdp

import falcon_rl  # noqa: F401  (registers falcon_rl/<Task>-v0)
from falcon_rl.envs import make_env
from falcon_rl.envs.gym import GYM_IDS
from falcon_rl.envs.gym.vector import FalconVectorEnv
from falcon_rl.envs.tasks import TERMINATION_CODE

ALTITUDE = "falcon_rl/Altitude-v0"
#: Five env steps per episode (10 ms control).
SHORT = {"decimation": 1, "episode_seconds": 0.05}


def make(num_envs: int = 4, **kwargs: object) -> FalconVectorEnv:
    return gym.make_vec(ALTITUDE, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def test_make_vec_builds_one_batched_simulator_with_gymnasium_spaces() -> None:
    envs = make(8)
    assert isinstance(envs, FalconVectorEnv) and envs.env.batch_size == (8,)  # one simulator, not 8
    assert isinstance(gym.make_vec(ALTITUDE, num_envs=2), FalconVectorEnv)  # the default mode
    assert envs.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert envs.max_episode_steps == gym.spec(ALTITUDE).max_episode_steps
    assert envs.single_observation_space.shape == (11,) and envs.single_action_space.shape == (2,)
    assert envs.observation_space.shape == (8, 11) and envs.action_space.shape == (8, 2)
    assert envs.observation_space.dtype == envs.action_space.dtype == np.float32
    obs, info = envs.reset(seed=0)
    assert obs.dtype == np.float32 and obs in envs.observation_space
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    assert obs.shape == (8, 11) and obs.dtype == np.float32 and obs in envs.observation_space
    assert reward.shape == terminated.shape == truncated.shape == (8,)
    assert reward.dtype == np.float64 and terminated.dtype == truncated.dtype == np.bool_
    assert {"altitude_error", "_altitude_error", "termination_reason"} <= set(info)
    for key in (k for k in info if not k.startswith("_")):
        assert info[key].shape[0] == 8 and info[f"_{key}"].dtype == np.bool_ and info[f"_{key}"].all()


def test_gymnasium_seed_and_option_checks() -> None:
    envs = make(3)
    check_reset_seed_determinism(envs)
    check_reset_options(envs)


def _rollout(envs: FalconVectorEnv, seed: int, steps: int) -> list[np.ndarray]:
    envs.action_space.seed(seed)
    obs, info = envs.reset(seed=seed)
    out = [info["initial_altitude"], obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
        out += [obs, reward, terminated, truncated, info["initial_altitude"]]
    return out


def test_seeded_reset_is_reproducible_with_distinct_sub_envs_and_none_is_fresh() -> None:
    first, second = make(6, **SHORT), make(6, **SHORT)  # built from fresh entropy
    assert not np.array_equal(first.reset()[1]["initial_altitude"], second.reset()[1]["initial_altitude"])
    runs = [_rollout(envs, 5, 12) for envs in (first, second)]  # crosses two autoresets
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
    targets = runs[0][0]
    assert len(np.unique(targets)) == 6  # each sub-env its own draw
    assert not np.array_equal(first.reset(seed=6)[1]["initial_altitude"], targets)


def test_same_step_autoreset_is_exact() -> None:
    """Against TorchRL's own step and reset of the same env: the done step returns the last
    transition's flags and reward, the next episode's first observation and the final one in info."""
    envs = make(4, airframe="navion", seed=1, **SHORT)
    reference = make_env("altitude", "navion", num_envs=4, backend="warp", seed=1, **SHORT)
    action = torch.tensor([[0.2, -0.1]]).expand(4, 2)
    envs.reset(seed=3)
    reference.set_seed(3)
    data = reference.reset()
    for step in range(5):
        obs, reward, terminated, truncated, info = envs.step(action.numpy())
        stepped = reference.step(data.set("action", action))
        nxt, data = stepped["next"], step_mdp(stepped)
        np.testing.assert_array_equal(reward, nxt["reward"].reshape(-1).numpy())
        assert truncated.tolist() == [step == 4] * 4 and not terminated.any()
    assert info["_final_obs"].all() and info["_final_info"].all()
    np.testing.assert_array_equal(np.stack(list(info["final_obs"])), nxt["observation"].numpy())
    np.testing.assert_array_equal(info["final_info"]["altitude_error"],
                                  nxt["task", "altitude_error"].reshape(-1).numpy())
    data = reference.reset()  # what a reset at that point gives (the same random stream)
    np.testing.assert_array_equal(obs, data["observation"].numpy())
    np.testing.assert_array_equal(envs.step(action.numpy())[0],
                                  reference.step(data.set("action", action))["next", "observation"].numpy())


def test_partial_resets_and_per_env_masks() -> None:
    envs = make(4, seed=2, **SHORT)
    actions = np.zeros((4, 2), np.float32)
    envs.reset(seed=0)
    envs.step(actions)
    before = envs.step(actions)[0]
    obs, info = envs.reset(options={"reset_mask": np.array([True, False, False, False])})
    assert info["_altitude_error"].tolist() == [True, False, False, False]
    np.testing.assert_array_equal(obs[1:], before[1:])  # the other rows keep their observation
    assert not np.array_equal(obs[0], before[0])
    for _ in range(2):
        assert not envs.step(actions)[3].any()
    _, _, _, truncated, info = envs.step(actions)  # rows 1-3 reach 5 steps, row 0 has 3
    assert truncated.tolist() == [False, True, True, True]
    assert info["_final_obs"].tolist() == truncated.tolist() and info["final_obs"][0] is None
    assert info["final_info"]["_altitude_error"].tolist() == truncated.tolist()
    envs.step(actions)
    assert envs.step(actions)[3].tolist() == [True, False, False, False]


def test_max_episode_steps_truncates_at_the_smaller_horizon() -> None:
    for limit, expected in ((3, 3), (50, 5)):
        envs = make(2, max_episode_steps=limit, **SHORT)
        envs.reset(seed=0)
        ends = [step for step in range(1, 8) if envs.step(np.zeros((2, 2), np.float32))[3].all()]
        assert ends[0] == expected


@pytest.mark.parametrize("actions", [np.zeros((4, 1), np.float32), np.zeros(2, np.float32),
                                     np.zeros((5, 2), np.float32), np.zeros((4, 2), bool),
                                     np.zeros((4, 2), np.complex64), np.zeros((4, 2), np.int32)],
                         ids=["one-column", "unbatched", "five-rows", "bool", "complex", "int"])
def test_wrong_actions_are_refused_before_anything_moves(actions: np.ndarray) -> None:
    envs, twin = make(4, seed=0), make(4, seed=0)
    envs.reset(seed=8)
    twin.reset(seed=8)
    with pytest.raises(ValueError, match="actions") as refused:
        envs.step(actions)
    assert "\n" not in str(refused.value)
    good = np.full((4, 2), 0.25, np.float32)
    np.testing.assert_array_equal(envs.step(good)[0], twin.step(good)[0])


def test_a_nan_action_terminates_its_env_only_and_infinities_are_clamped() -> None:
    envs, twin = make(3, seed=0), make(3, seed=0)
    envs.reset(seed=1)
    twin.reset(seed=1)
    actions = np.array([[np.nan, 0.0], [np.inf, -np.inf], [0.5, 0.5]], np.float32)
    obs, _, terminated, _, info = envs.step(actions)
    expected, _, expected_terminated, _, _ = twin.step(np.array([[0.0, 0.0], [1.0, -1.0], [0.5, 0.5]],
                                                                np.float32))
    assert terminated.tolist() == [True, False, False] and not expected_terminated.any()
    assert info["final_info"]["termination_reason"][0] == TERMINATION_CODE["non_finite"]
    np.testing.assert_array_equal(obs[1:], expected[1:])


def test_misuse_is_refused_in_one_line() -> None:
    envs = make(2)
    with pytest.raises(RuntimeError, match="reset"):
        envs.step(np.zeros((2, 2), np.float32))
    with pytest.raises(ValueError, match="seed"):
        envs.reset(seed=[1, 2])
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"unknown": 1})
    envs.reset(seed=0)
    with pytest.raises(ValueError, match="reset_mask"):
        envs.reset(options={"reset_mask": np.zeros(2, bool)})


def _parity_actions(rng: np.random.Generator, step: int, num_envs: int, action_dim: int) -> np.ndarray:
    """Step ``step``'s actions [N, A]: uniform in [-1.5, 1.5] (float64 on even steps), rows 4 and 5 at
    full up and full down elevator (alpha stalls), a NaN in row 0 at step 3, infinities in row 1 at
    step 4."""
    actions = rng.uniform(-1.5, 1.5, (num_envs, action_dim))
    actions[4:6, 0] = (1.0, -1.0)
    if step == 3:
        actions[0, -1] = np.nan
    if step == 4:
        actions[1] = np.where(np.arange(action_dim) % 2, -np.inf, np.inf)
    return actions if step % 2 == 0 else actions.astype(np.float32)


def _scribble(value: object) -> None:
    """Overwrite every array in ``value`` (nested dicts, tuples, object arrays) in place, as a user may:
    the env must not keep views of what it hands out."""
    if isinstance(value, dict):
        for item in value.values():
            _scribble(item)
    elif isinstance(value, tuple | list):
        for item in value:
            _scribble(item)
    elif isinstance(value, np.ndarray) and value.dtype == object:
        _scribble(list(value))
    elif isinstance(value, np.ndarray) and value.flags.writeable:
        value[...] = 7


#: (task, env options, host arrays from one packed copy as off the CPU).
PARITY_CASES = [(task, {}, False) for task in sorted(GYM_IDS)] + [
    ("altitude", {"lean": True}, False), ("altitude", {"backend": "torch", "dtype": torch.float64}, False),
    ("altitude", {}, True), ("trajectory", {"backend": "torch", "dtype": torch.float64}, True)]


@pytest.mark.parametrize(("task", "options", "pack"), PARITY_CASES,
                         ids=[*sorted(GYM_IDS), "altitude-lean", "altitude-torch-float64", "altitude-packed",
                              "trajectory-torch-float64-packed"])
def test_tensor_core_steps_exactly_as_torchrl_step_and_maybe_reset(task: str, options: dict,
                                                                   pack: bool) -> None:
    """The fast path (the env's tensor core) and TorchRL's step_and_maybe_reset, side by side from one
    seed: the same observations, rewards, flags and infos (final_obs and final_info included) through
    autoresets after truncations, alpha stalls, NaN actions and a NaN state, a partial reset and a
    reseeded reset; what the fast path hands out is overwritten each time (it keeps no view of it)."""
    fast = FalconVectorEnv(6, task, "navion", seed=4, episode_seconds=1.0, **options)  # 20 steps per episode
    slow = FalconVectorEnv(6, task, "navion", seed=4, episode_seconds=1.0, fast_path=False, **options)
    assert fast.core is not None and slow.core is None
    fast.core.pack = pack
    rng, seen = np.random.default_rng(1), set()

    def same(outputs: tuple, reference: tuple, where: str) -> None:
        assert_identical(outputs, reference, where)
        _scribble(outputs)

    same(fast.reset(seed=5), slow.reset(seed=5), "reset")
    for step in range(45):
        if step == 12:
            mask = np.array([True, False, False, True, False, False])
            same(fast.reset(options={"reset_mask": mask}), slow.reset(options={"reset_mask": mask}),
                 "partial reset")
        if step == 30:
            same(fast.reset(seed=6), slow.reset(seed=6), "reseeded reset")
        if step == 35:
            for envs in (fast, slow):  # a NaN in row 2's state: terminated, its entries zeroed
                envs.env.sim.x[2] = float("nan")
        actions = _parity_actions(rng, step, 6, fast.single_action_space.shape[0])
        result = fast.step(actions)
        if "final_info" in result[4]:
            final = result[4]["final_info"]
            seen |= set(final["termination_reason"][final["_termination_reason"]].tolist())
        same(result, slow.step(actions), f"step {step}")
    # the landing task flies its approach at 1.3 V_stall or so: the same elevator pulls do not reach 1.5
    # alpha_stall within its 1 s episodes (truncations and the NaN state still end them)
    stalls = set() if task == "landing" else {TERMINATION_CODE["alpha_stall"]}
    assert {0, TERMINATION_CODE["non_finite"], *stalls} <= seen
