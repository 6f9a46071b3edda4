"""Flight over the sea: a calm sea is the flat ground exactly, the two batch engines agree over waves, the
ground-effect slopes are the correlations' derivatives, a crest under the right tip rolls the aircraft left,
the Warp sine-cosine is accurate and the water ends an episode as "water_contact"."""

from __future__ import annotations

import math

import pytest
import torch
import warp as wp

from falcon_rl.physics import Simulator
from falcon_rl.physics._warp import init_warp, warp_available
from falcon_rl.physics.ground_effect import influence_ratios, wing_constants
from falcon_rl.physics.sea import sincos_wp

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


@wp.kernel(module="unique")
def sincos_kernel(x: wp.array(dtype=wp.float32), out: wp.array2d(dtype=wp.float32)):
    i = wp.tid()
    sc = sincos_wp(x[i])
    out[i, 0] = sc[0]
    out[i, 1] = sc[1]


@needs_warp
def test_the_warp_sine_cosine_is_accurate():
    init_warp()
    x = torch.linspace(-3000.0, 3000.0, 200_001)
    out = torch.zeros(x.shape[0], 2)
    wp.launch(sincos_kernel, dim=x.shape[0], inputs=[wp.from_torch(x), wp.from_torch(out)], device="cpu")
    exact = torch.stack([torch.sin(x.double()), torch.cos(x.double())], -1)
    assert float((out.double() - exact).abs().max()) < 2e-6


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
