"""The guidance laws against hand-computed cases of their published equations (PX4's NPFG and TECS,
ArduPilot's L1), batched; and the guided LQR flying the path-following task."""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl.baselines.guidance import (
    L1Params,
    NPFGParams,
    TECSParams,
    TECSState,
    circle_frame,
    climb_rate_setpoint,
    l1_loiter,
    l1_waypoints,
    line_frame,
    npfg,
    segment_frame,
    tecs_update,
)
from falcon_rl.baselines.guidance.npfg import bearing_feasibility, reference_air_velocity
from falcon_rl.constants import G0

V = 15.0


def rows(*values: float) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float64)


def vectors(*pairs: tuple[float, float]) -> torch.Tensor:
    return torch.tensor(pairs, dtype=torch.float64)


def close(actual: torch.Tensor, expected: float, rel: float = 0.01) -> bool:
    return abs(float(actual) - expected) <= rel * abs(expected) + 1e-9


# ---------------------------------------------------------------------------------------------------- paths
def test_the_track_error_is_positive_right_of_the_path():
    north = line_frame(vectors((0.0, 10.0), (0.0, -10.0)), vectors((0.0, 0.0), (0.0, 0.0)), rows(0.0, 0.0))
    assert north.track_error.tolist() == [10.0, -10.0]
    east = segment_frame(vectors((5.0, 50.0)), vectors((0.0, 0.0)), vectors((0.0, 100.0)))
    assert torch.allclose(east.tangent, vectors((0.0, 1.0))) and float(east.track_error) == -5.0
    # Clockwise circle of 100 m: outside it (north of the centre, flying east) is left of the path.
    circle = circle_frame(vectors((120.0, 0.0)), vectors((0.0, 0.0)), rows(100.0), rows(1.0))
    assert torch.allclose(circle.tangent, vectors((0.0, 1.0)))
    assert float(circle.track_error) == -20.0 and float(circle.curvature) == 0.01


# ---------------------------------------------------------------------------------------------------- NPFG
def test_npfg_off_a_line_turns_back_by_its_look_ahead_angle():
    """A north line, the aircraft 21 m right of it flying north at 15 m/s, no wind, PX4's defaults: period
    10 s (its lower bound 1.5 pi 0.5 / 0.7 = 3.4 s is below), T = 7 s, e_b = 105 m, e_n = 0.2, lambda = (pi/2)
    0.8^2, bearing (sin lambda, -cos lambda), a = (4 pi 0.7 / 10) (v x v_ref) / |v_ref|."""
    frame = line_frame(vectors((0.0, 21.0)), vectors((0.0, 0.0)), rows(0.0))
    out = npfg(frame, vectors((V, 0.0)), vectors((0.0, 0.0)), V, 20.0)
    look_ahead = 0.5 * math.pi * 0.8**2
    gain = 4.0 * math.pi * 0.7 / 10.0
    accel = gain * (V * (-V * math.cos(look_ahead))) / V
    assert close(out.period, 10.0) and close(out.track_error_bound, 105.0)
    assert torch.allclose(out.bearing, vectors((math.sin(look_ahead), -math.cos(look_ahead))))
    assert close(out.lateral_accel, accel) and float(out.lateral_accel) < 0.0  # a left turn, to the line
    assert close(out.bank, math.atan(accel / G0))


def test_npfg_on_a_circle_flies_the_centripetal_feed_forward():
    """On a clockwise 100 m circle at 15 m/s, tangent to it, no wind: no feedback, a = V^2 / R (right)."""
    frame = circle_frame(vectors((100.0, 0.0)), vectors((0.0, 0.0)), rows(100.0), rows(1.0))
    out = npfg(frame, vectors((0.0, V)), vectors((0.0, 0.0)), V, 20.0)
    assert close(out.lateral_accel, V**2 / 100.0)
    assert close(out.track_proximity, 1.0)


def test_npfg_crabs_into_a_cross_wind_and_knows_an_infeasible_bearing():
    """A 5 m/s wind towards the west across a north bearing: the air velocity (sqrt(15^2 - 5^2), 5) keeps the
    track; a 20 m/s head wind leaves no feasible bearing at 15 m/s."""
    params = NPFGParams()
    bearing = vectors((1.0, 0.0))
    reference = reference_air_velocity(vectors((0.0, -5.0)), bearing, rows(0.0), V, 20.0, params)
    assert torch.allclose(reference, vectors((math.sqrt(V**2 - 25.0), 5.0)))
    head = vectors((-20.0, 0.0))
    assert float(bearing_feasibility(rows(0.0), (head * bearing).sum(-1), V, rows(20.0), 1.5)) == 0.0
    assert float(bearing_feasibility(rows(5.0), rows(0.0), V, rows(5.0), 1.5)) == 1.0


