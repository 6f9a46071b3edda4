"""Tabulated aero and propulsion terms of an airframe: the JSON schema and its packed arrays.

A table term adds to one output (an aero coefficient, or the thrust or torque of each thrust-map motor)

    out[output] += gain * prod_j x_j^multiply_j * T(x_a, x_b, x_c)

where T is a 0-3 dimensional table over some of the variables x (:data:`TABLE_VARIABLES`), read by
multilinear interpolation and clamped at the edges of each axis, and the product is a monomial
multiplier (exponents 0..3). This is the shape most JSBSim ``<aerodynamics>`` functions take once the
reference factors (qbar S, times b or c for a moment) are divided out. The physics evaluates every term
of every airframe with one kernel (``physics/interpolated_terms.py``): the terms are data bound at run time.

JSON (``aero.tables``, and ``propulsion.thrust_map`` for the motors whose ``model`` is "thrust_map")::

    {"name": "CLwbh", "output": "CL", "gain": 1.0, "multiply": {"elevator": 1},
     "axes": [{"variable": "alpha", "breakpoints": [...]}, {"variable": "h_over_b", "breakpoints": [...]}],
     "values": [[...], ...]}

``values`` nests one list level per axis (row-major, first axis outermost; a number when there are no
axes); breakpoints strictly increase. For propulsion terms the variable ``airspeed`` is the motor's axial
inflow speed and ``throttle`` its own throttle.

``alpha_dot`` (alpha-dot c / 2V, non-dimensional like q) is not a state: the physics solves it from the
accelerations the forces set (``physics/alpha_dot.py``), in closed form because the force is linear in
it. So it may only be an aero term's multiplier, with exponent 1 (never an axis, a higher power or a
thrust-map variable); the parser refuses anything else.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np


class FieldReader(Protocol):
    """The airframe file reader the parsers here use (``airframe._Reader``): typed field access whose
    errors name the file, the dotted field and the constraint."""

    def fail(self, where: str, constraint: str) -> ValueError: ...

    def get(self, data: dict, key: str, where: str, kind: type | tuple, default: Any = ...) -> Any: ...

    def no_unknown(self, data: dict, allowed: set[str], where: str) -> None: ...

    def text(self, data: dict, key: str, where: str, default: Any = ..., file_name: bool = False) -> str: ...

#: Variables a table term may read, in the order of the physics' variable vector [N, 14]. Angles and
#: deflections in rad, rates non-dimensional (p b/2V, q c/2V, r b/2V, alpha_dot c/2V), airspeed m/s,
#: density kg/m^3, h_over_b = height of the wing reference point over span, throttle in [0, 1].
TABLE_VARIABLES: tuple[str, ...] = ("alpha", "beta", "elevator", "aileron", "rudder", "p", "q", "r", "mach",
                                    "airspeed", "h_over_b", "throttle", "density", "alpha_dot")
#: The variable the physics solves rather than reads (a multiplier of exponent 1 of aero terms only).
ALPHA_DOT_VARIABLE = "alpha_dot"
#: Outputs of table terms: the six aero coefficients, then per thrust-map motor its thrust (N, along the
#: thrust axis), its reaction torque on the airframe about the thrust axis (N m, signed) and its
#: propeller's angular momentum about the thrust axis (N m s, signed; the gyroscopic moment h a x omega).
TABLE_OUTPUTS: tuple[str, ...] = ("CL", "CD", "CY", "Cl", "Cm", "Cn", "thrust", "torque", "angular_momentum")
AERO_OUTPUTS = 6
#: Output code of the padding term (an airframe without tables still binds one-element arrays).
NO_OUTPUT = len(TABLE_OUTPUTS)
MAX_TABLE_AXES = 3
MAX_MULTIPLIER_EXPONENT = 3
MULTIPLIER_BITS = 2
MAX_BREAKPOINTS = 256
#: Columns of the packed term index (:meth:`TableSet.index`).
INDEX_COLUMNS = ("output", "multiplier_code", "var0", "var1", "var2", "n0", "n1", "n2",
                 "bp0", "bp1", "bp2", "values")
#: Padding of unused breakpoint slots in the torch grid (above any variable value).
GRID_PAD = 1e30


@dataclass(frozen=True)
class TableTerm:
    """One term: ``gain * prod x^multiply * T(axes)``."""

    name: str
    output: int  # index into TABLE_OUTPUTS
    gain: float
    multiply: tuple[int, ...]  # [14] exponents, TABLE_VARIABLES order
    variables: tuple[int, ...]  # axis variables, 0..3 of them
    breakpoints: tuple[np.ndarray, ...]  # per axis, strictly increasing, SI
    values: np.ndarray  # shape = breakpoint counts (a 0-d array without axes)

    def to_json(self) -> dict[str, Any]:
        """The JSON object of this term (inverse of :func:`parse_term`)."""
        doc: dict[str, Any] = {"name": self.name, "output": TABLE_OUTPUTS[self.output], "gain": self.gain}
        multiply = {TABLE_VARIABLES[j]: e for j, e in enumerate(self.multiply) if e}
        if multiply:
            doc["multiply"] = multiply
        doc["axes"] = [{"variable": TABLE_VARIABLES[v], "breakpoints": [float(b) for b in bp]}
                       for v, bp in zip(self.variables, self.breakpoints, strict=True)]
        doc["values"] = self.values.tolist()
        return doc


@dataclass(frozen=True)
class TableSet:
    """All table terms of an airframe, sorted by output, and their packed arrays for the physics."""

    terms: tuple[TableTerm, ...] = ()

    def sorted(self) -> TableSet:
        return TableSet(tuple(sorted(self.terms, key=lambda t: t.output)))

    @property
    def num_terms(self) -> int:
        """K of the packed arrays (at least 1: an empty set packs one padding term)."""
        return max(1, len(self.terms))

    def output_start(self) -> np.ndarray:
        """[NO_OUTPUT + 1] int: terms of output o are [start[o], start[o + 1]) in :meth:`index`."""
        outputs = np.array([t.output for t in self.terms], dtype=np.int64)
        return np.searchsorted(outputs, np.arange(NO_OUTPUT + 1), side="left").astype(np.int32)

    def index(self) -> np.ndarray:
        """[K, 12] int32, columns INDEX_COLUMNS: output, packed multiplier exponents (2 bits per
        variable), axis variables (-1 unused), axis sizes (1 unused), breakpoint offsets, value offset."""
        rows, bp_offset, value_offset = [], 0, 0
        for term in self.terms:
            code = sum(e << (MULTIPLIER_BITS * j) for j, e in enumerate(term.multiply))
            variables = list(term.variables) + [-1] * (MAX_TABLE_AXES - len(term.variables))
            sizes = [len(b) for b in term.breakpoints] + [1] * (MAX_TABLE_AXES - len(term.variables))
            offsets = []
            for k in range(MAX_TABLE_AXES):
                offsets.append(bp_offset)
                bp_offset += len(term.breakpoints[k]) if k < len(term.breakpoints) else 0
            rows.append([term.output, code, *variables, *sizes, *offsets, value_offset])
            value_offset += term.values.size
        if not rows:
            rows.append([NO_OUTPUT, 0, -1, -1, -1, 1, 1, 1, 0, 0, 0, 0])
        return np.array(rows, dtype=np.int32)

    def breakpoints(self) -> np.ndarray:
        """[B] every axis' breakpoints, concatenated (at least one element)."""
        parts = [b for t in self.terms for b in t.breakpoints]
        return np.concatenate(parts) if parts else np.zeros(1)

    def values(self) -> np.ndarray:
        """[V] every term's values, row-major, concatenated (at least one element)."""
        parts = [t.values.reshape(-1) for t in self.terms]
        return np.concatenate(parts) if parts else np.zeros(1)

    def gains(self) -> np.ndarray:
        """[K] term gains (0 for the padding term)."""
        return np.array([t.gain for t in self.terms] or [0.0])

    def exponents(self) -> np.ndarray:
        """[K, 14] int multiplier exponents."""
        return np.array([t.multiply for t in self.terms] or [[0] * len(TABLE_VARIABLES)], dtype=np.int64)

    def max_breakpoints(self) -> int:
        """L of :meth:`grid` (at least 2)."""
        return max([2] + [len(b) for t in self.terms for b in t.breakpoints])

    def grid(self) -> np.ndarray:
        """[K, 3, L] breakpoints per term and axis, padded with GRID_PAD (an unused axis holds 0 first)."""
        out = np.full((self.num_terms, MAX_TABLE_AXES, self.max_breakpoints()), GRID_PAD)
        out[:, :, 0] = 0.0
        for k, term in enumerate(self.terms):
            for a, bp in enumerate(term.breakpoints):
                out[k, a, :len(bp)] = bp
        return out


