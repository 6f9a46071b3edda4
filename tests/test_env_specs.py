"""Every task's TorchRL env passes check_env_specs, on each airframe and (when present) on warp."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs import EnvBase
from torchrl.envs.utils import check_env_specs

import falcon_rl
from falcon_rl import Simulator
from falcon_rl.envs import FixedWingEnv, make_env
from falcon_rl.envs.maneuvers import MANEUVERS
from falcon_rl.envs.tasks import task_names


def warp_available() -> bool:
    try:
        Simulator("navion", num_envs=2, backend="warp")
    except (ImportError, ModuleNotFoundError, NotImplementedError):
        return False
    return True


requires_warp = pytest.mark.skipif(not warp_available(), reason="warp backend not available")


@pytest.mark.parametrize("airframe", ["navion", "volantex_ranger"])
@pytest.mark.parametrize("task", task_names())
def test_check_env_specs(task: str, airframe: str) -> None:
    env = make_env(task, airframe, num_envs=4, seed=3)
    assert isinstance(env, EnvBase) and env.batch_locked
    check_env_specs(env, break_when_any_done="both")


@pytest.mark.parametrize("maneuver", MANEUVERS)
def test_check_env_specs_maneuvers(maneuver: str) -> None:
    env = make_env("attitude", "volantex_ranger", num_envs=2, maneuver=maneuver)
    check_env_specs(env, break_when_any_done="both")


@requires_warp
@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_check_env_specs_warp(task: str) -> None:
    env = make_env(task, "navion", num_envs=4, backend="warp")
    check_env_specs(env, break_when_any_done="both")


def test_make_env_is_exported_and_splits_options() -> None:
    env = falcon_rl.make_env("altitude", "navion", num_envs=2, decimation=2, target_altitudes=(50.0,),
                             episode_seconds=1.0)
    assert isinstance(env, FixedWingEnv)
    assert env.config.decimation == 2 and env.task.config.target_altitudes == (50.0,)
    assert env.max_episode_steps == 50
    td = env.rand_step(env.reset())
    assert torch.allclose(td["next", "state", "time"], torch.full((2,), 0.02))
    assert (td["next", "task", "target_altitude"] == 50.0).all()


def test_make_env_rejects_unknown_options() -> None:
    with pytest.raises(TypeError, match="unexpected keyword argument"):
        make_env("altitude", "navion", wingspan=3.0)
    with pytest.raises(ValueError, match="unknown task"):
        make_env("loop", "navion")


def test_spec_shapes() -> None:
    env = make_env("altitude", "navion", num_envs=3)
    assert env.observation_spec["observation"].shape == (3, 11)
    assert env.action_spec.shape == (3, 2)
    assert set(env.done_spec.keys()) == {"done", "terminated", "truncated"}
    state_keys = set(env.observation_spec["state"].keys())
    assert {"height", "airspeed", "euler", "angular_rate_body", "alpha", "beta", "velocity_ned",
            "position_ned", "thrust", "throttle"} <= state_keys
    env = make_env("attitude", "navion", num_envs=3)
    assert env.observation_spec["observation"].shape == (3, 15)
    assert env.action_spec.shape == (3, 4)
