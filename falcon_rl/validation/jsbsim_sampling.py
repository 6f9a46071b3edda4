"""JSBSim aero functions -> falcon-rl table terms, by sampling.

Each function of an ``<axis>`` is evaluated as a coefficient, C = f / (qbar S L_ref) (L_ref = b for
ROLL and YAW, c for PITCH, 1 for forces), on falcon-rl's variables (``TABLE_VARIABLES``: alpha, beta,
deflections, non-dimensional rates, airspeed, h/b, throttle, density), through a property context
that computes JSBSim's properties from them (:class:`PropertyContext`). Then, numerically:

1. dependencies: the variables whose change moves C at random points of the flight box;
2. multipliers: a dependency in which C is odd and homogeneous of degree one (C(2v) = 2 C(v),
   C(-v) = -C(v)) becomes a multiplier, so that ``qbar S c de 0.43`` is ``0.43 x elevator``;
3. while more than three remain, the weakest dependency (if it moves C by under WEAK_FRACTION of the
   strongest one's effect) is held at the reference point (e.g. the cos(alpha) in JSBSim's prop-wash
   dynamic pressure);
   (alpha_dot must: the physics solves it in closed form only where the force is linear in it);
4. the rest (at most three) become the table's axes, sampled on the union of the breakpoints of the
   tables indexed by that variable (so a table of tables is exact at its nodes) or on a default grid;
5. an axis in which C = x T(x) (JSBSim's ``alpha-rad`` times a table of ``alpha-rad``, not piecewise
   linear in x) is also made a multiplier when that makes the term exact (T then is piecewise linear).

The error each term leaves (table against the function at random points) is measured and returned, as
is every function that could not be expressed, with the reason.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..airframe_terms import ALPHA_DOT_VARIABLE, MAX_TABLE_AXES, TABLE_OUTPUTS, TABLE_VARIABLES, TableTerm
from ..constants import FT
from .jsbsim_functions import Node, UnsupportedFunctionError, multilinear, table_breakpoints

SLUG_FT3 = 515.378818  # kg/m^3 per slug/ft^3
DEG = np.pi / 180.0
#: Axis -> (output, reference length key or None).
AXES = {
    "LIFT": ("CL", None),
    "DRAG": ("CD", None),
    "SIDE": ("CY", None),
    "ROLL": ("Cl", "bw"),
    "PITCH": ("Cm", "cbarw"),
    "YAW": ("Cn", "bw"),
}
#: A dependency moving C by less than this fraction of the strongest one's effect may be held at the
#: reference point when more than three remain (weakest first); the error it leaves is measured.
WEAK_FRACTION = 0.15
#: A table axis also becomes a multiplier (C = x T(x)) when that cuts the term's largest error by this
#: factor: JSBSim's "alpha x table(alpha)" (the c182's C_m_alpha) is then exact instead of a chord.
SELF_MULTIPLIER_GAIN = 1e-3
#: Grid nodes closer to 0 than this count as 0 when an axis divides its own coefficient; the quotient
#: there is extrapolated from ZERO_STEP and 2 ZERO_STEP.
ZERO_NODE = 1e-12
#: A term whose largest error is below this is exact (round-off): nothing to improve.
EXACT = 1e-12
ZERO_STEP = 1e-6
V = {name: k for k, name in enumerate(TABLE_VARIABLES)}
#: Variables that may become multipliers.
MULTIPLIER_CANDIDATES = ("elevator", "aileron", "rudder", "p", "q", "r", "alpha_dot", "alpha", "beta")
#: Properties whose table breakpoints give a variable's grid: property -> (variable, scale to SI).
GRID_SOURCES: dict[str, tuple[str, float]] = {
    "aero/alpha-rad": ("alpha", 1.0),
    "aero/alpha-deg": ("alpha", DEG),
    "aero/beta-rad": ("beta", 1.0),
    "aero/beta-deg": ("beta", DEG),
    "aero/h_b-mac-ft": ("h_over_b", 1.0),
    "aero/h_b-cg-ft": ("h_over_b", 1.0),
    "fcs/elevator-pos-rad": ("elevator", 1.0),
    "fcs/left-aileron-pos-rad": ("aileron", 1.0),
    "fcs/rudder-pos-rad": ("rudder", 1.0),
}


@dataclass
class Flight:
    """The box the importer samples, SI: per variable (low, reference, high)."""

    box: dict[str, tuple[float, float, float]]
    grids: dict[str, np.ndarray]


@dataclass
class PropertyContext:
    """JSBSim properties computed from falcon-rl variables (arrays, broadcast together).

    ``held`` fixes properties the import does not model (flaps 0, gear down, stall hysteresis 0),
    ``engine`` maps (airspeed m/s, throttle, density kg/m^3) to sampled engine properties, and
    ``functions`` holds the aircraft's named functions (``aero/function/...``)."""

    metrics_ft: Mapping[str, float]
    held: Mapping[str, float]
    engine: Callable[[str, np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None
    functions: Mapping[str, Node]
    used: set[str]

    def bind(self, x: Mapping[str, np.ndarray]) -> Callable[[str], np.ndarray]:
        v_fps = x["airspeed"] / FT
        rho = x["density"] / SLUG_FT3
        b, c = self.metrics_ft["bw"], self.metrics_ft["cbarw"]
        p, q, r = x["p"] * 2 * v_fps / b, x["q"] * 2 * v_fps / c, x["r"] * 2 * v_fps / b
        alpha_dot = x["alpha_dot"] * 2 * v_fps / c
        table: dict[str, np.ndarray | float] = {
            "aero/alpha-rad": x["alpha"],
            "aero/alpha-deg": x["alpha"] / DEG,
            "aero/beta-rad": x["beta"],
            "aero/beta-deg": x["beta"] / DEG,
            "aero/mag-beta-rad": np.abs(x["beta"]),
            "fcs/elevator-pos-rad": x["elevator"],
            "fcs/mag-elevator-pos-rad": np.abs(x["elevator"]),
            "fcs/elevator-pos-deg": x["elevator"] / DEG,
            "fcs/left-aileron-pos-rad": x["aileron"],
            "fcs/right-aileron-pos-rad": -x["aileron"],
            "fcs/rudder-pos-rad": x["rudder"],
            "aero/bi2vel": b / (2 * v_fps),
            "aero/ci2vel": c / (2 * v_fps),
            "velocities/p-aero-rad_sec": p,
            "velocities/q-aero-rad_sec": q,
            "velocities/r-aero-rad_sec": r,
            "velocities/p-rad_sec": p,
            "velocities/q-rad_sec": q,
            "velocities/r-rad_sec": r,
            "aero/alphadot-rad_sec": alpha_dot,
            "aero/alphadot-deg_sec": alpha_dot / DEG,
            "aero/qbar-psf": 0.5 * rho * v_fps**2,
            "atmosphere/rho-slugs_ft3": rho,
            "velocities/vt-fps": v_fps,
            "velocities/u-aero-fps": v_fps * np.cos(x["alpha"]) * np.cos(x["beta"]),
            "aero/h_b-mac-ft": x["h_over_b"],
            "aero/h_b-cg-ft": x["h_over_b"],
            "metrics/Sw-sqft": self.metrics_ft["Sw"],
            "metrics/bw-ft": b,
            "metrics/cbarw-ft": c,
        }

        def get(name: str) -> np.ndarray:
            self.used.add(name)
            if name in table:
                return np.asarray(table[name])
            if name in self.held:
                return np.asarray(self.held[name])
            if name in self.functions:
                return self.functions[name](get)
            if name.startswith("propulsion/") and self.engine is not None:
                return self.engine(name, x["airspeed"] * np.cos(x["alpha"]), x["throttle"], x["density"])
            raise UnsupportedFunctionError(f"property {name!r} is not modelled by the importer")

        return get


def coefficient(
    node: Node, context: PropertyContext, ref: str | None, x: Mapping[str, np.ndarray]
) -> np.ndarray:
    """C = f / (qbar S L_ref) at the variables ``x``."""
    get = context.bind(x)
    scale = get("aero/qbar-psf") * context.metrics_ft["Sw"] * (context.metrics_ft[ref] if ref else 1.0)
    return node(get) / scale


def _random(flight: Flight, n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {k: rng.uniform(lo, hi, n) for k, (lo, _, hi) in flight.box.items()}


def convert(
    name: str, axis: str, node: Node, context: PropertyContext, flight: Flight, rng: np.random.Generator
) -> tuple[TableTerm | None, dict[str, object]]:
    """(the table term or None, a report row: name, axis, output, axes, multipliers, errors or reason)."""
    output, ref = AXES[axis]
    row: dict[str, object] = {"name": name, "axis": axis, "output": output}

    def c_at(x: Mapping[str, np.ndarray]) -> np.ndarray:
        return np.broadcast_to(
            coefficient(node, context, ref, x), np.broadcast_shapes(*(np.shape(v) for v in x.values()))
        ).astype(np.float64)

    base = _random(flight, 96, rng)
    c0 = c_at(base)
    deps = []
    for var in TABLE_VARIABLES:
        if var not in flight.box:
            continue
        moved = dict(base, **{var: _random(flight, 96, rng)[var]})
        if np.max(np.abs(c_at(moved) - c0)) > 1e-12 * max(1.0, float(np.max(np.abs(c0)))):
            deps.append(var)
    multiply = [0] * len(TABLE_VARIABLES)
    for var in [d for d in deps if d in MULTIPLIER_CANDIDATES]:
        t = base[var]
        doubled, negated = c_at(dict(base, **{var: 2 * t})), c_at(dict(base, **{var: -t}))
        tol = 1e-9 * max(1e-9, float(np.max(np.abs(c0))))
        if np.max(np.abs(doubled - 2 * c0)) < tol and np.max(np.abs(negated + c0)) < tol:
            multiply[V[var]] = 1
    rest = [d for d in deps if not multiply[V[d]]]
    if ALPHA_DOT_VARIABLE in rest:
        row["reason"] = "not linear in alpha-dot (the physics solves alpha-dot only where it multiplies)"
        row["rms_coefficient"] = float(np.sqrt(np.mean(c0**2)))
        return None, row
    reference = {k: np.asarray(mid) for k, (_, mid, _) in flight.box.items()}
    for var in [k for k in TABLE_VARIABLES if multiply[V[k]]]:
        reference[var] = np.asarray(1.0)
    held = []
    if len(rest) > MAX_TABLE_AXES:
        effect = {}
        for var in rest:
            lo, _, hi = flight.box[var]
            sweep = dict(reference, **{var: np.linspace(lo, hi, 9)})
            effect[var] = float(np.ptp(c_at(sweep)))
        scale = max(effect.values()) or 1.0
        for var in sorted(rest, key=lambda v: effect[v]):
            if len(rest) > MAX_TABLE_AXES and effect[var] < WEAK_FRACTION * scale:
                rest.remove(var)
                held.append(var)
    if len(rest) > MAX_TABLE_AXES:
        row["reason"] = f"depends on {rest}: more than {MAX_TABLE_AXES} table axes"
        row["rms_coefficient"] = float(np.sqrt(np.mean(c0**2)))
        return None, row
    grids = [grid_for(var, node, flight, context.functions) for var in rest]
    values = _table_values(c_at, reference, rest, grids, multiply)
    if not np.any(values):
        row["reason"] = f"zero at the held inputs {sorted(context.held)}" if not held else "zero"
        return None, row
    check = _random(flight, 2000, rng)
    exact = c_at(check)
    error = _table_error(values, rest, grids, multiply, check, exact)
    for var in [v for v in rest if v in MULTIPLIER_CANDIDATES and np.max(np.abs(error)) > EXACT]:
        # C = var T(var) (JSBSim's "alpha x table(alpha)") is not piecewise linear in var, T is
        own = list(multiply)
        own[V[var]] += 1
        own_values = _table_values(c_at, reference, rest, grids, own)
        own_error = _table_error(own_values, rest, grids, own, check, exact)
        if np.max(np.abs(own_error)) < SELF_MULTIPLIER_GAIN * np.max(np.abs(error)):
            multiply, values, error = own, own_values, own_error
    term = TableTerm(
        name,
        TABLE_OUTPUTS.index(output),
        1.0,
        tuple(multiply),
        tuple(V[v] for v in rest),
        tuple(grids),
        values,
    )
    row.update(
        axes=rest,
        multiply=[k for k in TABLE_VARIABLES if multiply[V[k]]],
        held_at_reference=held,
        max_error=float(np.max(np.abs(error))),
        rms_error=float(np.sqrt(np.mean(error**2))),
        rms_coefficient=float(np.sqrt(np.mean(exact**2))),
    )
    return term, row


def _table_values(
    c_at: Callable[[Mapping[str, np.ndarray]], np.ndarray],
    reference: Mapping[str, np.ndarray],
    axes: list[str],
    grids: list[np.ndarray],
    multiply: list[int],
) -> np.ndarray:
    """Table values on ``grids`` [G1, .., Gk] such that C = prod(x^multiply) T(axes) (the multipliers that
    are not axes are 1 in ``reference``). An axis that is also a multiplier divides C by its own value; at
    a node where that value is 0 the quotient is extrapolated linearly from two points just above it
    (exact for a piecewise-linear T)."""
    mesh = np.meshgrid(*grids, indexing="ij") if grids else []
    x = dict(reference, **{var: m for var, m in zip(axes, mesh, strict=True)})
    values = np.asarray(c_at(x) if grids else c_at(reference).reshape(()), dtype=np.float64)
    for var, grid_x in zip(axes, mesh, strict=True):
        if multiply[V[var]]:
            zero = np.abs(grid_x) < ZERO_NODE
            near = [c_at(dict(x, **{var: np.where(zero, h, grid_x)})) / h for h in (ZERO_STEP, 2 * ZERO_STEP)]
            values = np.where(zero, 2.0 * near[0] - near[1], values / np.where(zero, 1.0, grid_x))
    return values


def _table_error(
    values: np.ndarray,
    axes: list[str],
    grids: list[np.ndarray],
    multiply: list[int],
    check: Mapping[str, np.ndarray],
    exact: np.ndarray,
) -> np.ndarray:
    """The term's error [P] against ``exact`` = C at the ``check`` points."""
    factor = np.prod([check[k] ** e for k, e in zip(TABLE_VARIABLES, multiply, strict=True) if e], axis=0)
    approx = factor * (multilinear(tuple(grids), values, [check[v] for v in axes]) if grids else values)
    return approx - exact


def grid_for(var: str, node: Node, flight: Flight, functions: Mapping[str, Node]) -> np.ndarray:
    """The union of the variable's default grid and the breakpoints (SI) of the tables indexed by ``var``
    within ``node`` and the named functions it reads."""
    found = dict(table_breakpoints(node))
    for prop in node.properties & set(functions):
        for key, bp in table_breakpoints(functions[prop]).items():
            found[key] = np.union1d(found.get(key, np.array([])), bp)
    points = [
        bp * scale
        for prop, bp in found.items()
        for name, (v, scale) in GRID_SOURCES.items()
        if prop == name and v == var
    ]
    # The default grid joins the breakpoints: the extra nodes bound the interpolation error of a coefficient
    # that is not piecewise linear in ``var`` (a table times its own variable is made exact in ``convert``).
    merged = np.unique(np.round(np.concatenate([flight.grids[var], *points]), 9))
    return merged[np.concatenate([[True], np.diff(merged) > 1e-6])]
