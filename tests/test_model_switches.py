"""Model switches (``falcon_rl.physics.switches``): each simplified form against its analytic
expectation, torch-Warp parity with each switch on and off, mixed batches and spec errors.

Parity tolerances are those of ``test_warp_parity.py``: derivative components at rtol 1e-5 plus 1e-5
of each column's largest magnitude, 50 RK4 steps from perturbed cruise at 1e-3 m, 1e-5 (quaternion)
and 1e-4 m/s.
"""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl import Simulator
from falcon_rl.envs.factory import make_env
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import init_warp, warp_available
from falcon_rl.physics.actuators import command_targets
from falcon_rl.physics.aero import aero_forces
from falcon_rl.physics.atmosphere import RHO_SEA_LEVEL, isa_density
from falcon_rl.physics.dynamics import derivative, evaluate
from falcon_rl.physics.params import bind_warp_params, build_params, check_randomizable
from falcon_rl.physics.propulsion import propulsion_forces
from falcon_rl.physics.rotations import euler_to_quaternion
from falcon_rl.physics.switches import SWITCH_NAMES, ModelSwitches

BACKENDS = ("torch", "warp") if warp_available() else ("torch",)
needs_warp = pytest.mark.skipif(not warp_available(), reason="warp-lang is not installed")
#: One simplified form per switch, and the full model (None).
VARIANTS = (None, {"actuators": "ideal"}, {"throttle_lag": False}, {"atmosphere": "constant"},
            {"rate_damping": False}, {"propeller_torque": False})
FLAG_ROWS = ("ideal_actuators", "ideal_throttle", "constant_density", "no_rate_damping",
             "no_propeller_torque")

if warp_available():
    import warp as wp

    from falcon_rl.physics.warp_kernels import derivative_kernel


@pytest.fixture(scope="module", autouse=True)
def _warp_ready():
    if warp_available():
        init_warp()


def _with_torque(sim: Simulator) -> Simulator:
    """``sim`` with a propeller reaction torque (the shipped airframes have none): k_tp = 1e-4 N m s^2,
    k_omega = 300 rad/s, so Q = 9 N m at full throttle."""
    ones = torch.ones(sim.num_envs, dtype=torch.bool)
    sim.params.assign(ones, torque_coefficient=torch.tensor(1e-4), torque_speed_constant=torch.tensor(300.0))
    return sim


def _states(sim: Simulator, gen: torch.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """(state [N, S], command [N, 4]) around cruise at 20-3000 m, surfaces and commands past limits."""
    n, af = sim.num_envs, sim.airframe

    def u(lo: float, hi: float, *shape: int) -> torch.Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=gen)

    x = torch.zeros(n, sim.layout.size)
    x[:, 2] = -u(20.0, 3000.0, n)
    x[:, S.QUATERNION] = euler_to_quaternion(torch.stack([u(-1, 1, n), u(-0.5, 0.5, n), u(-3, 3, n)], -1))
    speed, alpha, beta = af.envelope.cruise_speed * u(0.6, 1.5, n), u(-0.2, 0.3, n), u(-0.2, 0.2, n)
    x[:, S.VELOCITY] = speed[:, None] * torch.stack(
        [torch.cos(alpha) * torch.cos(beta), torch.sin(beta), torch.sin(alpha) * torch.cos(beta)], -1)
    x[:, S.ANGULAR_RATE] = u(-1.0, 1.0, n, 3)
    lo, hi = sim.params.surface_min, sim.params.surface_max
    x[:, S.SURFACE_POSITION] = lo + (hi - lo) * u(-0.2, 1.2, n, 3)
    x[:, S.SURFACE_RATE] = u(-2.0, 2.0, n, 3)
    x[:, sim.layout.throttle] = u(0.0, 1.0, n, af.num_motors)
    return x, u(-1.3, 1.3, n, 4)


# --------------------------------------------------------------------------------------- the spec
def test_defaults_are_the_full_model_and_randomisable():
    p = build_params(Simulator("navion").airframe, 3)
    for row in FLAG_ROWS:
        assert torch.equal(getattr(p, row), torch.zeros(3, dtype=torch.int32)), row
        check_randomizable([row])  # domain randomisation may draw them per episode
    assert ModelSwitches.from_spec(None) == ModelSwitches()
    assert set(ModelSwitches(actuators="ideal", throttle_lag=False, atmosphere="constant", rate_damping=False,
                             propeller_torque=False, surface="sea").flags().values()) == {1}


@pytest.mark.parametrize("spec, match", [
    ({"actuators": "instant"}, "'actuators' must be one of"),
    ({"atmosphere": "standard"}, "'atmosphere' must be one of"),
    ({"throttle_lag": "no"}, "'throttle_lag' must be True or False"),
    ({"rate_damp": False}, "unknown model switches \\['rate_damp'\\]; switches: "),
    (3, "model must be None, a ModelSwitches or a mapping"),
])
def test_bad_specs_give_one_line_errors(spec, match):
    with pytest.raises(ValueError, match=match) as err:
        ModelSwitches.from_spec(spec)
    assert "\n" not in str(err.value)
    with pytest.raises(ValueError, match=match):
        Simulator("navion", model=spec)


