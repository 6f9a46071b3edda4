"""Assemble an airframe document (schema v1) from a geometry source: sweep, fit, propulsion,
envelope, provenance. ``derive_airframe`` is what ``falcon-rl airframe derive`` runs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..airframe import AERO_VARIABLES, parse_airframe
from ..constants import DEG, G0
from ..physics.atmosphere import isa_density
from .aerobuildup import AeroModel
from .envelope import envelope
from .fit import CoefficientFit, evaluate, fit_tables
from .geometry import GeometrySpec, load_geometry
from .propulsion import momentum_constants
from .sweep import ALPHA_RANGE_DEG, BETA_DEG, Sweep, run_sweep

OFF_RANGE_WEIGHT = 0.1  # fit weight of sweep points beyond stall or below -5 deg alpha (1 between)
CLEAN_WEIGHT = 10.0  # extra weight of the clean alpha sweep: it sets the base polynomial where trims live
COEFFICIENTS = ("CL", "CD", "CY", "Cl", "Cm", "Cn")


def sig(x: float, digits: int = 6) -> float:
    """Round to ``digits`` significant digits (the shipped JSON is rounded, hence reproducible)."""
    return float(f"{float(x):.{digits}g}")


@dataclass
class Derived:
    """A derived airframe: the JSON document plus the data behind it (for plots and tests)."""

    document: dict[str, Any]
    spec: GeometrySpec
    sweep: Sweep
    fits: dict[str, CoefficientFit]


def _rho(spec: GeometrySpec) -> float:
    import torch

    return float(isa_density(torch.tensor(spec.altitude, dtype=torch.float64)))


def _mass(spec: GeometrySpec, span: float) -> dict[str, float]:
    m = spec.raw["mass"]
    mass = float(m["mass_kg"])
    if "radii_of_gyration" in m:  # Roskam: R_x = 2 k_x / b, R_y = 2 k_y / L, R_z = 2 k_z / ((b + L) / 2)
        r, length = m["radii_of_gyration"], float(m["length_m"])
        out = {"mass_kg": mass, "ixx_kg_m2": mass * (r["rx"] * span / 2) ** 2,
               "iyy_kg_m2": mass * (r["ry"] * length / 2) ** 2,
               "izz_kg_m2": mass * (r["rz"] * (span + length) / 4) ** 2, "ixz_kg_m2": 0.0}
    else:
        out = {k: float(m[k]) for k in ("mass_kg", "ixx_kg_m2", "iyy_kg_m2", "izz_kg_m2")}
        out["ixz_kg_m2"] = float(m.get("ixz_kg_m2", 0.0))
    return {k: sig(v) for k, v in out.items()}


def _body(spec: GeometrySpec, p: list[float]) -> list[float]:
    """Datum (geometry) axes point -> body FRD relative to the CG."""
    cg = spec.cg
    return [sig(-(p[0] - cg[0]), 5) + 0.0, sig(p[1] - cg[1], 5) + 0.0, sig(-(p[2] - cg[2]), 5) + 0.0]


def _propulsion(spec: GeometrySpec) -> tuple[dict[str, Any], list[str]]:
    prop = spec.raw["propulsion"]
    motors, notes = [], []
    for m in prop["motors"]:
        disk, c_p, k_m, note = momentum_constants(m, prop["powerplant"], spec.cruise_speed)
        notes.append(f"{m['name']}: {note}")
        motors.append({
            "name": m["name"], "position_m": _body(spec, m["position_m"]), "thrust_axis": m["thrust_axis"],
            "spin": int(m["spin"]), "disk_area_m2": sig(disk), "thrust_coefficient": sig(c_p),
            "discharge_speed_mps": sig(k_m), "torque_coefficient": 0.0, "torque_speed_constant_rad_s": 0.0,
            "time_constant_s": float(prop["time_constant_s"]), "powerplant": prop["powerplant"]})
    return {"motors": motors}, notes


def _terms(fit: CoefficientFit) -> list[dict[str, Any]]:
    out = []
    for exps, c in zip(fit.terms, fit.coefs, strict=True):
        term: dict[str, Any] = {"coef": sig(c)}
        term.update({v: int(e) for v, e in zip(AERO_VARIABLES, exps, strict=True) if e})
        out.append(term)
    return out


def _oswald(fits: dict[str, CoefficientFit], alpha: float, aspect_ratio: float) -> float:
    """e of the local parabolic polar of the fitted tables at ``alpha`` (cruise):
    1 / (pi A dC_D/d(C_L^2)) with dC_D/d(C_L^2) = C_D_alpha / (2 C_L C_L_alpha), clipped to [0.3, 1]."""
    x = np.zeros((3, 5))
    x[:, 0] = alpha + np.array([-1e-4, 0.0, 1e-4])
    cl = evaluate(x, fits["CL"].terms, fits["CL"].coefs)
    cd = evaluate(x, fits["CD"].terms, fits["CD"].coefs)
    k = (cd[2] - cd[0]) / (cl[2] ** 2 - cl[0] ** 2)
    return float(min(1.0, max(0.3, 1.0 / (math.pi * aspect_ratio * k)))) if k > 0 else 1.0


def _actuators(spec: GeometrySpec) -> dict[str, Any]:
    # Paper, "Actuators": servo-driven surfaces are second order, omega_n = 10 rad/s, zeta = 1/sqrt 2.
    lim = spec.raw["actuators"]
    return {k: {"order": 2, "natural_frequency_rad_s": 10.0, "damping_ratio": sig(1 / math.sqrt(2)),
                "limits_rad": [sig(-lim[f"{k}_deg"] * DEG), sig(lim[f"{k}_deg"] * DEG)]}
            for k in ("elevator", "aileron", "rudder")}


def derivatives_at(fits: dict[str, CoefficientFit], rates: np.ndarray, alpha: float) -> dict[str, float]:
    """Stability and control derivatives of the fitted tables at ``alpha`` (central differences)."""
    out: dict[str, float] = {}
    h = 1e-4
    for j, var in enumerate(("alpha", "beta", "de", "da", "dr")):
        xp, xm = np.zeros((1, 5)), np.zeros((1, 5))
        xp[0, 0] = xm[0, 0] = alpha
        xp[0, j] += h
        xm[0, j] -= h
        for name, f in fits.items():
            d = (evaluate(xp, f.terms, f.coefs) - evaluate(xm, f.terms, f.coefs))[0] / (2 * h)
            out[f"{name}_{var}"] = sig(d, 4)
    for k, name in enumerate(COEFFICIENTS):
        for j, r in enumerate("pqr"):
            out[f"{name}_{r}"] = sig(rates[k, j], 4)
    return out


def derive_airframe(geometry_path: str | Path) -> Derived:
    """Run the sweep and fit for one geometry file and return the airframe document."""
    spec = load_geometry(geometry_path)
    model = AeroModel(spec)
    ref = model.ref
    mass = _mass(spec, ref.span)
    rho = _rho(spec)
    cl_cruise = mass["mass_kg"] * G0 / (0.5 * rho * spec.cruise_speed**2 * ref.area)
    limits = {k: spec.raw["actuators"][f"{k}_deg"] * DEG for k in ("elevator", "aileron", "rudder")}
    sweep = run_sweep(model, limits, cl_cruise)
    clean = (sweep.group == "alpha") & ~sweep.held_out
    i_max = int(np.argmax(sweep.coefficients[clean, 0]))
    alpha_stall, cl_max = float(sweep.x[clean, 0][i_max]), float(sweep.coefficients[clean, 0][i_max])
    in_range = (sweep.x[:, 0] >= -5 * DEG - 1e-9) & (sweep.x[:, 0] <= alpha_stall + 1e-9)
    weights = np.where(in_range, 1.0, OFF_RANGE_WEIGHT) * np.where(sweep.group == "alpha", CLEAN_WEIGHT, 1.0)
    fits = fit_tables(sweep.x, sweep.coefficients, sweep.held_out, weights)
    propulsion, prop_notes = _propulsion(spec)
    coefficients = {}
    for k, name in enumerate(COEFFICIENTS):
        entry: dict[str, Any] = {"terms": _terms(fits[name])}
        rates = {r: sig(sweep.rate_derivatives[k, j]) for j, r in enumerate("pqr")
                 if abs(sweep.rate_derivatives[k, j]) > 1e-5}
        if rates:
            entry["rates"] = rates
        coefficients[name] = entry
    doc: dict[str, Any] = {
        "schema_version": 1, "name": spec.name, "display_name": spec.display_name,
        "description": spec.description,
        "geometry": {"wing_area_m2": sig(ref.area), "span_m": sig(ref.span), "mean_chord_m": sig(ref.chord),
                     "aspect_ratio": sig(ref.aspect_ratio), "taper_ratio": sig(ref.taper_ratio),
                     "wing_quarter_chord_m": [sig(v, 5) + 0.0 for v in ref.quarter_chord]},
        "mass": mass,
        "aero": {"oswald_efficiency": sig(_oswald(fits, sweep.rate_alpha, ref.aspect_ratio), 4),
                 "alpha_range_rad": [sig(a * DEG) for a in ALPHA_RANGE_DEG],
                 "beta_range_rad": [sig(min(BETA_DEG) * DEG), sig(max(BETA_DEG) * DEG)],
                 "alpha_stall_rad": sig(alpha_stall), "coefficients": coefficients},
        "propulsion": propulsion,
        "actuators": _actuators(spec),
        "envelope": {},
    }
    stall = math.sqrt(2 * mass["mass_kg"] * G0 / (rho * ref.area * cl_max))
    doc["envelope"] = {"stall_speed_mps": sig(stall, 4), "cruise_speed_mps": spec.cruise_speed,
                       "max_speed_mps": sig(3 * spec.cruise_speed, 4), "max_bank_rad": 1.0,
                       "climb_rate_limit_mps": 1.0}
    env, env_notes = envelope(parse_airframe(_with_provenance(doc, spec), spec.path), spec, stall)
    doc["envelope"] = env
    doc["provenance"] = _provenance(spec, model, sweep, fits, prop_notes, env_notes, cl_max)
    parse_airframe(doc, spec.path)  # the shipped document must validate
    return Derived(doc, spec, sweep, fits)


def _with_provenance(doc: dict[str, Any], spec: GeometrySpec) -> dict[str, Any]:
    return {**doc, "provenance": {"sources": spec.raw["provenance"]["sources"], "method": "derive"}}


def _corrections(spec: GeometrySpec, model: AeroModel) -> str:
    factors = ", ".join(f"{k} {v:.3f}" for k, v in sorted(model.control_factor.items()))
    return (f"tail downwash 2 C_L,wing/(pi A), eta_t {spec.tail_q_ratio}; fin sidewash factor "
            f"{model.sidewash:.3f} (Nelson eq. 2.79); control increments times C_L_alpha/c_l_alpha of the "
            f"carrying surface: {factors}")


def _provenance(spec: GeometrySpec, model: AeroModel, sweep: Sweep, fits: dict[str, CoefficientFit],
                prop_notes: list[str], env_notes: dict[str, str], cl_max: float) -> dict[str, Any]:
    src = spec.raw["provenance"]
    return {
        "method": ("derived from the geometry source with AeroSandbox AeroBuildup (NeuralFoil sections) "
                   "by falcon-rl airframe derive: fixed sweep, least-squares monomial fit with orders "
                   "chosen on held-out points, momentum-theory propulsion, trimmed envelope"),
        "geometry_source": f"airframes/geometry/{spec.path.name}",
        "sources": list(src["sources"]),
        "notes": {**src.get("notes", {}), "propulsion_identification": "; ".join(prop_notes), **env_notes,
                  "oswald_efficiency": ("local parabolic polar of the fitted tables at the cruise alpha: "
                                        "1/(pi A dC_D/dC_L^2), so the ground-effect correction scales the "
                                        "lift-dependent drag the tables carry"),
                  "aero_corrections": _corrections(spec, model)},
        "fit": {
            "sweep": {"airspeed_mps": spec.airspeed, "altitude_m": spec.altitude,
                      "alpha_deg": list(ALPHA_RANGE_DEG), "beta_deg": [min(BETA_DEG), max(BETA_DEG)],
                      "points_train": int((~sweep.held_out).sum()),
                      "points_held_out": int(sweep.held_out.sum()),
                      "rate_alpha_deg": sig(sweep.rate_alpha / DEG, 4), "cl_max": sig(cl_max, 4),
                      "weights": f"1 for alpha in [-5 deg, stall], {OFF_RANGE_WEIGHT} outside; "
                                 f"clean alpha sweep x {CLEAN_WEIGHT}"},
            "residuals": {n: {"orders": f.orders, "rms_train": sig(f.rms_train, 3),
                              "rms_held_out": sig(f.rms_held_out, 3),
                              "rms_held_out_in_range": sig(f.rms_held_out_full_weight, 3),
                              "max_abs_held_out": sig(f.max_abs_held_out, 3),
                              "data_range": sig(f.range_of_data, 3)} for n, f in fits.items()},
            "derivatives_at_rate_alpha": derivatives_at(fits, sweep.rate_derivatives, sweep.rate_alpha),
        },
    }
