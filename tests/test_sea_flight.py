"""Flight over the sea: a calm sea is the flat ground exactly, the two batch engines agree over waves, the
ground-effect slopes are the correlations' derivatives, a crest under the right tip rolls the aircraft left,
the Warp sine-cosine is accurate, the native sums over the components match torch (and compile for CUDA) and
the water ends an episode as "water_contact"."""

from __future__ import annotations

import math

import pytest
import torch
import warp as wp

from falcon_rl.physics import Simulator
from falcon_rl.physics._warp import init_warp, warp_available
from falcon_rl.physics.ground_effect import influence_ratios, wing_constants
from falcon_rl.physics.sea import SeaFieldWp
from falcon_rl.physics.sea_native import sea_sums_wp

needs_warp = pytest.mark.skipif(not warp_available(), reason="warp-lang is not installed")
HEIGHTS = torch.tensor([3.0, 5.0, 8.0, 20.0])


def fly(sim: Simulator, steps: int = 40) -> Simulator:
    sim.reset({"height": HEIGHTS, "euler": torch.tensor([[0.2, 0.02, 0.3]]).expand(4, 3)})
    command = torch.zeros(4, 4)
    command[:, 3] = 0.3
    for _ in range(steps):
        sim.step(command, 2)
    return sim


@pytest.mark.parametrize("backend", ["torch", pytest.param("warp", marks=needs_warp)])
def test_a_calm_sea_is_the_flat_ground_exactly(backend):
    flat = fly(Simulator("navion", 4, backend=backend, seed=1))
    calm = fly(Simulator("navion", 4, backend=backend, seed=1, model={"surface": "sea"}))
    assert torch.equal(flat.x, calm.x)
    state = calm.state
    assert torch.equal(state["surface_clearance"], state["height"]) and bool(state["over_water"].all())


@needs_warp
def test_the_engines_agree_over_a_sea():
    torch_sim = fly(Simulator("navion", 4, backend="torch", seed=3, sea=4))
    warp_sim = fly(Simulator("navion", 4, backend="warp", seed=3, sea=4))
    flat = fly(Simulator("navion", 4, backend="torch", seed=3))
    assert (torch_sim.x - flat.x).abs().max() > 1e-2  # the sea changed the flight
    torch.testing.assert_close(warp_sim.x, torch_sim.x, rtol=1e-4, atol=1e-3)
    torch.testing.assert_close(warp_sim.surface, torch_sim.surface, rtol=1e-3, atol=2e-3)


def test_ground_effect_slopes_are_the_derivatives():
    constants = wing_constants(torch.tensor(7.0, dtype=torch.float64), torch.tensor(0.6, dtype=torch.float64))
    x = torch.linspace(0.08, 1.5, 40, dtype=torch.float64)
    cl = torch.full_like(x, 0.6)
    _, _, slope_l, slope_d = influence_ratios(x, constants, cl, slopes=True)
    h = 1e-6
    up, down = influence_ratios(x + h, constants, cl), influence_ratios(x - h, constants, cl)
    torch.testing.assert_close(slope_l, (up[0] - down[0]) / (2 * h), rtol=1e-5, atol=1e-7)
    torch.testing.assert_close(slope_d, (up[1] - down[1]) / (2 * h), rtol=1e-5, atol=1e-7)
    assert bool((slope_l < 0).all()) and bool((slope_d > 0).all())


def test_a_crest_under_the_right_tip_rolls_the_aircraft_left():
    sim = Simulator("navion", 1, backend="torch", sea=3, dtype=torch.float64)
    sea = sim.sea
    sea.amplitude.zero_()
    sea.amplitude[0, 0] = 0.3  # one long wave travelling east, crest at the right tip (heading north)
    sea.wavenumber[0, 0], sea.frequency[0, 0] = 0.2, math.sqrt(9.80665 * 0.2)
    sea.direction_cos[0, 0], sea.direction_sin[0, 0] = 0.0, 1.0
    span = float(sim.params.span[0])
    sea.phase[0, 0] = -0.2 * 0.5 * span
    sim.reset({"height": torch.tensor([0.3 * span + 0.3])})
    crest = sim.state["aero_moment_body"][0, 0]
    sim.set_sea(None)
    sim.reset({"height": torch.tensor([0.3 * span + 0.3])})
    assert float(crest) < float(sim.state["aero_moment_body"][0, 0]) - 1.0


