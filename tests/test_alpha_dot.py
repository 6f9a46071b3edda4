"""Alpha-dot table terms: the closed-form solve against analytic cases, finite differences and Warp.

The hand-made tabulated airframe of ``test_tabulated_aero`` gains a lift term C_L += CLad(alpha) alpha_dot
c/2V and a pitch term C_m += Cmad alpha_dot c/2V; the same airframe without them is the reference.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from test_tabulated_aero import (
    fly_one_second_on_both_backends,
    make_sim,
    parse,
    re_escape,
    tabulated_document,
)

from falcon_rl.airframe import AirframeError
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import init_warp, wp
from falcon_rl.physics.atmosphere import isa_density
from falcon_rl.physics.dynamics import air_data, derivative
from falcon_rl.physics.interpolated_terms import has_alpha_dot_terms
from falcon_rl.physics.params import bind_warp_params, build_params

N = 64
STATE_SIZE = S.THROTTLE_START + 1  # one motor
CMAD = -9.0  # Cm per unit alpha_dot c/2V (the c172p's is -7.27)
CLAD_TABLE = ([-0.2, 0.0, 0.3], [2.0, 3.0, 1.0])  # CL per unit alpha_dot c/2V over alpha


def alpha_dot_document(clad: tuple[list[float], list[float]] = CLAD_TABLE, cmad: float = CMAD) -> dict:
    doc = tabulated_document()
    doc["aero"]["tables"] += [
        {"name": "CLadot", "output": "CL", "multiply": {"alpha_dot": 1},
         "axes": [{"variable": "alpha", "breakpoints": clad[0]}], "values": clad[1]},
        {"name": "Cmadot", "output": "Cm", "multiply": {"alpha_dot": 1}, "values": cmad},
    ]
    return doc


def random_states(size: int, n: int, gen: torch.Generator) -> torch.Tensor:
    x = torch.zeros(n, size, dtype=torch.float64)
    x[:, 2] = -(20.0 + 100.0 * torch.rand(n, generator=gen, dtype=torch.float64))
    q = torch.tensor([1.0, 0.0, 0.0, 0.0]) + 0.2 * torch.randn(n, 4, generator=gen, dtype=torch.float64)
    x[:, S.QUATERNION] = q / q.norm(dim=-1, keepdim=True)
    x[:, S.VELOCITY] = torch.tensor([40.0, 0.0, 2.0]) + 5.0 * torch.randn(n, 3, generator=gen,
                                                                             dtype=torch.float64)
    x[:, S.ANGULAR_RATE] = 0.4 * torch.randn(n, 3, generator=gen, dtype=torch.float64)
    x[:, S.SURFACE_POSITION] = 0.3 * torch.rand(n, 3, generator=gen, dtype=torch.float64) - 0.15
    x[:, S.THROTTLE_START] = torch.rand(n, generator=gen, dtype=torch.float64)
    return x


def test_only_airframes_with_alpha_dot_terms_solve_it():
    assert has_alpha_dot_terms(build_params(parse(alpha_dot_document()), 1))
    assert not has_alpha_dot_terms(build_params(parse(tabulated_document()), 1))


@pytest.mark.parametrize("ge", ["tables", "induced"])
def test_the_solved_alpha_dot_is_the_rate_of_alpha_the_derivative_sets(ge):
    """v_dot(with) = v_dot(without) + ad qS CL_ad [sin a, 0, -cos a] / m with ad = c/2V d(alpha)/dt, the
    alpha rate measured by central differences of alpha along the derivative; likewise the pitch
    acceleration gains I^-1 (qS c Cm_ad ad e_y + r_ref x F_1)."""
    with_terms = build_params(parse(alpha_dot_document()), N, dtype=torch.float64, ground_effect=ge)
    without = build_params(parse(tabulated_document()), N, dtype=torch.float64, ground_effect=ge)
    gen = torch.Generator().manual_seed(3)
    x = random_states(STATE_SIZE, N, gen)
    command = torch.zeros(N, 4, dtype=torch.float64)
    xdot = derivative(x, command, with_terms)
    h = 1e-5
    alpha_plus = air_data((x + h * xdot)[:, S.VELOCITY])[1]
    alpha_minus = air_data((x - h * xdot)[:, S.VELOCITY])[1]
    alpha_rate = (alpha_plus - alpha_minus) / (2 * h)
    airspeed, alpha, _ = air_data(x[:, S.VELOCITY])
    ad = alpha_rate * with_terms.chord / (2 * airspeed)
    qs = 0.5 * isa_density(-x[:, 2]) * airspeed**2 * with_terms.wing_area
    clad_at = torch.from_numpy(np.interp(alpha.numpy(), *CLAD_TABLE))
    force_1 = torch.stack([torch.sin(alpha), torch.zeros_like(alpha), -torch.cos(alpha)], -1) * (
        qs * clad_at)[:, None]
    reference = derivative(x, command, without)
    expected_v_dot = reference[:, S.VELOCITY] + ad[:, None] * force_1 / with_terms.mass[:, None]
    torch.testing.assert_close(xdot[:, S.VELOCITY], expected_v_dot, rtol=1e-7, atol=1e-7)
    moment_1 = torch.zeros_like(force_1)
    moment_1[:, 1] = qs * with_terms.chord * CMAD
    moment_1 = moment_1 + torch.linalg.cross(with_terms.aero_reference, force_1, dim=-1)
    expected_w_dot = reference[:, S.ANGULAR_RATE] + ad[:, None] * (
        with_terms.inertia_inv @ moment_1.unsqueeze(-1)).squeeze(-1)
    torch.testing.assert_close(xdot[:, S.ANGULAR_RATE], expected_w_dot, rtol=1e-7, atol=1e-7)
    assert (ad.abs() > 1e-4).float().mean() > 0.5  # the check is not vacuous


def test_alpha_dot_lift_adds_the_effective_mass_of_z_wdot():
    """At alpha = beta = 0 (u = V, w = 0) alpha_dot = w_dot / V and a constant C_L_ad gives
    Z_wdot = -rho S c C_L_ad / 4, so w_dot = w_dot_0 / (1 + rho S c C_L_ad / (4 m)) exactly."""
    clad = 30.0
    doc = alpha_dot_document(clad=([-1.0, 1.0], [clad, clad]), cmad=0.0)
    with_terms = build_params(parse(doc), 3, dtype=torch.float64, ground_effect="off")
    without = build_params(parse(tabulated_document()), 3, dtype=torch.float64, ground_effect="off")
    x = torch.zeros(3, STATE_SIZE, dtype=torch.float64)
    x[:, 2] = -500.0
    x[:, 3] = 1.0
    x[:, S.VELOCITY_START] = torch.tensor([30.0, 45.0, 60.0], dtype=torch.float64)
    x[:, S.ANGULAR_RATE_START + 1] = torch.tensor([0.2, -0.1, 0.0], dtype=torch.float64)
    x[:, S.SURFACE_POSITION_START] = torch.tensor([0.05, -0.1, 0.0], dtype=torch.float64)
    x[:, S.THROTTLE_START] = 0.5
    command = torch.zeros(3, 4, dtype=torch.float64)
    w_dot = derivative(x, command, with_terms)[:, S.VELOCITY_START + 2]
    w_dot_0 = derivative(x, command, without)[:, S.VELOCITY_START + 2]
    density = isa_density(torch.tensor(500.0, dtype=torch.float64))
    factor = 1 + density * with_terms.wing_area * with_terms.chord * clad / (4 * with_terms.mass)
    torch.testing.assert_close(w_dot, w_dot_0 / factor, rtol=1e-4, atol=1e-9)
    assert (factor > 1.02).all() and (w_dot_0.abs() > 1.0).all()


def test_no_rate_damping_drops_the_alpha_dot_terms():
    doc = alpha_dot_document()
    switches = {"rate_damping": False}
    with_terms = build_params(parse(doc), N, dtype=torch.float64, switches=switches)
    without = build_params(parse(tabulated_document()), N, dtype=torch.float64, switches=switches)
    x = random_states(STATE_SIZE, N, torch.Generator().manual_seed(4))
    command = torch.zeros(N, 4, dtype=torch.float64)
    torch.testing.assert_close(derivative(x, command, with_terms), derivative(x, command, without))


@pytest.mark.parametrize("ge", ["tables", "induced"])
def test_warp_derivative_matches_torch_with_alpha_dot_terms(ge):
    pytest.importorskip("warp")
    sim = make_sim(parse(alpha_dot_document()), N, "warp", ge, wind=[3.0, -2.0, 0.5])
    x = random_states(sim.layout.size, N, torch.Generator().manual_seed(5)).float()
    command = torch.zeros(N, 4)
    ref = assert_warp_derivative_matches_torch(sim, x, command)
    plain = derivative(x, command, make_sim(parse(tabulated_document()), N, "torch", ge,
                                            wind=[3.0, -2.0, 0.5]).params, sim.air)
    assert (plain - ref)[:, S.ANGULAR_RATE].abs().max() > 1e-2  # the alpha-dot terms act


def assert_warp_derivative_matches_torch(sim, x: torch.Tensor, command: torch.Tensor) -> torch.Tensor:
    """The Warp derivative kernel against ``dynamics.derivative`` at float32 states x [N, S] of a Warp
    simulator; returns the torch derivative."""
    from falcon_rl.physics.warp_kernels import derivative_kernel

    init_warp()
    ref = derivative(x, command, sim.params, sim.air)
    out = torch.zeros_like(x)
    wp.launch(derivative_kernel, dim=x.shape[0], device="cpu",
              inputs=[wp.from_torch(x), wp.from_torch(command, dtype=wp.vec4),
                      wp.from_torch(sim.wind_ned, dtype=wp.vec3),
                      wp.from_torch(sim.gust_velocity_body, dtype=wp.vec3),
                      wp.from_torch(sim.gust_rate_body, dtype=wp.vec3), wp.from_torch(sim.surface),
                      bind_warp_params(sim.params),
                      wp.from_torch(out)])
    scale = ref.abs().amax(dim=0, keepdim=True).clamp_min(1e-6)
    assert ((out - ref).abs() <= 1e-5 * ref.abs() + 2e-5 * scale).all()
    return ref


def test_one_second_torch_and_warp_agree_with_alpha_dot_terms():
    pytest.importorskip("warp")
    torch_x, warp_x = fly_one_second_on_both_backends(alpha_dot_document(), 0.3)
    assert (torch_x - warp_x).abs().max() < 1e-3


LAST = len(alpha_dot_document()["aero"]["tables"]) - 1


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["aero"]["tables"][LAST].update(multiply={"alpha_dot": 2}),
         f"aero.tables[{LAST}].multiply.alpha_dot"),
        (lambda d: d["aero"]["tables"][LAST].update(
            axes=[{"variable": "alpha_dot", "breakpoints": [0.0, 1.0]}], values=[0.0, 1.0]),
         f"aero.tables[{LAST}].axes[0].variable"),
        (lambda d: d["propulsion"]["thrust_map"][1].update(multiply={"alpha_dot": 1}),
         "propulsion.thrust_map[1].multiply.alpha_dot"),
    ],
)
def test_alpha_dot_outside_a_linear_aero_multiplier_is_refused(edit, field):
    doc = copy.deepcopy(alpha_dot_document())
    edit(doc)
    with pytest.raises(AirframeError, match=re_escape(field)) as info:
        parse(doc)
    assert "alpha_dot" in str(info.value) and "tabulated.json" in str(info.value)
