"""Seeding reaches every random stream: the env, the simulator and each robustness transform.

One seed, given to ``make_env``, to ``env.set_seed`` or to ``reset(seed=)``, gives the same rollout
with sensors, randomisation and ranged delays all on; unseeded envs and transforms draw fresh entropy;
the workers of batched envs, collectors and Gymnasium vector envs draw distinct streams of one seed.
"""

from __future__ import annotations

import functools

import gymnasium
import numpy as np
import pytest
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl._utils import seed_generator
from torchrl.collectors import MultiSyncCollector
from torchrl.envs import EnvBase, ParallelEnv, SerialEnv, TransformedEnv
from torchrl.envs.utils import step_mdp

import falcon_rl  # noqa: F401  (registers the Gymnasium ids)
from falcon_rl import make_env
from falcon_rl.physics.engine import derive_seed, fresh_seed
from falcon_rl.transforms import (
    ActionDelay,
    DomainRandomization,
    ObservationDelay,
    SensorChannel,
    SensorConfig,
    SensorTransform,
)

#: Every robustness transform on, with ranged delays (10 ms control: 1 to 5 steps of delay).
ROBUST = {"sensors": "mild", "obs_delay_ms": (10.0, 50.0), "action_delay_ms": (10.0, 50.0),
          "randomize": True, "turbulence": "mild", "decimation": 1}
N = 4


def _actions(steps: int, shape: torch.Size) -> list[torch.Tensor]:
    """Fixed pseudo-random actions of ``shape`` ([N, A], or [W, N, A] batched) in [-0.3, 0.3]."""
    generator = torch.Generator().manual_seed(1234)
    return [0.6 * torch.rand(shape, generator=generator) - 0.3 for _ in range(steps)]


def _roll(env: EnvBase, td: TensorDictBase, steps: int = 12) -> list[TensorDictBase]:
    """[reset data, step 1 data, ...] of ``steps`` steps from ``td`` under :func:`_actions`."""
    out = [td.clone()]
    for action in _actions(steps, env.action_spec.shape):
        td["action"] = action
        full = env.step(td)
        out.append(full["next"].clone())
        td = step_mdp(full)
    return out


def _assert_same_rollout(first: list[TensorDictBase], second: list[TensorDictBase]) -> None:
    assert len(first) == len(second)
    for t, (a, b) in enumerate(zip(first, second, strict=True)):
        keys = ["observation", ("measured", "position_ned")] + (["reward", "applied_action"] if t else [])
        for key in keys:
            assert torch.equal(a[key], b[key]), (t, key)


def test_derived_and_fresh_seeds() -> None:
    assert derive_seed(7, 0, "SensorTransform") == derive_seed(7, 0, "SensorTransform")
    assert len({derive_seed(7, 0, "A"), derive_seed(7, 1, "A"), derive_seed(8, 0, "A")}) == 3
    assert 0 <= derive_seed(2**70, "x") < 2**62
    assert fresh_seed() != fresh_seed()


def test_unseeded_transforms_draw_fresh_streams_and_seeded_ones_repeat() -> None:
    """A transform built without a seed (the default) draws fresh entropy, never a shared 0."""
    unseeded = [DomainRandomization(), DomainRandomization()]
    assert unseeded[0].seed is None
    draws = [torch.rand(8, generator=t.stream()) for t in unseeded]
    assert not torch.equal(draws[0], draws[1])
    config = SensorConfig(gyro=SensorChannel(noise_std=1.0))
    seeded = [SensorTransform(config, seed=seed) for seed in (5, 5, 6)]
    draws = [torch.rand(8, generator=t.stream()) for t in seeded]
    assert torch.equal(draws[0], draws[1]) and not torch.equal(draws[0], draws[2])
    seeded[1].seed = 6  # assigning the seed restarts the stream from it
    assert torch.equal(torch.rand(8, generator=seeded[1].stream()), draws[2])


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_unseeded_envs_differ(backend: str) -> None:
    envs = [make_env("altitude", num_envs=N, backend=backend, seed=None, **ROBUST) for _ in range(2)]
    resets = [env.reset() for env in envs]
    assert not torch.equal(resets[0]["observation"], resets[1]["observation"])
    masses = [env.transform[0].sampled()["mass"] for env in envs]
    assert not torch.equal(masses[0], masses[1])
    assert envs[0].base_env.seed_record[1] != envs[1].base_env.seed_record[1]


@pytest.mark.parametrize("route", ["constructor", "set_seed", "reset_seed"])
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_one_seed_gives_one_rollout(backend: str, route: str) -> None:
    """Observations, rewards and applied actions repeat exactly under sensors, randomisation, ranged
    delays and turbulence, whichever way the seed is given."""
    reference = make_env("altitude", num_envs=N, backend=backend, seed=11, **ROBUST)
    expected = _roll(reference, reference.reset())
    if route == "constructor":
        env = make_env("altitude", num_envs=N, backend=backend, seed=11, **ROBUST)
        td = env.reset()
    else:
        env = make_env("altitude", num_envs=N, backend=backend, seed=3, **ROBUST)
        _roll(env, env.reset(), steps=4)  # move every stream on first
        if route == "set_seed":
            env.set_seed(11)
            td = env.reset()
        else:
            td = env.reset(seed=11)
    _assert_same_rollout(expected, _roll(env, td))
    other = make_env("altitude", num_envs=N, backend=backend, seed=12, **ROBUST)
    assert not torch.equal(_roll(other, other.reset(), steps=2)[2]["observation"], expected[2]["observation"])


