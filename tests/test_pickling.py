"""Envs, engines and transforms pickle: a copy holds the same state and steps exactly as the original,
and an env instance runs in spawned worker processes (ParallelEnv, multi-process collectors)."""

from __future__ import annotations

import copy
import multiprocessing
import pickle
import time
from queue import Empty

import pytest
import torch
from tensordict import TensorDictBase
from torchrl.collectors import MultiSyncCollector
from torchrl.envs import EnvBase, ParallelEnv
from torchrl.envs.utils import step_mdp

from falcon_rl import make_env
from falcon_rl.physics import Simulator
from falcon_rl.physics.engine import PicklableGenerator, make_generator
from falcon_rl.physics.torch_backend import integrate
from falcon_rl.transforms import (
    ActionDelay,
    DomainRandomization,
    ObservationDelay,
    SensorTransform,
    sensor_preset,
)

#: Every robustness transform on, ranged delays, turbulence (10 ms control).
ROBUST = {"sensors": "mild", "obs_delay_ms": (10.0, 50.0), "action_delay_ms": (10.0, 50.0),
          "randomize": True, "turbulence": "mild", "decimation": 1}
N = 4
BUFFERS = ("x", "command", "time", "wind_ned", "gust_velocity_body", "gust_rate_body")


def _actions(steps: int, shape: torch.Size) -> list[torch.Tensor]:
    """Fixed pseudo-random actions of ``shape`` in [-0.3, 0.3]."""
    generator = torch.Generator().manual_seed(99)
    return [0.6 * torch.rand(shape, generator=generator) - 0.3 for _ in range(steps)]


def _roll(env: EnvBase, td: TensorDictBase, steps: int) -> tuple[list[TensorDictBase], TensorDictBase]:
    """([step data ...], the data to continue from) of ``steps`` steps under :func:`_actions`."""
    out = []
    for action in _actions(steps, env.action_spec.shape):
        full = env.step(td.set("action", action))
        out.append(full["next"].clone())
        td = step_mdp(full)
    return out, td


def _assert_same_sim(a: Simulator, b: Simulator) -> None:
    for name in BUFFERS:
        assert torch.equal(getattr(a, name), getattr(b, name)), name
    assert torch.equal(a.generator.get_state(), b.generator.get_state())
    assert torch.equal(a.turbulence.filter, b.turbulence.filter)
    assert torch.equal(a.turbulence.rng, b.turbulence.rng)


def test_generator_pickles_as_state_bytes() -> None:
    generator = make_generator("cpu", 5)
    torch.rand(3, generator=generator)
    _, (device, state) = generator.__reduce__()
    assert device == "cpu" and isinstance(state, bytes)  # no tensor for a worker's fd to lose
    clone = pickle.loads(pickle.dumps(generator))
    assert isinstance(clone, PicklableGenerator)
    assert torch.equal(torch.rand(5, generator=clone), torch.rand(5, generator=generator))


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_simulator_round_trips_and_steps_on_its_own_buffers(backend: str) -> None:
    sim = Simulator("navion", num_envs=3, backend=backend, turbulence="moderate", seed=4)
    command = torch.tensor([[0.0, 0.1, 0.0, 0.6], [-0.1, 0.0, 0.1, 0.5], [0.05, -0.1, 0.0, 0.7]])
    sim.step(command, substeps=3)
    loaded, duplicate = pickle.loads(pickle.dumps(sim)), copy.deepcopy(sim)
    _assert_same_sim(sim, loaded)
    assert type(loaded.engine) is type(sim.engine)
    x = sim.x.clone()
    loaded.step(command, substeps=5)
    assert torch.equal(sim.x, x)  # the copy's kernels write the copy's buffers
    for other in (sim, duplicate):
        other.step(command, substeps=5)
        _assert_same_sim(other, loaded)
        assert torch.equal(other.state["thrust"], loaded.state["thrust"])


def test_a_compiled_torch_engine_pickles_and_compiles_again() -> None:
    sim = Simulator("navion", num_envs=2, backend="torch", compile=True)
    loaded = pickle.loads(pickle.dumps(sim))  # nothing compiled yet: compiling is lazy
    assert loaded.engine._integrate is not integrate and loaded.engine.setup.options["compile"]
    assert torch.equal(loaded.x, sim.x)


