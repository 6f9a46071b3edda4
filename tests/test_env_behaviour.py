"""Behaviour of FixedWingEnv: finite rollouts, masked partial reset, seeding, reference, terminations."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDict

from falcon_rl.envs import make_env
from falcon_rl.envs.layout import flat_scalars
from falcon_rl.envs.tasks import task_names


def assert_finite(td: TensorDict) -> None:
    for key, value in td.items(include_nested=True, leaves_only=True):
        if value.is_floating_point():
            assert torch.isfinite(value).all(), f"non-finite values in {key}"


@pytest.mark.parametrize("task", task_names())
def test_random_actions_stay_finite(task: str) -> None:
    torch.manual_seed(0)
    num_envs, steps = (256, 200) if task == "altitude" else (64, 100)
    env = make_env(task, "volantex_ranger", num_envs=num_envs, seed=1)
    assert_finite(env.rollout(steps, break_when_any_done=False))


@pytest.mark.slow
@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_random_actions_stay_finite_large(task: str) -> None:
    torch.manual_seed(0)
    env = make_env(task, "navion", num_envs=1024, seed=1)
    td = env.reset()
    for _ in range(1000):
        td = env.rand_step(td)
        assert_finite(td["next"])
        _, td = env.step_and_maybe_reset(td)


@pytest.mark.parametrize("task", ["altitude", "attitude", "trajectory"])
def test_partial_reset_touches_only_masked_rows(task: str) -> None:
    torch.manual_seed(0)
    env = make_env(task, "navion", num_envs=6, seed=2)
    td = env.rollout(20, break_when_any_done=False)[:, -1]["next"]
    x_before = env.sim.x.clone()
    mask = torch.tensor([True, False, True, False, False, True])
    out = env._reset(TensorDict({"_reset": mask[:, None]}, batch_size=[6]))  # the env's own output
    keep = ~mask
    assert torch.equal(env.sim.x[keep], x_before[keep])
    assert torch.equal(out["observation"][keep], td["observation"][keep])
    assert not torch.equal(env.sim.x[mask], x_before[mask])
    assert (env.sim.state["time"][mask] == 0).all() and (env.step_count[mask] == 0).all()
    assert (env.step_count[keep] == 20).all()


def test_same_seed_same_rollout() -> None:
    def rollout(seed: int) -> TensorDict:
        env = make_env("attitude", "volantex_ranger", num_envs=8, seed=seed)
        torch.manual_seed(123)
        return env.rollout(50, break_when_any_done=False)

    a, b, c = rollout(5), rollout(5), rollout(6)
    assert (a == b).all()
    assert not torch.equal(a["observation"], c["observation"])


def test_set_seed_replays_initial_conditions() -> None:
    env = make_env("altitude", "navion", num_envs=16)
    env.set_seed(11)
    first = env.reset()["task", "initial_altitude"].clone()
    env.set_seed(11)
    assert torch.equal(env.reset()["task", "initial_altitude"], first)


def test_initial_offsets_and_reference_ramp() -> None:
    env = make_env("altitude", "navion", num_envs=16, seed=4, episode_seconds=10.0, decimation=5)
    rate = env.airframe.envelope.climb_rate_limit
    hold_trim = env.task.trim.command[[0, 3]].expand(16, 2)
    td = flat_scalars(env.rollout(120, policy=lambda tensordict: tensordict.set("action", hold_trim),
                                  break_when_any_done=False))
    target = td["next", "task", "target_altitude"][:, 0]
    start = td["next", "task", "initial_altitude"][:, 0]
    offset = (start - target).abs()
    assert ((offset >= 12.0) & (offset <= 18.0)).all()
    assert set(target.tolist()) <= {20.0, 40.0, 60.0, 80.0, 100.0}
    t = td["next", "state", "time"]
    expected = target[:, None] - torch.sign(target - start)[:, None] * (
        (offset[:, None] - rate * t).clamp_min(0.0))
    torch.testing.assert_close(td["next", "task", "reference_altitude"], expected, atol=1e-3, rtol=0)
    ramping = rate * t < offset[:, None] - 1e-3
    climb = td["next", "task", "reference_climb_rate"]
    assert torch.allclose(climb[ramping].abs(), torch.tensor(rate))
    assert (climb[rate * t > offset[:, None] + 1e-3] == 0).all()
    obs = td["next", "observation"]
    torch.testing.assert_close(obs[..., 10], (climb / 5.0).clamp(-3, 3))
    assert obs.abs().max() <= 3.0


@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_initial_airspeed_spread_draws_off_trim_starts(task: str) -> None:
    """Spread s: initial airspeeds fill trim x [1 - s, 1 + s], the same per seed; without it every
    episode starts at trim and the seed's draws (targets, offsets) are those of an env without the field."""
    def reset(**options) -> TensorDict:
        return make_env(task, "airship_v7", num_envs=256, seed=9, **options).reset()

    spread, plain = reset(initial_airspeed_spread=0.2), reset()
    trim = make_env(task, "airship_v7", num_envs=1, seed=0).task.trim_airspeed
    speeds = spread["state", "airspeed"][:, 0] / trim
    assert speeds.min() >= 0.8 - 1e-5 and speeds.max() <= 1.2 + 1e-5
    assert speeds.min() < 0.85 and speeds.max() > 1.15
    torch.testing.assert_close(plain["state", "airspeed"][:, 0], torch.full((256,), trim))
    assert (reset(initial_airspeed_spread=0.2) == spread).all()
    assert (reset(initial_airspeed_spread=0.0) == plain).all()
    with pytest.raises(ValueError, match="initial_airspeed_spread must be a number in"):
        make_env(task, "airship_v7", initial_airspeed_spread=0.7)


