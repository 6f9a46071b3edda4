"""A task written outside the package, as CONTRIBUTING.md's "Add a task" lays it out
(``tests/user_tasks/hold``: task, kernels, spec), has one body, its Warp functions: it runs in the warp
engine's one-launch env step exactly as a built-in task does, and the same functions step it on the
torch engine in float32 and float64; its outputs are the equations of its docstring. Editing its
reward in its kernels module changes the reward on every engine. A torch task still runs, warned once
that it is unfused, and a subclass that would change a Warp task's step in torch is refused."""

from __future__ import annotations

import importlib
import shutil
import sys
import warnings

import pytest
import torch
from user_tasks.hold import SPEC, HoldConfig, HoldTask

from falcon_rl import make_env
from falcon_rl.envs.tasks import Task, register_task, unregister_task

TOL = {"rtol": 1e-5, "atol": 1e-5}
HOLD_DIR = SPEC.task.__module__  # "user_tasks.hold.task"


@pytest.fixture
def user_task():
    spec = register_task(SPEC)
    yield spec
    unregister_task(spec.name)


def rollout(env, steps: int = 60):
    generator = torch.Generator().manual_seed(1)
    actions = torch.rand(steps, *env.action_spec.shape, generator=generator) * 2.0 - 1.0

    def policy(td):
        td["action"] = actions[policy.step].to(env.sim.dtype)
        policy.step += 1
        return td

    policy.step = 0
    return env.rollout(steps, policy, break_when_any_done=False)


def hold_equations(td, config: HoldConfig, trim_airspeed: float, height_term=lambda e_h: e_h * e_h):
    """(reward [T, N, 1], observation [T, N, 2]) of the docstring's equations on the rollout's states;
    ``height_term`` is the height penalty's shape (e_h^2 in the task as shipped)."""
    state = td["next", "state"]
    e_h, airspeed = state["height"] - config.height, state["airspeed"]
    airspeed_error = (airspeed - trim_airspeed).abs() / trim_airspeed
    reward = -config.w_height * height_term(e_h) - config.w_airspeed * airspeed_error
    observation = torch.cat([e_h / 10.0, airspeed / trim_airspeed - 1.0], -1).clamp(-5.0, 5.0)
    return reward, observation


def assert_hold_equations(td, env, rtol: float = 1e-5, **kwargs) -> None:
    reward, observation = hold_equations(td, env.task.config, env.task.trim_airspeed, **kwargs)
    torch.testing.assert_close(td["next", "reward"], reward, rtol=rtol, atol=1e-4)
    torch.testing.assert_close(td["next", "observation"], observation, rtol=rtol, atol=1e-5)
    terms = td["next", "reward_terms"]
    torch.testing.assert_close(terms["height"] + terms["airspeed"], td["next", "reward"], rtol=rtol,
                               atol=1e-5)


def test_a_user_task_runs_in_the_engines_one_launch_step_by_its_equations(user_task) -> None:
    fused = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0)
    staged = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0,
                      fused=False)
    assert isinstance(fused.task, HoldTask) and fused.task.has_warp_step()
    assert fused.env_stepper() is not None and staged.env_stepper() is None
    assert type(fused.env_stepper()).__module__ == "falcon_rl.physics.fused_env_step"
    a, b = rollout(fused), rollout(staged)
    assert int(a["next", "done"].sum()) >= 6  # episodes end and restart within the rollout
    for key in (("next", "observation"), ("next", "reward"), ("next", "task", "height_error")):
        torch.testing.assert_close(a[key], b[key], **TOL)
    for key in (("next", "done"), ("next", "termination_reason")):
        assert torch.equal(a[key], b[key])
    assert_hold_equations(a, fused)
    # the config reaches the kernel: a heavier airspeed weight changes the reward by the equations
    heavy = make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0,
                     w_airspeed=50.0)
    c = rollout(heavy)
    assert not torch.allclose(c["next", "reward"], a["next", "reward"])
    assert_hold_equations(c, heavy)


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_the_torch_engine_runs_the_same_functions_in_either_dtype(user_task, dtype) -> None:
    env = make_env("user_hold", "navion", num_envs=6, backend="torch", seed=2, episode_seconds=1.0,
                   dtype=dtype)
    assert env.env_stepper() is None and env.task.fused_stepper() is not None  # torch physics, Warp task
    td = rollout(env)
    assert td["next", "reward"].dtype == td["next", "observation"].dtype == dtype
    assert_hold_equations(td, env, rtol=1e-5 if dtype == torch.float32 else 1e-4)
    # the observation of a given (measured) state is the same function, with no side effect
    state = td["next", "state"][:, -1]
    torch.testing.assert_close(env.observe(state), td["next", "observation"][:, -1], **TOL)


