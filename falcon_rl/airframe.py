"""Airframe description: load and validate an airframe JSON file into typed parameters.

The JSON schema is documented in ``airframes/README.md``. Every error raised here is an
:class:`AirframeError` whose message names the file, the field (as a dotted path) and the
constraint that failed, so that a bad file never reaches the physics kernels.
"""

from __future__ import annotations

import json
import math
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .airframe_terms import AERO_OUTPUTS, TABLE_OUTPUTS, TABLE_VARIABLES, TableSet, TableTerm, parse_terms
from .constants import G0

#: Largest power of one variable in an aero monomial (the Warp twin tabulates powers 0..6).
MAX_EXPONENT = 6
#: Aero model variables, in the order of the monomial exponent columns.
AERO_VARIABLES: tuple[str, ...] = ("alpha", "beta", "elevator", "aileron", "rudder")
#: Aerodynamic coefficients, in the order of the coefficient columns.
AERO_COEFFICIENTS: tuple[str, ...] = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
#: Non-dimensional rates (p b/2V, q c/2V, r b/2V).
RATE_NAMES: tuple[str, ...] = ("p", "q", "r")
#: Control surfaces, in the order of the command vector (throttle comes last).
SURFACES: tuple[str, ...] = ("elevator", "aileron", "rudder")
CONTROL_NAMES: tuple[str, ...] = (*SURFACES, "throttle")
POWERPLANTS: tuple[str, ...] = ("electric", "piston")
#: Aero model kinds: monomial tables only, or table terms (``airframe_tables``) on top of optional monomials.
AERO_KINDS: tuple[str, ...] = ("monomial", "tabulated")
#: Propeller models: momentum theory (discharge-velocity form), or the airframe's sampled thrust map.
MOTOR_MODELS: tuple[str, ...] = ("momentum", "thrust_map")
#: Largest magnitude of any number in an airframe file (1e300 is a typo, and it would overflow the physics).
MAX_MAGNITUDE = 1e9
#: Largest magnitude of an aero coefficient of a monomial or rate term.
MAX_COEFFICIENT = 1e6
#: Smallest positive physical quantity (a mass of 1e-300 kg is a typo, and it would overflow the physics).
MIN_POSITIVE = 1e-9
#: Largest airframe file, bytes.
MAX_FILE_BYTES = 16 * 2**20
#: Longest name or display name, characters.
MAX_NAME_LENGTH = 100

# The shipped JSON files: falcon_rl/airframes links to the repository's airframes/ folder and
# the wheel carries the files themselves.
_SHIPPED_DIR = Path(__file__).resolve().parent / "airframes"


class AirframeError(ValueError):
    """An airframe file failed validation; the message names file, field and constraint."""


@dataclass(frozen=True)
class Geometry:
    """Wing reference geometry. Lengths in m, areas in m^2."""

    wing_area: float
    span: float
    mean_chord: float
    aspect_ratio: float
    taper_ratio: float
    wing_quarter_chord: tuple[float, float, float]  # body FRD, relative to the CG


@dataclass(frozen=True)
class Actuator:
    """One control-surface actuator: first order (tau) or second order (omega_n, zeta)."""

    order: int
    time_constant: float  # s, first order
    natural_frequency: float  # rad/s, second order
    damping_ratio: float
    limits: tuple[float, float]  # rad, (min, max) deflection


@dataclass(frozen=True)
class Motor:
    """A propeller driven by a motor or engine (momentum theory, discharge-velocity form).

    T = 1/2 rho S_p C_p V_d (V_d - V_a) with V_d = V_a + delta_t (k_m - V_a), T >= 0.
    The reaction torque about the thrust axis is -spin * k_tp * (k_omega delta_t)^2.
    """

    name: str
    position: tuple[float, float, float]  # m, body FRD relative to the CG
    thrust_axis: tuple[float, float, float]  # unit vector, body FRD
    spin: int  # +1: propeller turns clockwise seen from behind, -1 otherwise
    disk_area: float  # S_p, m^2
    thrust_coefficient: float  # C_p
    discharge_speed: float  # k_m, m/s
    torque_coefficient: float  # k_tp, N m s^2
    torque_speed_constant: float  # k_omega, rad/s at full throttle
    time_constant: float  # s, first-order throttle lag
    powerplant: str
    model: str = "momentum"  # MOTOR_MODELS; "thrust_map" reads thrust and torque from Airframe.tables
    #: thrust-map motors: shift of the thrust line per rad of inflow angle (JSBSim's p-factor), m/rad
    p_factor: float = 0.0