def test_target_sequence_releases_a_new_target() -> None:
    env = make_env("altitude", "navion", num_envs=4, target_sequence=True, hold_seconds=0.05,
                   offset_min=0.0, offset_max=0.0)
    td = env.reset()
    first = td["task", "target_altitude"][:, 0].clone()
    hold_trim = env.task.trim.command[[0, 3]].expand(4, 2)
    td = flat_scalars(env.rollout(10, policy=lambda tensordict: tensordict.set("action", hold_trim),
                                  tensordict=td, auto_reset=False))
    new = td["next", "task", "target_altitude"][:, -1]
    assert (new != first).all()
    assert set(new.tolist()) <= {20.0, 40.0, 60.0, 80.0, 100.0}
    assert (td["next", "task", "reference_climb_rate"][:, -1].abs() > 0).all()


def test_ground_contact_and_stall_terminate_and_horizon_truncates() -> None:
    env = make_env("altitude", "navion", num_envs=3, episode_seconds=0.05, decimation=1)
    td = env.reset()
    env.sim.x[0, 2] = 1.0  # 1 m below ground
    env.sim.x[1, 7:10] = torch.tensor([5.0, 0.0, 0.0])  # far below stall speed
    td = env.rand_step(td)["next"]
    assert td["terminated"][:, 0].tolist() == [True, True, False]
    assert td["done"][:, 0].tolist() == [True, True, False]
    assert not td["truncated"].any()
    env.reset()
    for _ in range(5):
        td = env.rand_step(TensorDict({}, batch_size=[3]))["next"]
    assert td["truncated"].all() and not td["terminated"].any() and td["done"].all()


def test_alpha_beyond_stall_terminates() -> None:
    env = make_env("attitude", "navion", num_envs=2, decimation=1)
    env.reset()
    alpha = 1.6 * env.airframe.aero.alpha_stall
    speed = env.airframe.envelope.cruise_speed
    env.sim.x[0, 7:10] = torch.tensor([speed * math.cos(alpha), 0.0, speed * math.sin(alpha)])
    td = env.rand_step(TensorDict({}, batch_size=[2]))["next"]
    assert td["terminated"][:, 0].tolist() == [True, False]


def test_decimation_runs_physics_steps_per_env_step() -> None:
    env = make_env("altitude", "navion", num_envs=2, decimation=4)
    td = env.rand_step(env.reset())
    assert torch.allclose(td["next", "state", "time"], torch.full((2,), 0.04))


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_a_diverged_env_is_terminated_with_finite_outputs(backend):
    """An env whose state leaves the finite numbers is terminated; every output of its row is finite
    (zeroed), the other envs are untouched, and a reset of the row flies on."""
    env = make_env("altitude", "volantex_ranger", num_envs=3, backend=backend, seed=0)
    td = env.reset()
    td["action"] = env.action_spec.zero()
    reference = make_env("altitude", "volantex_ranger", num_envs=3, backend=backend, seed=0)
    ref_td = reference.reset()
    ref_td["action"] = reference.action_spec.zero()
    env.sim.x[1, 7] = float("nan")
    out = env.step(td)["next"]
    ref = reference.step(ref_td)["next"]
    assert out["terminated"][:, 0].tolist() == [False, True, False]
    for key in out.keys(True, True):
        value = out[key]
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
            assert torch.equal(value[[0, 2]], ref[key][[0, 2]]), key
    reset = env.reset(out.clone().set("_reset", out["done"]))
    assert torch.isfinite(env.sim.x).all() and torch.isfinite(reset["observation"]).all()
