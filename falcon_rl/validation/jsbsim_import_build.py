"""Assemble the airframe document of an imported JSBSim aircraft (``jsbsim_import``)."""

from __future__ import annotations

import hashlib
import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from ..airframe_terms import TABLE_OUTPUTS, TableTerm
from ..constants import FT, G0
from .jsbsim_engine import LBF, EngineMap, sample_engine
from .jsbsim_functions import UnsupportedFunctionError, multilinear, parse_function
from .jsbsim_import import (
    APPROXIMATIONS,
    HELD,
    Imported,
    JSBSimImportError,
    location,
    mass_properties,
    measure,
    resolve,
    surface_limits,
    to_body,
    xml_root,
)
from .jsbsim_propeller import PROPELLER_RPM, Propeller, read_propeller
from .jsbsim_sampling import AXES, Flight, PropertyContext, V, convert

ENGINE_SPEEDS = np.array([0.0, 10.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 55.0, 60.0, 65.0, 70.0, 80.0,
                          95.0])  # m/s
#: Every 0.05, every 0.025 above 0.8: a piston engine's thrust is far from linear in throttle (manifold
#: pressure) and flattens near full throttle, where a coarse grid (0.8, 1.0) left the trim throttle of the
#: pa28 and the c182 off by up to 0.2.
ENGINE_THROTTLES = np.union1d(np.linspace(0.0, 0.8, 17), np.linspace(0.8, 1.0, 9))
#: Every 250 m: with the mixture full rich, JSBSim's piston engines lose thrust steeply above ~1000 m
#: (the pa28's by 10 % from 1000 to 1500 m), and they stop above ~2700 m, so the map ends at 2500 m.
ENGINE_ALTITUDES = np.arange(0.0, 2501.0, 250.0)  # m
ACTUATOR_TIME_CONSTANT = 0.03  # s: JSBSim's aerosurface_scale has no lag; a short first-order lag here


def _flight(limits: dict[str, tuple[float, float]], cruise_guess: float, engine: EngineMap) -> Flight:
    """The sampling box and default grids; terms that read the engine (prop wash) are tabulated on the
    engine map's own airspeed, throttle and density nodes, so they add no second interpolation."""
    box = {
        "alpha": (-0.1, 0.05, 0.3),
        "beta": (-0.2, 0.0, 0.2),
        "p": (-0.05, 0.0, 0.05),
        "q": (-0.05, 0.0, 0.05),
        "r": (-0.05, 0.0, 0.05),
        "alpha_dot": (-0.05, 0.0, 0.05),
        "airspeed": (20.0, cruise_guess, 80.0),
        "h_over_b": (0.0, 100.0, 1.5),
        "throttle": (0.0, 0.6, 1.0),
        "density": (0.9, 1.1, 1.225),
    }
    for surface, (lo, hi) in limits.items():
        box[surface] = (lo, 0.0, hi)
    grids = {
        "alpha": np.linspace(-0.2, 0.5, 15),
        "beta": np.array([-0.35, -0.2, -0.1, 0.0, 0.1, 0.2, 0.35]),
        "p": np.array([-0.1, 0.0, 0.1]),
        "q": np.array([-0.1, 0.0, 0.1]),
        "r": np.array([-0.1, 0.0, 0.1]),
        "alpha_dot": np.array([-0.1, 0.0, 0.1]),
        "airspeed": engine.airspeed[engine.airspeed >= 10.0],
        "throttle": engine.throttle,
        "density": engine.density,
        "h_over_b": np.array([0.0, 0.1, 0.2, 0.5, 1.1]),
    }
    for surface, (lo, hi) in limits.items():
        grids[surface] = np.array([lo, 0.0, hi])
    return Flight(box, grids)