def test_bad_set_model_leaves_the_params_alone():
    sim = Simulator("navion", 4)
    with pytest.raises(ValueError, match="unknown model switches"):
        sim.set_model(None, actuators="ideal", lag=False)
    assert int(sim.params.ideal_actuators.sum()) == 0


# ------------------------------------------------------------------------------ analytic expectations
@pytest.mark.parametrize("backend", BACKENDS)
def test_ideal_actuators_and_throttle_sit_on_the_command_after_one_step(backend):
    model = {"actuators": "ideal", "throttle_lag": False}
    sim = Simulator("volantex_ranger", 8, backend=backend, model=model)
    command = torch.linspace(-1.4, 1.4, 32).reshape(8, 4)
    sim.step(command)
    surfaces, throttle = command_targets(command, sim.params)
    surfaces = torch.minimum(torch.maximum(surfaces, sim.params.surface_min), sim.params.surface_max)
    torch.testing.assert_close(sim.x[:, S.SURFACE_POSITION], surfaces, rtol=0, atol=1e-7)
    assert torch.equal(sim.x[:, S.SURFACE_RATE], torch.zeros(8, 3))
    throttle = throttle[:, None].expand(8, sim.airframe.num_motors)
    torch.testing.assert_close(sim.x[:, sim.layout.throttle], throttle, rtol=0, atol=1e-7)
    derived = sim.state["surface_position"]
    torch.testing.assert_close(derived, surfaces, rtol=0, atol=1e-7)


def test_constant_density_is_sea_level_at_every_height():
    sim = Simulator("navion", 3, model={"atmosphere": "constant"})
    x = sim.x.clone()
    x[:, 2] = torch.tensor([0.0, -1000.0, -5000.0])
    ev = evaluate(x, sim.params)
    torch.testing.assert_close(ev.density, torch.full((3,), RHO_SEA_LEVEL), rtol=0, atol=0)
    torch.testing.assert_close(ev.density[1], isa_density(torch.tensor(0.0)), rtol=1e-6, atol=0)
    full = evaluate(x, build_params(sim.airframe, 3))
    assert full.density[1] < 0.91 * RHO_SEA_LEVEL  # ISA at 1 km: 0.907 of sea level
    drag_ratio = ev.aero_force_body[:, 0] / full.aero_force_body[:, 0]
    torch.testing.assert_close(drag_ratio, RHO_SEA_LEVEL / full.density, rtol=1e-5, atol=0)


def test_no_rate_damping_makes_the_aero_moment_independent_of_the_rates():
    af = Simulator("navion").airframe
    params = {flag: build_params(af, 2, switches={"rate_damping": flag}) for flag in (True, False)}
    zeros = torch.zeros(2)
    omega = torch.tensor([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])  # pure roll rate p = 1 rad/s
    moments = {flag: aero_forces(torch.full((2,), 50.0), zeros + 0.05, zeros, omega, torch.zeros(2, 3),
                                 torch.full((2,), 1.2), torch.full((2,), 10.0), p).moment_body
               for flag, p in params.items()}
    assert torch.equal(moments[False][0], moments[False][1])
    assert torch.equal(moments[False][0], moments[True][0])
    assert abs(float(moments[True][1, 0] - moments[True][0, 0])) > 1.0  # roll damping on: C_lp p b/2V


def test_no_propeller_torque_removes_the_moment_about_the_thrust_axis():
    af = Simulator("navion").airframe
    v_air, throttle, rho = torch.tensor([[40.0, 0.0, 2.0]]), torch.tensor([[0.8]]), torch.tensor([1.2])
    axial = {}
    for flag in (True, False):
        p = build_params(af, 1, switches={"propeller_torque": flag})
        p.assign(torch.ones(1, dtype=torch.bool), torque_coefficient=torch.tensor(1e-4),
                 torque_speed_constant=torch.tensor(300.0))
        _, moment, thrust = propulsion_forces(v_air, throttle, rho, p)
        assert float(thrust.sum()) > 0.0
        axial[flag] = float((moment * p.motor_axis[:, 0]).sum())  # r x F is normal to the axis
    assert abs(axial[False]) < 1e-4 and abs(axial[True]) > 1.0


# ----------------------------------------------------------------------------------------- parity
@needs_warp
@pytest.mark.parametrize("name", ("navion", "volantex_ranger"))
@pytest.mark.parametrize("model", VARIANTS)
def test_derivative_parity(name, model):
    sim = _with_torque(Simulator(name, 128, backend="warp", model=model, wind=[3.0, -2.0, 0.5]))
    x, command = _states(sim, torch.Generator().manual_seed(11))
    ref = derivative(x, command, sim.params, sim.air)
    out = torch.zeros_like(x)
    wp.launch(derivative_kernel, dim=128, inputs=[
        wp.from_torch(x), wp.from_torch(command, dtype=wp.vec4), wp.from_torch(sim.wind_ned, dtype=wp.vec3),
        wp.from_torch(sim.gust_velocity_body, dtype=wp.vec3),
        wp.from_torch(sim.gust_rate_body, dtype=wp.vec3), wp.from_torch(sim.surface),
        bind_warp_params(sim.params), wp.from_torch(out)],
        device="cpu")
    scale = ref.abs().amax(dim=0, keepdim=True).clamp_min(1e-6)
    excess = ((out - ref).abs() - 1e-5 * ref.abs() - 1e-5 * scale).max()
    assert excess <= 0, f"derivative differs beyond tolerance by {excess:.2e}"