@needs_warp
@pytest.mark.parametrize("lanes", [8, 1])
def test_the_native_sine_cosine_is_accurate(lanes):
    """One unit component per env at phase x = north (the others zero): the root's elevation sum is cos x and
    its north slope -sin x, in the 8-lane blocks (8 components) and in the scalar tail (1)."""
    init_warp()
    x = torch.linspace(-3000.0, 3000.0, 20_001)
    n = x.shape[0]
    field = {name: torch.zeros(n, lanes) for name in ("amplitude", "wavenumber", "frequency", "direction_cos",
                                                      "direction_sin", "phase")}
    field["amplitude"][:, 0] = 1.0
    field["wavenumber"][:, 0] = 1.0
    field["direction_cos"][:, 0] = 1.0
    views = SeaFieldWp()
    for name, tensor in field.items():
        setattr(views, name, wp.from_torch(tensor))
    out = torch.zeros(n, 14)
    wp.launch(unit_sums_kernel, dim=n, inputs=[views, wp.from_torch(x), wp.from_torch(out)], device="cpu")
    exact = torch.stack([torch.cos(x.double()), -torch.sin(x.double())], -1)
    assert float((out[:, [2, 5]].double() - exact).abs().max()) < 2e-6


@wp.kernel(module="unique")
def unit_sums_kernel(sea: SeaFieldWp, x: wp.array(dtype=wp.float32), out: wp.array2d(dtype=wp.float32)):
    i = wp.tid()
    sums = sea_sums_wp(sea.amplitude, sea.wavenumber, sea.frequency, sea.direction_cos, sea.direction_sin,
                       sea.phase, i, x[i], 0.0, 0.0, 0.0, 0.0, 100.0, 0.1)
    for m in range(14):
        out[i, m] = sums[m]


@pytest.mark.parametrize("backend", ["torch", pytest.param("warp", marks=needs_warp)])
def test_the_water_stops_a_diving_aircraft(backend):
    sim = Simulator("navion", 4, backend=backend, seed=2, sea=5)
    sim.reset({"height": torch.full((4,), 4.0), "euler": torch.tensor([[0.0, -0.5, 0.0]]).expand(4, 3)})
    command = torch.zeros(4, 4)
    for _ in range(40):
        sim.step(command, 2)
    state = sim.state
    assert bool(state["crashed"].all()) and bool(state["water_contact"].all())
    assert not bool(state["ground_contact"].any())
    assert float(state["velocity_body"].abs().max()) == 0.0  # stopped on the water, not under the ground


@needs_warp
@pytest.mark.parametrize("components", [64, 67])
def test_the_native_sums_match_the_torch_sample(components):
    """The native sampler's 8-lane blocks (and, at 67 components, its scalar tail) give the torch sample."""
    samples = []
    for backend in ("torch", "warp"):
        sim = Simulator("navion", 4, backend=backend, seed=3, sea=4, sea_components=components)
        sim.reset({"height": HEIGHTS, "euler": torch.tensor([[0.3, 0.05, 1.1]]).expand(4, 3),
                   "position_ned": torch.tensor([[120.0, -45.0, 0.0]]).expand(4, 3)})
        samples.append(sim.surface.clone())
    assert torch.allclose(samples[0], samples[1], atol=2e-4, rtol=1e-4)
    assert float(samples[0][:, 0].abs().max()) > 0.05  # a real sea under them


@wp.kernel(module="unique")
def native_sums_kernel(sea: SeaFieldWp, out: wp.array2d(dtype=wp.float32)):
    i = wp.tid()
    sums = sea_sums_wp(sea.amplitude, sea.wavenumber, sea.frequency, sea.direction_cos, sea.direction_sin,
                       sea.phase, i, 10.0, 3.0, 0.5, 0.2, 1.0, 1.0, 0.1)
    for m in range(14):
        out[i, m] = sums[m]


@needs_warp
def test_the_native_sums_compile_for_cuda():
    """The snippet's CUDA path (one lane) compiles for sm_90 on any machine (NVRTC ships with Warp)."""
    init_warp()
    paths = wp.compile_aot_module(native_sums_kernel.module, arch=90)
    assert paths and paths[0].stat().st_size > 0