@dataclass(frozen=True)
class Envelope:
    stall_speed: float
    cruise_speed: float
    max_speed: float
    max_bank: float  # rad
    climb_rate_limit: float  # m/s


@dataclass(frozen=True)
class AeroModel:
    """Monomial tables: C_k = sum_t coef[t, k] * prod_j x_j^exponents[t, j] + rates[k] . p_hat."""

    exponents: np.ndarray  # [T, 5] int, columns AERO_VARIABLES
    coefficients: np.ndarray  # [T, 6] float, columns AERO_COEFFICIENTS
    rate_derivatives: np.ndarray  # [6, 3] float, rows AERO_COEFFICIENTS, columns p, q, r
    oswald_efficiency: float
    alpha_range: tuple[float, float]
    beta_range: tuple[float, float]
    alpha_stall: float
    kind: str = "monomial"  # AERO_KINDS
    #: Point the moment coefficients are taken about and the aero forces act at (body FRD, relative
    #: to the CG, m): the CG itself unless the file gives ``moment_reference_m`` (JSBSim's AERORP).
    moment_reference: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Airframe:
    """A validated airframe. All quantities SI, angles in rad."""

    name: str
    display_name: str
    path: Path
    geometry: Geometry
    mass: float
    inertia: np.ndarray  # [3, 3] body inertia tensor about the CG, kg m^2
    aero: AeroModel
    motors: tuple[Motor, ...]
    actuators: dict[str, Actuator]
    envelope: Envelope
    provenance: dict[str, Any] = field(default_factory=dict)
    #: Table terms (aero ``aero.tables`` and the propulsion ``thrust_map``), sorted by output.
    tables: TableSet = field(default_factory=TableSet)

    @property
    def num_motors(self) -> int:
        return len(self.motors)

    @property
    def weight(self) -> float:
        return self.mass * G0

    def summary(self) -> dict[str, Any]:
        """One row of ``falcon-rl airframes``."""
        g = self.geometry
        return {
            "name": self.name,
            "display_name": self.display_name,
            "span_m": g.span,
            "wing_area_m2": g.wing_area,
            "mean_chord_m": g.mean_chord,
            "aspect_ratio": g.aspect_ratio,
            "taper_ratio": g.taper_ratio,
            "mass_kg": self.mass,
            "motors": self.num_motors,
            "powerplant": self.motors[0].powerplant if self.motors else "none",
            "stall_speed_mps": self.envelope.stall_speed,
            "cruise_speed_mps": self.envelope.cruise_speed,
            "max_speed_mps": self.envelope.max_speed,
        }


def list_airframes() -> list[str]:
    """Names of the airframes shipped with falcon-rl."""
    return sorted(p.stem for p in _shipped_files())


def load_airframe(name_or_path: str | Path) -> Airframe:
    """Load and validate an airframe by shipped name (``"navion"``) or by JSON path."""
    path = _resolve(name_or_path)
    return parse_airframe(read_json_strictly(path), path)


