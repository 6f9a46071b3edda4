"""Every validation rule gives an AirframeError naming the file, the field and the constraint."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from falcon_rl import AirframeError, list_airframes, load_airframe

SOURCE = Path(__file__).resolve().parent.parent / "airframes" / "volantex_ranger.json"


@pytest.fixture()
def doc():
    return json.loads(SOURCE.read_text())


def _load(tmp_path: Path, document) -> None:
    path = tmp_path / "broken.json"
    path.write_text(document if isinstance(document, str) else json.dumps(document))
    load_airframe(path)


def test_shipped_airframes_load():
    assert {"navion", "volantex_ranger"} <= set(list_airframes())
    for name in list_airframes():
        a = load_airframe(name)
        assert a.mass > 0 and a.num_motors >= 1


def test_unknown_name_lists_choices():
    with pytest.raises(AirframeError, match=r"unknown airframe .concorde.*navion"):
        load_airframe("concorde")


def test_invalid_json_names_line(tmp_path):
    with pytest.raises(AirframeError, match=r"broken.json: not valid JSON .* line 1"):
        _load(tmp_path, "{nope")


CASES = [
    ("missing field", lambda d: d["mass"].pop("mass_kg"), r"'mass.mass_kg': missing required field"),
    ("unknown field", lambda d: d["geometry"].update(wingspan=3), r"'geometry': unknown field.*wingspan"),
    ("unknown top-level", lambda d: d.update(colour="red"), r"'<root>': unknown field.*colour"),
    ("wrong type", lambda d: d["geometry"].update(span_m="1.6"), r"'geometry.span_m': expected number, got str"),
    ("bool for number", lambda d: d["mass"].update(mass_kg=True), r"'mass.mass_kg': expected number, got bool"),
    ("non-positive mass", lambda d: d["mass"].update(mass_kg=0), r"'mass.mass_kg': must be > 0"),
    ("negative length", lambda d: d["geometry"].update(mean_chord_m=-0.1), r"'geometry.mean_chord_m': must be > 0"),
    ("aspect ratio", lambda d: d["geometry"].update(aspect_ratio=7.0), r"'geometry.aspect_ratio': inconsistent"),
    ("taper > 1", lambda d: d["geometry"].update(taper_ratio=1.5), r"'geometry.taper_ratio': must be in \(0, 1\]"),
    ("not positive definite", lambda d: d["mass"].update(ixz_kg_m2=1.0), r"'mass': inertia tensor not positive definite"),
    ("triangle inequality", lambda d: d["mass"].update(izz_kg_m2=0.2), r"'mass': principal moments violate the triangle"),
    ("limits out of order", lambda d: d["actuators"]["elevator"].update(limits_rad=[0.3, -0.3]),
     r"'actuators.elevator.limits_rad': limits out of order"),
    ("alpha range", lambda d: d["aero"].update(alpha_range_rad=[0.2, 0.1]), r"'aero.alpha_range_rad': limits out of order"),
    ("speeds out of order", lambda d: d["envelope"].update(cruise_speed_mps=30.0), r"'envelope': speeds out of order"),
    ("actuator order", lambda d: d["actuators"]["rudder"].update(order=3), r"'actuators.rudder.order': must be 1 or 2"),
    ("second order needs omega", lambda d: d["actuators"]["rudder"].pop("natural_frequency_rad_s"),
     r"'actuators.rudder.natural_frequency_rad_s': missing required field"),
    ("thrust axis unit", lambda d: d["propulsion"]["motors"][0].update(thrust_axis=[1, 1, 0]),
     r"'propulsion.motors\[0\].thrust_axis': must be a unit vector"),
    ("spin", lambda d: d["propulsion"]["motors"][0].update(spin=2), r"'propulsion.motors\[0\].spin': must be \+1 or -1"),
    ("powerplant", lambda d: d["propulsion"]["motors"][0].update(powerplant="jet"),
     r"'propulsion.motors\[0\].powerplant': must be one of"),
    ("no motors", lambda d: d["propulsion"].update(motors=[]), r"'propulsion.motors': needs at least one motor"),
    ("monomial variable", lambda d: d["aero"]["coefficients"]["CL"]["terms"].append({"coef": 1, "gamma": 1}),
     r"'aero.coefficients.CL.terms\[\d+\]': unknown field.*gamma"),
    ("exponent range", lambda d: d["aero"]["coefficients"]["CL"]["terms"].append({"coef": 1, "alpha": 9}),
     r"'aero.coefficients.CL.terms\[\d+\].alpha': exponent must be an integer in \[0, 6\]"),
    ("rate name", lambda d: d["aero"]["coefficients"]["Cm"]["rates"].update(w=1.0),
     r"'aero.coefficients.Cm.rates': unknown field.*'w'"),
    ("oswald", lambda d: d["aero"].update(oswald_efficiency=1.3), r"'aero.oswald_efficiency': must be in \(0, 1\]"),
    ("max bank", lambda d: d["envelope"].update(max_bank_rad=2.0), r"'envelope.max_bank_rad': must be < pi/2"),
    ("schema version", lambda d: d.update(schema_version=7), r"'schema_version': unsupported version 7"),
    ("provenance", lambda d: d["provenance"].update(sources=[]), r"'provenance': needs non-empty 'sources'"),
    ("vector length", lambda d: d["geometry"].update(wing_quarter_chord_m=[0, 0]),
     r"'geometry.wing_quarter_chord_m': expected a list of 3 numbers"),
    ("not finite", lambda d: d["geometry"].update(span_m=float("inf")), r"'geometry.span_m': must be finite"),
]


@pytest.mark.parametrize(("label", "mutate", "message"), CASES, ids=[c[0] for c in CASES])
def test_validation_errors_name_file_field_and_constraint(tmp_path, doc, label, mutate, message):
    broken = copy.deepcopy(doc)
    mutate(broken)
    with pytest.raises(AirframeError, match=message) as info:
        _load(tmp_path, broken)
    assert "broken.json" in str(info.value), label
