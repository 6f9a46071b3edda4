"""The tabulated aero kind and the thrust map: schema, analytic values, clamping, torch-Warp parity.

A hand-made tabulated airframe (the Navion's geometry, mass and actuators) carries 1-3D tables over
alpha, h/b, Mach, elevator and throttle plus a thrust map; a second one re-expresses the linear part of
the Navion's monomial model as tables, which must give the same coefficients.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from falcon_rl import Simulator, load_airframe
from falcon_rl.airframe import AERO_VARIABLES, AirframeError, parse_airframe
from falcon_rl.airframe_terms import TABLE_VARIABLES
from falcon_rl.physics import state as S
from falcon_rl.physics._warp import init_warp, wp
from falcon_rl.physics.aero import aero_forces, table_variables
from falcon_rl.physics.dynamics import derivative
from falcon_rl.physics.ground_effect import GE_MODES
from falcon_rl.physics.interpolated_terms import has_terms, table_outputs
from falcon_rl.physics.params import bind_warp_params, build_params
from falcon_rl.physics.propulsion import motor_thrust

N = 256


def navion_document() -> dict:
    return json.loads(load_airframe("navion").path.read_text())


def linear_documents() -> tuple[dict, dict]:
    """(monomial, tabulated) documents of the Navion's constant and linear monomials and its rates."""
    mono = navion_document()
    tab = copy.deepcopy(mono)
    tables = []
    for cname, entry in mono["aero"]["coefficients"].items():
        kept = [t for t in entry["terms"] if sum(t.get(v, 0) for v in AERO_VARIABLES) <= 1]
        entry["terms"] = kept
        for t in kept:
            var = next((v for v in AERO_VARIABLES if t.get(v, 0)), None)
            if var is None:
                tables.append({"output": cname, "values": t["coef"]})
            else:  # c x as a two-point table over [-2, 2]: exact inside
                tables.append(
                    {
                        "output": cname,
                        "axes": [{"variable": var, "breakpoints": [-2.0, 2.0]}],
                        "values": [-2.0 * t["coef"], 2.0 * t["coef"]],
                    }
                )
        tab["aero"]["coefficients"][cname]["terms"] = []
    tab["aero"]["kind"] = "tabulated"
    tab["aero"]["tables"] = tables
    return mono, tab


def tabulated_document() -> dict:
    """The Navion's linear model as tables plus ground-effect, 3-D, throttle and rate terms, a thrust map."""
    doc = linear_documents()[1]
    hb = [0.0, 0.1, 0.2, 0.5, 1.1]
    doc["aero"]["tables"] += [
        {
            "name": "kCL",
            "output": "CL",
            "axes": [
                {"variable": "alpha", "breakpoints": [-0.1, 0.0, 0.2, 0.3]},
                {"variable": "h_over_b", "breakpoints": hb},
            ],
            "values": [[0.1 * a * (1.1 - h) for h in hb] for a in (-1.0, 0.0, 2.0, 1.5)],
        },
        {
            "name": "CDge",
            "output": "CD",
            "axes": [{"variable": "h_over_b", "breakpoints": hb}],
            "values": [-0.01, -0.006, -0.003, -0.001, 0.0],
        },
        {
            "name": "Cm3d",
            "output": "Cm",
            "multiply": {"q": 1},
            "axes": [
                {"variable": "alpha", "breakpoints": [-0.2, 0.0, 0.3]},
                {"variable": "mach", "breakpoints": [0.0, 0.1, 0.3]},
                {"variable": "elevator", "breakpoints": [-0.3, 0.0, 0.3]},
            ],
            "values": (np.arange(27.0).reshape(3, 3, 3) * -0.1 - 1.0).tolist(),
        },
        {
            "name": "wash",
            "output": "Cm",
            "multiply": {"elevator": 1},
            "axes": [
                {"variable": "airspeed", "breakpoints": [10.0, 30.0, 60.0]},
                {"variable": "throttle", "breakpoints": [0.0, 1.0]},
            ],
            "values": [[0.0, -0.3], [0.0, -0.1], [0.0, -0.05]],
        },
    ]
    doc["aero"]["moment_reference_m"] = [-0.3, 0.02, 0.1]  # the warp and torch twins both transfer it
    speeds, throttles, densities = [0.0, 20.0, 40.0, 70.0], [0.0, 0.5, 1.0], [0.8, 1.225]
    doc["propulsion"]["thrust_map"] = [
        {
            "name": "thrust",
            "output": "thrust",
            "axes": [
                {"variable": "airspeed", "breakpoints": speeds},
                {"variable": "throttle", "breakpoints": throttles},
                {"variable": "density", "breakpoints": densities},
            ],
            "values": [
                [[2500.0 * t * (1 - v / 90) * d / 1.225 for d in densities] for t in throttles]
                for v in speeds
            ],
        },
        {
            "name": "torque",
            "output": "torque",
            "gain": -1.0,
            "axes": [{"variable": "throttle", "breakpoints": throttles}],
            "values": [0.0, 200.0, 500.0],
        },
    ]
    doc["propulsion"]["motors"][0]["model"] = "thrust_map"
    return doc