class _RefusedError(ValueError):
    """A JSON construct the airframe format refuses (raised while decoding, reported with the file)."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """object_pairs_hook: a JSON object as a dict, refusing a key given twice (the last would win)."""
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _RefusedError(f"duplicate key {key!r} in one JSON object (the later value would win)")
        seen[key] = value
    return seen


def _first_nonfinite(document: Any) -> str | None:
    """The dotted path of the first NaN or infinite number in a decoded document (walked without
    recursion), or None."""
    stack: list[tuple[str, Any]] = [("", document)]
    while stack:
        where, value = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            return where or "<root>"
        if isinstance(value, dict):
            stack.extend((f"{where}.{k}" if where else str(k), v) for k, v in reversed(value.items()))
        elif isinstance(value, list):
            stack.extend((f"{where}[{i}]", v) for i, v in reversed(list(enumerate(value))))
    return None


def read_json_strictly(path: Path, error: type[Exception] = AirframeError, kind: str = "airframe") -> Any:
    """The decoded document of ``path``: strict UTF-8 (a UTF-8 byte-order mark is skipped), strict JSON
    (no duplicate keys, NaN, Infinity or numbers beyond the float range), at most MAX_FILE_BYTES;
    ``error`` naming the file (and the field) otherwise; ``kind`` names the file's kind in messages."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise error(f"{path}: {size} bytes; {kind} files are at most {MAX_FILE_BYTES} bytes")
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror or type(exc).__name__})") from None
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise error(f"{path}: UTF-16 text; save the {kind} file as UTF-8")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})"
                            ) from None
    try:
        document = json.loads(text, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except _RefusedError as exc:
        raise error(f"{path}: {exc}") from None
    except RecursionError:
        raise error(f"{path}: JSON nested too deep ({kind} files nest a few levels)") from None
    except ValueError as exc:  # an integer literal of thousands of digits
        raise error(f"{path}: not valid JSON ({exc})") from None
    where = _first_nonfinite(document)
    if where is not None:
        raise error(f"{path}: field '{where}': must be finite (NaN and Infinity are not JSON)")
    return document


def _shipped_files() -> list[Path]:
    return sorted(_SHIPPED_DIR.glob("*.json"))


def _resolve(name_or_path: str | Path) -> Path:
    candidate = Path(name_or_path)
    if "\0" in str(name_or_path):
        raise AirframeError(f"{str(name_or_path)!r}: not a valid path (it holds a NUL character)")
    if candidate.suffix == ".json" or candidate.exists():
        if candidate.is_dir():
            raise AirframeError(f"{candidate}: a directory, not an airframe file")
        if not candidate.is_file():
            raise AirframeError(f"{candidate}: airframe file not found")
        return candidate
    for path in _shipped_files():
        if path.stem == str(name_or_path):
            return path
    raise AirframeError(
        f"unknown airframe {name_or_path!r}: expected one of {list_airframes()} or a .json path"
    )


class _Reader:
    """Typed field access that reports file and dotted field path on error."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, where: str, constraint: str) -> AirframeError:
        return AirframeError(f"{self.path}: field '{where}': {constraint}")

    def section(self, data: dict, key: str, where: str, allowed: set[str]) -> dict:
        value = self.get(data, key, where, dict)
        self.no_unknown(value, allowed, f"{where}.{key}" if where else key)
        return value

    def no_unknown(self, data: dict, allowed: set[str], where: str) -> None:
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise self.fail(where, f"unknown field(s) {unknown}; allowed: {sorted(allowed)}")

    def get(self, data: dict, key: str, where: str, kind: type | tuple, default: Any = ...) -> Any:
        name = f"{where}.{key}" if where else key
        if key not in data:
            if default is not ...:
                return default
            raise self.fail(name, "missing required field")
        value = data[key]
        if isinstance(value, bool) and kind is not bool:
            raise self.fail(name, f"expected {_kind_name(kind)}, got bool")
        if isinstance(value, int | float) and not isinstance(value, bool):
            if isinstance(value, float) and not math.isfinite(value):
                raise self.fail(name, "must be finite")
            if abs(value) > MAX_MAGNITUDE:
                size = f"{value:.3g}" if isinstance(value, float) else f"~1e{len(str(abs(value))) - 1}"
                raise self.fail(name, f"magnitude {size} is absurd (at most {MAX_MAGNITUDE:g})")
            if kind is float:
                value = float(value)
        if not isinstance(value, kind):
            raise self.fail(name, f"expected {_kind_name(kind)}, got {type(value).__name__}")
        return value

    def positive(self, data: dict, key: str, where: str, default: Any = ...) -> float:
        value = self.get(data, key, where, float, default)
        if not value > 0:
            raise self.fail(f"{where}.{key}", f"must be > 0, got {value}")
        if value < MIN_POSITIVE:
            raise self.fail(f"{where}.{key}", f"{value:.3g} is absurdly small (at least {MIN_POSITIVE:g})")
        return value

    def vector(self, data: dict, key: str, where: str, length: int) -> tuple[float, ...]:
        value = self.get(data, key, where, list)
        if len(value) != length or not all(_is_number(v) for v in value):
            raise self.fail(f"{where}.{key}", f"expected a list of {length} numbers (finite, of magnitude at "
                                              f"most {MAX_MAGNITUDE:g})")
        return tuple(float(v) for v in value)

    def interval(self, data: dict, key: str, where: str, bound: float = MAX_MAGNITUDE) -> tuple[float, float]:
        lo, hi = self.vector(data, key, where, 2)
        if not lo < hi:
            raise self.fail(f"{where}.{key}", f"limits out of order: [{lo}, {hi}] needs min < max")
        if not -bound <= lo < hi <= bound:
            raise self.fail(f"{where}.{key}", f"[{lo}, {hi}] must lie within [{-bound:.4g}, {bound:.4g}]")
        return lo, hi

    def text(self, data: dict, key: str, where: str, default: Any = ..., file_name: bool = False) -> str:
        """A non-empty printable string (no control characters); with ``file_name``, also usable as a
        file name (no path separators, no leading dot), as the outputs named after an airframe need."""
        name = f"{where}.{key}" if where else key
        value = self.get(data, key, where, str, default)
        if not value.strip() or len(value) > MAX_NAME_LENGTH:
            raise self.fail(name, f"must be 1 to {MAX_NAME_LENGTH} characters, got {len(value)}")
        if any(unicodedata.category(ch).startswith("C") for ch in value):
            raise self.fail(name, "contains control characters (terminal escapes, newlines, ...)")
        if file_name and ("/" in value or "\\" in value or value.startswith(".")):
            raise self.fail(name, "must be usable as a file name: no '/' or '\\', no leading '.'")
        return value


def _is_number(value: Any) -> bool:
    return (isinstance(value, int | float) and not isinstance(value, bool) and abs(value) <= MAX_MAGNITUDE
            and math.isfinite(value))


def _kind_name(kind: type | tuple) -> str:
    names = {float: "number", int: "integer", str: "string", list: "list", dict: "object"}
    if isinstance(kind, tuple):
        return " or ".join(names.get(k, k.__name__) for k in kind)
    return names.get(kind, kind.__name__)


_TOP = {"schema_version", "name", "display_name", "description", "geometry", "mass", "aero",
        "propulsion", "actuators", "envelope", "provenance"}


def parse_airframe(raw: Any, path: Path) -> Airframe:
    """Validate a decoded airframe document; ``path`` is only used in error messages."""
    r = _Reader(Path(path))
    if not isinstance(raw, dict):
        raise r.fail("<root>", "expected a JSON object")
    r.no_unknown(raw, _TOP, "<root>")
    version = r.get(raw, "schema_version", "", int)
    if version != 1:
        raise r.fail("schema_version", f"unsupported version {version}; this falcon-rl reads 1")
    name = r.text(raw, "name", "", file_name=True)
    display_name = r.text(raw, "display_name", "", name)
    geometry = _parse_geometry(r, raw)
    mass, inertia = _parse_mass(r, raw)
    aero, aero_terms = _parse_aero(r, raw)
    motors, map_terms = _parse_propulsion(r, raw)
    actuators = _parse_actuators(r, raw)
    envelope = _parse_envelope(r, raw, aero)
    provenance = r.get(raw, "provenance", "", dict)
    if not provenance.get("sources") or not provenance.get("method"):
        raise r.fail("provenance", "needs non-empty 'sources' and 'method'")
    return Airframe(
        name=name,
        display_name=display_name,
        path=Path(path),
        geometry=geometry,
        mass=mass,
        inertia=inertia,
        aero=aero,
        motors=motors,
        actuators=actuators,
        envelope=envelope,
        provenance=provenance,
        tables=TableSet(tuple(aero_terms + map_terms)).sorted(),
    )


def _parse_geometry(r: _Reader, raw: dict) -> Geometry:
    keys = {"wing_area_m2", "span_m", "mean_chord_m", "aspect_ratio", "taper_ratio",
            "wing_quarter_chord_m"}
    g = r.section(raw, "geometry", "", keys)
    area = r.positive(g, "wing_area_m2", "geometry")
    span = r.positive(g, "span_m", "geometry")
    chord = r.positive(g, "mean_chord_m", "geometry")
    aspect = r.positive(g, "aspect_ratio", "geometry")
    taper = r.positive(g, "taper_ratio", "geometry")
    if taper > 1.0:
        raise r.fail("geometry.taper_ratio", f"must be in (0, 1], got {taper}")
    expected = span**2 / area
    if abs(aspect - expected) > 0.02 * expected:
        raise r.fail(
            "geometry.aspect_ratio",
            f"inconsistent with span^2/area = {expected:.3f} (got {aspect}; tolerance 2%)",
        )
    qc = r.vector(g, "wing_quarter_chord_m", "geometry", 3)
    return Geometry(area, span, chord, aspect, taper, (qc[0], qc[1], qc[2]))


def _parse_mass(r: _Reader, raw: dict) -> tuple[float, np.ndarray]:
    keys = {"mass_kg", "ixx_kg_m2", "iyy_kg_m2", "izz_kg_m2", "ixz_kg_m2", "ixy_kg_m2", "iyz_kg_m2"}
    m = r.section(raw, "mass", "", keys)
    mass = r.positive(m, "mass_kg", "mass")
    ixx = r.positive(m, "ixx_kg_m2", "mass")
    iyy = r.positive(m, "iyy_kg_m2", "mass")
    izz = r.positive(m, "izz_kg_m2", "mass")
    ixz = r.get(m, "ixz_kg_m2", "mass", float, 0.0)
    ixy = r.get(m, "ixy_kg_m2", "mass", float, 0.0)
    iyz = r.get(m, "iyz_kg_m2", "mass", float, 0.0)
    # Products of inertia enter with a minus sign: J = [[Ixx, -Ixy, -Ixz], ...].
    inertia = np.array([[ixx, -ixy, -ixz], [-ixy, iyy, -iyz], [-ixz, -iyz, izz]])
    eig = np.linalg.eigvalsh(inertia)
    if eig.min() <= 0:
        raise r.fail("mass", f"inertia tensor not positive definite (eigenvalues {eig.round(6)})")
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        if eig[a] + eig[b] < eig[c] * (1 - 1e-9):
            raise r.fail(
                "mass",
                "principal moments violate the triangle inequality "
                f"({eig[a]:.6g} + {eig[b]:.6g} < {eig[c]:.6g}): not a physical rigid body",
            )
    return mass, inertia


def _parse_aero(r: _Reader, raw: dict) -> tuple[AeroModel, list[TableTerm]]:
    keys = {"kind", "coefficients", "tables", "oswald_efficiency", "alpha_range_rad", "beta_range_rad",
            "alpha_stall_rad", "moment_reference_m", "notes"}
    a = r.section(raw, "aero", "", keys)
    kind = r.get(a, "kind", "aero", str, "monomial")
    if kind not in AERO_KINDS:
        raise r.fail("aero.kind", f"must be one of {list(AERO_KINDS)}, got {kind!r}")
    if kind == "monomial" and "tables" in a:
        raise r.fail("aero.tables", "only an aero model of kind 'tabulated' has tables")
    table_terms = parse_terms(r, a.get("tables"), "aero.tables", TABLE_OUTPUTS[:AERO_OUTPUTS]) \
        if kind == "tabulated" else []
    if kind == "tabulated":
        _check_tables(r, table_terms)
    oswald = r.positive(a, "oswald_efficiency", "aero")
    if oswald > 1.0:
        raise r.fail("aero.oswald_efficiency", f"must be in (0, 1], got {oswald}")
    alpha_range = r.interval(a, "alpha_range_rad", "aero", math.pi / 2)
    beta_range = r.interval(a, "beta_range_rad", "aero", math.pi / 2)
    alpha_stall = r.positive(a, "alpha_stall_rad", "aero")
    if not alpha_range[0] < alpha_stall <= alpha_range[1] * 1.5:
        raise r.fail("aero.alpha_stall_rad", f"must lie in the alpha range {alpha_range}")
    coeffs = r.section(a, "coefficients", "aero", set(AERO_COEFFICIENTS)) if kind == "monomial" or (
        "coefficients" in a) else {}
    monomials: dict[tuple[int, ...], np.ndarray] = {}
    rates = np.zeros((len(AERO_COEFFICIENTS), len(RATE_NAMES)))
    for k, cname in enumerate(AERO_COEFFICIENTS):
        where = f"aero.coefficients.{cname}"
        if kind == "tabulated" and cname not in coeffs:
            continue
        entry = r.get(coeffs, cname, "aero.coefficients", dict)
        r.no_unknown(entry, {"terms", "rates"}, where)
        terms = r.get(entry, "terms", where, list)
        for i, term in enumerate(terms):
            twhere = f"{where}.terms[{i}]"
            if not isinstance(term, dict):
                raise r.fail(twhere, "expected an object like {\"coef\": 4.4, \"alpha\": 1}")
            r.no_unknown(term, {"coef", *AERO_VARIABLES}, twhere)
            coef = _coefficient(r, term, "coef", twhere)
            powers = []
            for var in AERO_VARIABLES:
                p = r.get(term, var, twhere, int, 0)
                if not 0 <= p <= MAX_EXPONENT:
                    raise r.fail(f"{twhere}.{var}",
                                 f"exponent must be an integer in [0, {MAX_EXPONENT}], got {p}")
                powers.append(p)
            row = monomials.setdefault(tuple(powers), np.zeros(len(AERO_COEFFICIENTS)))
            row[k] += coef
        rate_entry = r.get(entry, "rates", where, dict, {})
        r.no_unknown(rate_entry, set(RATE_NAMES), f"{where}.rates")
        for j, rname in enumerate(RATE_NAMES):
            rates[k, j] = _coefficient(r, rate_entry, rname, f"{where}.rates", 0.0)
    if not monomials and kind == "monomial":
        raise r.fail("aero.coefficients", "no monomial terms at all")
    if not monomials:  # a tabulated model without monomials binds one zero term
        monomials[(0,) * len(AERO_VARIABLES)] = np.zeros(len(AERO_COEFFICIENTS))
    keys_sorted = sorted(monomials)
    exponents = np.array(keys_sorted, dtype=np.int64).reshape(-1, len(AERO_VARIABLES))
    table = np.stack([monomials[k] for k in keys_sorted])
    if kind == "monomial":
        _check_not_empty(r, exponents, table, rates)
    ref = r.vector(a, "moment_reference_m", "aero", 3) if "moment_reference_m" in a else (0.0, 0.0, 0.0)
    model = AeroModel(exponents, table, rates, oswald, alpha_range, beta_range, alpha_stall, kind,
                      (float(ref[0]), float(ref[1]), float(ref[2])))
    return model, table_terms


def _check_tables(r: _Reader, terms: list[TableTerm]) -> None:
    """Refuse a tabulated model with no lift term in alpha or no drag term."""
    alpha = TABLE_VARIABLES.index("alpha")
    lift = [t for t in terms if t.output == 0 and (alpha in t.variables or t.multiply[alpha])]
    if not lift:
        raise r.fail("aero.tables", "needs a CL term in alpha (an axis or a multiplier)")
    if not any(t.output == 1 for t in terms):
        raise r.fail("aero.tables", "needs a CD term")


def _coefficient(r: _Reader, data: dict, key: str, where: str, default: Any = ...) -> float:
    """An aero coefficient: a finite number of magnitude at most MAX_COEFFICIENT."""
    value = r.get(data, key, where, float, default)
    if abs(value) > MAX_COEFFICIENT:
        raise r.fail(f"{where}.{key}", f"magnitude {value:.3g} is absurd for an aero coefficient "
                                       f"(at most {MAX_COEFFICIENT:g})")
    return value


def _check_not_empty(r: _Reader, exponents: np.ndarray, table: np.ndarray, rates: np.ndarray) -> None:
    """Refuse a physically empty model: every coefficient needs a non-zero term or rate derivative, lift a
    term in alpha, and drag a positive zero-lift term (C_D at zero alpha, beta and deflections)."""
    for k, cname in enumerate(AERO_COEFFICIENTS):
        if not table[:, k].any() and not rates[k].any():
            raise r.fail(f"aero.coefficients.{cname}", "every term and rate is zero or absent: a physically "
                                                      "empty model")
    alpha = AERO_VARIABLES.index("alpha")
    if not table[exponents[:, alpha] > 0, AERO_COEFFICIENTS.index("CL")].any():
        raise r.fail("aero.coefficients.CL", "needs a term in alpha (a lift curve slope)")
    constant = ~exponents.any(axis=1)
    cd0 = float(table[constant, AERO_COEFFICIENTS.index("CD")].sum())
    if not cd0 > 0:
        raise r.fail("aero.coefficients.CD", f"needs a positive zero-lift drag term (the constant term is "
                                             f"{cd0:g})")


def _parse_propulsion(r: _Reader, raw: dict) -> tuple[tuple[Motor, ...], list[TableTerm]]:
    p = r.section(raw, "propulsion", "", {"motors", "thrust_map"})
    map_terms = parse_terms(r, p["thrust_map"], "propulsion.thrust_map", TABLE_OUTPUTS[AERO_OUTPUTS:]) \
        if "thrust_map" in p else []
    motors_raw = r.get(p, "motors", "propulsion", list)
    if not motors_raw:
        raise r.fail("propulsion.motors", "needs at least one motor")
    keys = {"name", "position_m", "thrust_axis", "spin", "disk_area_m2", "thrust_coefficient",
            "discharge_speed_mps", "torque_coefficient", "torque_speed_constant_rad_s",
            "time_constant_s", "powerplant", "model", "p_factor_m_per_rad"}
    motors = []
    for i, m in enumerate(motors_raw):
        where = f"propulsion.motors[{i}]"
        if not isinstance(m, dict):
            raise r.fail(where, "expected an object")
        r.no_unknown(m, keys, where)
        axis = np.array(r.vector(m, "thrust_axis", where, 3))
        norm = float(np.linalg.norm(axis))
        if abs(norm - 1.0) > 1e-3:
            raise r.fail(f"{where}.thrust_axis", f"must be a unit vector, norm is {norm:.4f}")
        spin = r.get(m, "spin", where, int)
        if spin not in (-1, 1):
            raise r.fail(f"{where}.spin", f"must be +1 or -1, got {spin}")
        plant = r.get(m, "powerplant", where, str)
        if plant not in POWERPLANTS:
            raise r.fail(f"{where}.powerplant", f"must be one of {list(POWERPLANTS)}, got {plant!r}")
        torque = r.get(m, "torque_coefficient", where, float, 0.0)
        if torque < 0:
            raise r.fail(f"{where}.torque_coefficient", f"must be >= 0, got {torque}")
        model = r.get(m, "model", where, str, "momentum")
        if model not in MOTOR_MODELS:
            raise r.fail(f"{where}.model", f"must be one of {list(MOTOR_MODELS)}, got {model!r}")
        if model == "thrust_map" and not any(t.output == TABLE_OUTPUTS.index("thrust") for t in map_terms):
            raise r.fail(f"{where}.model", "a thrust_map motor needs a thrust term in propulsion.thrust_map")
        # A thrust-map motor reads no momentum-theory constant: they default to 1 (unused).
        unused = 1.0 if model == "thrust_map" else ...
        ax = tuple(float(v) for v in axis / norm)
        motors.append(Motor(
            name=r.text(m, "name", where, f"motor{i}"),
            position=tuple(r.vector(m, "position_m", where, 3)),  # type: ignore[arg-type]
            thrust_axis=ax,  # type: ignore[arg-type]
            spin=spin,
            disk_area=r.positive(m, "disk_area_m2", where, unused),
            thrust_coefficient=r.positive(m, "thrust_coefficient", where, unused),
            discharge_speed=r.positive(m, "discharge_speed_mps", where, unused),
            torque_coefficient=torque,
            torque_speed_constant=r.get(m, "torque_speed_constant_rad_s", where, float, 0.0),
            time_constant=r.positive(m, "time_constant_s", where),
            powerplant=plant,
            model=model,
            p_factor=_p_factor(r, m, where, model),
        ))
    return tuple(motors), map_terms


def _p_factor(r: _Reader, motor: dict, where: str, model: str) -> float:
    """A thrust-map motor's p-factor (m of thrust-line shift per rad of inflow angle, >= 0)."""
    value = r.get(motor, "p_factor_m_per_rad", where, float, 0.0)
    if value < 0 or (value and model != "thrust_map"):
        raise r.fail(f"{where}.p_factor_m_per_rad",
                     f"must be >= 0, and only on a thrust_map motor; got {value}")
    return value


def _parse_actuators(r: _Reader, raw: dict) -> dict[str, Actuator]:
    a = r.section(raw, "actuators", "", set(SURFACES))
    out = {}
    for name in SURFACES:
        where = f"actuators.{name}"
        entry = r.get(a, name, "actuators", dict)
        r.no_unknown(entry, {"order", "time_constant_s", "natural_frequency_rad_s",
                             "damping_ratio", "limits_rad"}, where)
        order = r.get(entry, "order", where, int)
        if order not in (1, 2):
            raise r.fail(f"{where}.order", f"must be 1 or 2, got {order}")
        if order == 1:
            tau = r.positive(entry, "time_constant_s", where)
            wn, zeta = 0.0, 0.0
        else:
            tau = 0.0
            wn = r.positive(entry, "natural_frequency_rad_s", where)
            zeta = r.positive(entry, "damping_ratio", where)
        lo, hi = r.interval(entry, "limits_rad", where, math.pi / 2)
        if not lo <= 0.0 <= hi:
            raise r.fail(f"{where}.limits_rad", f"must contain 0, got [{lo}, {hi}]")
        out[name] = Actuator(order, tau, wn, zeta, (lo, hi))
    return out


def _parse_envelope(r: _Reader, raw: dict, aero: AeroModel) -> Envelope:
    keys = {"stall_speed_mps", "cruise_speed_mps", "max_speed_mps", "max_bank_rad",
            "climb_rate_limit_mps"}
    e = r.section(raw, "envelope", "", keys)
    stall = r.positive(e, "stall_speed_mps", "envelope")
    cruise = r.positive(e, "cruise_speed_mps", "envelope")
    vmax = r.positive(e, "max_speed_mps", "envelope")
    if not stall < cruise < vmax:
        raise r.fail("envelope", f"speeds out of order: need stall {stall} < cruise {cruise} "
                                 f"< max {vmax}")
    bank = r.positive(e, "max_bank_rad", "envelope")
    if bank >= math.pi / 2:
        raise r.fail("envelope.max_bank_rad", f"must be < pi/2, got {bank}")
    return Envelope(stall, cruise, vmax, bank, r.positive(e, "climb_rate_limit_mps", "envelope"))