def test_npfg_bounds_its_period_below_by_the_roll_time_constant():
    """NPFG_PERIOD 1 s is raised to 1.5 pi tau_roll / zeta (PX4's lower bound with its safety factor)."""
    frame = line_frame(vectors((0.0, 5.0)), vectors((0.0, 0.0)), rows(0.0))
    out = npfg(frame, vectors((V, 0.0)), vectors((0.0, 0.0)), V, 20.0, p=NPFGParams(NPFG_PERIOD=1.0))
    assert close(out.period, 1.5 * math.pi * 0.5 / 0.7)
    assert NPFGParams().px4()["FW_R_LIM"] == pytest.approx(50.0)


# ---------------------------------------------------------------------------------------------------- L1
def test_l1_on_a_line_steers_by_the_angle_to_its_reference_point():
    """A north line, 10 m right of it, flying north at 15 m/s: L1 = 0.75 x 17 x 15 / pi, Nu = asin(-10 / L1),
    a = 4 x 0.75^2 V^2 / L1 sin(Nu); 100 m off, the 45 deg capture limit."""
    length = 0.75 * 17.0 * V / math.pi
    gain = 4.0 * 0.75**2
    for offset, nu in ((10.0, math.asin(-10.0 / length)), (100.0, -math.pi / 4.0)):
        out = l1_waypoints(vectors((0.0, offset)), vectors((0.0, 0.0)), vectors((1000.0, 0.0)),
                           vectors((V, 0.0)), rows(0.0), 0.1, p=L1Params(NAVL1_XTRACK_I=0.0))
        assert close(out.l1_distance, length) and float(out.crosstrack_error) == -offset
        assert close(out.nu, nu, 1e-3)
        assert close(out.lateral_accel, gain * V**2 / length * math.sin(nu))
    # Heading 30 deg off the line on it: Nu = -30 deg (turn back left).
    heading = math.radians(30.0)
    out = l1_waypoints(vectors((0.0, 0.0)), vectors((0.0, 0.0)), vectors((1000.0, 0.0)),
                       vectors((V * math.cos(heading), V * math.sin(heading))), rows(heading), 0.1)
    assert close(out.nu, -heading, 1e-3)


def test_l1_loiter_on_its_circle_flies_the_centripetal_acceleration():
    out = l1_loiter(vectors((80.0, 0.0)), vectors((0.0, 0.0)), rows(80.0), rows(1.0), vectors((0.0, V)),
                    rows(math.pi / 2))
    assert close(out.lateral_accel, V**2 / 80.0)
    # Outside the circle flying at its centre: the capture law (Nu = 0, straight in) until the laws cross.
    far = l1_loiter(vectors((500.0, 0.0)), vectors((0.0, 0.0)), rows(80.0), rows(1.0), vectors((-V, 0.0)),
                    rows(math.pi))
    assert float(far.lateral_accel) == 0.0
    assert L1Params().ardupilot()["ROLL_LIMIT_DEG"] == pytest.approx(45.0)


# ---------------------------------------------------------------------------------------------------- TECS
def test_tecs_altitude_loop_commands_a_limited_climb_rate():
    p = TECSParams()
    assert close(climb_rate_setpoint(rows(50.0), rows(60.0), 1.0, p), 10.0 / 5.0 + 0.3)
    assert float(climb_rate_setpoint(rows(50.0), rows(100.0), 0.0, p)) == 5.0
    assert float(climb_rate_setpoint(rows(100.0), rows(0.0), 0.0, p)) == -5.0


def test_tecs_one_step_matches_the_energy_equations():
    """From level flight at 15 m/s, 10 m below the reference: hdot* = 2 m/s, SPE* = 2 g, SKE* = 0; pitch*
    = (0.3 SEB_err + SEB*) / (V g) + I (then rate limited by 7 / V per s), throttle* = trim + STE* (1 -
    trim) / STE_max + 0.05 STE_err / (STE_max - STE_min) + I_thr."""
    dt, p = 0.1, TECSParams()
    state = TECSState.zeros(1, dtype=torch.float64)
    out = tecs_update(state, dt, rows(50.0), rows(0.0), rows(V), rows(0.0), rows(60.0), V, p=p)
    spe = 2.0 * G0
    integral = spe * 0.1 / (V * G0) * dt
    unlimited = (0.3 * spe + spe) / (V * G0) + integral
    assert close(out.climb_rate, 2.0) and close(out.seb_rate_setpoint, spe)
    assert unlimited > dt * 7.0 / V and close(out.pitch, dt * 7.0 / V)  # the vertical acceleration limit
    ste_max, ste_min = 5.0 * G0, -2.0 * G0
    scale = 1.0 / (ste_max - ste_min)
    throttle = 0.6 + spe * 0.4 / ste_max + 0.05 * spe * scale + spe * 0.05 * dt * scale
    assert close(out.throttle, throttle)
    # A second step continues from the state (the pitch rate limit again).
    out = tecs_update(state, dt, rows(50.0), rows(0.0), rows(V), rows(0.0), rows(60.0), V, p=p)
    assert close(out.pitch, 2.0 * dt * 7.0 / V)