def test_unused_transforms_pickle() -> None:
    transforms = [ActionDelay((10.0, 50.0)), ObservationDelay(20.0, seed=3),
                  SensorTransform(sensor_preset("severe")), DomainRandomization()]
    for transform in transforms:
        clone = pickle.loads(pickle.dumps(transform))
        assert type(clone) is type(transform) and clone.seed == transform.seed


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_env_with_every_transform_round_trips(backend: str) -> None:
    """After load the copy holds the same state (simulator, streams, transform buffers) and the next
    steps are identical to the original's."""
    env = make_env("altitude", num_envs=N, backend=backend, seed=7, **ROBUST)
    _, td = _roll(env, env.reset(), steps=5)
    loaded = pickle.loads(pickle.dumps(env))
    duplicate = copy.deepcopy(env)
    _assert_same_sim(env.base_env.sim, loaded.base_env.sim)
    assert torch.equal(env.base_env.generator.get_state(), loaded.base_env.generator.get_state())
    for ours, theirs in zip(env.transform, loaded.transform, strict=True):
        assert type(ours) is type(theirs) and ours.root_seed == theirs.root_seed
        assert torch.equal(ours.stream().get_state(), theirs.stream().get_state())
        if isinstance(ours, ActionDelay | ObservationDelay):
            assert torch.equal(ours.delays, theirs.delays)
            for key, line in ours._lines.items():
                assert torch.equal(line.buffer, theirs._lines[key].buffer)
                assert line.head == theirs._lines[key].head
    for name, value in env.transform[0].sampled().items():
        assert torch.equal(value, loaded.transform[0].sampled()[name]), name
    expected, _ = _roll(env, td.clone(), steps=10)
    for other in (loaded, duplicate):
        got, _ = _roll(other, td.clone(), steps=10)
        for a, b in zip(expected, got, strict=True):
            assert (a == b).all(), "a pickled copy stepped differently"


def _step_in_worker(env: EnvBase, queue: multiprocessing.Queue) -> None:
    steps, _ = _roll(env, env.reset(), steps=3)
    queue.put(torch.stack([step["observation"] for step in steps]).numpy())


def test_env_instance_runs_in_a_spawned_process() -> None:
    """A warp env with every transform, passed as it is to a spawned process (what ParallelEnv and the
    collectors do with an instance), steps there exactly as its twin here."""
    env = make_env("altitude", num_envs=N, backend="warp", seed=2, **ROBUST)
    twin = copy.deepcopy(env)
    context = multiprocessing.get_context("spawn")
    queue = context.Queue()
    worker = context.Process(target=_step_in_worker, args=(env, queue))
    worker.start()
    deadline = time.monotonic() + 240.0
    try:
        while True:
            try:
                remote = torch.from_numpy(queue.get(timeout=1.0))
                break
            except Empty:
                if not worker.is_alive() or time.monotonic() > deadline:
                    pytest.fail(f"the worker sent nothing (exit code {worker.exitcode})")
    finally:
        worker.join(timeout=60)
    steps, _ = _roll(twin, twin.reset(), steps=3)
    assert worker.exitcode == 0
    assert torch.equal(remote, torch.stack([step["observation"] for step in steps]))


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:A lambda function was passed to ParallelEnv")
def test_env_instance_runs_in_parallel_env_and_multi_sync_collector() -> None:
    """Workers receive copies of one instance (identical streams until seeded); set_seed gives each
    worker its own."""
    env = make_env("altitude", num_envs=N, backend="warp", seed=3, **ROBUST)
    parallel = ParallelEnv(2, lambda env=env: env)  # TorchRL's idiom for an instance
    try:
        copies = parallel.reset()["observation"]
        assert torch.equal(copies[0], copies[1])
        assert torch.equal(copies[0], copy.deepcopy(env).reset()["observation"])
        parallel.set_seed(5)
        seeded = parallel.reset()["observation"]
        assert not torch.equal(seeded[0], seeded[1])
    finally:
        parallel.close()
    collector = MultiSyncCollector([env, env], policy=None, frames_per_batch=2 * N * 3,
                                   total_frames=2 * N * 6)
    try:
        batches = [batch for batch in collector]
    finally:
        collector.shutdown()
    assert len(batches) == 2
    for batch in batches:
        assert batch["next", "observation"].shape[:2] == (2, N)
        assert torch.isfinite(batch["next", "observation"]).all()
