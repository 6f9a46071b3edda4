"""The parameter table: ModelParams, build_params, WarpParams and bind_warp_params all follow it."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from falcon_rl import load_airframe
from falcon_rl.airframe import SURFACES
from falcon_rl.physics._warp import init_warp, warp_available, wp
from falcon_rl.physics.ground_effect import wing_constants
from falcon_rl.physics.param_schema import (
    BuildOptions,
    Derivation,
    ParamRow,
    bind_warp,
    build_values,
    check_table,
    make_container,
    make_warp_struct,
    warp_annotation,
)
from falcon_rl.physics.params import (
    PARAMETER_TABLE,
    RANDOMIZABLE_PARAMETERS,
    WARP_EXTRAS,
    WARP_TYPES,
    ModelParams,
    WarpParams,
    bind_warp_params,
    build_params,
    check_randomizable,
    parameter_table_markdown,
    table_sizes,
)
from falcon_rl.transforms.randomize import _FIELDS as RANDOMIZED_TODAY

needs_warp = pytest.mark.skipif(not warp_available(), reason="warp-lang is not installed")
N = 3

# The table plus one synthetic source row and one row derived from it: nothing else is declared.
EXTENDED_TABLE = (
    *PARAMETER_TABLE,
    ParamRow("drag_area", "[N, M]", lambda af, _: [0.01 * (k + 1) for k in range(af.num_motors)],
             randomizable=True, unit="m^2", doc="synthetic test row"),
    ParamRow("drag_area_total", "[N]", Derivation(("drag_area",), lambda d: d.sum(-1)), unit="m^2"),
)
ExtendedParams = make_container(EXTENDED_TABLE, "ExtendedParams", header="Test container.", module=__name__)
ExtendedWarpParams = make_warp_struct(EXTENDED_TABLE, WARP_EXTRAS, "ExtendedWarpParams", doc="Test struct.",
                                      module=__name__, custom=WARP_TYPES)

if warp_available():
    @wp.kernel
    def _read_extended(p: ExtendedWarpParams, out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = p.drag_area[i, 0] * p.mass[i] + p.drag_area_total[i] + float(p.num_motors)


@pytest.fixture(scope="module")
def navion_params():
    return build_params(load_airframe("navion"), N, ground_effect="paper", gravity=9.81)


def _warp_shape(array) -> tuple[int, ...]:
    """The torch shape of a Warp array: its dimensions, then its element's."""
    return tuple(array.shape) + tuple(getattr(array.dtype, "_shape_", ()))


def test_every_row_is_a_model_params_field_with_its_shape(navion_params):
    names = [row.name for row in PARAMETER_TABLE]
    assert [f.name for f in dataclasses.fields(ModelParams)] == names
    assert list(vars(navion_params)) == names
    sizes = table_sizes(load_airframe("navion"), N)
    for row in PARAMETER_TABLE:
        tensor = getattr(navion_params, row.name)
        assert tuple(tensor.shape) == row.resolve(sizes), row.name
        assert tensor.is_contiguous(), row.name
    assert navion_params.per_env_fields() == [row.name for row in PARAMETER_TABLE if row.per_env]
    assert navion_params.num_envs == N


@needs_warp
def test_every_warp_row_is_a_warp_params_field_with_matching_shape(navion_params):
    init_warp()
    warp_rows = [row.name for row in PARAMETER_TABLE if row.warp is not None]
    assert list(WarpParams.vars) == warp_rows + [extra.name for extra in WARP_EXTRAS]
    bound = bind_warp_params(navion_params)
    for name in warp_rows:
        tensor = getattr(navion_params, name)
        assert _warp_shape(getattr(bound, name)) == tuple(tensor.shape), name
        assert getattr(bound, name).ptr == tensor.data_ptr(), f"{name} is not zero-copy"
    assert bound.num_terms == navion_params.aero_exponents.shape[0]
    assert bound.num_motors == navion_params.motor_spin.shape[1] == 1