def _aero_terms(
    el: ET.Element, path: Path, context: PropertyContext, flight: Flight, rng: np.random.Generator
) -> tuple[list[TableTerm], list[dict[str, Any]]]:
    aero = el.find("aerodynamics")
    if aero is None:
        raise JSBSimImportError(f"{path}: field 'aerodynamics': missing")
    terms, rows = [], []
    for axis in aero.findall("axis"):
        axis_name = axis.get("name", "").upper()
        for fn in axis.findall("function"):
            fname = fn.get("name", "?")
            if axis_name not in AXES:
                rows.append(
                    {"name": fname, "axis": axis_name, "reason": "axis not in LIFT DRAG SIDE ROLL PITCH YAW"}
                )
                continue
            try:
                term, row = convert(fname, axis_name, parse_function(fn), context, flight, rng)
            except UnsupportedFunctionError as exc:
                term, row = None, {"name": fname, "axis": axis_name, "reason": str(exc)}
            rows.append(row)
            if term is not None:
                terms.append(term)
    return terms, rows


def _named_functions(el: ET.Element) -> dict[str, Any]:
    out = {}
    aero = el.find("aerodynamics")
    for fn in aero.findall("function") if aero is not None else []:
        try:
            out[fn.get("name", "")] = parse_function(fn)
        except UnsupportedFunctionError:
            continue
    return out


def _engine_properties(el: ET.Element) -> tuple[str, ...]:
    names = {
        p.text.strip() for p in el.iter("property") if p.text and p.text.strip().startswith("propulsion/")
    }
    return tuple(sorted(names))


def _thrust_map(engine: EngineMap, propeller: Propeller) -> list[dict[str, Any]]:
    axes = [
        {"variable": "airspeed", "breakpoints": engine.airspeed.tolist()},
        {"variable": "throttle", "breakpoints": engine.throttle.tolist()},
        {"variable": "density", "breakpoints": engine.density.round(6).tolist()},
    ]
    angular_momentum = propeller.gyroscopic_sign * propeller.ixx * engine.properties[PROPELLER_RPM] * (
        2 * math.pi / 60)
    return [
        {"name": "thrust", "output": "thrust", "axes": axes, "values": engine.thrust.round(3).tolist()},
        {"name": "torque", "output": "torque", "axes": axes, "values": engine.torque.round(3).tolist()},
        {"name": "angular_momentum", "output": "angular_momentum", "axes": axes,
         "values": angular_momentum.round(4).tolist()},
    ]


def term_total(terms: list[TableTerm], output: str, x: dict[str, np.ndarray]) -> np.ndarray:
    """Sum of the terms of ``output`` at the variables ``x`` (name -> array, all of one shape)."""
    names = list(V)
    out = np.zeros_like(x["alpha"])
    for t in terms:
        if TABLE_OUTPUTS[t.output] != output:
            continue
        factor = np.prod([x[k] ** e for k, e in zip(names, t.multiply, strict=True) if e], axis=0)
        table = (
            multilinear(tuple(t.breakpoints), t.values, [x[names[v]] for v in t.variables])
            if t.variables
            else t.values
        )
        out = out + t.gain * factor * table
    return out


def _free_air(alpha: np.ndarray, airspeed: float, throttle: float) -> dict[str, np.ndarray]:
    x = {name: np.zeros_like(alpha) for name in V}
    x.update(
        alpha=alpha,
        airspeed=np.full_like(alpha, airspeed),
        h_over_b=np.full_like(alpha, 100.0),
        density=np.full_like(alpha, 1.225),
        throttle=np.full_like(alpha, throttle),
    )
    return x


def _polar(terms: list[TableTerm], aspect: float) -> tuple[float, float, float]:
    """(Oswald e from the free-air polar, alpha at CL max, CL max), flaps up, no deflections."""
    alpha = np.linspace(-0.1, 0.45, 221)
    x = _free_air(alpha, 50.0, 0.6)
    cl, cd = term_total(terms, "CL", x), term_total(terms, "CD", x)
    linear = (alpha > 0.0) & (alpha < 0.12)
    slope = np.polyfit(cl[linear] ** 2, cd[linear], 1)[0]
    oswald = float(np.clip(1.0 / (math.pi * aspect * max(slope, 1e-6)), 0.3, 1.0))
    k = int(np.argmax(cl))
    return oswald, float(alpha[k]), float(cl[k])