# ---------------------------------------------------------------------------------------------- parse
def parse_term(r: FieldReader, raw: Any, where: str, outputs: tuple[str, ...]) -> TableTerm:
    """Validate one JSON table term whose output is one of ``outputs``."""
    if not isinstance(raw, dict):
        raise r.fail(where, "expected an object like {\"output\": \"CL\", \"axes\": [...], \"values\": ...}")
    r.no_unknown(raw, {"name", "output", "gain", "multiply", "axes", "values"}, where)
    name = r.text(raw, "name", where) if "name" in raw else where
    output = r.get(raw, "output", where, str)
    if output not in outputs:
        raise r.fail(f"{where}.output", f"must be one of {list(outputs)}, got {output!r}")
    gain = r.get(raw, "gain", where, float, 1.0)
    multiply_raw = r.get(raw, "multiply", where, dict, {})
    r.no_unknown(multiply_raw, set(TABLE_VARIABLES), f"{where}.multiply")
    multiply = []
    for var in TABLE_VARIABLES:
        e = r.get(multiply_raw, var, f"{where}.multiply", int, 0)
        if not 0 <= e <= MAX_MULTIPLIER_EXPONENT:
            raise r.fail(f"{where}.multiply.{var}",
                         f"exponent must be in [0, {MAX_MULTIPLIER_EXPONENT}], got {e}")
        multiply.append(e)
    if multiply[TABLE_VARIABLES.index(ALPHA_DOT_VARIABLE)] > 1:
        raise r.fail(f"{where}.multiply.{ALPHA_DOT_VARIABLE}",
                     "alpha_dot may only enter linearly (exponent 1): the physics solves it in closed form")
    if multiply[TABLE_VARIABLES.index(ALPHA_DOT_VARIABLE)] and output not in TABLE_OUTPUTS[:AERO_OUTPUTS]:
        raise r.fail(f"{where}.multiply.{ALPHA_DOT_VARIABLE}", "alpha_dot is an aero variable, not a "
                                                             "thrust-map one")
    axes_raw = r.get(raw, "axes", where, list, [])
    if len(axes_raw) > MAX_TABLE_AXES:
        raise r.fail(f"{where}.axes", f"at most {MAX_TABLE_AXES} axes, got {len(axes_raw)}")
    variables, breakpoints = [], []
    for a, axis in enumerate(axes_raw):
        awhere = f"{where}.axes[{a}]"
        if not isinstance(axis, dict):
            raise r.fail(awhere, "expected an object {\"variable\": ..., \"breakpoints\": [...]}")
        r.no_unknown(axis, {"variable", "breakpoints"}, awhere)
        var = r.get(axis, "variable", awhere, str)
        if var not in TABLE_VARIABLES:
            raise r.fail(f"{awhere}.variable", f"must be one of {list(TABLE_VARIABLES)}, got {var!r}")
        if var == ALPHA_DOT_VARIABLE:
            raise r.fail(f"{awhere}.variable", "alpha_dot may not be a table axis, only a multiplier "
                                               "(exponent 1): the physics solves it in closed form where "
                                               "the force is linear in it")
        if TABLE_VARIABLES.index(var) in variables:
            raise r.fail(f"{awhere}.variable", f"{var!r} is already an axis of this term")
        bp = _numbers(r, axis, "breakpoints", awhere)
        if not 2 <= bp.size <= MAX_BREAKPOINTS or not np.all(np.diff(bp) > 0):
            raise r.fail(f"{awhere}.breakpoints", f"needs 2 to {MAX_BREAKPOINTS} strictly increasing numbers")
        variables.append(TABLE_VARIABLES.index(var))
        breakpoints.append(bp)
    shape = tuple(b.size for b in breakpoints)
    try:
        values = np.array(raw.get("values"), dtype=np.float64)
    except (TypeError, ValueError):
        raise r.fail(f"{where}.values", f"expected numbers nested as {list(shape)}") from None
    if "values" not in raw or values.shape != shape or not np.all(np.isfinite(values)):
        raise r.fail(f"{where}.values", f"expected finite numbers nested as {list(shape)}, got shape "
                                        f"{list(values.shape) if 'values' in raw else 'none'}")
    return TableTerm(name, TABLE_OUTPUTS.index(output), gain, tuple(multiply), tuple(variables),
                     tuple(breakpoints), values)


def _numbers(r: FieldReader, data: dict, key: str, where: str) -> np.ndarray:
    value = r.get(data, key, where, list)
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value):
        raise r.fail(f"{where}.{key}", "expected a list of numbers")
    out = np.array(value, dtype=np.float64)
    if not np.all(np.isfinite(out)):
        raise r.fail(f"{where}.{key}", "must be finite")
    return out


def parse_terms(r: FieldReader, raw: Any, where: str, outputs: tuple[str, ...]) -> list[TableTerm]:
    """A JSON list of table terms."""
    if not isinstance(raw, list):
        raise r.fail(where, "expected a list of table terms")
    return [parse_term(r, t, f"{where}[{i}]", outputs) for i, t in enumerate(raw)]