def test_build_params_matches_the_airframe_by_hand(navion_params):
    af = load_airframe("navion")
    p = navion_params

    def rep(value, dtype=torch.float32):
        return torch.as_tensor(value, dtype=torch.float64).to(dtype).expand(N, *torch.as_tensor(value).shape)

    assert torch.equal(p.mass, rep(af.mass))
    assert torch.equal(p.inertia, rep(af.inertia))
    assert torch.allclose(p.inertia_inv @ p.inertia, torch.eye(3).expand(N, 3, 3), atol=1e-6)
    assert torch.equal(p.chord, rep(af.geometry.mean_chord))
    assert torch.equal(p.gravity, rep(9.81))
    assert torch.equal(p.ground_effect_mode, torch.full((N,), 2, dtype=torch.int32))
    assert torch.equal(p.aero_coefficients, rep(af.aero.coefficients))
    assert torch.equal(p.thrust_coefficient, rep([af.motors[0].thrust_coefficient]))
    assert torch.equal(p.motor_position, rep([af.motors[0].position]))
    assert torch.equal(p.motor_spin, rep([float(af.motors[0].spin)]))
    assert all(af.actuators[s].order == 2 for s in SURFACES)  # navion: second-order surfaces
    assert torch.equal(p.actuator_second_order, torch.ones(N, 3, dtype=torch.bool))
    assert torch.equal(p.actuator_time_constant, torch.ones(N, 3))  # 1 where unused
    assert torch.equal(p.surface_max, rep([af.actuators[s].limits[1] for s in SURFACES]))
    assert torch.equal(p.aero_exponents, torch.as_tensor(af.aero.exponents, dtype=torch.long))
    expected = wing_constants(torch.tensor(af.geometry.aspect_ratio, dtype=torch.float64),
                              torch.tensor(af.geometry.taper_ratio, dtype=torch.float64))
    assert torch.equal(p.wing_constants, rep(expected))
    p.mass[0] = 1.0  # each env owns its copy
    assert p.mass[1] == torch.tensor(af.mass, dtype=torch.float32)
    p.mass[0] = p.mass[1]


def test_to_casts_floats_only(navion_params):
    q = navion_params.to(dtype=torch.float64)
    assert type(q) is ModelParams
    assert q.mass.dtype == torch.float64 and q.ground_effect_mode.dtype == torch.int32
    assert q.actuator_second_order.dtype == torch.bool and q.aero_exponents.dtype == torch.long
    assert torch.equal(q.mass.float(), navion_params.mass)


def test_assign_refreshes_derived_rows_on_the_mask_only():
    p = build_params(load_airframe("navion"), N)
    before = {name: getattr(p, name).clone() for name in ("inertia_inv", "wing_constants")}
    mask = torch.tensor([True, False, True])
    p.assign(mask, inertia=p.inertia * 2.0, aspect_ratio=torch.tensor(4.0))
    assert torch.allclose(p.inertia_inv[mask], before["inertia_inv"][mask] / 2.0)
    assert torch.allclose(p.wing_constants, wing_constants(p.aspect_ratio, p.taper_ratio))
    assert torch.equal(p.inertia_inv[~mask], before["inertia_inv"][~mask])
    assert torch.equal(p.wing_constants[~mask], before["wing_constants"][~mask])
    p.assign(mask, taper_ratio=torch.tensor(0.3))  # one input is enough to refresh
    assert torch.allclose(p.wing_constants, wing_constants(p.aspect_ratio, p.taper_ratio))
    with pytest.raises(KeyError):
        p.assign(mask, aero_exponents=p.aero_exponents)  # shared, not assignable
    with pytest.raises(KeyError):
        p.assign(mask, no_such_parameter=torch.tensor(1.0))