def parse(doc: dict, name: str = "tabulated"):
    return parse_airframe(doc, Path(f"{name}.json"))


def make_sim(af, n: int, backend: str, ge: str, **kw) -> Simulator:
    """A simulator in ground-effect mode ``ge`` (the facade's default trim does not know mode "tables"
    yet, so that mode is set after construction)."""
    sim = Simulator(af, num_envs=n, backend=backend, ground_effect="off" if ge == "tables" else ge, **kw)
    sim.params.assign(torch.ones(n, dtype=torch.bool), ground_effect_mode=torch.tensor(GE_MODES[ge]))
    return sim


def random_inputs(airframe, n: int, gen: torch.Generator) -> dict[str, torch.Tensor]:
    def u(lo, hi, *shape):
        return lo + (hi - lo) * torch.rand(*shape, generator=gen, dtype=torch.float64)

    lo, hi = airframe.aero.alpha_range
    return {
        "airspeed": u(15.0, 70.0, n),
        "alpha": u(lo, hi, n),
        "beta": u(*airframe.aero.beta_range, n),
        "omega_air": u(-1.0, 1.0, n, 3),
        "surfaces": u(-0.3, 0.3, n, 3),
        "density": u(0.7, 1.225, n),
        "h_over_b": u(0.02, 1.5, n),
    }


def test_tables_reproduce_the_linear_monomial_model():
    mono_doc, tab_doc = linear_documents()
    mono, tab = parse(mono_doc, "mono"), parse(tab_doc)
    gen = torch.Generator().manual_seed(0)
    inputs = random_inputs(mono, N, gen)
    for ge in ("off", "induced"):
        ref = aero_forces(**inputs, p=build_params(mono, N, dtype=torch.float64, ground_effect=ge))
        out = aero_forces(**inputs, p=build_params(tab, N, dtype=torch.float64, ground_effect=ge))
        torch.testing.assert_close(out.coefficients, ref.coefficients, rtol=1e-12, atol=1e-12)
        torch.testing.assert_close(out.force_body, ref.force_body, rtol=1e-10, atol=1e-9)


def test_table_values_interpolate_multilinearly_and_clamp_at_the_edges():
    af = parse(tabulated_document())
    p = build_params(af, 4, dtype=torch.float64, ground_effect="tables")
    x = torch.zeros(4, len(TABLE_VARIABLES), dtype=torch.float64)
    x[:, 0] = torch.tensor([0.1, -0.5, 0.9, 0.25], dtype=torch.float64)  # alpha: in cells, below, above
    x[:, 10] = torch.tensor([0.15, 0.0, 5.0, 0.35], dtype=torch.float64)  # h/b
    # All other terms read alpha only linearly (or not at all) at zero deflections, rates and throttle.
    linear = build_params(parse(linear_documents()[1]), 4, dtype=torch.float64)
    cl = table_outputs(x, p)[:, 0] - table_outputs(x, linear)[:, 0]

    def exact(
        a: float, h: float
    ) -> float:  # bilinear in a cell of a product's table: exact (np.interp clamps)
        return 0.1 * float(np.interp(a, [-0.1, 0.0, 0.2, 0.3], [-1.0, 0.0, 2.0, 1.5])) * (1.1 - min(h, 1.1))

    expected = [exact(0.1, 0.15), exact(-0.5, 0.0), exact(0.9, 5.0), exact(0.25, 0.35)]
    torch.testing.assert_close(cl, torch.tensor(expected, dtype=torch.float64), rtol=1e-12, atol=1e-12)