def test_tecs_speed_weight_two_gives_pitch_to_speed_alone():
    """FW_T_SPDWEIGHT 2: the energy balance is - V Vdot (height ignored by pitch)."""
    state = TECSState.zeros(1, dtype=torch.float64)
    out = tecs_update(state, 0.1, rows(50.0), rows(1.0), rows(V), rows(0.0), rows(60.0), V + 5.0,
                      p=TECSParams(FW_T_SPDWEIGHT=2.0))
    vdot = min(5.0 / 5.0, 0.5 * 5.0 * G0 / V)
    assert close(out.seb_rate_setpoint, -V * vdot) and float(out.seb_rate) == 0.0


# ---------------------------------------------------------------------------------------------------- flight
@pytest.mark.skipif(pytest.importorskip("warp") is None, reason="warp-lang is not installed")
@pytest.mark.parametrize("lateral", ["npfg", "l1"])
def test_the_guided_lqr_follows_a_line_in_moderate_turbulence(lateral):
    from falcon_rl import make_env
    from falcon_rl.baselines.guided import guided_lqr

    env = make_env("path_following", "airship_v7", num_envs=4, backend="warp", seed=3, turbulence="moderate")
    policy = guided_lqr(env, lateral)
    with torch.no_grad():
        rollout = env.rollout(env.max_episode_steps, policy, break_when_any_done=False)
    nxt = rollout["next"]
    assert not bool(nxt["terminated"].any())
    error = nxt["task", "cross_track_error"][:, env.max_episode_steps // 2:]
    assert float(error.pow(2).mean().sqrt()) < 2.0
    assert float(nxt["task", "altitude_error"][:, env.max_episode_steps // 2:].abs().max()) < 10.0


@pytest.mark.skipif(pytest.importorskip("warp") is None, reason="warp-lang is not installed")
def test_the_guided_ppo_executor_flies_the_shipped_attitude_policy():
    """NPFG over the shipped PPO attitude policy (fed the attitude task's own observation) follows the line
    on the Ranger in moderate turbulence."""
    from falcon_rl import make_env
    from falcon_rl.baselines.guided import guided_ppo

    env = make_env("path_following", "volantex_ranger", num_envs=4, backend="warp", seed=3,
                   turbulence="moderate")
    with torch.no_grad():
        rollout = env.rollout(env.max_episode_steps, guided_ppo(env), break_when_any_done=False)
    nxt = rollout["next"]
    assert not bool(nxt["terminated"].any())
    assert float(nxt["task", "cross_track_error"][:, env.max_episode_steps // 2:].pow(2).mean().sqrt()) < 2.0


def test_an_executor_refuses_a_policy_of_another_task():
    from falcon_rl import make_env
    from falcon_rl.baselines.guided import PolicyExecutor
    from falcon_rl.policies import shipped_policy
    from falcon_rl.policies.format import FileFormatError

    env = make_env("path_following", "airship_v7", num_envs=1, backend="torch", seed=0)
    with pytest.raises(FileFormatError,
                       match="an executor needs an attitude-task policy, this one is for task 'altitude'"):
        PolicyExecutor(env, shipped_policy("altitude", "airship_v7"))


@pytest.mark.skipif(pytest.importorskip("warp") is None, reason="warp-lang is not installed")
def test_the_guided_lqr_follows_the_trajectory_arc():
    from falcon_rl import make_env
    from falcon_rl.baselines.guided import guided_lqr
    from falcon_rl.envs.layout import flat_scalars
    from falcon_rl.evaluation.tracking_metrics import arc_distance

    env = make_env("trajectory", "airship_v7", num_envs=4, backend="warp", seed=1)
    with torch.no_grad():
        rollout = env.rollout(env.max_episode_steps, guided_lqr(env), break_when_any_done=False)
    nxt = flat_scalars(rollout["next"])
    assert not bool(nxt["terminated"].any())
    assert float(arc_distance(nxt)[:, env.max_episode_steps // 2:].max()) < 2.0