def test_randomisable_rows():
    assert set(RANDOMIZED_TODAY) <= set(RANDOMIZABLE_PARAMETERS)
    rows = {row.name: row for row in PARAMETER_TABLE}
    for name in ("mass", "inertia", "wing_area", "span", "chord", "aspect_ratio", "taper_ratio", "oswald",
                 "aero_coefficients", "aero_rates", "thrust_coefficient", "discharge_speed",
                 "throttle_time_constant", "actuator_damping"):
        assert name in RANDOMIZABLE_PARAMETERS
    for name in ("inertia_inv", "wing_constants", "ground_effect_mode", "aero_exponents"):
        assert name not in RANDOMIZABLE_PARAMETERS
    assert all(not rows[name].derived for name in RANDOMIZABLE_PARAMETERS)
    check_randomizable(RANDOMIZABLE_PARAMETERS)
    with pytest.raises(ValueError, match="not randomisable"):
        check_randomizable(["mass", "ground_effect_mode"])
    with pytest.raises(KeyError):
        check_randomizable(["no_such_parameter"])
    p = build_params(load_airframe("navion"), N)
    mask = torch.ones(N, dtype=torch.bool)
    with pytest.raises(ValueError, match="not randomisable"):
        p.assign(mask, randomizable_only=True, inertia_inv=p.inertia_inv)
    with pytest.raises(ValueError, match="not randomisable"):
        p.assign(mask, randomizable_only=True, ground_effect_mode=torch.tensor(0))
    assert torch.equal(p.ground_effect_mode, torch.ones(N, dtype=torch.int32))  # nothing written
    p.assign(mask, randomizable_only=True, mass=torch.tensor(1000.0))
    assert torch.equal(p.mass, torch.full((N,), 1000.0))
    p.assign(mask, ground_effect_mode=torch.tensor(0))  # allowed when not asked to be strict
    assert torch.equal(p.ground_effect_mode, torch.zeros(N, dtype=torch.int32))


def test_markdown_and_docstring_list_every_row():
    text = parameter_table_markdown()
    lines = text.strip().splitlines()
    assert len(lines) == 2 + len(PARAMETER_TABLE)
    for row, line in zip(PARAMETER_TABLE, lines[2:], strict=True):
        assert line.startswith(f"| `{row.name}` | {row.shape} |")
        assert ("| yes |" in line) == row.randomizable
        assert row.name in ModelParams.__doc__


def test_one_extra_row_is_all_it_takes():
    af = load_airframe("navion")
    assert [f.name for f in dataclasses.fields(ExtendedParams)][-2:] == ["drag_area", "drag_area_total"]
    values = build_values(EXTENDED_TABLE, af, table_sizes(af, N), BuildOptions(), "cpu", torch.float32)
    p = ExtendedParams(**values)
    assert p.drag_area.shape == (N, 1) and torch.allclose(p.drag_area_total, torch.full((N,), 0.01))
    assert "drag_area" in p.per_env_fields()
    mask = torch.tensor([False, True, False])
    p.assign(mask, randomizable_only=True, drag_area=torch.tensor([0.5]))
    assert torch.allclose(p.drag_area_total, torch.tensor([0.01, 0.5, 0.01]))
    assert type(p.to(dtype=torch.float64)) is ExtendedParams
    if not warp_available():
        return
    assert list(ExtendedWarpParams.vars)[-6:] == ["drag_area", "drag_area_total", "aero_exponent_codes",
                                                  "num_terms", "num_motors", "num_alpha_dot_terms"]
    init_warp()
    bound = bind_warp(ExtendedWarpParams, EXTENDED_TABLE, WARP_EXTRAS, p, WARP_TYPES)
    assert _warp_shape(bound.drag_area) == (N, 1)
    out = torch.zeros(N)
    wp.launch(_read_extended, dim=N, inputs=[bound, wp.from_torch(out)], device="cpu")
    wp.synchronize_device("cpu")
    expected = p.drag_area[:, 0] * p.mass + p.drag_area_total + 1.0
    assert torch.allclose(out, expected)


def test_malformed_tables_are_rejected():
    mass = PARAMETER_TABLE[0]
    with pytest.raises(ValueError, match="twice"):
        check_table((mass, mass))
    with pytest.raises(ValueError, match="earlier source row"):
        check_table((ParamRow("y", "[N]", Derivation(("x",), torch.neg)),))
    with pytest.raises(ValueError, match="start with N"):
        check_table((ParamRow("x", "[3]", lambda af, _: [0.0, 0.0, 0.0]),))
    with pytest.raises(ValueError, match="derived row"):
        check_table((mass, ParamRow("y", "[N]", Derivation(("mass",), torch.neg), randomizable=True)))
    af = load_airframe("navion")
    bad_shape = (ParamRow("x", "[N, 2]", lambda af, _: [0.0, 0.0, 0.0]),)
    with pytest.raises(ValueError, match="declared"):
        build_values(bad_shape, af, table_sizes(af, N), BuildOptions(), "cpu", torch.float32)
    if warp_available():
        with pytest.raises(ValueError, match="does not fit"):
            warp_annotation(ParamRow("x", "[N, 2]", lambda af, _: [0.0, 0.0], warp="vec3"), WARP_TYPES)
