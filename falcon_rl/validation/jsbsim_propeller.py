"""A JSBSim propeller's gyroscopic and p-factor data (``engine/<thruster file>.xml`` and the thruster).

JSBSim (``FGPropeller``) adds to the aircraft

- a gyroscopic moment omega x (I_p Omega Sense S x): I_p the propeller's ``ixx``, Omega its speed, Sense
  +1 clockwise seen from behind, and S = +1 for a propeller file without ``version`` > 1 (its legacy
  sign, opposite to the physical -omega x H) or -1 for one with it. falcon-rl's model is (h a) x omega
  (``physics/propulsion.py``), so the importer writes h = -Sense S I_p Omega: JSBSim's moment, whichever
  sign it has;
- a p-factor: the thrust acts ``p_factor`` inches aside per rad of inflow angle (JSBSim's shift is in
  the structural frame, in inches), here m per rad.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from .jsbsim_import import JSBSimImportError, measure, xml_root

#: The sampled engine property that gives the propeller speed (rev/min).
PROPELLER_RPM = "propulsion/engine[0]/propeller-rpm"
INCH = 0.0254


@dataclass(frozen=True)
class Propeller:
    ixx: float  # kg m^2
    disk_area: float  # m^2
    p_factor: float  # m of thrust-line shift per rad of inflow angle
    gyroscopic_sign: float  # h = gyroscopic_sign * I_p * Omega reproduces JSBSim's moment


def read_propeller(root: Path, thruster: ET.Element, aircraft: Path) -> Propeller:
    """The propeller of ``thruster`` (an ``<engine><thruster file=...>`` element of ``aircraft``)."""
    name = thruster.get("file")
    if not name:
        raise JSBSimImportError(f"{aircraft}: field 'propulsion.engine.thruster': no file attribute")
    path = root / "engine" / f"{name}.xml"
    if not path.is_file():
        raise JSBSimImportError(f"{aircraft}: field 'propulsion.engine.thruster': {path} not found")
    el = xml_root(path)
    if el.tag != "propeller":
        raise JSBSimImportError(f"{path}: field '{el.tag}': the importer reads propellers only")
    ixx = measure(el.find("ixx"), "propeller.ixx", path, "SLUG*FT2") if el.find("ixx") is not None else 0.0
    diameter = measure(el.find("diameter"), "propeller.diameter", path, "IN")
    sense = 1.0 if float(thruster.findtext("sense") or 1.0) >= 0 else -1.0
    p_factor = float(thruster.findtext("p_factor") or 0.0)
    if p_factor < 0:
        raise JSBSimImportError(f"{aircraft}: field 'propulsion.engine.thruster.p_factor': must be >= 0")
    legacy = not float(el.get("version", "1.0")) > 1.0
    return Propeller(
        ixx=ixx,
        disk_area=math.pi * diameter**2 / 4,
        p_factor=p_factor * INCH,
        gyroscopic_sign=-sense * (1.0 if legacy else -1.0),
    )
