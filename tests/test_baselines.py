"""LQR/LQRI and MPPI baselines: linear models against Nelson's Navion modes, stabilising gains,
closed-loop behaviour in the env, and MPPI's contract (actions inside the spec, planning works)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from falcon_rl import load_airframe, make_env
from falcon_rl.baselines.linear_models import climb_rate_row, linear_model
from falcon_rl.baselines.lqr import AltitudeLQR, altitude_schedule, attitude_schedule
from falcon_rl.baselines.mppi import MPPI, MPPIConfig
from falcon_rl.physics import state as S


def _closest(eigs: np.ndarray, target: complex) -> complex:
    return complex(eigs[np.argmin(np.abs(eigs - target))])


def test_navion_modes_match_nelson():
    """Nelson's worked Navion examples (sea level, 176 ft/s): short period -2.51 +- 2.59j,
    phugoid -0.017 +- 0.213j, Dutch roll -0.487 +- 2.335j, roll -8.43, spiral -0.0087 (1/s).
    Our model folds C_m_alphadot into C_mq, which raises the short-period frequency about 10%;
    the tolerances below are set by that and by the approximate modes Nelson quotes."""
    nelson = load_airframe("navion_nelson")  # Nelson's derivative set (the shipped navion is derived)
    full = linear_model(nelson, 53.64, 100.0, full=True, ground_effect=False)
    eigs = np.linalg.eigvals(full.A)
    sp = _closest(eigs, -2.51 + 2.59j)
    assert abs(sp.real + 2.51) < 0.25 and abs(sp.imag - 2.59) < 0.4
    ph = _closest(eigs, -0.017 + 0.213j)
    assert abs(ph.real + 0.017) < 0.02 and abs(ph.imag - 0.213) < 0.03
    dr = _closest(eigs, -0.487 + 2.335j)
    assert abs(dr.real + 0.487) < 0.05 and abs(dr.imag - 2.335) < 0.1
    roll = _closest(eigs, -8.43)
    assert abs(roll.real + 8.43) < 0.4 and abs(roll.imag) < 1e-6
    spiral = _closest(eigs, -0.0087)
    assert abs(spiral.real + 0.0087) < 0.01 and abs(spiral.imag) < 1e-6


def test_linear_models_are_at_equilibrium_and_climb_row(ranger):
    lon = linear_model(ranger, 15.0, 50.0)
    assert lon.A.shape == (8, 8) and lon.B.shape == (8, 2)
    full = linear_model(ranger, 15.0, 50.0, full=True)
    row = climb_rate_row(full)
    names = full.states
    # hdot = u sin(theta) - w cos(theta) at wings level: d/dw = -cos(theta), d/dtheta = u cos + w sin.
    theta, u, w = full.x_trim[names.index("theta")], full.x_trim[0], full.x_trim[2]
    assert row[names.index("w")] == pytest.approx(-np.cos(theta))
    assert row[names.index("theta")] == pytest.approx(u * np.cos(theta) + w * np.sin(theta))


@pytest.mark.parametrize("name", ["navion", "volantex_ranger"])
def test_gain_schedules_stabilise_every_trim_point(name, request):
    airframe = request.getfixturevalue("navion" if name == "navion" else "ranger")
    alt = altitude_schedule(airframe, 0.01)
    assert alt.spectral_radius < 1.0 and torch.isfinite(alt.K).all()
    assert alt.K.shape[-2:] == (2, 9)
    att = attitude_schedule(airframe, 0.01)
    assert att.spectral_radius < 1.0 and att.K.shape[-2:] == (4, 18)


def test_altitude_lqr_climbs_to_the_reference(ranger):
    env = make_env("altitude", "volantex_ranger", num_envs=4, seed=3, episode_seconds=12.0, backend="warp",
                   decimation=1)
    policy = AltitudeLQR(ranger, dt=env.control_dt)
    with torch.no_grad():
        rollout = env.rollout(1200, policy, break_when_any_done=False)
    assert not rollout["next", "terminated"].any()
    error = rollout["next", "state", "height"] - rollout["next", "task", "target_altitude"]
    assert error[:, 0].abs().min() > 11.0  # started 12-18 m away
    assert error[:, -1].abs().max() < 1.0  # inside the capture band at 12 s
    actions = rollout["action"]
    assert actions.abs().max() <= 1.0


def test_mppi_plans_inside_the_action_spec():
    env = make_env("altitude", "volantex_ranger", num_envs=2, seed=0, episode_seconds=1.0, decimation=1)
    policy = MPPI(env, MPPIConfig(samples=8, horizon_seconds=0.5, plan_dt=0.05, replan_seconds=0.05))
    with torch.no_grad():
        rollout = env.rollout(20, policy, break_when_any_done=False)
    actions = rollout["action"]
    assert actions.shape == (2, 20, 2)
    assert env.action_spec.is_in(actions[:, -1])
    assert len(policy.planning_seconds) == 20 // 5
    assert policy.plan.shape == (2, policy.horizon, 2)
    lag = max(m.time_constant for m in env.sim.airframe.motors)
    assert policy.horizon_seconds >= 2 * lag + 1.0  # the plan sees the throttle act
    with pytest.raises(ValueError, match="whole number"):
        MPPI(env, MPPIConfig(samples=2, plan_dt=0.1, replan_seconds=0.05))


def test_mppi_samples_from_the_env_seed_unless_given_its_own():
    """Each evaluation seed (an experiment draw) samples its own planning noise; the same seed the
    same noise; an explicit ``MPPIConfig.seed`` wins."""
    def first_noise(env_seed: int, seed: int | None = None) -> torch.Tensor:
        env = make_env("altitude", "volantex_ranger", num_envs=1, seed=env_seed, decimation=1)
        return MPPI(env, MPPIConfig(samples=4, seed=seed))._smooth_noise(1, 4, 5, 2)

    assert torch.equal(first_noise(3), first_noise(3))
    assert not torch.equal(first_noise(3), first_noise(4))
    assert torch.equal(first_noise(3, seed=7), first_noise(4, seed=7))


def test_mppi_held_samples_hold_the_plan_from_a_random_step_on():
    """``hold_fraction``: the last samples follow the plan up to a random step and hold it from there,
    plus noise; the first of them is the plan's first command held without noise; sample 0 is the plan.
    Without held samples the candidates (and the generator's draws) are those of the plain sampler."""
    env = make_env("attitude", "airship_v7", num_envs=2, seed=3, maneuver="figure8", decimation=1)
    plan = torch.linspace(-0.5, 0.5, 2 * 40 * 4).reshape(2, 40, 4)  # a plan that changes at every step

    def candidates(fraction: float, sigma: float) -> torch.Tensor:
        config = MPPIConfig(samples=16, hold_fraction=fraction, noise_sigma=(sigma,) * 4, seed=5)
        policy = MPPI(env, config, tracks="attitude")
        assert policy.horizon == 40
        return policy._candidates(plan)

    held = candidates(0.25, 0.0)  # no noise: the bases themselves
    assert held.shape == (2, 16, 40, 4)
    assert torch.equal(held[:, :12], plan[:, None].expand(2, 12, 40, 4))  # the others: the plan
    assert torch.equal(held[:, 12], plan[:, :1].expand(2, 40, 4))  # the first command, held
    starts = set()
    for sample in held[0, 13:]:  # the plan up to a step, constant after it
        off = (sample != plan[0]).any(-1)
        start = int(off.nonzero()[0]) - 1 if off.any() else 39
        assert torch.equal(sample[:start + 1], plan[0, :start + 1])
        assert torch.equal(sample[start:], plan[0, start].expand(40 - start, 4))
        starts.add(start)
    assert len(starts) > 1  # drawn, not one fixed step
    noisy = candidates(0.25, 0.02)
    assert torch.equal(noisy[:, 0], plan) and torch.equal(noisy[:, 12], held[:, 12])
    assert not torch.equal(noisy[:, 13:], held[:, 13:])
    plain = MPPI(env, MPPIConfig(samples=16, noise_sigma=(0.02,) * 4, seed=5), tracks="attitude")
    expected = (plan[:, None] + plain._smooth_noise(2, 16, 40, 4)).clamp(-1.0, 1.0)
    expected[:, 0] = plan
    assert torch.equal(candidates(0.0, 0.02), expected)
    for bad in (-0.1, 1.0, float("nan"), "0.5"):
        with pytest.raises(ValueError, match="hold_fraction"):
            MPPI(env, MPPIConfig(samples=4, hold_fraction=bad), tracks="attitude")


def test_mppi_reads_the_maneuver_stream_ahead():
    env = make_env("attitude", "volantex_ranger", num_envs=2, seed=0, maneuver="s_turn", decimation=1)
    policy = MPPI(env, MPPIConfig(samples=4, horizon_seconds=1.0, plan_dt=0.1))
    td = env.reset()
    td["state", "time"] = torch.full_like(td["state", "time"], 3.0)  # [N, 1]  # 3 s into the stream
    ref = policy._references(td)
    table = env.task.table
    assert ref["bank"].shape == (policy.horizon, 2 * 4)
    for j in (0, policy.horizon - 1):
        row = table[300 + round((j + 1) * 0.1 / env.control_dt)]
        assert torch.allclose(ref["bank"][j], row[0].expand(8))
        assert torch.allclose(ref["airspeed"][j], row[2].expand(8))
    assert ref["bank"][-1, 0] != ref["bank"][0, 0]  # the s-turn's bank changes over the horizon


def test_mppi_altitude_reference_ramps_to_the_target():
    env = make_env("altitude", "volantex_ranger", num_envs=3, seed=1, decimation=1)
    policy = MPPI(env, MPPIConfig(samples=2, horizon_seconds=8.0, plan_dt=0.1))
    td = env.reset()
    ref = policy._references(td)
    target = td["task", "target_altitude"].repeat_interleave(2)
    start = td["task", "reference_altitude"].repeat_interleave(2)
    rate = td["task", "reference_climb_rate"].repeat_interleave(2)
    assert torch.allclose(ref["height"][0], start + rate * 0.1, atol=1e-4)  # on the ramp after one step
    assert torch.allclose(ref["height"][-1], target)  # 12-18 m at 2.5 m/s: the ramp ends inside 8 s
    assert (ref["climb"][-1] == 0).all() and torch.allclose(ref["climb"][0], rate)


def test_mppi_climbs_towards_the_target():
    """Closed loop on the Ranger with a small planner: within 3 s every episode has moved towards
    its commanded altitude at a good fraction of the reference climb rate, and nothing crashed."""
    torch.manual_seed(0)
    env = make_env("altitude", "volantex_ranger", num_envs=2, seed=2, backend="warp", decimation=1)
    policy = MPPI(env, MPPIConfig(samples=32, horizon_seconds=1.5, plan_dt=0.1, replan_seconds=0.1))
    with torch.no_grad():
        rollout = env.rollout(300, policy, break_when_any_done=False)
    assert not rollout["next", "terminated"].any()
    error = (rollout["next", "state", "height"] - rollout["next", "task", "target_altitude"]).abs()
    assert (error[:, 0] - error[:, -1] > 0.5 * 2.5 * 3.0 * 0.5).all()  # half the ramp's 7.5 m at least
    assert len(policy.planning_cpu_seconds) == len(policy.planning_seconds) == 30


def test_mppi_attitude_cost_penalises_sideslip():
    env = make_env("attitude", "volantex_ranger", num_envs=1, seed=0, maneuver="circle")
    policy = MPPI(env, MPPIConfig(samples=2, horizon_seconds=1.0))
    speed, beta = env.task.trim_airspeed, np.radians(4.0)
    x = policy.planner.x.clone()  # [2, S]: wings level at 100 m, no rates
    x[:, S.POSITION] = torch.tensor([0.0, 0.0, -100.0])
    x[:, S.QUATERNION] = torch.tensor([1.0, 0.0, 0.0, 0.0])
    x[:, S.ANGULAR_RATE] = 0.0
    x[0, S.VELOCITY] = torch.tensor([speed, 0.0, 0.0])
    x[1, S.VELOCITY] = torch.tensor([speed * np.cos(beta), speed * np.sin(beta), 0.0])  # 4 deg slip
    ref = {"bank": torch.zeros(2), "climb": torch.zeros(2), "airspeed": torch.full((2,), speed)}
    cost = policy._step_cost(x, ref)
    assert float(cost[1] - cost[0]) == pytest.approx((4.0 / 2.0) ** 2, rel=1e-3)


def test_mppi_weights_ignore_diverged_samples():
    from falcon_rl.baselines.mppi import mppi_weights

    cost = torch.tensor([[1.0, 2.0, float("nan"), 3.0], [float("inf"), 5.0, 5.0, 5.0]])
    weights = mppi_weights(cost, temperature=0.2)
    assert torch.isfinite(weights).all() and torch.allclose(weights.sum(dim=1), torch.ones(2))
    assert weights[0, 2] == 0 and weights[1, 0] == 0
    assert weights[0, 0] > weights[0, 1] > weights[0, 3]  # cheaper rollouts weigh more
    assert torch.allclose(weights[1, 1:], torch.full((3,), 1 / 3))


def test_mppi_attitude_height_profile_integrates_the_climb_commands():
    env = make_env("attitude", "volantex_ranger", num_envs=1, seed=0, maneuver="helix", decimation=1)
    policy = MPPI(env, MPPIConfig(samples=2, horizon_seconds=2.0, plan_dt=0.1))
    td = env.reset()
    policy.start_height.fill_(100.0)
    table, dt = env.task.table, env.control_dt
    td["state", "time"] = torch.full_like(td["state", "time"], 20.0)  # mid-helix: climbing
    ref = policy._references(td)
    for j in (0, policy.horizon - 1):
        index = 2000 + round((j + 1) * 0.1 / dt)
        expected = 100.0 + float(table[:index, 1].double().sum()) * dt
        assert float(ref["height"][j, 0]) == pytest.approx(expected, abs=1e-3)
    assert float(ref["height"][-1, 0] - ref["height"][0, 0]) > 0.5 * float(table[2000, 1]) * 1.9


def test_lqr_design_leaves_first_order_actuator_rates_out():
    """A first-order actuator's rate state neither moves nor acts (an uncontrollable mode at z = 1 that
    made the Riccati solve fail for the imported JSBSim aircraft): it gets zero gain, the rest is stable."""
    from falcon_rl.baselines.linear_models import LONGITUDINAL_INDEX
    from falcon_rl.baselines.lqr import ALTITUDE_INPUT_MAX, ALTITUDE_INTEGRAL_MAX, ALTITUDE_STATE_MAX
    from falcon_rl.baselines.lqr_design import design_lqri, inert_states

    model = linear_model(load_airframe("jsbsim_c172p"), 50.0, 10.0, ground_effect="tables")
    outputs = np.zeros((1, model.A.shape[0]))
    outputs[0, LONGITUDINAL_INDEX["h"]] = 1.0
    assert inert_states(model, outputs).nonzero()[0].tolist() == [LONGITUDINAL_INDEX["elevator_rate"]]
    gain = design_lqri(model, 0.05, outputs, ALTITUDE_STATE_MAX, ALTITUDE_INPUT_MAX, ALTITUDE_INTEGRAL_MAX)
    assert gain.K.shape == (2, model.A.shape[0] + 1) and gain.spectral_radius < 1.0
    assert not gain.K[:, LONGITUDINAL_INDEX["elevator_rate"]].any()
