"""Analytic cases for the torch model: free fall, torque-free rotation, actuator responses,
trim hold, RK4 against the SciPy reference, Jacobians against finite differences."""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl import Simulator, trim_level
from falcon_rl.physics import state as S
from falcon_rl.physics.linearize import finite_difference_jacobians, linearize
from falcon_rl.physics.rotations import rotation_matrix


def _forces_off(sim: Simulator) -> None:
    sim.params.aero_coefficients.zero_()
    sim.params.aero_rates.zero_()
    sim.params.thrust_coefficient.zero_()


def test_free_fall_is_exact(ranger):
    """No aero, no thrust: z = z0 + g t^2 / 2 and w = g t; RK4 is exact for this polynomial,
    so only float64 rounding remains (tolerance 1e-9)."""
    sim = Simulator(ranger, dtype=torch.float64)
    _forces_off(sim)
    sim.reset({"height": torch.tensor([500.0]), "velocity_body": torch.zeros(1, 3),
               "euler": torch.zeros(1, 3)})
    for _ in range(300):
        sim.step(torch.zeros(1, 4))
    t, g = 3.0, 9.80665
    st = sim.state
    assert st["height"].item() == pytest.approx(500.0 - 0.5 * g * t * t, abs=1e-9)
    assert st["velocity_ned"][0, 2].item() == pytest.approx(g * t, abs=1e-9)
    assert st["velocity_ned"][0, :2].abs().max().item() < 1e-12


def test_torque_free_rotation_conserves_momentum_and_energy(ranger):
    """Ranger inertia has Ixz != 0, so the rotation couples all axes. Over 2 s at dt 0.01 the RK4
    truncation error is ~1e-9; tolerance 1e-7 relative."""
    sim = Simulator(ranger, dtype=torch.float64)
    _forces_off(sim)
    w0 = torch.tensor([[1.5, -0.7, 0.9]], dtype=torch.float64)
    sim.reset({"height": torch.tensor([500.0]), "velocity_body": torch.zeros(1, 3),
               "angular_rate_body": w0, "euler": torch.tensor([[0.3, 0.2, -0.4]])})
    J = sim.params.inertia[0]

    def invariants():
        w = sim.x[0, S.ANGULAR_RATE]
        R = rotation_matrix(sim.x[:1, S.QUATERNION])[0]
        return R @ (J @ w), 0.5 * w @ (J @ w)

    h0, e0 = invariants()
    for _ in range(200):
        sim.step(torch.zeros(1, 4))
        q = sim.x[0, S.QUATERNION]
        assert abs(float(q.norm()) - 1.0) < 1e-12
    h1, e1 = invariants()
    assert torch.allclose(h1, h0, rtol=0, atol=1e-7 * float(h0.norm()))
    assert float(e1) == pytest.approx(float(e0), rel=1e-7)


def test_quaternion_stays_unit_in_float32(navion):
    sim = Simulator(navion, num_envs=8)
    gen = torch.Generator().manual_seed(3)
    for _ in range(200):
        sim.step(torch.rand(8, 4, generator=gen) * 2 - 1)
        norms = sim.x[:, S.QUATERNION].norm(dim=-1)
        assert (norms - 1).abs().max() < 1e-6


@pytest.mark.parametrize("name", ["navion", "volantex_ranger"])
def test_trimmed_aircraft_holds_altitude_and_airspeed_for_30_s(name):
    """float32, RK4, dt 0.01: a trim converged to 1e-9 drifts only through rounding; tolerances
    0.5 m and 0.1 m/s over 30 s leave room for the slow phugoid excited by float32 state."""
    sim = Simulator(name)
    st0 = sim.state
    cmd = sim.command.clone()
    for _ in range(3000):
        sim.step(cmd)
    st = sim.state
    assert abs(st["height"].item() - st0["height"].item()) < 0.5
    assert abs(st["airspeed"].item() - st0["airspeed"].item()) < 0.1
    assert abs(st["euler"][0, 0].item()) < 1e-3


def test_actuator_step_responses_match_analytic(ranger):
    """Second-order surfaces (w_n 10 rad/s, zeta 0.707), a first-order surface and the throttle
    lag, each against its closed-form step response; RK4 at dt 0.01 on these linear systems is
    accurate to ~1e-8 (tolerance 1e-6)."""
    sim = Simulator(ranger, dtype=torch.float64)
    sim.params.actuator_second_order[:, 1] = False  # aileron as first order, tau 0.05 s
    sim.params.actuator_time_constant[:, 1] = 0.05
    sim.reset({"surface_position": torch.zeros(1, 3), "throttle": torch.zeros(1)})
    u = torch.tensor([[0.5, -0.4, 0.0, 0.6]], dtype=torch.float64)
    p = sim.params
    target = p.surface_min + 0.5 * (u[:, :3] + 1) * (p.surface_max - p.surface_min)
    wn, zeta, tau_thr = 10.0, 1 / math.sqrt(2), ranger.motors[0].time_constant
    wd = wn * math.sqrt(1 - zeta**2)
    for k in range(1, 101):
        sim.step(u)
        t = k * sim.dt
        second = 1 - math.exp(-zeta * wn * t) * (math.cos(wd * t) + zeta / math.sqrt(1 - zeta**2)
                                                 * math.sin(wd * t))
        first = 1 - math.exp(-t / 0.05)
        thr = 0.8 * (1 - math.exp(-t / tau_thr))
        pos = sim.x[0, S.SURFACE_POSITION]
        assert float(pos[0]) == pytest.approx(float(target[0, 0]) * second, abs=1e-6)
        assert float(pos[1]) == pytest.approx(float(target[0, 1]) * first, abs=1e-6)
        assert float(sim.x[0, S.THROTTLE_START]) == pytest.approx(thr, abs=1e-6)


