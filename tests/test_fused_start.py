"""The tasks' start of episodes (``Task.start_episodes`` with ``FusedStep.start``: the reset rows'
buffers and every env's observation in one Warp launch after the physics reset) against the torch
reference's start (``tests/task_references.py``): the same observations, task buffers and states over
partial resets of random rows in every task, the step's own output buffers left untouched, no state
built for a lean reset, and a torch task's start."""

from __future__ import annotations

import pytest
import torch
from task_references import torch_reference

from falcon_rl import make_env
from falcon_rl.physics._warp import warp_cuda_available

N = 16
#: float32 tolerance, as the fused step's tests.
TOL = {"rtol": 1e-5, "atol": 1e-5}
#: (task, airframe, options) of each start compared: every task, the attitude task's two command sources.
CASES = [
    ("altitude", "volantex_ranger", {}),
    ("altitude", "navion", {"initial_airspeed_spread": 0.1, "turbulence": None}),
    ("altitude", "volantex_ranger", {"warp_cpu_threads": 2}),  # the start launched per CPU slice
    ("climb_descend", "volantex_ranger", {}),
    ("attitude", "volantex_ranger", {}),
    ("attitude", "navion", {"maneuver": "s_turn"}),
    ("path_following", "airship_v7", {}),
    ("trajectory", "navion", {}),
]


def task_env(task: str, airframe: str, fused: bool, device: str = "cpu", **options):
    """A ``task`` env on the warp engine: its Warp step, or (``fused=False``) the torch reference."""
    options = {"num_envs": N, "seed": 11, "wind": (2.0, -1.0, 0.0), "turbulence": "light",
               "decimation": 5, **options}
    env = make_env(task, airframe, backend="warp", device=device, **options)
    return env if fused else torch_reference(env)


def task_tensors(task: object) -> dict[str, torch.Tensor]:
    """Every tensor the task holds, its command stream's included."""
    tensors = {name: value for name, value in vars(task).items() if isinstance(value, torch.Tensor)}
    stream = getattr(task, "random_stream", None)
    if stream is not None:
        tensors |= {f"random_stream.{name}": value for name, value in vars(stream).items()
                    if isinstance(value, torch.Tensor)}
    return tensors


def run_with_partial_resets(env, steps: int, with_state: bool) -> list[torch.Tensor]:
    """Observations of ``steps`` steps of random actions, each followed by a reset of random rows."""
    generator = torch.Generator().manual_seed(4)
    shape = env.action_spec.shape
    observations = [env.reset_tensors(with_state=with_state)[0]]
    for _ in range(steps):
        action = (torch.rand(shape, generator=generator) * 2.0 - 1.0).to(env.device)
        observations.append(env.step_tensors(action, with_state=False).observation)
        mask = (torch.rand(N, generator=generator) < 0.2).to(env.device)
        observations.append(env.reset_tensors(mask, with_state=with_state)[0])
    return observations


def assert_same_start(task: str, airframe: str, device: str = "cpu", **options) -> None:
    envs = {fused: task_env(task, airframe, fused, device, **options) for fused in (False, True)}
    assert envs[True].task.has_warp_step() and not envs[False].task.has_warp_step()
    if "warp_cpu_threads" in options:
        assert len(envs[True].sim.engine.slices) > 1
    runs = {fused: run_with_partial_resets(env, 40, with_state=not fused) for fused, env in envs.items()}
    for k, (expected, actual) in enumerate(zip(runs[False], runs[True], strict=True)):
        torch.testing.assert_close(actual, expected, **TOL, msg=lambda m, k=k: f"output {k}: {m}")
    expected, actual = task_tensors(envs[False].task), task_tensors(envs[True].task)
    assert expected.keys() == actual.keys()
    for name, value in expected.items():
        torch.testing.assert_close(actual[name], value, **TOL, msg=lambda m, name=name: f"{name}: {m}")
    torch.testing.assert_close(envs[True].sim.x, envs[False].sim.x, **TOL)


@pytest.mark.parametrize(("task", "airframe", "options"), CASES)
def test_fused_start_matches_the_torch_start(task, airframe, options):
    assert_same_start(task, airframe, **options)


@pytest.mark.gpu
@pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA")
@pytest.mark.parametrize(("task", "airframe", "options"), CASES[:1])  # the kernels compiled ahead (altitude)
def test_fused_start_matches_the_torch_start_on_cuda(task, airframe, options):
    assert_same_start(task, airframe, "cuda", **options)


def test_a_reset_leaves_the_step_buffers_alone():
    """The Gymnasium same-step autoreset reads the step's buffers after resetting the done rows."""
    env = task_env("altitude", "volantex_ranger", True)
    env.reset_tensors()
    step = env.step_tensors(torch.full((N, 2), 0.3), with_state=False, copy=False)
    kept = [step.observation.clone(), step.reward.clone(), step.reason.clone()]
    fresh, state = env.reset_tensors(torch.arange(N) % 2 == 0, with_state=False)
    assert state is None
    for before, after in zip(kept, (step.observation, step.reward, step.reason), strict=True):
        assert torch.equal(before, after)
    assert not torch.equal(fresh[::2], step.observation[::2])
    torch.testing.assert_close(fresh[1::2], step.observation[1::2], **TOL)


def test_the_state_is_built_when_asked_for_or_started_in_torch():
    fused, plain = (task_env("altitude", "volantex_ranger", f) for f in (True, False))
    assert fused.reset_tensors(with_state=True)[1] is not None
    assert fused.reset_tensors(with_state=False)[1] is None  # the Warp start reads the buffers
    assert plain.reset_tensors(with_state=False)[1] is not None  # a torch start reads it
