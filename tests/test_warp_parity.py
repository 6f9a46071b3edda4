"""Parity of the Warp backend with the torch reference, component by component, in float32.

Inputs are random but seeded and cover the flight envelope and beyond: airspeed 0.5-1.6x cruise,
alpha and beta past the aero table's validity range (clamping), body rates up to 1.5 rad/s, wing
heights from 0.01 to 2 spans (ground effect active, including below the h/b = 0.05 clamp), surface
positions and throttles past their limits and commands outside [-1, 1] (saturated actuators), for both
shipped airframes and all three ground-effect modes.

Tolerances. Both sides compute in float32 (eps = 1.2e-7) but not with the same operation order: Warp
evaluates x^a as exp(a ln x) with a shared logarithm, accumulates the aero table term by term
(integer powers by products) and lets the compiler contract multiply-adds; torch uses pow and tensor
reductions. The observed differences are 1-2 ulps (up to 2e-7 relative to each output's magnitude),
so components are compared at rtol = 1e-5 plus an absolute floor of 1e-5 times the largest magnitude
of that output (a coefficient that nearly cancels inherits the rounding of its larger terms): 50x
above what is observed, far below any modelling difference (a wrong sign or missing term shows up at
1e-2 or more). One integrator step must agree to 2e-6 of each state component's scale (observed
2e-7). Over 1 s (100 RK4 steps) rounding differences are carried by the dynamics; observed 1e-5 m in
position, 1e-7 in the quaternion and 4e-6 m/s in velocity, tested at 1e-3 m, 1e-5 and 1e-4 m/s (100x
margin for other CPUs and CUDA's fused math, which round differently).
"""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl import Simulator, load_airframe
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import init_warp, warp_available, warp_cuda_available
from falcon_rl.physics.actuators import actuator_derivative
from falcon_rl.physics.aero import aero_forces, aero_forces_wp
from falcon_rl.physics.atmosphere import isa_density, isa_density_wp
from falcon_rl.physics.dynamics import air_data, derivative
from falcon_rl.physics.ground_effect import (
    WingConstants,
    phillips_hunsaker,
    phillips_hunsaker_wp,
    wing_constants,
)
from falcon_rl.physics.params import (
    EXPONENT_BITS,
    EXPONENT_MASK,
    WarpParams,
    bind_warp_params,
    build_params,
    pack_exponents,
)
from falcon_rl.physics.propulsion import motor_thrust, propulsion_forces, propulsion_forces_wp
from falcon_rl.physics.rotations import euler_to_quaternion, quat_from_warp, quat_to_warp, rotation_matrix

pytestmark = pytest.mark.skipif(not warp_available(), reason="warp-lang is not installed")

