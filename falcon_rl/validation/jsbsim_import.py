"""Import a JSBSim aircraft (``aircraft/NAME/NAME.xml``) as a falcon-rl airframe document.

What comes across, in SI and body FRD about the loaded CG:
- metrics: S, b, c; the aero reference point (AERORP) becomes ``wing_quarter_chord_m``, so the tables'
  h/b is JSBSim's ``aero/h_b-mac-ft``, and ``aero.moment_reference_m``: JSBSim's moment coefficients are
  about the AERORP and its aero forces act there (M_cg = M_rp + r_rp x F);
- mass balance: empty weight, CG and inertia, point masses and tank contents combined as JSBSim does
  (the empty inertia is taken about the loaded CG unshifted; point masses and tanks add m (r^2 I - r r^T)
  about the loaded CG);
- flight-control limits: the ``aerosurface_scale`` that writes each surface position (range x gain);
- aerodynamics: every axis function as a table term by sampling (``jsbsim_sampling``), with its error,
  or reported by name with the reason it was left out; JSBSim's ground-effect tables become h/b axes,
  read in ground-effect mode "tables";
- engine and propeller: a steady-state thrust map sampled from JSBSim itself (``jsbsim_engine``), with
  the propeller's angular momentum (its gyroscopic moment) and p-factor (``jsbsim_propeller``).
JSBSim's structural frame (x aft, y right, z up, inches) maps to body FRD by r_b = (-(x - x_cg),
y - y_cg, -(z - z_cg)).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

UNITS = {
    "FT": 0.3048,
    "IN": 0.0254,
    "M": 1.0,
    "FT2": 0.09290304,
    "M2": 1.0,
    "LBS": 0.45359237,
    "KG": 1.0,
    "SLUG*FT2": 1.3558179483,
    "KG*M2": 1.0,
    "DEG": math.pi / 180,
    "RAD": 1.0,
}
#: Properties the import holds fixed: flaps up, fixed gear down, no stall hysteresis.
HELD = {
    "fcs/flap-pos-deg": 0.0,
    "fcs/flap-pos-norm": 0.0,
    "gear/gear-pos-norm": 1.0,
    "aero/stall-hyst-norm": 0.0,
}
SURFACE_OUTPUTS = {
    "elevator": "fcs/elevator-pos-rad",
    "aileron": "fcs/left-aileron-pos-rad",
    "rudder": "fcs/rudder-pos-rad",
}
APPROXIMATIONS = (
    "lift and drag act in stability axes (JSBSim: wind axes; differences are second order in beta)",
    "the propeller's gyroscopic moment reads its steady-state speed; its p-factor leaves out the in-plane "
    "inflow omega x r that the body rotation adds at the propeller",
    "the CG and inertia are those of the initial load (JSBSim moves them as fuel burns)",
    "thrust and the engine properties the aero functions read are steady state (JSBSim's engine speed lags)",
)


class JSBSimImportError(ValueError):
    """A JSBSim file the importer cannot read; the message names the file, the field and the reason."""


@dataclass
class Imported:
    document: dict[str, Any]
    report: dict[str, Any]


def measure(element: ET.Element | None, where: str, path: Path, default_unit: str) -> float:
    if element is None or element.text is None:
        raise JSBSimImportError(f"{path}: field '{where}': missing")
    unit = element.get("unit", default_unit).upper()
    if unit not in UNITS:
        raise JSBSimImportError(f"{path}: field '{where}': unit {unit!r} is not one of {sorted(UNITS)}")
    return float(element.text.strip()) * UNITS[unit]


def location(element: ET.Element | None, where: str, path: Path) -> np.ndarray:
    if element is None:
        raise JSBSimImportError(f"{path}: field '{where}': missing")
    unit = element.get("unit", "IN")
    return np.array([measure(_with_unit(element.find(a), unit), f"{where}.{a}", path, unit) for a in "xyz"])


def _with_unit(element: ET.Element | None, unit: str) -> ET.Element | None:
    if element is not None and "unit" not in element.attrib:
        element.set("unit", unit)
    return element


def to_body(r_structural: np.ndarray, cg: np.ndarray) -> np.ndarray:
    """Structural (x aft, y right, z up) -> body FRD relative to the CG, m."""
    d = r_structural - cg
    return np.array([-d[0], d[1], -d[2]])


def resolve(name_or_path: str) -> tuple[Path, Path, str]:
    """(JSBSim root, aircraft XML, model name) of a model name (JSBSim's own aircraft) or an XML path."""
    candidate = Path(name_or_path)
    if candidate.suffix == ".xml":
        if not candidate.is_file():
            raise JSBSimImportError(f"{candidate}: JSBSim aircraft file not found")
        return candidate.resolve().parent.parent.parent, candidate, candidate.stem
    import jsbsim

    root = Path(jsbsim.get_default_root_dir())
    path = root / "aircraft" / name_or_path / f"{name_or_path}.xml"
    if not path.is_file():
        known = sorted(p.name for p in (root / "aircraft").iterdir() if (p / f"{p.name}.xml").is_file())
        raise JSBSimImportError(
            f"unknown JSBSim aircraft {name_or_path!r}: expected one of {known} or an .xml path"
        )
    return root, path, name_or_path


def mass_properties(root_el: ET.Element, path: Path) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass kg, CG structural m, inertia tensor [3, 3] kg m^2 body FRD about the CG)."""
    mb = root_el.find("mass_balance")
    if mb is None:
        raise JSBSimImportError(f"{path}: field 'mass_balance': missing")
    empty = measure(mb.find("emptywt"), "mass_balance.emptywt", path, "LBS")
    empty_cg = location(mb.find("location[@name='CG']"), "mass_balance.location[CG]", path)
    points = [(empty, empty_cg)]
    for k, pm in enumerate(mb.findall("pointmass")):
        points.append(
            (
                measure(pm.find("weight"), f"mass_balance.pointmass[{k}].weight", path, "LBS"),
                location(pm.find("location"), f"mass_balance.pointmass[{k}].location", path),
            )
        )
    for k, tank in enumerate(root_el.findall("propulsion/tank")):
        contents = tank.find("contents")
        if contents is not None:
            points.append(
                (
                    measure(contents, f"propulsion.tank[{k}].contents", path, "LBS"),
                    location(tank.find("location"), f"propulsion.tank[{k}].location", path),
                )
            )
    mass = sum(m for m, _ in points)
    cg = sum(m * r for m, r in points) / mass
    get = {
        a: measure(mb.find(a), f"mass_balance.{a}", path, "SLUG*FT2") if mb.find(a) is not None else 0.0
        for a in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
    }
    sign = -1.0 if mb.get("negated_crossproduct_inertia", "true") == "true" else 1.0
    inertia = np.array(
        [
            [get["ixx"], sign * get["ixy"], sign * get["ixz"]],
            [sign * get["ixy"], get["iyy"], sign * get["iyz"]],
            [sign * get["ixz"], sign * get["iyz"], get["izz"]],
        ]
    )
    for m, r in points[1:]:
        rb = to_body(r, cg)
        inertia += m * (rb @ rb * np.eye(3) - np.outer(rb, rb))
    return mass, cg, inertia


def surface_limits(root_el: ET.Element, path: Path) -> dict[str, tuple[float, float]]:
    """Deflection limits (rad) from the aerosurface_scale writing each surface position."""
    out = {}
    for surface, prop in SURFACE_OUTPUTS.items():
        for comp in root_el.iter("aerosurface_scale"):
            if (comp.findtext("output") or "").strip() == prop:
                gain = float(comp.findtext("gain") or 1.0)
                lo, hi = float(comp.findtext("range/min")), float(comp.findtext("range/max"))
                out[surface] = (lo * gain, hi * gain)
        if surface not in out:
            raise JSBSimImportError(f"{path}: field 'flight_control': no aerosurface_scale writes {prop}")
    return out


def xml_root(path: Path) -> ET.Element:
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise JSBSimImportError(f"{path}: not valid XML ({exc})") from None
