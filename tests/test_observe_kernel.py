"""A task's observation of a given (measured) state, ``FixedWingEnv.observe`` (the sensor transform's
hook), is its Warp step's observe kernel: the same code as the step's observation, equal to the torch
reference's ``observe`` (``tests/task_references.py``) after the same flight, with no side effect on the
task's buffers."""

from __future__ import annotations

import pytest
import torch
from task_references import torch_reference
from tensordict import TensorDict

from falcon_rl import make_env
from falcon_rl.envs.layout import simulator_layout

TASKS = ["altitude", "attitude", "path_following", "trajectory", "climb_descend"]
TOL = {"rtol": 1e-5, "atol": 1e-5}


def flown(task: str, backend: str = "warp", reference: bool = False):
    """A ``task`` env (or its torch reference) after 12 steps of seeded random actions."""
    env = make_env(task, "volantex_ranger", num_envs=5, seed=1, backend=backend, episode_seconds=3.0)
    if reference:
        torch_reference(env)
    env.reset()
    generator = torch.Generator().manual_seed(3)
    for _ in range(12):
        env.step_tensors(torch.rand(env.action_spec.shape, generator=generator) * 2.0 - 1.0)
    return env


def measured(state, seed: int = 0) -> dict[str, torch.Tensor]:
    """The state's entries with noise on the fields the tasks observe."""
    generator = torch.Generator().manual_seed(seed)
    noisy = {key: value.clone() for key, value in state.items()}
    for key in ("height", "airspeed", "alpha", "beta", "euler", "angular_rate_body", "velocity_ned"):
        noisy[key] = noisy[key] + 0.05 * torch.randn(noisy[key].shape, generator=generator)
    return noisy


@pytest.mark.parametrize("backend", ["warp", "torch"])
@pytest.mark.parametrize("task", TASKS)
def test_the_observe_kernel_equals_the_torch_observe_and_writes_nothing(task: str, backend: str) -> None:
    env, reference = flown(task, backend), flown(task, backend, reference=True)
    stepper = env.task.fused_stepper()
    assert stepper is not None and stepper.observe_kernel is not None
    buffers = {name: value.clone() for name, value in vars(env.task).items()
               if isinstance(value, torch.Tensor)}
    state = measured(env.sim.state)
    kernel = env.observe(state)
    torch.testing.assert_close(kernel, reference.observe(state), **TOL)
    torch.testing.assert_close(kernel, stepper.observe(simulator_layout(state, 5)), rtol=0, atol=0)
    for name, value in vars(env.task).items():
        if name in buffers:
            assert torch.equal(value, buffers[name]), name
    # [N, 1] scalars, as a transform's TensorDict holds them, read the same as the simulator's [N]
    columns = TensorDict({key: value.reshape(5, -1) if value.dim() == 1 else value
                          for key, value in state.items()}, batch_size=[5])
    torch.testing.assert_close(env.observe(columns), kernel, rtol=0, atol=0)
    assert not torch.equal(env.observe(measured(env.sim.state, seed=1)), kernel)


@pytest.mark.parametrize("task", TASKS)
def test_the_true_state_observed_by_the_kernel_is_the_steps_observation(task: str) -> None:
    env = make_env(task, "volantex_ranger", num_envs=5, seed=2, episode_seconds=3.0)
    td = env.reset()
    for _ in range(5):
        td = env.rand_step(td)
        torch.testing.assert_close(env.observe(env.sim.state), td["next", "observation"], **TOL)
        td = td["next"].exclude("reward", "terminated", "truncated", "done")


def test_a_torch_task_observes_with_its_torch_observe() -> None:
    env = flown("altitude", reference=True)
    calls = []
    observe = env.task.observe
    env.task.observe = lambda state: calls.append(1) or observe(state)
    env.observe(env.sim.state)
    assert calls == [1]