if warp_available():
    import warp as wp

    from falcon_rl.physics._warp import warp_device
    from falcon_rl.physics.actuators import actuator_derivative_wp
    from falcon_rl.physics.rotations import rotation_matrix_wp
    from falcon_rl.physics.state import StateVec
    from falcon_rl.physics.warp_kernels import derivative_kernel

    @wp.kernel
    def _atmosphere_kernel(h: wp.array(dtype=float), out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = isa_density_wp(h[i])

    @wp.kernel
    def _ground_effect_kernel(hb_cl: wp.array(dtype=wp.vec2), wing: wp.array(dtype=WingConstants),
                              out: wp.array(dtype=wp.vec2)):
        i = wp.tid()
        out[i] = phillips_hunsaker_wp(hb_cl[i][0], wing[i], hb_cl[i][1])

    @wp.kernel
    def _aero_kernel(air: wp.array(dtype=wp.vec3), omega: wp.array(dtype=wp.vec3),
                     surfaces: wp.array(dtype=wp.vec3), rho_hb: wp.array(dtype=wp.vec2), p: WarpParams,
                     out: wp.array2d(dtype=float)):
        i = wp.tid()
        a = air[i]
        r = aero_forces_wp(a[0], a[1], a[2], omega[i], surfaces[i], rho_hb[i][0],
                                         rho_hb[i][1], p, i)
        for k in range(3):
            out[i, k] = r.force_body[k]
            out[i, 3 + k] = r.moment_body[k]
        for k in range(6):
            out[i, 6 + k] = r.coefficients[k]
        out[i, 12] = r.induced_drag_coefficient
        out[i, 13] = r.kappa_lift
        out[i, 14] = r.kappa_drag

    @wp.kernel
    def _propulsion_kernel(v_air: wp.array(dtype=wp.vec3), x: wp.array2d(dtype=float),
                           rho: wp.array(dtype=float), p: WarpParams, out: wp.array2d(dtype=float)):
        i = wp.tid()
        s = StateVec()
        for k in range(x.shape[1]):
            s[k] = x[i, k]
        r = propulsion_forces_wp(v_air[i], s, rho[i], p, i)
        for k in range(3):
            out[i, k] = r.force_body[k]
            out[i, 3 + k] = r.moment_body[k]
        out[i, 6] = r.thrust

    @wp.kernel
    def _actuator_kernel(x: wp.array2d(dtype=float), command: wp.array(dtype=wp.vec4), p: WarpParams,
                         out: wp.array2d(dtype=float)):
        i = wp.tid()
        s = StateVec()
        for k in range(x.shape[1]):
            s[k] = x[i, k]
        d = actuator_derivative_wp(s, command[i], p, i)
        for k in range(x.shape[1]):
            out[i, k] = d[k]

    @wp.kernel
    def _quaternion_kernel(q: wp.array(dtype=wp.vec4), mine: wp.array(dtype=wp.mat33),
                           theirs: wp.array(dtype=wp.mat33), back: wp.array(dtype=wp.vec4)):
        i = wp.tid()
        mine[i] = rotation_matrix_wp(q[i])
        wq = quat_to_warp(q[i])
        theirs[i] = wp.quat_to_matrix(wq)
        back[i] = quat_from_warp(wq)


AIRFRAMES = ("navion", "volantex_ranger")
GE_MODES = (True, "paper", False)
N = 256
_REPORT = False


@pytest.fixture(scope="module", autouse=True)
def _warp_ready():
    init_warp()


def _close(name: str, actual: torch.Tensor, expected: torch.Tensor, rtol: float = 1e-5,
           floor: float = 1e-5) -> None:
    """|a - e| <= rtol |e| + floor * max|e| per column (floor scales with the output's magnitude)."""
    scale = expected.abs().amax(dim=0, keepdim=True).clamp_min(1e-6) if expected.dim() > 1 else (
        expected.abs().max().clamp_min(1e-6))
    err = (actual - expected).abs()
    bound = rtol * expected.abs() + floor * scale
    worst = (err - bound).max()
    if _REPORT:
        print(name, f"{(err / (expected.abs() + scale)).max():.1e}")
    assert torch.isfinite(actual).all(), f"{name}: non-finite warp output"
    assert worst <= 0, f"{name}: max error {err.max():.3e} exceeds tolerance (excess {worst:.3e})"


def _random_states(sim: Simulator, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """(state [N, S], command [N, 4]) spread over and past the envelope, low heights included."""
    n = sim.num_envs
    af = sim.airframe
    cruise = af.envelope.cruise_speed

    def u(lo: float, hi: float, *shape: int) -> torch.Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=gen)

    x = torch.zeros(n, sim.layout.size)
    x[:, 0:2] = u(-500.0, 500.0, n, 2)
    wing_h = af.geometry.span * torch.exp(u(math.log(0.01), math.log(2.0), n))
    x[:, 2] = -(wing_h + 0.5)
    high = torch.rand(n, generator=gen) < 0.25
    x[high, 2] = -u(50.0, 3000.0, int(high.sum()))
    euler = torch.stack([u(-1.2, 1.2, n), u(-0.6, 0.6, n), u(-math.pi, math.pi, n)], dim=-1)
    x[:, S.QUATERNION] = euler_to_quaternion(euler)
    speed = cruise * u(0.5, 1.6, n)
    alpha, beta = u(-0.5, 0.6, n), u(-0.5, 0.5, n)
    x[:, 7] = speed * torch.cos(alpha) * torch.cos(beta)
    x[:, 8] = speed * torch.sin(beta)
    x[:, 9] = speed * torch.sin(alpha) * torch.cos(beta)
    x[:, S.ANGULAR_RATE] = u(-1.5, 1.5, n, 3)
    lo, hi = sim.params.surface_min.cpu(), sim.params.surface_max.cpu()
    x[:, S.SURFACE_POSITION] = lo + (hi - lo) * u(-0.2, 1.2, n, 3)
    x[:, S.SURFACE_RATE] = u(-2.0, 2.0, n, 3)
    x[:, sim.layout.throttle] = u(-0.1, 1.1, n, af.num_motors)
    command = u(-1.3, 1.3, n, 4)
    return x, command


def _sim(name: str, ge: bool | str = True, n: int = N, device: str = "cpu", backend: str = "warp",
         **kw) -> Simulator:
    return Simulator(name, num_envs=n, backend=backend, ground_effect=ge, device=device, **kw)


def _launch(kernel, n: int, inputs: list, device: str = "cpu") -> None:
    wp.launch(kernel, dim=n, inputs=inputs, device=device)


def test_quaternion_convention_matches_warp_quat():
    """Our (w, x, y, z) DCM equals Warp's quat_to_matrix after the boundary conversion."""
    gen = torch.Generator().manual_seed(0)
    q = torch.randn(64, 4, generator=gen)
    q = q / q.norm(dim=-1, keepdim=True)
    mine, theirs = torch.zeros(64, 3, 3), torch.zeros(64, 3, 3)
    back = torch.zeros(64, 4)
    _launch(_quaternion_kernel, 64, [wp.from_torch(q, dtype=wp.vec4), wp.from_torch(mine, dtype=wp.mat33),
                                     wp.from_torch(theirs, dtype=wp.mat33),
                                     wp.from_torch(back, dtype=wp.vec4)])
    torch.testing.assert_close(mine, rotation_matrix(q), rtol=0, atol=1e-6)
    torch.testing.assert_close(theirs, mine, rtol=0, atol=1e-6)
    torch.testing.assert_close(back, q, rtol=0, atol=0)


def test_atmosphere():
    h = torch.cat([torch.linspace(-1500.0, 25000.0, 997), torch.tensor([0.0, 11000.0, 10999.0])])
    out = torch.zeros_like(h)
    _launch(_atmosphere_kernel, h.numel(), [wp.from_torch(h), wp.from_torch(out)])
    _close("density", out, isa_density(h), rtol=2e-6, floor=0.0)


@pytest.mark.parametrize("name", AIRFRAMES)
def test_ground_effect_factors(name):
    g = load_airframe(name).geometry
    hb = torch.exp(torch.linspace(math.log(0.005), math.log(3.0), 200)).repeat(5)
    cl = torch.tensor([0.0, 0.3, -0.4, 1.2, 1e-4]).repeat_interleave(200)
    ar, tr = torch.full_like(hb, g.aspect_ratio), torch.full_like(hb, g.taper_ratio)
    out = torch.zeros(hb.numel(), 2)
    wing = wing_constants(ar, tr).contiguous()
    _launch(_ground_effect_kernel, hb.numel(),
            [wp.from_torch(torch.stack([hb, cl], -1).contiguous(), dtype=wp.vec2),
             wp.from_torch(wing, dtype=WingConstants), wp.from_torch(out, dtype=wp.vec2)])
    kappa_l, kappa_d = phillips_hunsaker(hb, ar, tr, cl)
    _close("kappa", out, torch.stack([kappa_l, kappa_d], -1), rtol=1e-5, floor=0.0)


@pytest.mark.parametrize("name", AIRFRAMES)
@pytest.mark.parametrize("ge", GE_MODES)
def test_aero_forces_and_moments(name, ge):
    sim = _sim(name, ge, backend="torch")
    gen = torch.Generator().manual_seed(1)
    x, _ = _random_states(sim, gen)
    airspeed, alpha, beta = air_data(x[:, S.VELOCITY])
    omega = x[:, S.ANGULAR_RATE].contiguous()
    surfaces = torch.minimum(torch.maximum(x[:, S.SURFACE_POSITION], sim.params.surface_min),
                             sim.params.surface_max).contiguous()
    rho = isa_density(-x[:, 2])
    hb = torch.exp(torch.linspace(math.log(0.01), math.log(2.0), N))
    ref = aero_forces(airspeed, alpha, beta, omega, surfaces, rho, hb, sim.params)
    out = torch.zeros(N, 15)
    _launch(_aero_kernel, N, [wp.from_torch(torch.stack([airspeed, alpha, beta], -1), dtype=wp.vec3),
                              wp.from_torch(omega, dtype=wp.vec3), wp.from_torch(surfaces, dtype=wp.vec3),
                              wp.from_torch(torch.stack([rho, hb], -1), dtype=wp.vec2),
                              bind_warp_params(sim.params), wp.from_torch(out)])
    _close("aero force", out[:, 0:3], ref.force_body)
    _close("aero moment", out[:, 3:6], ref.moment_body)
    _close("coefficients", out[:, 6:12], ref.coefficients)
    _close("induced drag", out[:, 12], ref.induced_drag_coefficient)
    _close("kappa_L", out[:, 13], ref.kappa_lift, rtol=1e-5, floor=0.0)
    _close("kappa_D", out[:, 14], ref.kappa_drag, rtol=1e-5, floor=0.0)


@pytest.mark.parametrize("name", AIRFRAMES)
def test_thrust_and_propulsion(name):
    sim = _sim(name, backend="torch")
    gen = torch.Generator().manual_seed(2)
    x, _ = _random_states(sim, gen)
    v_air = x[:, S.VELOCITY].contiguous()
    rho = isa_density(-x[:, 2])
    throttle = x[:, sim.layout.throttle]
    force, moment, thrust = propulsion_forces(v_air, throttle, rho, sim.params)
    assert torch.equal(thrust, motor_thrust(v_air, throttle, rho, sim.params))
    out = torch.zeros(N, 7)
    _launch(_propulsion_kernel, N, [wp.from_torch(v_air, dtype=wp.vec3), wp.from_torch(x),
                                    wp.from_torch(rho), bind_warp_params(sim.params), wp.from_torch(out)])
    _close("thrust", out[:, 6], thrust.sum(-1))
    _close("propulsion force", out[:, 0:3], force)
    _close("propulsion moment", out[:, 3:6], moment)
    assert (thrust == 0).any() and (thrust > 0).any(), "cover both idle/windmilling and thrusting"


@pytest.mark.parametrize("name", AIRFRAMES)
def test_actuator_derivative_saturated(name):
    """Mixed first/second order actuators, commands past +-1 and positions past the limits."""
    params = build_params(load_airframe(name), N)
    params.actuator_second_order[: N // 2] = ~params.actuator_second_order[: N // 2]
    params.actuator_time_constant[:] = 0.05
    sim = _sim(name, backend="torch")
    gen = torch.Generator().manual_seed(3)
    x, command = _random_states(sim, gen)
    d_pos, d_rate, d_thr = actuator_derivative(x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE],
                                               x[:, S.THROTTLE_START:], command, params)
    out = torch.zeros_like(x)
    _launch(_actuator_kernel, N, [wp.from_torch(x), wp.from_torch(command, dtype=wp.vec4),
                                  bind_warp_params(params), wp.from_torch(out)])
    _close("surface rate of change", out[:, S.SURFACE_POSITION], d_pos)
    _close("surface acceleration", out[:, S.SURFACE_RATE], d_rate)
    _close("throttle rate", out[:, S.THROTTLE_START:], d_thr)


@pytest.mark.parametrize("name", AIRFRAMES)
@pytest.mark.parametrize("ge", GE_MODES)
def test_full_derivative(name, ge):
    sim = _sim(name, ge, wind=[4.0, -3.0, 1.0])
    gen = torch.Generator().manual_seed(4)
    x, command = _random_states(sim, gen)
    sim.gust_velocity_body[:] = torch.randn(N, 3, generator=gen)
    sim.gust_rate_body[:] = 0.1 * torch.randn(N, 3, generator=gen)
    ref = derivative(x, command, sim.params, sim.air)
    out = torch.zeros_like(x)
    _launch(derivative_kernel, N, [wp.from_torch(x), wp.from_torch(command, dtype=wp.vec4),
                                   wp.from_torch(sim.wind_ned, dtype=wp.vec3),
                                   wp.from_torch(sim.gust_velocity_body, dtype=wp.vec3),
                                   wp.from_torch(sim.gust_rate_body, dtype=wp.vec3),
                                   wp.from_torch(sim.surface),
                                   bind_warp_params(sim.params), wp.from_torch(out)])
    _close("derivative", out, ref)


def _pair(name: str, ge: bool | str, integrator: str, device: str = "cpu", n: int = N
          ) -> tuple[Simulator, Simulator, torch.Tensor]:
    sims = [_sim(name, ge, n=n, device=device, backend=b, integrator=integrator, wind=[3.0, 2.0, 0.0])
            for b in ("torch", "warp")]
    gen = torch.Generator().manual_seed(5)
    x, command = _random_states(sims[0], gen)
    for sim in sims:
        sim.reset(x.to(device))
    return sims[0], sims[1], command.to(device)


@pytest.mark.parametrize("name", AIRFRAMES)
@pytest.mark.parametrize("integrator", ["rk4", "euler"])
def test_one_step(name, integrator):
    ref, sim, command = _pair(name, True, integrator)
    ref.step(command)
    sim.step(command)
    scale = ref.x.abs().amax(dim=0).clamp_min(1.0)
    err = ((sim.x - ref.x).abs() / scale).max()
    if _REPORT:
        print("step", name, integrator, f"{err:.1e}")
    assert err < 2e-6, f"one {integrator} step differs by {err:.2e} (relative to the state's scale)"
    assert torch.all(sim.x[:, sim.layout.throttle] <= 1.0) and torch.all(sim.x[:, 3] >= 0.0)


def _trajectory_check(ref: Simulator, sim: Simulator, command: torch.Tensor, steps: int = 100) -> None:
    for _ in range(steps):
        ref.step(command)
        sim.step(command)
    cruise = ref.airframe.envelope.cruise_speed
    # compare only envs still flying (a ground strike is where both models stop being meaningful)
    alive = (-ref.x[:, 2] > 0.0) & (ref.x[:, S.VELOCITY].norm(dim=-1) < 3.0 * cruise)
    assert alive.sum() >= ref.num_envs // 4
    diff = (sim.x - ref.x).abs()[alive]
    if _REPORT:
        print("traj", ref.airframe.name, [f"{diff[:, sl].max():.1e}" for sl in
                                          (S.POSITION, S.QUATERNION, S.VELOCITY, S.ANGULAR_RATE)])
    assert diff[:, S.POSITION].max() < 1e-3, f"position {diff[:, S.POSITION].max():.2e} m"
    assert diff[:, S.QUATERNION].max() < 1e-5, f"quaternion {diff[:, S.QUATERNION].max():.2e}"
    assert diff[:, S.VELOCITY].max() < 1e-4, f"velocity {diff[:, S.VELOCITY].max():.2e} m/s"
    assert torch.isfinite(sim.x).all()


def _perturbed_cruise(ref: Simulator, sim: Simulator, seed: int = 6) -> torch.Tensor:
    """Reset both to trimmed cruise perturbed at low height (ground effect on) with body-rate kicks;
    returns random held commands near trim. Trajectories start inside the aero table's range: from
    the random states past the envelope of the component tests, alpha/beta clamp kinks straddled by
    RK4 stages amplify 1-ulp differences (measured: 1 Ranger env in ~600 drifts by 1-3 cm over 1 s,
    on CPU and CUDA alike, while every derivative along its path agrees to 1e-5)."""
    n = ref.num_envs
    gen = torch.Generator().manual_seed(seed)
    x = ref.x.clone().cpu()
    x[:, 2] = -(0.15 + 0.5 * torch.rand(n, generator=gen)) * ref.airframe.geometry.span - 0.3
    x[:, S.ANGULAR_RATE] = 0.1 * torch.randn(n, 3, generator=gen)
    command = (ref.command.cpu() + 0.1 * torch.randn(n, 4, generator=gen)).clamp(-1.0, 1.0)
    for s in (ref, sim):
        s.reset(x.to(s.device))
    return command.to(ref.device)


@pytest.mark.parametrize("name", AIRFRAMES)
@pytest.mark.parametrize("ge", GE_MODES)
def test_one_second_trajectory(name, ge):
    """100 RK4 steps from trimmed cruise perturbed at low height, random held commands."""
    ref, sim = (_sim(name, ge, n=64, backend=b) for b in ("torch", "warp"))
    _trajectory_check(ref, sim, _perturbed_cruise(ref, sim))


def test_domain_randomisation_is_seen_without_rebinding():
    """A masked parameter write (ModelParams.assign) reaches the next launch; so does a new dt."""
    ref, sim, command = _pair("volantex_ranger", True, "rk4", n=32)
    mask = torch.arange(32) % 2 == 0
    for s in (ref, sim):
        s.params.assign(mask, mass=torch.tensor(3.1), inertia=s.params.inertia * 1.3)
        s.dt = 0.02
        s.step(command)
    err = ((sim.x - ref.x).abs() / ref.x.abs().amax(dim=0).clamp_min(1.0)).max()
    assert err < 2e-6


def test_randomised_wing_reaches_the_ground_effect_constants():
    """Assigning aspect or taper ratio refreshes the precomputed wing constants, so both backends
    fly the randomised wing (and agree), and the constants equal a fresh computation."""
    ref, sim, command = _pair("navion", True, "rk4", n=32)
    mask = torch.arange(32) % 3 == 0
    for s in (ref, sim):
        s.x[:, 2] = -0.2 * s.airframe.geometry.span  # deep in ground effect
        before = s.params.wing_constants.clone()
        s.params.assign(mask, aspect_ratio=torch.tensor(4.0), taper_ratio=torch.tensor(0.3))
        expected = wing_constants(s.params.aspect_ratio, s.params.taper_ratio)
        assert torch.allclose(s.params.wing_constants, expected)
        assert not torch.allclose(s.params.wing_constants[mask], before[mask])
        assert torch.equal(s.params.wing_constants[~mask], before[~mask])
        for _ in range(5):
            s.step(command)
    err = ((sim.x - ref.x).abs() / ref.x.abs().amax(dim=0).clamp_min(1.0)).max()
    assert err < 1e-5
    assert torch.allclose(sim.time, ref.time) and torch.allclose(sim.time, torch.full((32,), 5 * sim.dt))


def test_warp_step_restores_the_callers_floating_point_mode():
    """The CPU kernel flushes denormals while it runs (they cost a third of a step on trimmed,
    symmetric states) and restores the caller's mode: gradual underflow still works afterwards."""
    import numpy as np

    sim = Simulator("navion", num_envs=8, backend="warp")
    sim.step(sim.command.clone())
    tiny = np.float32(1e-38) * np.float32(1e-3)
    assert tiny != 0.0 and torch.tensor(1e-38) * 1e-3 != 0.0


def test_exponent_codes_unpack_to_the_table():
    exponents = build_params(load_airframe("navion"), 1).aero_exponents
    codes = pack_exponents(exponents)
    assert codes.dtype == torch.int32 and codes.shape == (exponents.shape[0],)
    unpacked = torch.stack([(codes >> (EXPONENT_BITS * j)) & EXPONENT_MASK for j in range(5)], -1)
    assert torch.equal(unpacked.long(), exponents)
    with pytest.raises(ValueError, match=r"\[0, 7\]"):
        pack_exponents(torch.tensor([[8, 0, 0, 0, 0]]))


def test_warp_backend_rejects_float64():
    with pytest.raises(ValueError, match="float32"):
        Simulator("navion", backend="warp", dtype=torch.float64)


@pytest.mark.gpu
@pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA (torch and warp)")
@pytest.mark.parametrize("name", AIRFRAMES)
def test_one_second_trajectory_cuda(name):
    """Warp on CUDA against torch on CUDA, 1,024 envs, as the CPU trajectory test."""
    ref, sim = (_sim(name, True, n=1024, device="cuda", backend=b) for b in ("torch", "warp"))
    assert warp_device(sim.device).startswith("cuda")
    _trajectory_check(ref, sim, _perturbed_cruise(ref, sim))


@pytest.mark.parametrize("name", AIRFRAMES)
def test_state_fields_match_torch(name):
    """``Simulator.state`` on warp (one evaluation kernel) equals the torch evaluation, field by field,
    on random states over and past the envelope, with wind and gusts."""
    ref, sim, _ = _pair(name, True, "rk4", n=256)
    gen = torch.Generator().manual_seed(9)
    for s in (ref, sim):
        s.gust_velocity_body.copy_(2.0 * torch.randn(256, 3, generator=gen))
        s.gust_rate_body.copy_(0.1 * torch.randn(256, 3, generator=gen))
        gen.manual_seed(9)
    a, b = ref.state, sim.state
    assert set(a.keys()) == set(b.keys())
    for key in sorted(a.keys()):  # (iterating a TensorDict walks its batch, not its keys)
        assert a[key].shape == b[key].shape and a[key].dtype == b[key].dtype, key
        if a[key].dtype == torch.bool:
            assert torch.equal(a[key], b[key]), key
        else:
            _close(key, b[key], a[key])
