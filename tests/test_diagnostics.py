"""The engine's diagnostics (aero force and moment, thrust per motor, ground-effect h/b and influence
factors): parity between backends and agreement with the physics they summarise."""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl import Simulator
from falcon_rl.physics.atmosphere import isa_density
from falcon_rl.physics.derived import DERIVED_FIELDS

DIAGNOSTICS = ("aero_force_body", "aero_moment_body", "motor_thrust", "ge_h_over_b", "ge_lift_factor",
               "ge_drag_factor")


def flown(airframe: str, backend: str, height: float, ground_effect: bool | str = True) -> Simulator:
    """Three envs started at ``height`` m and flown 0.2 s under a mixed command."""
    sim = Simulator(airframe, num_envs=3, backend=backend, ground_effect=ground_effect, seed=3)
    sim.reset({"height": torch.tensor([height, height + 0.3, 40.0])})
    sim.step(torch.tensor([[0.05, 0.2, -0.1, 0.7]]).expand(3, 4), substeps=20)
    return sim


def test_diagnostics_are_declared():
    declared = {name for name, _ in DERIVED_FIELDS}
    assert set(DIAGNOSTICS) <= declared


@pytest.mark.parametrize("airframe", ["volantex_ranger", "airship_v7"])
def test_backends_agree(airframe):
    torch_state = flown(airframe, "torch", 0.5).state
    warp_state = flown(airframe, "warp", 0.5).state
    for name in DIAGNOSTICS:
        scale = torch_state[name].abs().max().clamp_min(1.0)
        assert torch.allclose(warp_state[name], torch_state[name], atol=2e-5 * scale), name


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_diagnostics_match_the_physics(backend):
    sim = flown("airship_v7", backend, 0.6)
    s = sim.state
    motors = sim.airframe.num_motors
    assert s["motor_thrust"].shape == (3, motors)
    assert torch.allclose(s["motor_thrust"].sum(-1), s["thrust"], rtol=1e-5)
    # The aero force is q S (C_X, C_Y, C_Z) with the lift and drag rotated from wind to body axes.
    geometry = sim.airframe.geometry
    qs = 0.5 * isa_density(s["height"]) * s["airspeed"] ** 2 * geometry.wing_area
    cl, cd, cy = s["aero_coefficients"][:, 0], s["aero_coefficients"][:, 1], s["aero_coefficients"][:, 2]
    ca, sa = torch.cos(s["alpha"]), torch.sin(s["alpha"])
    expected = torch.stack([-cd * ca + cl * sa, cy, -cd * sa - cl * ca], dim=-1) * qs[:, None]
    assert torch.allclose(s["aero_force_body"], expected, rtol=2e-3, atol=1e-3)
    moment = s["aero_coefficients"][:, 3:] * qs[:, None] * torch.tensor(
        [geometry.span, geometry.mean_chord, geometry.span])
    assert torch.allclose(s["aero_moment_body"], moment, rtol=2e-3, atol=1e-3)
    assert torch.allclose(s["ge_h_over_b"], s["wing_height"] / geometry.span)


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_ground_effect_indicators(backend):
    near = flown("volantex_ranger", backend, 0.4).state
    # Near the ground lift grows and induced drag falls; far above both ratios tend to 1.
    assert (near["ge_lift_factor"][:2] > 1.01).all() and (near["ge_drag_factor"][:2] < 0.99).all()
    assert math.isclose(float(near["ge_lift_factor"][2]), 1.0, abs_tol=1e-3)
    off = flown("volantex_ranger", backend, 0.4, ground_effect=False).state
    assert (off["ge_lift_factor"] == 1.0).all() and (off["ge_drag_factor"] == 1.0).all()
