"""Per-env model parameters as tensors shaped [N, ...], built from an :class:`Airframe`.

The parameters are declared once, in :data:`PARAMETER_TABLE` (one :class:`ParamRow` each); the
torch container :class:`ModelParams`, :func:`build_params`, the Warp struct :class:`WarpParams`,
:func:`bind_warp_params` and :data:`RANDOMIZABLE_PARAMETERS` are generated from it (machinery in
:mod:`.param_schema`). Adding a parameter is one row here (plus its Airframe field).

Every row but the aero monomial exponents is per env, so that domain randomisation is one masked
write (``ModelParams.assign``); the exponents are shared by all envs (they fix the structure, not
the values), as are the packed table terms (``airframe_tables``) but their gains. N = envs, T = aero
monomials, M = motors, K = table terms, B = breakpoints, V = table values, L = longest table axis.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

import torch

from ..airframe import MOTOR_MODELS, SURFACES, Actuator, Airframe
from ..airframe_terms import ALPHA_DOT_VARIABLE, INDEX_COLUMNS, NO_OUTPUT, TABLE_VARIABLES
from ..constants import G0
from . import param_schema
from ._warp import vector_type, wp
from .ground_effect import WingConstants, ground_effect_mode, wing_constants
from .param_schema import (
    BuildOptions,
    Derivation,
    ParamRow,
    Source,
    WarpExtra,
    bind_warp,
    build_values,
    make_container,
    make_warp_struct,
    table_markdown,
)
from .switches import ModelSwitches

#: Bits per exponent in a packed monomial code (:func:`pack_exponents`).
EXPONENT_BITS = 3
EXPONENT_MASK = (1 << EXPONENT_BITS) - 1

Vec6 = vector_type(6)  # one aero-table row (CL, CD, CY, Cl, Cm, Cn)
#: Warp types the table names beyond warp's own (``vec3``, ``mat33``, ``float32``, ...).
WARP_TYPES: dict[str, Any] = {"Vec6": Vec6, "WingConstants": WingConstants}


def pack_exponents(exponents: torch.Tensor) -> torch.Tensor:
    """[T] int32 codes of the [T, V] exponent table, EXPONENT_BITS bits per variable (variable j
    in bits 3j..3j+2). The warp aero table (``aero_monomials.aero_coefficients_oge_wp``) reads one code per
    monomial and unpacks it with shifts and masks into indices that are provably in range; five
    int64 reads with sign fix-ups cost three times as many instructions (the table was a third of
    the CPU step)."""
    if exponents.numel() and (int(exponents.min()) < 0 or int(exponents.max()) > EXPONENT_MASK):
        raise ValueError(f"aero exponents must be in [0, {EXPONENT_MASK}] to be packed")
    shifts = torch.arange(exponents.shape[-1], device=exponents.device) * EXPONENT_BITS
    return (exponents.long() << shifts).sum(-1).to(torch.int32).contiguous()


# ------------------------------------------------------------------------------------------ sources
def _motors(attr: str) -> Source:
    return lambda af, _: [getattr(m, attr) for m in af.motors]


def _surfaces(get: Callable[[Actuator], Any]) -> Source:
    return lambda af, _: [get(af.actuators[s]) for s in SURFACES]


def _geometry(attr: str) -> Source:
    return lambda af, _: getattr(af.geometry, attr)


def _switch(row: str, doc: str) -> ParamRow:
    """An int32 [N] model-switch row (``switches.ModelSwitches``): 0 full model, 1 simplified."""
    return ParamRow(row, "[N]", lambda _, o: o.switches.flags()[row], dtype="int32", warp="int32",
                    randomizable=True, doc=f"model switch, 1: {doc} (build_params(switches=...))")


PARAMETER_TABLE: tuple[ParamRow, ...] = (
    ParamRow("mass", "[N]", lambda af, _: af.mass, randomizable=True, unit="kg", doc="total mass"),
    ParamRow("inertia", "[N, 3, 3]", lambda af, _: af.inertia, randomizable=True, warp="mat33",
             unit="kg m^2", doc="body inertia tensor about the CG"),
    ParamRow("inertia_inv", "[N, 3, 3]", Derivation(("inertia",), torch.linalg.inv), warp="mat33",
             unit="1/(kg m^2)", doc="inverse of inertia"),
    ParamRow("gravity", "[N]", lambda _, o: o.gravity, unit="m/s^2", doc="build_params(gravity=...)"),
    ParamRow("wing_area", "[N]", _geometry("wing_area"), randomizable=True, unit="m^2", doc="reference area"),
    ParamRow("span", "[N]", _geometry("span"), randomizable=True, unit="m", doc="wing span"),
    ParamRow("chord", "[N]", _geometry("mean_chord"), randomizable=True, unit="m", doc="mean chord"),
    ParamRow("aspect_ratio", "[N]", _geometry("aspect_ratio"), randomizable=True, doc="b^2 / S"),
    ParamRow("taper_ratio", "[N]", _geometry("taper_ratio"), randomizable=True, doc="tip / root chord"),
    ParamRow("oswald", "[N]", lambda af, _: af.aero.oswald_efficiency, randomizable=True,
             doc="Oswald efficiency"),
    ParamRow("wing_constants", "[N, 5]", Derivation(("aspect_ratio", "taper_ratio"), wing_constants),
             warp="WingConstants", doc="ground_effect.wing_constants(aspect_ratio, taper_ratio)"),
    ParamRow("wing_quarter_chord", "[N, 3]", _geometry("wing_quarter_chord"), randomizable=True,
             warp="vec3", unit="m", doc="body FRD, relative to the CG"),
    ParamRow("aero_reference", "[N, 3]", lambda af, _: af.aero.moment_reference, randomizable=True,
             warp="vec3", unit="m", doc="aero moment reference point, body FRD, relative to the CG"),
    ParamRow("aero_coefficients", "[N, T, 6]", lambda af, _: af.aero.coefficients, randomizable=True,
             warp="Vec6", doc="monomial coefficients, columns CL, CD, CY, Cl, Cm, Cn"),
    ParamRow("aero_rates", "[N, 6, 3]", lambda af, _: af.aero.rate_derivatives, randomizable=True,
             doc="rate derivatives, rows CL..Cn, columns p, q, r (non-dimensional)"),
    ParamRow("alpha_range", "[N, 2]", lambda af, _: af.aero.alpha_range, warp="vec2", unit="rad",
             doc="validity range of the aero tables"),
    ParamRow("beta_range", "[N, 2]", lambda af, _: af.aero.beta_range, warp="vec2", unit="rad",
             doc="validity range of the aero tables"),
    ParamRow("ground_effect_mode", "[N]", lambda _, o: ground_effect_mode(o.ground_effect), dtype="int32",
             warp="int32", doc="0 off, 1 induced, 2 paper (build_params(ground_effect=...))"),
    ParamRow("motor_position", "[N, M, 3]", _motors("position"), randomizable=True, warp="vec3", unit="m",
             doc="body FRD, relative to the CG"),
    ParamRow("motor_axis", "[N, M, 3]", _motors("thrust_axis"), warp="vec3",
             doc="unit thrust axis, body FRD"),
    ParamRow("motor_spin", "[N, M]", _motors("spin"), doc="+1 clockwise seen from behind, -1 otherwise"),
    ParamRow("disk_area", "[N, M]", _motors("disk_area"), randomizable=True, unit="m^2", doc="S_p"),
    ParamRow("thrust_coefficient", "[N, M]", _motors("thrust_coefficient"), randomizable=True, doc="C_p"),
    ParamRow("discharge_speed", "[N, M]", _motors("discharge_speed"), randomizable=True, unit="m/s",
             doc="k_m"),
    ParamRow("torque_coefficient", "[N, M]", _motors("torque_coefficient"), randomizable=True,
             unit="N m s^2", doc="k_tp"),
    ParamRow("torque_speed_constant", "[N, M]", _motors("torque_speed_constant"), randomizable=True,
             unit="rad/s", doc="k_omega, at full throttle"),
    ParamRow("motor_p_factor", "[N, M]", _motors("p_factor"), randomizable=True, unit="m/rad",
             doc="thrust-map motors: thrust-line shift per rad of inflow angle (p-factor)"),
    ParamRow("throttle_time_constant", "[N, M]", _motors("time_constant"), randomizable=True, unit="s",
             doc="first-order throttle lag"),
    ParamRow("actuator_second_order", "[N, 3]", _surfaces(lambda ac: ac.order == 2), dtype="bool",
             warp="bool", doc="surface actuator is second order"),
    ParamRow("actuator_time_constant", "[N, 3]", _surfaces(lambda ac: ac.time_constant if ac.order == 1
                                                           else 1.0),
             randomizable=True, warp="vec3", unit="s", doc="first order; 1 where unused"),
    ParamRow("actuator_natural_frequency", "[N, 3]", _surfaces(lambda ac: ac.natural_frequency),
             randomizable=True, warp="vec3", unit="rad/s", doc="second order"),
    ParamRow("actuator_damping", "[N, 3]", _surfaces(lambda ac: ac.damping_ratio), randomizable=True,
             warp="vec3", doc="second-order damping ratio"),
    ParamRow("surface_min", "[N, 3]", _surfaces(lambda ac: ac.limits[0]), warp="vec3", unit="rad",
             doc="lower deflection limit"),
    ParamRow("surface_max", "[N, 3]", _surfaces(lambda ac: ac.limits[1]), warp="vec3", unit="rad",
             doc="upper deflection limit"),
    _switch("ideal_actuators", "surfaces at the clamped commanded deflection, no lag"),
    _switch("ideal_throttle", "throttle state = commanded throttle"),
    _switch("constant_density", "sea-level ISA density at every height"),
    _switch("no_rate_damping", "no aero rate-derivative terms"),
    _switch("no_propeller_torque", "no propeller reaction torque"),
    _switch("sea_surface", "over the env's sea (surface.py), not the flat ground"),
    ParamRow("aero_exponents", "[T, 5]", lambda af, _: af.aero.exponents, dtype="int64", per_env=False,
             warp=None, doc="monomial exponents, columns alpha, beta, elevator, aileron, rudder"),
    ParamRow("motor_model", "[N, M]", lambda af, _: [MOTOR_MODELS.index(m.model) for m in af.motors],
             dtype="int32", warp="int32", doc="0 momentum theory, 1 the airframe's thrust map (table terms)"),
    ParamRow("table_gain", "[N, K]", lambda af, _: af.tables.gains(), randomizable=True,
             doc="gain of each table term (physics/interpolated_terms.py)"),
    ParamRow("table_index", "[K, 12]", lambda af, _: af.tables.index(), dtype="int32", per_env=False,
             warp="int32", doc=f"packed table terms, columns {', '.join(INDEX_COLUMNS)}"),
    ParamRow("table_output_start", f"[{NO_OUTPUT + 1}]", lambda af, _: af.tables.output_start(),
             dtype="int32", per_env=False, warp="int32", doc="terms of output o: [start[o], start[o + 1])"),
    ParamRow("table_breakpoints", "[B]", lambda af, _: af.tables.breakpoints(), per_env=False,
             doc="every table axis' breakpoints, concatenated"),
    ParamRow("table_values", "[V]", lambda af, _: af.tables.values(), per_env=False,
             doc="every table's values, row-major, concatenated"),
    ParamRow("table_grid", "[K, 3, L]", lambda af, _: af.tables.grid(), per_env=False, warp=None,
             doc="breakpoints per term and axis, padded (the torch lookup)"),
    ParamRow("table_exponents", "[K, 14]", lambda af, _: af.tables.exponents(), dtype="int64",
             per_env=False, warp=None, doc="table-term multiplier exponents, columns TABLE_VARIABLES"),
)

#: Warp struct fields computed at binding rather than stored in :class:`ModelParams`.
WARP_EXTRAS: tuple[WarpExtra, ...] = (
    WarpExtra("aero_exponent_codes", "int32", 1, lambda p: wp.from_torch(pack_exponents(p.aero_exponents)),
              doc="[T] pack_exponents(aero_exponents)"),
    WarpExtra("num_terms", "int32", 0, lambda p: int(p.aero_exponents.shape[0]), doc="T"),
    WarpExtra("num_motors", "int32", 0, lambda p: int(p.motor_spin.shape[1]), doc="M"),
    WarpExtra("num_alpha_dot_terms", "int32", 0, lambda p: int(
        (p.table_exponents[:, TABLE_VARIABLES.index(ALPHA_DOT_VARIABLE)] > 0).sum()),
        doc="table terms that multiply alpha_dot (0: the alpha-dot solve is skipped)"),
)

#: Rows domain randomisation may overwrite (``ModelParams.assign(..., randomizable_only=True)``).
RANDOMIZABLE_PARAMETERS: tuple[str, ...] = tuple(row.name for row in PARAMETER_TABLE if row.randomizable)

ModelParams = make_container(
    PARAMETER_TABLE, "ModelParams", module=__name__,
    header="Model parameters, one tensor per row of PARAMETER_TABLE. N = envs, T = aero monomials, "
           "M = motors.")

WarpParams = make_warp_struct(
    PARAMETER_TABLE, WARP_EXTRAS, "WarpParams", module=__name__, custom=WARP_TYPES,
    doc="""Warp views of :class:`ModelParams` (zero-copy, same memory; shapes as in ModelParams).

    Generated from PARAMETER_TABLE: [N, 3] rows are arrays of vec3, [N, 3, 3] arrays of mat33,
    [N, M, 3] 2-D arrays of vec3, plus WARP_EXTRAS. Writes to the torch tensors
    (``ModelParams.assign``) are seen by the next launch without rebinding or recompiling.
    """)


def table_sizes(airframe: Airframe, num_envs: int) -> dict[str, int]:
    """Sizes of the shape symbols: N envs, T aero monomials, M motors; K table terms, B breakpoints,
    V table values, L longest axis (``airframe_tables.TableSet``)."""
    tables = airframe.tables
    return {"N": num_envs, "T": len(airframe.aero.exponents), "M": airframe.num_motors,
            "K": tables.num_terms, "B": tables.breakpoints().size, "V": tables.values().size,
            "L": tables.max_breakpoints()}


def build_params(
    airframe: Airframe,
    num_envs: int,
    device: torch.device | str = "cpu",
    dtype: torch.dtype = torch.float32,
    ground_effect: bool | str = True,
    gravity: float = G0,
    switches: ModelSwitches | Mapping[str, Any] | None = None,
) -> ModelParams:
    """Tensors for ``num_envs`` copies of ``airframe`` (contiguous, independently writable);
    ``switches`` (None: the full model) fills the model-switch rows (see :mod:`.switches`)."""
    options = BuildOptions(gravity=gravity, ground_effect=ground_effect,
                           switches=ModelSwitches.from_spec(switches))
    values = build_values(PARAMETER_TABLE, airframe, table_sizes(airframe, num_envs), options, device, dtype)
    return ModelParams(**values)


def bind_warp_params(p: ModelParams) -> WarpParams:
    """Zero-copy Warp views of float32 ``p`` (its tensors must stay allocated and contiguous)."""
    return bind_warp(WarpParams, PARAMETER_TABLE, WARP_EXTRAS, p, WARP_TYPES)


def check_randomizable(names: Iterable[str]) -> None:
    """Raise KeyError for an unknown parameter name, ValueError for one that is not randomisable."""
    param_schema.check_randomizable(PARAMETER_TABLE, names)


def parameter_table_markdown() -> str:
    """The parameter table as markdown (name, shape, dtype, unit, randomisable, Warp type, doc)."""
    return table_markdown(PARAMETER_TABLE)