def build_document(
    root: Path, path: Path, model: str, el: ET.Element, name: str, rng: np.random.Generator
) -> Imported:
    metrics = el.find("metrics")
    if metrics is None:
        raise JSBSimImportError(f"{path}: field 'metrics': missing")
    area = measure(metrics.find("wingarea"), "metrics.wingarea", path, "FT2")
    span = measure(metrics.find("wingspan"), "metrics.wingspan", path, "FT")
    chord = measure(metrics.find("chord"), "metrics.chord", path, "FT")
    mass, cg, inertia = mass_properties(el, path)
    aero_rp = to_body(
        location(metrics.find("location[@name='AERORP']"), "metrics.location[AERORP]", path), cg
    )
    limits = surface_limits(el, path)
    engines = el.findall("propulsion/engine")
    if len(engines) != 1 or engines[0].find("thruster") is None:
        raise JSBSimImportError(
            f"{path}: field 'propulsion.engine': the importer reads single-engine propeller "
            f"aircraft, found {len(engines)} engines"
        )
    thruster = engines[0].find("thruster")
    assert thruster is not None
    motor_position = to_body(
        location(thruster.find("location"), "propulsion.engine.thruster.location", path), cg
    )
    orient = thruster.find("orient")
    pitch = measure(orient.find("pitch"), "thruster.orient.pitch", path, "DEG") if orient is not None else 0.0
    yaw = measure(orient.find("yaw"), "thruster.orient.yaw", path, "DEG") if orient is not None else 0.0
    axis = [math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch)]
    engine = sample_engine(
        root,
        model,
        ENGINE_SPEEDS,
        ENGINE_THROTTLES,
        ENGINE_ALTITUDES,
        (*_engine_properties(el), "propulsion/engine[0]/thrust-lbs", PROPELLER_RPM),
    )
    propeller = read_propeller(root, thruster, path)
    metrics_ft = {"Sw": area / FT**2, "bw": span / FT, "cbarw": chord / FT}
    context = PropertyContext(metrics_ft, HELD, engine, _named_functions(el), set())
    flight = _flight(limits, 50.0, engine)
    terms, rows = _aero_terms(el, path, context, flight, rng)
    aspect = span**2 / area
    oswald, alpha_stall, cl_max = _polar(terms, aspect)
    weight = mass * G0
    stall = math.sqrt(2 * weight / (1.225 * area * cl_max))
    max_speed = _top_speed(terms, engine, weight, area, stall)
    sense = float(thruster.findtext("sense") or 1.0)
    document = {
        "schema_version": 1,
        "name": name,
        "display_name": f"{(el.findtext('fileheader/description') or model).strip()} "
        f"(JSBSim {model}, imported)",
        "description": f"Imported from JSBSim's {model}.xml by falcon-rl airframe import-jsbsim.",
        "geometry": {
            "wing_area_m2": area,
            "span_m": span,
            "mean_chord_m": chord,
            "aspect_ratio": aspect,
            "taper_ratio": 1.0,
            "wing_quarter_chord_m": aero_rp.round(6).tolist(),
        },
        "mass": {
            "mass_kg": mass,
            "ixx_kg_m2": inertia[0, 0],
            "iyy_kg_m2": inertia[1, 1],
            "izz_kg_m2": inertia[2, 2],
            "ixz_kg_m2": -inertia[0, 2],
            "ixy_kg_m2": -inertia[0, 1],
            "iyz_kg_m2": -inertia[1, 2],
        },
        "aero": {
            "kind": "tabulated",
            "tables": [t.to_json() for t in terms],
            "oswald_efficiency": oswald,
            "alpha_range_rad": [-0.2, 0.5],
            "beta_range_rad": [-0.35, 0.35],
            "alpha_stall_rad": alpha_stall,
            "moment_reference_m": aero_rp.round(6).tolist(),
        },
        "propulsion": {
            "motors": [
                {
                    "name": engines[0].get("file", "engine"),
                    "position_m": motor_position.round(6).tolist(),
                    "thrust_axis": axis,
                    "spin": 1 if sense >= 0 else -1,
                    "disk_area_m2": propeller.disk_area,
                    "p_factor_m_per_rad": propeller.p_factor,
                    "time_constant_s": 0.2,
                    "powerplant": "piston",
                    "model": "thrust_map",
                }
            ],
            "thrust_map": _thrust_map(engine, propeller),
        },
        "actuators": {
            s: {"order": 1, "time_constant_s": ACTUATOR_TIME_CONSTANT, "limits_rad": list(limits[s])}
            for s in ("elevator", "aileron", "rudder")
        },
        "envelope": {
            "stall_speed_mps": round(stall, 3),
            "cruise_speed_mps": round(0.85 * max_speed, 3),
            "max_speed_mps": round(max_speed, 3),
            "max_bank_rad": 1.0,
            "climb_rate_limit_mps": 3.0,
        },
    }
    omitted = [r for r in rows if "reason" in r]
    report = {
        "model": model,
        "terms": [r for r in rows if "reason" not in r],
        "omitted": omitted,
        "held": HELD,
        "properties_read": sorted(context.used),
        "approximations": list(APPROXIMATIONS),
    }
    document["provenance"] = {
        "imported_from": "jsbsim",
        "sources": [
            f"JSBSim aircraft {model} ({path.name}, sha256 "
            f"{hashlib.sha256(path.read_bytes()).hexdigest()[:16]})"
        ],
        "method": "falcon-rl airframe import-jsbsim: metrics, mass balance, FCS limits and every aero "
        "function "
        "sampled into table terms; engine+propeller sampled by JSBSim in steady state into a thrust map "
        "(airspeed x throttle x density); envelope: stall from CL max, max level speed from the map, "
        "cruise 0.85 x max; taper ratio 1 (JSBSim has none) for Phillips-Hunsaker only",
        "jsbsim": {
            "model": model,
            "held_properties": HELD,
            "approximations": list(APPROXIMATIONS),
            "terms": report["terms"],
            "omitted": omitted,
        },
    }
    return Imported(_rounded(document), report)


