"""Thrust-map propellers' gyroscopic and p-factor moments against closed forms, and torch against Warp.

The hand-made tabulated airframe of ``test_tabulated_aero`` gains a constant propeller angular momentum
(an "angular_momentum" thrust-map term) and a p-factor; the same airframe without them is the reference.
"""

from __future__ import annotations

import math

import pytest
import torch
from test_alpha_dot import assert_warp_derivative_matches_torch, random_states
from test_tabulated_aero import make_sim, parse, re_escape, tabulated_document

from falcon_rl.airframe import AirframeError
from falcon_rl.physics import state as S
from falcon_rl.physics.dynamics import derivative
from falcon_rl.physics.params import build_params
from falcon_rl.physics.propulsion import propulsion_forces

ANGULAR_MOMENTUM = 300.0  # N m s about the thrust axis
P_FACTOR = 0.15  # m of thrust-line shift per rad of inflow angle
N = 64


def propeller_document(angular_momentum: float = ANGULAR_MOMENTUM, p_factor: float = P_FACTOR) -> dict:
    doc = tabulated_document()
    doc["propulsion"]["thrust_map"].append(
        {"name": "spinning propeller", "output": "angular_momentum", "values": angular_momentum})
    motor = doc["propulsion"]["motors"][0]
    motor["p_factor_m_per_rad"] = p_factor
    motor["disk_area_m2"] = 2.8
    return doc


def moments(doc: dict, v_air: torch.Tensor, omega: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(moment [n, 3], thrust [n]) of the motors at air velocity [n, 3], body rates [n, 3], throttle 0.7,
    sea-level density."""
    n = v_air.shape[0]
    p = build_params(parse(doc), n, dtype=torch.float64)
    throttle = torch.full((n, 1), 0.7, dtype=torch.float64)
    density = torch.full((n,), 1.225, dtype=torch.float64)
    _, moment, thrust = propulsion_forces(v_air, throttle, density, p, omega)
    return moment, thrust[:, 0]


def test_gyroscopic_moment_is_h_cross_omega():
    """Thrust axis x, h = 300 N m s: a pitch rate q yaws by h q, a yaw rate r pitches by -h r."""
    v_air = torch.tensor([[40.0, 0.0, 0.0]] * 3, dtype=torch.float64)  # no in-plane inflow: no p-factor
    omega = torch.tensor([[0.0, 0.2, 0.0], [0.0, 0.0, -0.3], [0.5, 0.0, 0.0]], dtype=torch.float64)
    with_h, _ = moments(propeller_document(p_factor=0.0), v_air, omega)
    without, _ = moments(tabulated_document(), v_air, omega)
    expected = torch.tensor([[0.0, 0.0, ANGULAR_MOMENTUM * 0.2], [0.0, ANGULAR_MOMENTUM * 0.3, 0.0],
                             [0.0, 0.0, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(with_h - without, expected, rtol=1e-12, atol=1e-9)


def test_p_factor_shifts_the_thrust_line_by_the_inflow_angle():
    """At alpha the in-plane inflow is +z: M_z = -spin P T atan2(V sin a, V cos a + v_i), v_i from
    momentum theory over the disk; at sideslip beta (in-plane +y) the thrust line rises: M_y =
    -spin P T angle."""
    alpha = torch.tensor([0.05, 0.12, -0.08], dtype=torch.float64)
    speed = 35.0
    v_air = torch.stack([speed * torch.cos(alpha), torch.zeros(3, dtype=torch.float64),
                         speed * torch.sin(alpha)], -1)
    omega = torch.zeros(3, 3, dtype=torch.float64)
    with_p, thrust = moments(propeller_document(angular_momentum=0.0), v_air, omega)
    without, _ = moments(tabulated_document(), v_air, omega)
    v_axial = speed * torch.cos(alpha)
    induced = 0.5 * (-v_axial + torch.sqrt(v_axial**2 + 2 * thrust / (1.225 * 2.8)))
    angle = torch.atan2(speed * torch.sin(alpha).abs(), v_axial + induced)
    expected_yaw = -P_FACTOR * thrust * angle * torch.sign(alpha)
    torch.testing.assert_close((with_p - without)[:, 2], expected_yaw, rtol=1e-10, atol=1e-9)
    torch.testing.assert_close((with_p - without)[:, :2], torch.zeros(3, 2, dtype=torch.float64))
    assert (expected_yaw[:2] < -1.0).all()  # positive alpha, clockwise propeller: yaw left
    beta = 0.1
    sideslip = torch.tensor([[speed * math.cos(beta), speed * math.sin(beta), 0.0]], dtype=torch.float64)
    with_b, thrust_b = moments(propeller_document(angular_momentum=0.0), sideslip, omega[:1])
    without_b, _ = moments(tabulated_document(), sideslip, omega[:1])
    v_axial_b = speed * math.cos(beta)
    induced_b = 0.5 * (-v_axial_b + torch.sqrt(v_axial_b**2 + 2 * thrust_b / (1.225 * 2.8)))
    angle_b = torch.atan2(torch.tensor(speed * math.sin(beta), dtype=torch.float64), v_axial_b + induced_b)
    expected_b = torch.stack([torch.zeros(1, dtype=torch.float64), -P_FACTOR * thrust_b * angle_b,
                              torch.zeros(1, dtype=torch.float64)], -1)
    torch.testing.assert_close(with_b - without_b, expected_b, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("ge", ["tables", "off"])
def test_warp_derivative_matches_torch_with_propeller_moments(ge):
    pytest.importorskip("warp")
    sim = make_sim(parse(propeller_document()), N, "warp", ge, wind=[3.0, -2.0, 0.5])
    x = random_states(sim.layout.size, N, torch.Generator().manual_seed(6)).float()
    ref = assert_warp_derivative_matches_torch(sim, x, torch.zeros(N, 4))
    plain = make_sim(parse(tabulated_document()), N, "torch", ge, wind=[3.0, -2.0, 0.5])
    moved = (derivative(x, torch.zeros(N, 4), plain.params, plain.air) - ref)[:, S.ANGULAR_RATE]
    assert moved.abs().max() > 1e-2  # the propeller moments act


def test_p_factor_on_a_momentum_motor_is_refused():
    doc = propeller_document()
    doc["propulsion"]["motors"][0]["model"] = "momentum"
    del doc["propulsion"]["thrust_map"]
    with pytest.raises(AirframeError, match=re_escape("propulsion.motors[0].p_factor_m_per_rad")):
        parse(doc)


def test_zero_sideslip_trim_balances_the_p_factor_with_a_bank():
    """The p-factor's yaw moment: wings-level trim flies with sideslip, zero-sideslip trim (JSBSim's
    full trim) with a small bank instead; both null every acceleration, and without a p-factor the
    zero-sideslip trim of this symmetric airframe is wings level."""
    from falcon_rl.physics.trim import trim_level

    af = parse(propeller_document())
    level = trim_level(af, 40.0, 500.0, ground_effect="off")
    banked = trim_level(af, 40.0, 500.0, ground_effect="off", lateral="zero_sideslip")
    assert abs(float(level.beta[0])) > 1e-4 and level.bank is None
    assert banked.bank is not None and abs(float(banked.bank[0])) > 1e-4
    assert abs(float(banked.beta[0])) < 1e-9
    assert float(banked.residual[0]) < 1e-7
    symmetric = trim_level(parse(propeller_document(p_factor=0.0)), 40.0, 500.0, ground_effect="off",
                           lateral="zero_sideslip")
    assert symmetric.bank is not None
    torch.testing.assert_close(symmetric.alpha, level.alpha, rtol=0.0, atol=1e-3)