def test_ground_effect_tables_read_h_over_b_only_in_mode_tables():
    af = parse(tabulated_document())
    gen = torch.Generator().manual_seed(1)
    inputs = random_inputs(af, N, gen)
    inputs["h_over_b"] = torch.full((N,), 0.1, dtype=torch.float64)
    far = dict(inputs, h_over_b=torch.full((N,), 50.0, dtype=torch.float64))
    tables = build_params(af, N, dtype=torch.float64, ground_effect="tables")
    off = build_params(af, N, dtype=torch.float64, ground_effect="off")
    near = aero_forces(**inputs, p=tables).coefficients
    free = aero_forces(**far, p=tables).coefficients
    torch.testing.assert_close(aero_forces(**inputs, p=off).coefficients, free)
    assert (near[:, 1] < free[:, 1]).all()  # the CDge table lowers drag at h/b = 0.1
    assert not torch.allclose(near[:, 0], free[:, 0])


def test_monomial_airframes_carry_one_padding_term_and_no_output():
    p = build_params(load_airframe("navion"), 2)
    assert p.table_index.shape[0] == 1 and not has_terms(p, 0, 8)
    assert torch.count_nonzero(table_outputs(torch.randn(2, len(TABLE_VARIABLES)), p)) == 0


def test_thrust_map_reads_the_table_at_the_axial_inflow():
    af = parse(tabulated_document())
    p = build_params(af, 3, dtype=torch.float64)
    v_air = torch.tensor([[20.0, 0.0, 0.0], [40.0, 3.0, 2.0], [100.0, 0.0, 0.0]], dtype=torch.float64)
    throttle = torch.tensor([[0.5], [1.0], [1.0]], dtype=torch.float64)
    density = torch.tensor([1.225, 0.8, 1.225], dtype=torch.float64)
    thrust = motor_thrust(v_air, throttle, density, p)[:, 0]
    expected = [2500 * 0.5 * (1 - 20 / 90), 2500 * (1 - 40 / 90) * 0.8 / 1.225, 2500 * (1 - 70 / 90)]
    torch.testing.assert_close(thrust, torch.tensor(expected, dtype=torch.float64))


@pytest.mark.parametrize("ge", ["tables", "induced", "off"])
def test_warp_derivative_matches_torch(ge):
    pytest.importorskip("warp")
    from falcon_rl.physics.warp_kernels import derivative_kernel

    init_warp()
    af = parse(tabulated_document())
    sim = make_sim(af, N, "warp", ge, wind=[3.0, -2.0, 0.5])
    gen = torch.Generator().manual_seed(2)
    x = torch.zeros(N, sim.layout.size)
    x[:, 2] = -(0.2 + 12.0 * torch.rand(N, generator=gen))
    x[:, 3] = 1.0
    x[:, S.VELOCITY] = torch.tensor([35.0, 0.0, 2.0]) + 6.0 * torch.randn(N, 3, generator=gen)
    x[:, S.ANGULAR_RATE] = 0.5 * torch.randn(N, 3, generator=gen)
    x[:, S.SURFACE_POSITION] = 0.4 * torch.rand(N, 3, generator=gen) - 0.2
    x[:, sim.layout.throttle] = 1.2 * torch.rand(N, 1, generator=gen) - 0.1
    command = 2.0 * torch.rand(N, 4, generator=gen) - 1.0
    ref = derivative(x, command, sim.params, sim.air)
    out = torch.zeros_like(x)
    wp.launch(
        derivative_kernel,
        dim=N,
        device="cpu",
        inputs=[
            wp.from_torch(x),
            wp.from_torch(command, dtype=wp.vec4),
            wp.from_torch(sim.wind_ned, dtype=wp.vec3),
            wp.from_torch(sim.gust_velocity_body, dtype=wp.vec3),
            wp.from_torch(sim.gust_rate_body, dtype=wp.vec3),
            wp.from_torch(sim.surface),
            bind_warp_params(sim.params),
            wp.from_torch(out),
        ],
    )
    scale = ref.abs().amax(dim=0, keepdim=True).clamp_min(1e-6)
    assert ((out - ref).abs() <= 1e-5 * ref.abs() + 2e-5 * scale).all()


