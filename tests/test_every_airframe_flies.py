"""Every shipped airframe flies every registered task on both fast backends: the env passes TorchRL's
spec check and flies 10 s under the task's baseline (the LQR where it applies, trim otherwise)
without an error or a non-finite number; under the LQR no episode ends early."""

from __future__ import annotations

import pytest
import torch
from tensordict.nn import TensorDictModuleBase
from torchrl.envs.utils import check_env_specs

from falcon_rl import list_airframes, load_airframe, make_env
from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.envs.tasks import task_names, task_spec

#: 20 Hz control (the shipped recipes' rate) keeps 10 s at 200 env steps.
DECIMATION = 5
SECONDS = 10.0
_CONTROLLERS: dict[tuple[str, object], TensorDictModuleBase] = {}


def baseline(task: str) -> str:
    """The task's baseline controller: the LQR where it applies, trim otherwise."""
    return "lqr" if "lqr" in task_spec(task).controllers else "trim"


def controller(env, airframe: str, task: str) -> TensorDictModuleBase:
    """The baseline of (airframe, task), designed once and shared by both backends and by the tasks
    that name the same factory (an LQR design trims a grid of points: seconds; its integrators
    restart at each episode's t = 0)."""
    key = (airframe, task_spec(task).controllers[baseline(task)])
    if key not in _CONTROLLERS:
        _CONTROLLERS[key] = task_spec(task).controller(baseline(task))(env)
    return _CONTROLLERS[key]


def _cases() -> list:
    """(airframe, task, backend) of every shipped airframe, task and fast backend; an imported airframe's
    torch cases are slow (its tabulated aero in eager torch: ~10 s a case) and its warp cases run by
    default (the backends' parity on the tables is tests/test_tabulated_aero.py's)."""
    cases = []
    for airframe in list_airframes():
        imported = load_airframe(airframe).provenance.get("imported_from") is not None
        for task in task_names():
            for backend in ("torch", "warp"):
                slow = backend == "torch" and (imported or slow_at_sea(airframe, task))
                marks = [pytest.mark.slow] if slow else []
                cases.append(pytest.param(airframe, task, backend, marks=marks,
                                          id=f"{airframe}-{task}-{backend}"))
    return cases


def slow_at_sea(airframe: str, task: str) -> bool:
    """Sea skimming in eager torch (a sea sample per sub-step, ~20 s a case with the LQR's ground-effect
    design): the default airframe's runs by default, the others' are slow (tests/test_sea_skimming.py
    has the backends' parity and the LQR over a sea on both)."""
    return task == "sea_skimming" and airframe != DEFAULT_AIRFRAME


@pytest.mark.parametrize(("airframe", "task", "backend"), _cases())
def test_airframe_flies_task(airframe: str, task: str, backend: str):
    env = make_env(task, airframe, num_envs=2, backend=backend, seed=0, decimation=DECIMATION)
    check_env_specs(env, seed=0)
    policy = controller(env, airframe, task)
    steps = round(SECONDS / env.control_dt)
    with torch.no_grad():
        rollout = env.rollout(steps, policy, break_when_any_done=False)
    assert rollout.shape == (2, steps)
    for key in ("observation", "reward"):
        assert torch.isfinite(rollout["next", key]).all(), f"non-finite {key}"
    assert torch.isfinite(rollout["next", "state", "position_ned"]).all()
    if baseline(task) == "lqr":
        terminated = rollout["next", "terminated"].any(dim=1).squeeze(-1)
        assert not terminated.any(), f"the LQR lost envs {terminated.nonzero().flatten().tolist()}"


def test_two_motor_airframes_are_in_the_matrix():
    """The paper's airframe (two motors) is among those every task is flown with."""
    from falcon_rl import load_airframe

    assert load_airframe("airship_v7").num_motors == 2
    assert "airship_v7" in list_airframes()
