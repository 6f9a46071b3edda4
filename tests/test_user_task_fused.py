"""A task written outside the package, as CONTRIBUTING.md's "Add a task" lays it out
(``tests/user_tasks/hold``: task, kernels, spec), runs fused on the warp engine exactly as a built-in task
does (the engine's one-launch env step around its kernel), matches its own torch step, and a subclass
that overrides a method its kernel twins steps in torch with one warning."""

from __future__ import annotations

import warnings

import pytest
import torch
from user_tasks.hold import SPEC, HoldTask

from falcon_rl import make_env
from falcon_rl.envs.tasks import AltitudeTask, register_task, task_spec, unregister_task
from falcon_rl.envs.tasks.registry import TaskSpec

TOL = {"rtol": 1e-5, "atol": 1e-5}


@pytest.fixture
def user_task():
    spec = register_task(SPEC)
    yield spec
    unregister_task(spec.name)


def rollout(env, steps: int = 60):
    generator = torch.Generator().manual_seed(1)
    actions = torch.rand(steps, *env.action_spec.shape, generator=generator) * 2.0 - 1.0

    def policy(td):
        td["action"] = actions[policy.step]
        policy.step += 1
        return td

    policy.step = 0
    return env.rollout(steps, policy, break_when_any_done=False)


def test_a_user_task_runs_in_the_engines_one_launch_step_and_matches_its_torch_step(user_task) -> None:
    fused = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0)
    plain = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0,
                     fused=False)
    assert isinstance(fused.task, HoldTask)
    assert fused.env_stepper() is not None and plain.env_stepper() is None
    assert type(fused.env_stepper()).__module__ == "falcon_rl.physics.fused_env_step"
    a, b = rollout(fused), rollout(plain)
    assert int(a["next", "done"].sum()) >= 6  # episodes end and restart within the rollout
    for key in (("next", "observation"), ("next", "reward"), ("next", "task", "height_error")):
        torch.testing.assert_close(a[key], b[key], **TOL)
    for key in (("next", "done"), ("next", "termination_reason")):
        assert torch.equal(a[key], b[key])
    # the config reaches the kernel: a heavier airspeed weight changes the fused reward as the torch one
    heavy = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0,
                     w_airspeed=50.0)
    c = rollout(heavy)
    assert not torch.allclose(c["next", "reward"], a["next", "reward"])
    heavy_plain = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0,
                           w_airspeed=50.0, fused=False)
    torch.testing.assert_close(c["next", "reward"], rollout(heavy_plain)["next", "reward"], **TOL)


def test_the_torch_engine_runs_the_same_kernel_and_float64_the_torch_step(user_task) -> None:
    env = make_env("user_hold", "navion", num_envs=6, backend="torch", seed=2, episode_seconds=1.0)
    plain = make_env("user_hold", "navion", num_envs=6, backend="torch", seed=2, episode_seconds=1.0,
                     fused=False)
    assert env.env_stepper() is None and env.task.fused_stepper() is not None  # torch physics, Warp task
    torch.testing.assert_close(rollout(env)["next", "reward"], rollout(plain)["next", "reward"], **TOL)
    reference = make_env("user_hold", "navion", num_envs=2, backend="torch", seed=0, dtype=torch.float64)
    assert reference.task.fused_stepper() is None
    assert rollout(reference, 5)["next", "reward"].isfinite().all()


class SharperAltitude(AltitudeTask):
    """An altitude task with a reward of its own: the altitude kernel no longer twins it."""

    def reward(self, state, action):
        return super().reward(state, action) - 1.0


def test_a_subclass_that_overrides_what_the_kernel_twins_steps_in_torch_and_warns_once() -> None:
    altitude = task_spec("altitude")
    spec = register_task(TaskSpec(name="sharper_altitude", task=SharperAltitude, config=altitude.config,
                                  gym_id="falcon_rl_test/SharperAltitude-v0", title="Sharper altitude",
                                  protocol=altitude.protocol, metrics=(), defaults=altitude.defaults))
    try:
        with pytest.warns(RuntimeWarning, match="SharperAltitude overrides reward of AltitudeTask"):
            env = make_env("sharper_altitude", "navion", num_envs=2, backend="warp", seed=0)
            assert env.env_stepper() is None
            td = rollout(env, 3)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # once per class: a second env says nothing
            again = make_env("sharper_altitude", "navion", num_envs=2, backend="warp", seed=0)
            assert again.env_stepper() is None
            rollout(again, 3)
        base = rollout(make_env("altitude", "navion", num_envs=2, backend="warp", seed=0), 3)
        torch.testing.assert_close(td["next", "reward"], base["next", "reward"] - 1.0, **TOL)
    finally:
        unregister_task(spec.name)