def fly_one_second_on_both_backends(doc: dict, elevator: float) -> tuple[torch.Tensor, torch.Tensor]:
    """States [8, S] of the torch and warp simulators of airframe document ``doc`` after 1 s (100 steps)
    from trim at heights 1-8 m under a fixed command with ``elevator``."""
    af = parse(doc)
    sims = [make_sim(af, 8, b, "tables") for b in ("torch", "warp")]
    start = sims[0].x.clone()
    start[:, 2] = -torch.linspace(1.0, 8.0, 8)
    command = torch.tensor([[elevator, 0.05, -0.05, 0.6]]).repeat(8, 1)
    for sim in sims:
        sim.reset(start)
        for _ in range(100):
            sim.step(command)
    return sims[0].x, sims[1].x


def test_one_second_torch_and_warp_agree():
    pytest.importorskip("warp")
    torch_x, warp_x = fly_one_second_on_both_backends(tabulated_document(), 0.1)
    assert (torch_x - warp_x).abs().max() < 1e-3


def test_table_variables_put_mach_from_the_density():
    x = table_variables(
        *(torch.zeros(1, dtype=torch.float64),) * 2,
        torch.zeros(1, 3, dtype=torch.float64),
        torch.zeros(1, 3, dtype=torch.float64),
        torch.tensor([340.294], dtype=torch.float64),
        torch.tensor([1.225], dtype=torch.float64),
        torch.zeros(1, dtype=torch.float64),
        torch.zeros(1, dtype=torch.float64),
    )
    assert math.isclose(float(x[0, 8]), 1.0, rel_tol=1e-4)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["aero"]["tables"][0].update(output="CX"), "aero.tables[0].output"),
        (lambda d: d["aero"]["tables"][-1]["axes"][0].update(breakpoints=[0.0, 0.0, 1.0]), "aero.tables["),
        (lambda d: d["aero"]["tables"][-1].update(values=[1.0]), ".values"),
        (lambda d: d["aero"].update(kind="spline"), "aero.kind"),
        (lambda d: d["propulsion"]["motors"][0].update(model="rocket"), "propulsion.motors[0].model"),
    ],
)
def test_bad_tables_name_the_field(edit, field):
    doc = tabulated_document()
    edit(doc)
    with pytest.raises(AirframeError, match=re_escape(field)):
        parse(doc)


def re_escape(text: str) -> str:
    import re

    return re.escape(text)


def test_aero_moment_is_transferred_from_the_moment_reference_point():
    """M_cg = M_ref + r x F: moving the reference point changes the moment by exactly r x F."""
    from falcon_rl.physics.aero import aero_forces
    from falcon_rl.physics.params import build_params

    doc = tabulated_document()
    ref = torch.tensor([-0.3, 0.02, 0.1], dtype=torch.float64)
    doc["aero"]["moment_reference_m"] = [0.0, 0.0, 0.0]
    at_cg = build_params(parse(doc), 3, dtype=torch.float64)
    at_ref = build_params(parse(tabulated_document()), 3, dtype=torch.float64)
    args = (torch.tensor([30.0, 40.0, 50.0], dtype=torch.float64), torch.tensor([0.05, 0.1, -0.02],
            dtype=torch.float64), torch.tensor([0.0, 0.05, -0.1], dtype=torch.float64),
            torch.full((3, 3), 0.1, dtype=torch.float64), torch.full((3, 3), 0.05, dtype=torch.float64),
            torch.full((3,), 1.2, dtype=torch.float64), torch.full((3,), 100.0, dtype=torch.float64))
    a, b = aero_forces(*args, at_cg), aero_forces(*args, at_ref)
    torch.testing.assert_close(b.force_body, a.force_body)
    transfer = torch.linalg.cross(ref.expand(3, 3), a.force_body)
    torch.testing.assert_close(b.moment_body - a.moment_body, transfer)
