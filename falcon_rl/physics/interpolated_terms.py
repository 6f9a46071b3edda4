"""Table terms: sums of monomial-weighted, multilinearly interpolated 1-3D tables (torch + Warp twin).

    out[o] = sum over the terms k of output o of  gain[k] prod_j x_j^e[k, j] T_k(x_a, x_b, x_c)

x [N, 14] holds the variables of ``airframe_tables.TABLE_VARIABLES``. Each axis clamps its variable to
its first and last breakpoint and interpolates linearly between breakpoints, so a term is exact at the
nodes and multilinear in each cell. The terms live in shared, flat arrays (``ModelParams.table_*``: the
packed index [K, 12], breakpoints [B], values [V]) with a per-env gain [N, K]; terms are sorted by
output and ``table_output_start`` [NO_OUTPUT + 1] gives each output's range. The aero model sums
outputs 0..5 (the coefficients, ``aero.py``), the propulsion model outputs 6, 7 and 8 (thrust N, torque
N m and angular momentum N m s of each thrust-map motor, ``propulsion.py``). Every airframe uses the
same code: no recompile per aircraft.

Terms that multiply ``alpha_dot`` (exponent 1, never an axis: ``airframe_tables`` refuses the rest) are
summed apart by :func:`split_alpha_dot` / :func:`table_output_split_wp`, evaluated at alpha_dot = 1: each
output is then out_0 + alpha_dot * out_1 exactly, which ``alpha_dot.py`` solves in closed form.
"""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Any

import torch

from ..airframe_terms import (
    ALPHA_DOT_VARIABLE,
    MAX_MULTIPLIER_EXPONENT,
    MAX_TABLE_AXES,
    MULTIPLIER_BITS,
    NO_OUTPUT,
    TABLE_VARIABLES,
)
from ._warp import vector_type, warp_func, wp
from .params import ModelParams, WarpParams

NUM_VARIABLES = len(TABLE_VARIABLES)
#: Index of each variable in the vector x (module constants, so that Warp functions can read them).
ALPHA, BETA, ELEVATOR, P_HAT, MACH, AIRSPEED, H_OVER_B, THROTTLE, DENSITY = (
    TABLE_VARIABLES.index(name) for name in ("alpha", "beta", "elevator", "p", "mach", "airspeed", "h_over_b",
                                             "throttle", "density"))
ALPHA_DOT = TABLE_VARIABLES.index(ALPHA_DOT_VARIABLE)
#: Bit shift of alpha_dot's exponent in a packed multiplier code.
ALPHA_DOT_SHIFT = MULTIPLIER_BITS * ALPHA_DOT
#: Output codes of the propulsion terms.
THRUST_OUTPUT, TORQUE_OUTPUT, ANGULAR_MOMENTUM_OUTPUT = 6, 7, 8
#: Corners of a 3-D cell: bit a of c selects the upper breakpoint of axis a.
_CORNERS = torch.tensor([[(c >> a) & 1 for a in range(MAX_TABLE_AXES)] for c in range(8)])


def _read_once(tensor: torch.Tensor, cache: dict[int, tuple[weakref.ref, Any]],
               read: Callable[[torch.Tensor], Any]) -> Any:
    """``read(tensor)``, computed once per tensor object (a shared, fixed table tensor) and kept in
    ``cache`` while the tensor lives: a host read per simulator, not a host sync per call."""
    key = id(tensor)
    cached = cache.get(key)
    if cached is None or cached[0]() is not tensor:
        ref = weakref.ref(tensor, lambda _ref, key=key: cache.pop(key, None))
        cached = cache[key] = (ref, read(tensor))
    return cached[1]


def has_terms(p: ModelParams, first: int, stop: int | None = None) -> bool:
    """Whether ``p`` has table terms of outputs [first, stop) (stop None: first + 1), read once per
    ``table_output_start`` tensor, so that a monomial airframe skips the table work for free."""
    stop = first + 1 if stop is None else stop
    starts = _read_once(p.table_output_start, _STARTS, lambda t: [int(v) for v in t.tolist()])
    return starts[stop] > starts[first]


def has_alpha_dot_terms(p: ModelParams) -> bool:
    """Whether any table term of ``p`` multiplies alpha_dot, read once per ``table_exponents`` tensor:
    airframes without such terms skip the alpha-dot solve for free."""
    return _read_once(p.table_exponents, _ALPHA_DOT, lambda t: bool((t[:, ALPHA_DOT] > 0).any()))