@pytest.fixture
def edited_hold(tmp_path):
    """A copy of the hold task whose reward was edited in its kernels module: the height penalty
    -w e_h^2 becomes -w |e_h| (the task renamed "edited_hold"); registered, then removed."""
    package = tmp_path / "edited_hold"
    shutil.copytree(importlib.import_module("user_tasks.hold").__path__[0], package,
                    ignore=shutil.ignore_patterns("__pycache__"))
    kernels = package / "kernels.py"
    source = kernels.read_text()
    assert source.count("-c.w_height * e_h * e_h") == 1
    kernels.write_text(source.replace("-c.w_height * e_h * e_h", "-c.w_height * wp.abs(e_h)"))
    for name, old, new in (("task.py", 'name = "user_hold"', 'name = "edited_hold"'),
                           ("spec.py", 'name="user_hold"', 'name="edited_hold"'),
                           ("spec.py", "UserHold-v0", "EditedHold-v0")):
        path = package / name
        text = path.read_text()
        assert text.count(old) == 1, (name, old)
        path.write_text(text.replace(old, new))
    sys.path.insert(0, str(tmp_path))
    try:
        spec = register_task(importlib.import_module("edited_hold").SPEC)
        yield spec
        unregister_task(spec.name)
    finally:
        sys.path.remove(str(tmp_path))
        for module in [m for m in sys.modules if m == "edited_hold" or m.startswith("edited_hold.")]:
            del sys.modules[module]


@pytest.mark.parametrize(("backend", "dtype"), [("warp", torch.float32), ("torch", torch.float32),
                                                ("torch", torch.float64)])
def test_an_edit_of_the_reward_in_the_kernels_reaches_every_engine(edited_hold, backend, dtype) -> None:
    env = make_env("edited_hold", "navion", num_envs=6, backend=backend, seed=2, episode_seconds=1.0,
                   dtype=dtype)
    td = rollout(env)
    rtol = 1e-5 if dtype == torch.float32 else 1e-4
    assert_hold_equations(td, env, rtol=rtol, height_term=torch.abs)
    squared, _ = hold_equations(td, env.task.config, env.task.trim_airspeed)
    assert (td["next", "reward"] - squared).abs().max() > 0.1, "the edited reward is not the shipped one"


class TorchHold(HoldTask):
    """The hold task written in torch instead (``fused_stepper = Task.fused_stepper``: no Warp step)."""

    fused_stepper = Task.fused_stepper

    def __init__(self, config, sim, generator, control_dt, ground_effect=True):
        super().__init__(config, sim, generator, control_dt, ground_effect)

    def observe(self, state):
        obs = torch.stack([(state["height"] - self.config.height) / 10.0,
                           state["airspeed"] / self.trim_airspeed - 1.0], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def update(self, state):
        self.height_error.copy_(state["height"] - self.config.height)

    def reward_terms_of(self, state, action):
        cfg = self.config
        return (-cfg.w_height * self.height_error**2,
                -cfg.w_airspeed * (state["airspeed"] - self.trim_airspeed).abs() / self.trim_airspeed)

    def after_reset(self, state, mask):
        super().after_reset(state, mask)
        self.update(state)


def test_a_torch_task_steps_unfused_and_is_warned_once(user_task) -> None:
    from falcon_rl.envs.tasks import base

    base._WARNED_UNFUSED.discard(TorchHold)
    spec = register_task(SPEC.__class__(**{**vars(SPEC), "name": "torch_hold", "task": TorchHold,
                                           "gym_id": "falcon_rl_test/TorchHold-v0"}))
    try:
        with pytest.warns(RuntimeWarning, match="TorchHold steps in torch, unfused"):
            env = make_env("torch_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0)
            assert env.env_stepper() is None and not env.task.has_warp_step()
            td = rollout(env)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # once per class: a second env says nothing
            again = make_env("torch_hold", "navion", num_envs=6, backend="warp", seed=2, episode_seconds=1.0)
            rollout(again, 3)
        assert_hold_equations(td, env)
        warp = rollout(make_env("user_hold", "navion", num_envs=6, backend="warp", seed=2,
                                episode_seconds=1.0))
        for key in (("next", "observation"), ("next", "reward")):
            torch.testing.assert_close(td[key], warp[key], **TOL)
    finally:
        unregister_task(spec.name)


def test_a_subclass_changing_a_warp_task_in_torch_is_refused(user_task) -> None:
    class SharperHold(HoldTask):
        def reward(self, state, action):
            return super().reward(state, action) - 1.0

    env = make_env("user_hold", "navion", num_envs=2, backend="warp", seed=0)
    with pytest.raises(TypeError, match="SharperHold defines reward, but its step is its Warp functions"):
        SharperHold(env.task.config, env.sim, env.generator, env.control_dt)
