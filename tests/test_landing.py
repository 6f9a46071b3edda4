"""The landing task: specs and Gymnasium, the glide path and the touchdown (its state, a wing-tip strike),
torch-warp parity, the protocol's scoring and the TECS + flare baseline landing within the limits."""

from __future__ import annotations

import math

import gymnasium
import pytest
import torch
from engine_parity import trim_flights
from gymnasium.utils.env_checker import check_env
from tensordict import TensorDict
from torchrl.envs.utils import check_env_specs

import falcon_rl  # noqa: F401 (registers the Gymnasium ids)
from falcon_rl import make_env
from falcon_rl.constants import DEG
from falcon_rl.envs.tasks import TERMINATION_CODE, task_spec
from falcon_rl.envs.tasks.landing.task import NOT_YET, approach_speed, glide_slope
from falcon_rl.evaluation.landing import landing_metrics
from falcon_rl.physics.rotations import euler_to_quaternion, ned_to_body

needs_warp = pytest.mark.skipif(pytest.importorskip("warp") is None, reason="warp-lang is not installed")
BACKENDS = ["torch", pytest.param("warp", marks=needs_warp)]


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_env_passes_torchrl_spec_check(backend):
    check_env_specs(make_env("landing", "volantex_ranger", num_envs=3, backend=backend, seed=0), seed=0)


def test_the_gym_id_alone_makes_a_checked_env():
    env = gymnasium.make("falcon_rl/Landing-v0")
    check_env(env.unwrapped)
    observation, _ = env.reset(seed=1)
    assert observation.shape == (19,)


def test_each_episode_starts_on_the_glide_path_short_of_the_runway():
    env = make_env("landing", "airship_v7", num_envs=16, backend="torch", seed=2)
    td = env.reset()
    task, airframe = env.task, env.sim.airframe
    assert task.trim_airspeed == pytest.approx(approach_speed(airframe))
    slope = task.config.glide_slope
    assert slope == pytest.approx(glide_slope(airframe, task.trim_airspeed)) and slope <= 3.0 * DEG
    north = td["state", "position_ned"][:, 0]
    assert bool(((north >= -250.0) & (north <= -150.0)).all())
    gear = 0.08 * airframe.geometry.span
    expected = gear + math.tan(slope) * (-north)
    assert torch.allclose(td["task", "glide_path_height"].squeeze(-1), expected, atol=1e-4)
    assert torch.allclose(td["state", "height"].squeeze(-1), expected, atol=1e-4)
    assert bool((td["task", "touchdown"] == 0).all())
    # ground effect's band (the wheels below one span) entered at the start where the glide is that low
    inside = td["task", "wheel_height"].squeeze(-1) < airframe.geometry.span
    entry = torch.where(inside, north, torch.full_like(north, NOT_YET))
    assert torch.equal(td["task", "ground_effect_north"].squeeze(-1), entry) and bool(inside.any())


def _fly_into_the_ground(backend: str, bank: float) -> TensorDict:
    """Two envs placed 1 cm above the wheels' contact, sinking at 0.5 m/s, banked ``bank`` rad: the step
    that follows touches down (or strikes a tip)."""
    env = make_env("landing", "volantex_ranger", num_envs=2, backend=backend, seed=0, decimation=5)
    td = env.reset()
    sim = env.sim
    x = sim.x.clone()
    layout = sim.layout
    gear = env.task.gear
    x[:, layout.slice_of("position_ned")] = torch.tensor([5.0, 1.0, -(gear + 0.01)], dtype=x.dtype)
    quaternion = euler_to_quaternion(torch.tensor([[bank, 4.0 * DEG, 0.0]], dtype=x.dtype))
    x[:, layout.slice_of("quaternion")] = quaternion
    # 0.5 m/s down in NED: the body velocity of that NED velocity at this attitude
    ned = torch.tensor([[env.task.trim_airspeed, 0.0, 0.5]], dtype=x.dtype)
    x[:, layout.slice_of("velocity_body")] = ned_to_body(quaternion, ned)
    sim.x.copy_(x)
    sim.sample_surface()
    td["action"] = env.trim_action().expand(2, -1).clone()
    return env.step(td)["next"]


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_wheels_on_the_runway_end_the_episode_with_its_touchdown_state(backend):
    nxt = _fly_into_the_ground(backend, 0.0)
    assert bool((nxt["termination_reason"] == TERMINATION_CODE["touchdown"]).all())
    assert bool(nxt["terminated"].all()) and bool((nxt["task", "touchdown"] == 1).all())
    sink = nxt["task", "touchdown_sink_rate"].squeeze(-1)
    assert bool(((sink > 0.3) & (sink < 1.5)).all())
    assert torch.allclose(nxt["task", "touchdown_lateral"].squeeze(-1), torch.ones(2), atol=0.05)
    assert bool((nxt["task", "touchdown_along"].squeeze(-1) > 5.0).all())
    assert bool((nxt["task", "ground_effect_north"].squeeze(-1) < NOT_YET).all())
    assert bool((nxt["reward"] > 0).all())  # the touchdown term, attitude within its limits


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_wing_tip_first_is_a_tip_strike(backend):
    nxt = _fly_into_the_ground(backend, 30.0 * DEG)
    assert bool((nxt["termination_reason"] == TERMINATION_CODE["tip_strike"]).all())
    assert bool((nxt["task", "touchdown"] == 0).all())