@needs_warp
@pytest.mark.parametrize("model", VARIANTS)
def test_fifty_step_trajectory_parity(model):
    sims = [_with_torque(Simulator("navion", 32, backend=b, model=model)) for b in ("torch", "warp")]
    gen = torch.Generator().manual_seed(12)
    x = sims[0].x.clone()
    x[:, S.ANGULAR_RATE] = 0.1 * torch.randn(32, 3, generator=gen)
    command = (sims[0].command + 0.2 * torch.randn(32, 4, generator=gen)).clamp(-1.0, 1.0)
    for sim in sims:
        sim.reset(x)
    for _ in range(50):
        for sim in sims:
            sim.step(command)
    diff = (sims[1].x - sims[0].x).abs()
    assert diff[:, S.POSITION].max() < 1e-3
    assert diff[:, S.QUATERNION].max() < 1e-5
    assert diff[:, S.VELOCITY].max() < 1e-4
    assert diff[:, S.SURFACE_POSITION].max() < 1e-5


@pytest.mark.parametrize("backend", BACKENDS)
def test_mixed_batch_matches_a_batch_of_each_variant(backend):
    n = 16
    mask = torch.arange(n) % 2 == 0
    mixed = _with_torque(Simulator("volantex_ranger", n, backend=backend))
    mixed.set_model(mask, actuators="ideal", propeller_torque=False)
    assert torch.equal(mixed.params.ideal_actuators.bool(), mask)
    ablated = {"actuators": "ideal", "propeller_torque": False}
    pure = {True: _with_torque(Simulator("volantex_ranger", n, backend=backend, model=ablated)),
            False: _with_torque(Simulator("volantex_ranger", n, backend=backend))}
    gen = torch.Generator().manual_seed(13)
    x = mixed.x.clone()
    x[:, S.ANGULAR_RATE] = 0.2 * torch.randn(n, 3, generator=gen)
    command = (mixed.command + 0.3 * torch.randn(n, 4, generator=gen)).clamp(-1.0, 1.0)
    for sim in (mixed, *pure.values()):
        sim.reset(x)
        for _ in range(20):
            sim.step(command)
    assert torch.equal(mixed.x[mask], pure[True].x[mask])
    assert torch.equal(mixed.x[~mask], pure[False].x[~mask])
    assert not torch.equal(pure[True].x, pure[False].x)


def test_make_env_passes_the_model_through():
    env = make_env("altitude", num_envs=2, model={"actuators": "ideal", "atmosphere": "constant"})
    params = env.sim.params
    assert params.ideal_actuators.tolist() == [1, 1] and params.constant_density.tolist() == [1, 1]
    assert params.ideal_throttle.tolist() == [0, 0]
    assert SWITCH_NAMES == ("actuators", "throttle_lag", "atmosphere", "rate_damping", "propeller_torque",
                            "surface")
    assert math.isclose(RHO_SEA_LEVEL, 1.225, rel_tol=1e-3)


def test_domain_randomisation_draws_model_switches_per_episode():
    """RandomizationConfig(model_switches={"actuators": 0.5}) mixes ideal and dynamic actuators in one
    batch, redraws only the reset rows, and a probability outside [0, 1] or an unknown switch is a
    one-line error."""
    from falcon_rl.transforms import RandomizationConfig

    config = RandomizationConfig(model_switches={"actuators": 0.5, "throttle_lag": 1.0})
    env = make_env("altitude", "volantex_ranger", num_envs=64, backend="warp", seed=3, randomize=config)
    td = env.rand_step(env.reset())
    assert torch.isfinite(td["next", "observation"]).all()
    flags = env.base_env.physical_parameters(["ideal_actuators", "ideal_throttle"])
    assert 10 < int(flags["ideal_actuators"].sum()) < 54
    assert bool((flags["ideal_throttle"] == 1).all())
    mask = torch.zeros(64, dtype=torch.bool)
    mask[:8] = True
    before = flags["ideal_actuators"].clone()
    env.reset(td["next"].clone().set("_reset", mask.unsqueeze(-1)))
    after = env.base_env.physical_parameters(["ideal_actuators"])["ideal_actuators"]
    assert torch.equal(after[8:], before[8:])
    with pytest.raises(ValueError, match="probability"):
        RandomizationConfig(model_switches={"actuators": 1.5})
    with pytest.raises(ValueError, match="unknown switch"):
        RandomizationConfig(model_switches={"flaps": 0.5})