def test_actuators_saturate_at_limits(ranger):
    sim = Simulator(ranger)
    for _ in range(200):
        sim.step(torch.tensor([[1.0, -1.0, 1.0, 1.0]]))
    pos = sim.state["surface_position"][0]
    assert torch.all(pos <= sim.params.surface_max[0] + 1e-7)
    assert torch.all(pos >= sim.params.surface_min[0] - 1e-7)
    assert float(pos[0]) == pytest.approx(float(sim.params.surface_max[0, 0]), abs=1e-6)
    assert float(sim.state["throttle"][0, 0]) == pytest.approx(1.0, abs=1e-4)


def _doublet(k: int) -> float:
    t = k * 0.01
    return 0.15 if 1.0 <= t < 1.5 else (-0.15 if 1.5 <= t < 2.0 else 0.0)


def test_rk4_agrees_with_scipy_reference_over_5_s_doublet(ranger):
    """RK4 (dt 0.01, float64) against solve_ivp RK45 (rtol 1e-10) with an elevator doublet.
    The RK4 global error at this step is ~1e-7 on these time scales; tolerances 1e-4 m, 1e-5 m/s
    and 1e-6 rad leave a factor of 100 and fail on any model difference."""
    rk4 = Simulator(ranger, dtype=torch.float64)
    ref = Simulator(ranger, backend="scipy")
    trim_cmd = rk4.command.clone()
    for k in range(500):
        cmd = trim_cmd.clone()
        cmd[0, 0] += _doublet(k)
        rk4.step(cmd)
        ref.step(cmd)
    a, b = rk4.state, ref.state
    assert abs(a["height"].item() - b["height"].item()) < 1e-4
    assert abs(a["airspeed"].item() - b["airspeed"].item()) < 1e-5
    assert torch.allclose(a["euler"], b["euler"], atol=1e-6)
    # The doublet really moved the aircraft.
    assert abs(a["height"].item() - 100.0) > 0.5


def test_jacobians_match_finite_differences(navion):
    trim = trim_level(navion, 53.64, 50.0)
    lin = linearize(navion, trim)
    A_fd, B_fd = finite_difference_jacobians(navion, trim)
    scale_a = A_fd.abs().max()
    assert torch.allclose(lin.A, A_fd, atol=1e-6 * float(scale_a), rtol=1e-5)
    assert torch.allclose(lin.B, B_fd, atol=1e-6 * float(B_fd.abs().max()), rtol=1e-5)
    # Short-period pair of the Navion is stable and near Nelson's (about -2.5 +- 2.6j rad/s).
    i = S.STATE_INDEX
    idx = [i["velocity_body"][S.X], i["velocity_body"][S.Z], i["angular_rate_body"][S.PITCH],
           i["quaternion"][2]]  # u, w, q, quaternion y ~ theta/2
    eig = torch.linalg.eigvals(lin.A[idx][:, idx])
    fastest = eig[eig.real.argmin()]
    assert -4.5 < float(fastest.real) < -1.5 and abs(float(fastest.imag)) > 1.0


def test_masked_reset_touches_only_masked_rows(navion):
    sim = Simulator(navion, num_envs=6)
    for _ in range(50):
        sim.step(torch.full((6, 4), 0.3))
    before = sim.x.clone()
    mask = torch.tensor([True, False, True, False, False, True])
    sim.reset(mask=mask)
    assert torch.equal(sim.x[~mask], before[~mask])
    assert torch.allclose(sim.state["height"][mask], torch.full((3,), 100.0))


def test_bad_commands_raise_and_leave_state_untouched(navion):
    sim = Simulator(navion, num_envs=3)
    before = sim.x.clone()
    with pytest.raises(ValueError, match="shape"):
        sim.step(torch.zeros(3, 3))
    bad = torch.zeros(3, 4)
    bad[1, 2] = float("nan")
    with pytest.raises(ValueError, match=r"envs \[1\]"):
        sim.step(bad)
    assert torch.equal(sim.x, before)


def test_ground_contact_detected(ranger):
    sim = Simulator(ranger, num_envs=2)
    sim.reset({"height": torch.tensor([0.3, 5.0]), "euler": torch.tensor([[0.8, 0.0, 0.0],
                                                                           [0.0, 0.0, 0.0]])})
    contact = sim.state["ground_contact"]
    assert contact.tolist() == [True, False]  # a 0.81 m half-span at 46 deg bank hits from 0.3 m