def _top_speed(terms: list[TableTerm], engine: EngineMap, weight: float, area: float, stall: float) -> float:
    """Highest level-flight airspeed at full throttle at sea level (drag from the tables)."""
    best = stall * 1.2
    alpha = np.linspace(-0.1, 0.3, 161)
    for v in np.linspace(stall * 1.2, 100.0, 120):
        q = 0.5 * 1.225 * v * v
        x = _free_air(alpha, float(v), 1.0)
        cl, cd = term_total(terms, "CL", x), term_total(terms, "CD", x)
        k = int(np.argmin(np.abs(cl - weight / (q * area))))
        thrust = float(engine("propulsion/engine[0]/thrust-lbs", np.array(v), np.array(1.0), np.array(1.225)))
        if thrust * LBF >= q * area * cd[k]:
            best = float(v)
    return best


def _rounded(value: Any) -> Any:
    """Floats to 9 significant digits (the JSON stays readable and byte-stable)."""
    if isinstance(value, float | np.floating):
        return float(f"{float(value):.9g}")
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_rounded(v) for v in value]
    if isinstance(value, np.ndarray):
        return _rounded(value.tolist())
    return value


def import_jsbsim(name_or_path: str, name: str | None = None, seed: int = 0) -> Imported:
    """Read a JSBSim aircraft (a name in the jsbsim package's library or an XML path) into an airframe
    document (see ``jsbsim_import``'s module doc) and a report."""
    root, path, model = resolve(name_or_path)
    return build_document(root, path, model, xml_root(path), name or model, np.random.default_rng(seed))