def test_transforms_of_one_env_draw_distinct_streams() -> None:
    """The two delays of one env, with the same range, draw different delays (one seed, two streams)."""
    env = make_env("altitude", num_envs=64, seed=5, obs_delay_ms=(10.0, 50.0), action_delay_ms=(10.0, 50.0),
                   decimation=1)
    env.reset()
    action_delay, obs_delay = env.transform[0], env.transform[1]
    assert isinstance(action_delay, ActionDelay) and isinstance(obs_delay, ObservationDelay)
    assert not torch.equal(action_delay.delays, obs_delay.delays)
    assert action_delay.root_seed == obs_delay.root_seed == 5


def test_a_transform_seed_holds_until_the_env_is_reseeded() -> None:
    base = make_env("altitude", num_envs=N, seed=1, decimation=1)
    sensors = SensorTransform(SensorConfig(gps_position=SensorChannel(noise_std=1.0)), seed=9)
    follower = ObservationDelay((10.0, 50.0))  # unseeded: follows the env
    env = TransformedEnv(base, sensors)
    env.append_transform(follower)
    env.reset()
    assert sensors.root_seed == 9 and follower.root_seed == 1
    env.set_seed(4)
    env.reset()
    assert sensors.root_seed == 4 and follower.root_seed == 4
    sensors.seed = 6  # the latest seeding wins: the transform's own, then the env's again
    env.reset()
    assert sensors.root_seed == 6 and follower.root_seed == 4
    env.set_seed(4)
    env.reset()
    assert sensors.root_seed == 4


def test_serial_env_workers_get_distinct_reproducible_streams() -> None:
    """TorchRL seeds the workers of a batched env with seed, seed_generator(seed), ...: each worker
    (and each of its transforms) draws its own stream, and the same seed repeats them all."""
    make = functools.partial(make_env, "altitude", num_envs=N, seed=None, **ROBUST)
    first, second = SerialEnv(2, make), SerialEnv(2, make)
    unseeded = first.reset()["observation"]
    assert not torch.equal(unseeded[0], unseeded[1])
    for batched in (first, second):
        batched.set_seed(21)
    seeds = [env.base_env.seed_record[1] for env in first._envs]
    assert seeds == [21, seed_generator(21)]
    observation = first.reset()["observation"]
    assert not torch.equal(observation[0], observation[1])
    assert torch.equal(observation, second.reset()["observation"])
    for batched in (first, second):
        batched.set_seed(21)
    rollouts = [_roll(batched, batched.reset(), steps=3) for batched in (first, second)]
    _assert_same_rollout(*rollouts)


def test_gymnasium_sub_envs_get_distinct_reproducible_streams() -> None:
    options = {"airframe": "navion", "sensors": "mild", "randomize": True, "decimation": 1}
    make = functools.partial(gymnasium.make, "falcon_rl/Altitude-v0", **options)
    vector = gymnasium.vector.SyncVectorEnv([make, make])
    observation, _ = vector.reset(seed=3)
    assert not np.array_equal(observation[0], observation[1])  # sub-env i is reseeded with 3 + i
    again, _ = gymnasium.vector.SyncVectorEnv([make, make]).reset(seed=3)
    np.testing.assert_array_equal(observation, again)
    unseeded = [make().reset()[0] for _ in range(2)]
    assert not np.array_equal(unseeded[0], unseeded[1])


@pytest.mark.slow
def test_parallel_env_and_collector_workers_from_constructors() -> None:
    """Spawned workers built from one constructor: unseeded they differ, seeded they repeat."""
    make = functools.partial(make_env, "altitude", num_envs=N, backend="warp", seed=None, **ROBUST)
    parallel = ParallelEnv(2, make)
    try:
        unseeded = parallel.reset()["observation"]
        assert not torch.equal(unseeded[0], unseeded[1])
        parallel.set_seed(8)
        seeded = parallel.reset()["observation"]
        parallel.set_seed(8)
        assert torch.equal(seeded, parallel.reset()["observation"])
        assert not torch.equal(seeded[0], seeded[1])
    finally:
        parallel.close()
    probe = make_env("altitude", num_envs=N, decimation=1)
    linear = torch.nn.Linear(probe.observation_spec["observation"].shape[-1], probe.action_spec.shape[-1])
    torch.nn.init.constant_(linear.weight, 0.05)
    torch.nn.init.zeros_(linear.bias)
    policy = TensorDictModule(linear, in_keys=["observation"], out_keys=["action"])  # deterministic
    batches = []
    for _ in range(2):
        collector = MultiSyncCollector([make, make], policy=policy, frames_per_batch=2 * N * 3,
                                       total_frames=-1, reset_at_each_iter=True)
        try:
            collector.set_seed(8)
            batches.append(next(iter(collector))["next", "observation"])
        finally:
            collector.shutdown()
    assert not torch.equal(batches[0][0], batches[0][1])  # one worker per leading index
    assert torch.equal(batches[0], batches[1])


def test_a_transform_stream_restores_from_its_random_state() -> None:
    """Checkpoints save each random transform's stream; restoring it continues the same draws."""
    from falcon_rl.transforms import SensorTransform

    env = make_env("altitude", "navion", num_envs=2, seed=3, sensors="mild")
    env.rollout(3, break_when_any_done=False)
    sensors = next(t for t in env.transform if isinstance(t, SensorTransform))
    saved = sensors.random_state()
    first = sensors.stream().get_state().clone()
    draws = torch.rand(4, generator=sensors.stream())
    sensors.set_random_state(saved)
    assert torch.equal(sensors.stream().get_state(), first)
    assert torch.equal(torch.rand(4, generator=sensors.stream()), draws)