#: id(table_output_start) -> (weak reference, its values)
_STARTS: dict[int, tuple[weakref.ref, Any]] = {}
#: id(table_exponents) -> (weak reference, whether a term multiplies alpha_dot)
_ALPHA_DOT: dict[int, tuple[weakref.ref, Any]] = {}


def multipliers(x: torch.Tensor, exponents: torch.Tensor) -> torch.Tensor:
    """The monomial multipliers prod_j x_j^(e_kj), shape [N, K], from x [N, 14] and exponents e [K, 14] in
    [0, 3] (by products, so that gradients stay finite at x = 0)."""
    xk = x.unsqueeze(1)  # [N, 1, 14]
    out = torch.ones(x.shape[0], exponents.shape[0], x.shape[1], dtype=x.dtype, device=x.device)
    for power in range(1, MAX_MULTIPLIER_EXPONENT + 1):
        out = torch.where(exponents >= power, out * xk, out)
    return out.prod(-1)


def table_outputs(x: torch.Tensor, p: ModelParams, gains: torch.Tensor | None = None) -> torch.Tensor:
    """Every output [N, NO_OUTPUT] from the variables x [N, 14] (outputs with no term are 0); ``gains``
    [N, K] replaces ``p.table_gain`` (rows of x that are not one per env)."""
    return sum_by_output(table_terms(x, p, gains), p)