@needs_warp
def test_the_task_step_agrees_on_both_engines():
    outputs = trim_flights("landing", "airship_v7")
    assert torch.allclose(outputs["torch"]["observation"], outputs["warp"]["observation"], atol=5e-3)
    key = ("task", "glide_path_error")
    assert torch.allclose(outputs["torch"][key], outputs["warp"][key], atol=5e-3)


def test_the_metrics_score_the_touchdown_against_the_limits():
    n, t = 3, 4
    reason = torch.zeros(n, t, 1, dtype=torch.long)
    reason[:, 2] = TERMINATION_CODE["touchdown"]
    reason[2, 2] = TERMINATION_CODE["tip_strike"]
    done = reason != 0
    task = {"touchdown_sink_rate": torch.tensor([0.3, 0.9, 0.2]).reshape(n, 1, 1).expand(n, t, 1),
            "touchdown_pitch": torch.full((n, t, 1), 4.0 * DEG), "touchdown_bank": torch.zeros(n, t, 1),
            "touchdown_along": torch.full((n, t, 1), 12.0), "touchdown_lateral": torch.full((n, t, 1), -1.0),
            "ground_effect_north": torch.full((n, t, 1), -40.0)}
    nxt = TensorDict({"done": done, "terminated": done.clone(), "termination_reason": reason, "task": task},
                     batch_size=[n, t])
    m = landing_metrics(TensorDict({"next": nxt}, batch_size=[n, t]), 0.0, 12.0 * DEG, 5.0 * DEG)
    assert m["touchdown"].tolist() == [True, True, False]
    assert m["landed_within_limits"].tolist() == [True, False, False]  # 0.9 m/s is above 0.6 m/s
    assert m["float_m"][0].item() == pytest.approx(52.0) and m["lateral_m"][0].item() == pytest.approx(1.0)
    assert math.isnan(m["sink_rate_mps"][2].item())


def test_a_bad_glide_slope_or_sea_state_is_refused_in_one_line():
    with pytest.raises(ValueError, match="glide_slope must be below pi/2"):
        make_env("landing", "volantex_ranger", num_envs=1, backend="torch", seed=0, glide_slope=2.0)
    with pytest.raises(ValueError, match="sea_states must hold WMO sea-state codes 0-6"):
        make_env("landing", "volantex_ranger", num_envs=1, backend="torch", seed=0, sea_states=(9.0,))


@needs_warp
@pytest.mark.parametrize("airframe", ["airship_v7", pytest.param("volantex_ranger", marks=pytest.mark.slow)])
def test_tecs_and_the_flare_land_within_the_limits(airframe):
    from falcon_rl.evaluation.controllers import make_controller
    from falcon_rl.evaluation.landing import landing_protocol

    result = landing_protocol(airframe, "tecs-flare", lambda env: make_controller("tecs-flare", env),
                              episodes=4, seed=0)
    assert result.summary["landed_within_limits"] == 1.0
    assert result.summary["sink_rate_mps"] < 0.6
    assert "tecs-flare" in task_spec("landing").controllers


@needs_warp
def test_a_ditching_touches_down_on_the_water():
    """With ``sea_states`` the surface is the sea: the wheels (a hull's keel) meet the water under them."""
    from falcon_rl.evaluation.controllers import make_controller
    from falcon_rl.evaluation.landing import landing_protocol

    env = make_env("landing", "airship_v7", num_envs=2, backend="warp", seed=0, sea_states=(2.0,))
    env.reset()
    assert bool(env.sim.state["over_water"].all()) and float(env.sim.sea.amplitude.abs().max()) > 0.0
    result = landing_protocol("airship_v7", "tecs-flare", lambda env: make_controller("tecs-flare", env),
                              episodes=2, seed=0, sea_states=(1.0,), decimation=5)  # 20 Hz: a quicker flight
    assert result.summary["touchdown"] == 1.0 and result.settings["sea_states"] == (1.0,)
    assert result.summary["sink_rate_mps"] < 0.6
