"""Robustness transforms: specs, exact delays, per-env buffers on partial resets, sensor chain, domain
randomisation and the make_env presets."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv
from torchrl.envs.utils import check_env_specs, step_mdp

from falcon_rl import make_env
from falcon_rl.envs.tasks import TERMINATION_CODE
from falcon_rl.physics.wind import dryden_scales
from falcon_rl.transforms import (
    ActionDelay,
    DomainRandomization,
    ObservationDelay,
    RandomizationConfig,
    SensorChannel,
    SensorConfig,
    SensorTransform,
)

N = 4


@pytest.mark.parametrize("options", [
    {"sensors": "mild"},
    {"obs_delay_ms": 50.0},
    {"action_delay_ms": (20.0, 100.0)},
    {"randomize": True},
    {"turbulence": "medium"},
    {"sensors": "severe", "obs_delay_ms": 80.0, "action_delay_ms": 100.0, "randomize": True,
     "turbulence": 0.15},
], ids=["sensors", "obs_delay", "action_delay", "randomize", "turbulence", "all"])
def test_check_env_specs(options: dict) -> None:
    env = make_env("attitude", "navion", num_envs=N, seed=1, **options)
    check_env_specs(env, seed=0)


def test_check_env_specs_warp() -> None:
    env = make_env("altitude", "navion", num_envs=N, backend="warp", sensors="medium", obs_delay_ms=60.0,
                   action_delay_ms=60.0, randomize=RandomizationConfig(turbulence_w20=(0.0, 10.0)),
                   turbulence="light")
    check_env_specs(env, seed=0)


def test_a_delay_that_rounds_to_no_step_is_refused() -> None:
    """20 ms at the default 20 Hz control (50 ms steps) would silently be no delay."""
    env = make_env("altitude", "navion", num_envs=N, obs_delay_ms=20.0, seed=0)
    with pytest.raises(ValueError, match="round to no delay"):
        env.reset()
    env = make_env("altitude", "navion", num_envs=N, obs_delay_ms=20.0, seed=0, decimation=1)
    assert env.reset()["observation"].shape[0] == N  # 2 steps of 10 ms


def test_nominal_presets_build_the_bare_env() -> None:
    env = make_env("altitude", num_envs=N, sensors="nominal", obs_delay_ms="nominal",
                   action_delay_ms=0, turbulence="nominal")
    assert not isinstance(env, TransformedEnv) and env.sim.turbulence is None


def _step(env, td, action: torch.Tensor):
    td["action"] = action
    td = env.step(td)
    return td, step_mdp(td)


def test_action_delay_is_exact() -> None:
    """The command of step t reaches the simulator at step t + k (k = 30 ms / 10 ms = 3)."""
    env = make_env("attitude", num_envs=N, action_delay_ms=30.0, decimation=1)
    base = env.base_env
    trim = base.task.trim.command[base.task.channels]
    td = env.reset()
    assert torch.equal(td["applied_action"], trim.expand(N, -1))
    actions = [torch.full((N, 4), 0.1 * t - 0.5) for t in range(8)]
    for t, action in enumerate(actions):
        full, td = _step(env, td, action)
        assert torch.equal(full["action"], action)  # the rollout keeps the policy's own action
        expected = actions[t - 3] if t >= 3 else trim.expand(N, -1)
        assert torch.equal(full["next", "applied_action"], expected)
        assert torch.allclose(base.sim.command[:, base.task.channels], expected.clamp(-1, 1))


def test_action_delay_checks_the_action_before_it_enters_the_line() -> None:
    """A refused action moves nothing; a NaN row terminates this very step (not k steps later) while
    the line holds and "applied_action" shows only clean, clamped values."""
    env = make_env("attitude", num_envs=N, action_delay_ms=30.0, decimation=1)
    td = env.reset()
    line = env.transform[0]._lines["action"]
    before, head, steps = line.buffer.clone(), line.head, env.base_env.episode_step
    for bad in (torch.zeros(N, 3), torch.zeros(N, 4, dtype=torch.long), torch.zeros(N, 4, dtype=torch.bool)):
        with pytest.raises(ValueError, match="action"):
            env.step(td.clone().set("action", bad))
    assert torch.equal(line.buffer, before) and line.head == head
    assert torch.equal(env.base_env.episode_step, steps)
    action = torch.full((N, 4), 0.2)
    action[1, 0] = float("nan")
    action[2, 3] = float("inf")
    full, _ = _step(env, td, action)
    nxt = full["next"]
    assert nxt["terminated"].flatten().tolist() == [False, True, False, False]
    assert nxt["termination_reason"][1].item() == TERMINATION_CODE["non_finite"]
    assert torch.isfinite(nxt["applied_action"]).all() and torch.isfinite(nxt["observation"]).all()
    clean = torch.full((N, 4), 0.2)
    clean[1] = 0.0
    clean[2, 3] = 1.0
    assert torch.equal(line.buffer[:, (line.head - 1) % line.size], clean)  # the clean, clamped value


def test_observation_delay_is_exact() -> None:
    """With k = 20 ms / 10 ms = 2, the observation after step t is the true one after step t - 2."""
    env = make_env("altitude", num_envs=N, obs_delay_ms=20.0, decimation=1)
    td = env.reset()
    truth = [td["state", "height"].clone()]
    observations = [td["observation"].clone()]
    assert torch.equal(td["measured", "height"], truth[0])
    for t in range(1, 7):
        full, td = _step(env, td, env.action_spec.rand())
        truth.append(full["next", "state", "height"].clone())
        assert torch.equal(full["next", "measured", "height"], truth[max(t - 2, 0)])
        observations.append(full["next", "observation"].clone())
    assert torch.equal(observations[1], observations[0]) and torch.equal(observations[2], observations[0])


def test_delays_drawn_per_episode_within_range() -> None:
    env = make_env("altitude", num_envs=256, action_delay_ms=(20.0, 100.0), obs_delay_ms=(20.0, 80.0),
                   decimation=1)
    env.reset()
    action_delay, obs_delay = env.transform[0], env.transform[1]
    assert isinstance(action_delay, ActionDelay) and isinstance(obs_delay, ObservationDelay)
    assert action_delay.delays.min() == 2 and action_delay.delays.max() == 10
    assert obs_delay.delays.min() == 2 and obs_delay.delays.max() == 8


def test_partial_reset_refills_only_masked_rows() -> None:
    env = make_env("attitude", num_envs=N, action_delay_ms=30.0, obs_delay_ms=30.0, sensors="mild",
                   decimation=1)
    base = env.base_env
    trim = base.task.trim.command[base.task.channels]
    td = env.reset()
    actions = [torch.full((N, 4), 0.2 * t - 0.4) for t in range(5)]
    for action in actions:
        _, td = _step(env, td, action)
    action_delay, sensors, obs_delay = env.transform[0], env.transform[1], env.transform[2]
    action_before = action_delay._lines["action"].buffer.clone()
    obs_before = obs_delay._lines["observation"].buffer.clone()
    bias_before = {k: st.bias.clone() for k, st in sensors._state.items()}
    mask = torch.tensor([True, False, True, False])
    td["_reset"] = mask.unsqueeze(-1)
    td = env.reset(td)
    after = action_delay._lines["action"].buffer
    assert torch.equal(after[~mask], action_before[~mask])
    assert torch.equal(after[mask], trim.expand(2, after.shape[1], -1))
    assert torch.equal(obs_delay._lines["observation"].buffer[~mask], obs_before[~mask])
    assert (obs_delay._lines["observation"].buffer[mask] == td["observation"][mask].unsqueeze(1)).all()
    for k, st in sensors._state.items():
        assert torch.equal(st.bias[~mask], bias_before[k][~mask])
    full, _ = _step(env, td, torch.full((N, 4), 0.9))
    applied = full["next", "applied_action"]
    assert torch.equal(applied[mask], trim.expand(2, -1))  # fresh episodes: trim until k steps pass
    assert torch.equal(applied[~mask], actions[2][~mask])  # running episodes: a_{t-3} continues (t = 5)


def test_domain_randomisation_resamples_only_masked_rows() -> None:
    cfg = RandomizationConfig(wind_speed=(0.0, 8.0), turbulence_w20=(1.0, 20.0))
    env = make_env("altitude", num_envs=64, randomize=cfg, turbulence="light", seed=3)
    sim = env.base_env.sim
    nominal_mass = env.base_env.airframe.mass
    env.reset()
    first = {k: v.clone() for k, v in env.transform[0].sampled().items()}
    ratio = first["mass"] / nominal_mass
    assert ratio.min() >= 0.9 and ratio.max() <= 1.1 and ratio.std() > 0.02
    speed = torch.linalg.vector_norm(first["wind_ned"], dim=-1)
    assert speed.max() <= 8.0 and speed.std() > 0.5 and (first["wind_ned"][:, 2] == 0).all()
    assert first["turbulence_w20"].min() >= 1.0 and first["turbulence_w20"].max() <= 20.0
    mask = torch.zeros(64, dtype=torch.bool)
    mask[::3] = True
    env.reset(TensorDict({"_reset": mask.unsqueeze(-1)}, batch_size=[64]))
    second = env.transform[0].sampled()
    for key, value in second.items():
        assert torch.equal(value[~mask], first[key][~mask]), key
        assert not torch.equal(value[mask], first[key][mask]), key
    assert torch.allclose(sim.params.inertia_inv[mask] @ sim.params.inertia[mask],
                          torch.eye(3).expand(int(mask.sum()), 3, 3), atol=1e-5)


def test_cg_shift_moves_wing_and_transfers_the_lift_moment() -> None:
    cfg = RandomizationConfig(mass_scale=None, inertia_scale=None, cg_shift=(0.05, 0.05), aero_scale=None,
                              motor_scale=None, actuator_bandwidth_scale=None)
    env = TransformedEnv(make_env("altitude", num_envs=2), DomainRandomization(cfg))
    p = env.base_env.sim.params
    nominal = {k: getattr(p, k).clone() for k in ("wing_quarter_chord", "aero_coefficients")}
    env.reset()
    assert torch.allclose(p.wing_quarter_chord[:, 0], nominal["wing_quarter_chord"][:, 0] - 0.05)
    d_cm = p.aero_coefficients[..., 4] - nominal["aero_coefficients"][..., 4]
    assert torch.allclose(d_cm, -0.05 / p.chord[:, None] * nominal["aero_coefficients"][..., 0], atol=1e-6)


# ------------------------------------------------------------------------------ sensor chain
def _sensor_env(config: SensorConfig, num_envs: int = 512, task: str = "altitude"):
    return TransformedEnv(make_env(task, num_envs=num_envs, decimation=1), SensorTransform(config, seed=0))


def test_sensor_noise_bias_scale_clip_and_quantisation() -> None:
    config = SensorConfig(
        gyro=SensorChannel(noise_std=0.02, bias=0.01),
        gps_position=SensorChannel(resolution=0.5),
        airspeed=SensorChannel(scale_factor=0.1, limits=(0.0, 40.0)),
        gps_velocity=SensorChannel(bias_std=0.3))
    env = _sensor_env(config)
    td = env.reset()
    error = td["measured", "angular_rate_body"] - td["state", "angular_rate_body"]
    assert error.mean().item() == pytest.approx(0.01, abs=0.002)
    assert error.std().item() == pytest.approx(0.02, rel=0.05)
    pos = td["measured", "position_ned"]
    assert torch.equal(pos, torch.round(td["state", "position_ned"] / 0.5) * 0.5)
    assert torch.equal(td["measured", "height"].flatten(), -pos[:, 2])
    assert torch.allclose(td["measured", "airspeed"], (1.1 * td["state", "airspeed"]).clamp(0.0, 40.0))
    bias = td["measured", "velocity_ned"] - td["state", "velocity_ned"]
    assert bias.std().item() == pytest.approx(0.3, rel=0.1)
    full, _ = _step(env, td, env.action_spec.zero())
    later = full["next", "measured", "velocity_ned"] - full["next", "state", "velocity_ned"]
    assert torch.allclose(later, bias, atol=1e-5)  # a constant bias within the episode


def test_sensor_sample_and_hold_and_transport_delay() -> None:
    config = SensorConfig(gps_position=SensorChannel(rate_hz=25.0),  # every 4 env steps
                          gyro=SensorChannel(delay_ms=30.0))
    env = _sensor_env(config, num_envs=2)
    td = env.reset()
    positions, truth_rates, rates = [td["measured", "position_ned"]], [td["state", "angular_rate_body"]], []
    actions = torch.tensor([[0.3, -0.2], [-0.3, 0.2]])
    for _ in range(9):
        full, td = _step(env, td, actions)
        positions.append(full["next", "measured", "position_ned"])
        truth_rates.append(full["next", "state", "angular_rate_body"])
        rates.append(full["next", "measured", "angular_rate_body"])
    for t in range(10):
        assert torch.equal(positions[t], positions[4 * (t // 4)])
    assert not torch.equal(positions[4], positions[3])
    for t in range(1, 10):
        assert torch.equal(rates[t - 1], truth_rates[max(t - 3, 0)])


def test_attitude_is_renormalised_and_observation_uses_measured_state() -> None:
    env = _sensor_env(SensorConfig(attitude=SensorChannel(noise_std=math.radians(2.0))), task="attitude")
    td = env.reset()
    q = td["measured", "quaternion"]
    assert torch.allclose(torch.linalg.vector_norm(q, dim=-1), torch.ones(512), atol=1e-6)
    bank_error = td["measured", "euler"][:, 0] - td["state", "euler"][:, 0]
    assert bank_error.std().item() == pytest.approx(math.radians(2.0), rel=0.15)
    base = env.base_env
    assert torch.allclose(td["observation"], base.observe(td["measured"]))
    assert not torch.allclose(td["observation"], base.observe(td["state"]))
    clean = _sensor_env(SensorConfig(gyro=SensorChannel()), num_envs=4, task="attitude")
    td = clean.reset()
    full, _ = _step(clean, td, clean.action_spec.zero())
    assert torch.equal(full["next", "observation"], clean.base_env.observe(full["next", "state"]))


def test_turbulence_ratio_resolves_at_the_task_operating_point() -> None:
    env = make_env("attitude", "navion", num_envs=2, turbulence=0.1)
    sim, task = env.sim, env.task
    _, sigma = dryden_scales(torch.tensor([task.config.initial_height]), sim.turbulence.w20[:1])
    assert sigma[0, 0].item() == pytest.approx(0.1 * task.trim_airspeed, rel=1e-4)
    mil = make_env("attitude", num_envs=2, turbulence="severe").sim.turbulence.w20
    assert mil[0].item() == pytest.approx(45 * 1852 / 3600)