def sum_by_output(terms: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """[N, NO_OUTPUT] the per-term values [N, K] summed per output."""
    onehot = torch.nn.functional.one_hot(p.table_index[:, 0].long(), NO_OUTPUT + 1).to(terms.dtype)
    return (terms @ onehot)[:, :NO_OUTPUT]


def split_alpha_dot(x: torch.Tensor, p: ModelParams) -> tuple[torch.Tensor, torch.Tensor]:
    """(out_0, out_1), each [N, NO_OUTPUT], with out = out_0 + alpha_dot * out_1 for every alpha_dot:
    the terms without and with the alpha_dot multiplier, from x [N, 14] (its alpha_dot column unread)."""
    x = x.clone()
    x[:, ALPHA_DOT] = 1.0
    terms = table_terms(x, p)  # [N, K]
    per_alpha_dot = (p.table_exponents[:, ALPHA_DOT] > 0).unsqueeze(0)  # [1, K]
    zero = torch.zeros_like(terms)
    return (sum_by_output(torch.where(per_alpha_dot, zero, terms), p),
            sum_by_output(torch.where(per_alpha_dot, terms, zero), p))


def table_terms(x: torch.Tensor, p: ModelParams, gains: torch.Tensor | None = None) -> torch.Tensor:
    """Each term's value [N, K], gain * multiplier * table, from the variables x [N, 14]; ``gains`` as in
    :func:`table_outputs`."""
    index = p.table_index.long()  # [K, 12]
    grid = p.table_grid  # [K, 3, L]
    variables = index[:, 2:5]  # [K, 3], -1 unused
    sizes = index[:, 5:8]  # [K, 3]
    xv = x[:, variables.clamp_min(0)]  # [N, K, 3]
    below = (grid.unsqueeze(0) <= xv.unsqueeze(-1)).sum(-1) - 1  # [N, K, 3]
    cell = torch.minimum(below.clamp_min(0), (sizes - 2).clamp_min(0))
    full = grid.unsqueeze(0).expand(x.shape[0], -1, -1, -1)
    lo = full.gather(-1, cell.unsqueeze(-1)).squeeze(-1)
    hi = full.gather(-1, (cell + 1).unsqueeze(-1)).squeeze(-1)
    used = sizes > 1
    span = torch.where(used, hi - lo, torch.ones_like(hi))
    frac = torch.where(used, ((xv - lo) / span).clamp(0.0, 1.0), torch.zeros_like(xv))  # [N, K, 3]
    corners = _CORNERS.to(x.device)  # [8, 3]
    weight = torch.where(corners.bool(), frac.unsqueeze(2), 1.0 - frac.unsqueeze(2)).prod(-1)  # [N, K, 8]
    strides = torch.stack([sizes[:, 1] * sizes[:, 2], sizes[:, 2], torch.ones_like(sizes[:, 2])], -1)
    flat = index[:, 11].unsqueeze(0).unsqueeze(-1) + (
        (cell.unsqueeze(2) + corners) * strides.unsqueeze(0).unsqueeze(2)).sum(-1)  # [N, K, 8]
    flat = flat.clamp(0, p.table_values.shape[0] - 1)
    table = (weight * p.table_values[flat]).sum(-1)  # [N, K]
    return (p.table_gain if gains is None else gains) * multipliers(x, p.table_exponents) * table  # [N, K]


# ---------------------------------------------------------------------------------------- warp twins
#: One env's variable vector (TABLE_VARIABLES order).
TableVars = vector_type(NUM_VARIABLES)


@warp_func
def table_axis_wp(x: float, breakpoints: wp.array(dtype=wp.float32), start: int, size: int) -> wp.vec2:
    """(cell index, fraction in [0, 1]) of x on the ``size`` breakpoints from ``start`` (clamped at the
    edges; (0, 0) for an unused axis of size 1)."""
    if size < 2:
        return wp.vec2(0.0, 0.0)
    cell = int(0)  # noqa: UP018, RUF046 (a mutable Warp local)
    for k in range(1, size - 1):
        if x >= breakpoints[start + k]:
            cell = k
    lo = breakpoints[start + cell]
    hi = breakpoints[start + cell + 1]
    return wp.vec2(float(cell), wp.clamp((x - lo) / (hi - lo), 0.0, 1.0))


@warp_func
def table_term_wp(x: TableVars, p: WarpParams, i: int, k: int) -> float:
    """Term k of env i: gain * multiplier * interpolated table (twin of one column of
    :func:`table_outputs`)."""
    code = p.table_index[k, 1]
    multiplier = p.table_gain[i, k]
    for j in range(NUM_VARIABLES):
        e = (code >> (MULTIPLIER_BITS * j)) & 3
        for _ in range(e):
            multiplier = multiplier * x[j]
    cells = wp.vec3()
    fracs = wp.vec3()
    for a in range(MAX_TABLE_AXES):
        var = p.table_index[k, 2 + a]
        if var >= 0:
            cf = table_axis_wp(x[var], p.table_breakpoints, p.table_index[k, 8 + a], p.table_index[k, 5 + a])
            cells[a] = cf[0]
            fracs[a] = cf[1]
    n2 = p.table_index[k, 7]
    strides = wp.vec3i(p.table_index[k, 6] * n2, n2, 1)
    base = p.table_index[k, 11]
    value = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for c in range(8):
        weight = float(1.0)  # noqa: UP018 (a mutable Warp local)
        offset = base
        for a in range(MAX_TABLE_AXES):
            upper = (c >> a) & 1
            weight = weight * wp.where(upper == 1, fracs[a], 1.0 - fracs[a])
            offset = offset + (int(cells[a]) + upper) * strides[a]
        if weight != 0.0:
            value = value + weight * p.table_values[offset]
    return multiplier * value


@warp_func
def table_output_wp(x: TableVars, p: WarpParams, i: int, output: int) -> float:
    """Sum of the terms of ``output`` for env i (twin of one column of :func:`table_outputs`)."""
    total = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for k in range(p.table_output_start[output], p.table_output_start[output + 1]):
        total = total + table_term_wp(x, p, i, k)
    return total


@warp_func
def table_output_split_wp(x: TableVars, p: WarpParams, i: int, output: int) -> wp.vec2:
    """(out_0, out_1) of ``output`` for env i: the sums of its terms without and with the alpha_dot
    multiplier, ``x`` holding alpha_dot = 1 (twin of one column of :func:`split_alpha_dot`)."""
    steady = float(0.0)  # noqa: UP018 (a mutable Warp local)
    per_alpha_dot = float(0.0)  # noqa: UP018 (a mutable Warp local)
    for k in range(p.table_output_start[output], p.table_output_start[output + 1]):
        value = table_term_wp(x, p, i, k)
        if (p.table_index[k, 1] >> ALPHA_DOT_SHIFT) & 3 != 0:
            per_alpha_dot = per_alpha_dot + value
        else:
            steady = steady + value
    return wp.vec2(steady, per_alpha_dot)
