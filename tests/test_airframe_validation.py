"""Every validation rule gives an AirframeError naming the file, the field and the constraint."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from falcon_rl import AirframeError, list_airframes, load_airframe
from falcon_rl.airframe import MAX_FILE_BYTES

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
    ("NaN in provenance", lambda d: d["provenance"].update(x=float("nan")), r"'provenance.x': must be finite"),
    ("absurd coefficient", lambda d: d["aero"]["coefficients"]["CL"]["terms"][0].update(coef=1e300),
     r"'aero.coefficients.CL.terms\[0\].coef': magnitude 1e\+300 is absurd"),
    ("large coefficient", lambda d: d["aero"]["coefficients"]["CD"]["terms"][0].update(coef=2e6),
     r"'aero.coefficients.CD.terms\[0\].coef': magnitude 2e\+06 is absurd for an aero coefficient"),
    ("large rate", lambda d: d["aero"]["coefficients"]["Cm"]["rates"].update(q=-3e6),
     r"'aero.coefficients.Cm.rates.q': magnitude -3e\+06 is absurd"),
    ("absurd mass", lambda d: d["mass"].update(mass_kg=1e300), r"'mass.mass_kg': magnitude 1e\+300 is absurd"),
    ("400-digit integer", lambda d: d["mass"].update(mass_kg=10**400), r"'mass.mass_kg': magnitude ~1e400 is absurd"),
    ("tiny mass", lambda d: d["mass"].update(mass_kg=1e-300), r"'mass.mass_kg': 1e-300 is absurdly small"),
    ("huge vector entry", lambda d: d["geometry"].update(wing_quarter_chord_m=[0, 0, 1e300]),
     r"'geometry.wing_quarter_chord_m': expected a list of 3 numbers"),
    ("empty drag table", lambda d: d["aero"]["coefficients"].update(CD={"terms": []}),
     r"'aero.coefficients.CD': every term and rate is zero or absent: a physically empty model"),
    ("all-zero moment", lambda d: d["aero"]["coefficients"].update(Cm={"terms": [{"coef": 0.0, "alpha": 1}]}),
     r"'aero.coefficients.Cm': every term and rate is zero"),
    ("no lift slope", lambda d: d["aero"]["coefficients"]["CL"].update(terms=[{"coef": 0.3}]),
     r"'aero.coefficients.CL': needs a term in alpha"),
    ("no zero-lift drag", lambda d: d["aero"]["coefficients"]["CD"].update(terms=[{"coef": 1.0, "alpha": 2}]),
     r"'aero.coefficients.CD': needs a positive zero-lift drag term \(the constant term is 0\)"),
    ("negative zero-lift drag", lambda d: d["aero"]["coefficients"]["CD"]["terms"].append({"coef": -1.0}),
     r"'aero.coefficients.CD': needs a positive zero-lift drag term"),
    ("alpha range too wide", lambda d: d["aero"].update(alpha_range_rad=[-4.0, 4.0]),
     r"'aero.alpha_range_rad': \[-4.0, 4.0\] must lie within \[-1.571, 1.571\]"),
    ("surface limits too wide", lambda d: d["actuators"]["elevator"].update(limits_rad=[-3.0, 3.0]),
     r"'actuators.elevator.limits_rad': \[-3.0, 3.0\] must lie within"),
    ("terminal escape in name", lambda d: d.update(name="\x1b[31mred"), r"'name': contains control characters"),
    ("bidi override in motor name", lambda d: d["propulsion"]["motors"][0].update(name="\u202eevil"),
     r"'propulsion.motors\[0\].name': contains control characters"),
    ("newline in display name", lambda d: d.update(display_name="a\nb"), r"'display_name': contains control"),
    ("path in name", lambda d: d.update(name="../evil"), r"'name': must be usable as a file name"),
    ("empty name", lambda d: d.update(name=" "), r"'name': must be 1 to 100 characters"),
    ("long name", lambda d: d.update(name="x" * 101), r"'name': must be 1 to 100 characters, got 101"),
    ("name not a string", lambda d: d.update(name=5), r"'name': expected string, got int"),
    ("section not an object", lambda d: d.update(geometry=[]), r"'geometry': expected object, got list"),
    ("terms not a list", lambda d: d["aero"]["coefficients"]["CL"].update(terms={}),
     r"'aero.coefficients.CL.terms': expected list, got dict"),
    ("term not an object", lambda d: d["aero"]["coefficients"]["CL"]["terms"].append(1),
     r"'aero.coefficients.CL.terms\[\d+\]': expected an object"),
    ("fractional exponent", lambda d: d["aero"]["coefficients"]["CL"]["terms"].append({"coef": 1, "alpha": 1.5}),
     r"'aero.coefficients.CL.terms\[\d+\].alpha': expected integer, got float"),
    ("missing section", lambda d: d.pop("envelope"), r"'envelope': missing required field"),
]


@pytest.mark.parametrize(("label", "mutate", "message"), CASES, ids=[c[0] for c in CASES])
def test_validation_errors_name_file_field_and_constraint(tmp_path, doc, label, mutate, message):
    broken = copy.deepcopy(doc)
    mutate(broken)
    with pytest.raises(AirframeError, match=message) as info:
        _load(tmp_path, broken)
    assert "broken.json" in str(info.value), label


def _replace(old: str, new: str):
    """A RAW_CASES transform: the shipped text with ``old`` (which must occur) replaced by ``new``, as UTF-8."""
    def transform(text: str) -> bytes:
        assert old in text, old
        return text.replace(old, new, 1).encode()
    return transform


#: Malformed files, byte by byte: (label, shipped text -> file bytes, message).
RAW_CASES = [
    ("empty file", lambda t: b"", r"not valid JSON \(Expecting value at line 1\)"),
    ("whitespace only", lambda t: b" \n\t\n", r"not valid JSON"),
    ("truncated", lambda t: t[: len(t) // 2].encode(), r"not valid JSON \(.*at line \d+\)"),
    ("trailing comma", lambda t: (t.rstrip()[:-1] + ",}").encode(), r"not valid JSON"),
    ("single quotes", _replace('"schema_version"', "'schema_version'"), r"not valid JSON"),
    ("root is a list", lambda t: b"[]", r"'<root>': expected a JSON object"),
    ("root is null", lambda t: b"null", r"'<root>': expected a JSON object"),
    ("NaN literal", _replace('"mass_kg": ', '"mass_kg": NaN, "x": '), r"'mass.mass_kg': must be finite"),
    ("Infinity literal", _replace('"span_m": ', '"span_m": Infinity, "x": '), r"'geometry.span_m': must be finite"),
    ("-Infinity literal", _replace('"mass_kg": ', '"mass_kg": -Infinity, "x": '), r"'mass.mass_kg': must be finite"),
    ("number beyond float", _replace('"span_m": ', '"span_m": 1e400, "x": '), r"'geometry.span_m': must be finite"),
    ("5000-digit integer", _replace('"mass_kg": ', '"mass_kg": ' + "9" * 5000 + ', "x": '),
     r"not valid JSON \(Exceeds the limit"),
    ("duplicate key", _replace('"mass_kg": ', '"mass_kg": 1.0, "mass_kg": '),
     r"duplicate key 'mass_kg' in one JSON object"),
    ("duplicate section", _replace('"envelope": {', '"envelope": {}, "envelope": {'), r"duplicate key 'envelope'"),
    ("deep nesting", lambda t: b"[" * 100_000 + b"]" * 100_000, r"JSON nested too deep"),
    ("deep nesting in provenance", _replace('"provenance": ', '"provenance": ' + "[" * 50_000 + "]" * 50_000 + ', "x": '),
     r"JSON nested too deep"),
    ("non-UTF-8 byte", lambda t: t.encode().replace(b'"name"', b'"n\xffame"', 1), r"not UTF-8 text \(byte 0xff at offset \d+\)"),
    ("Latin-1 text", lambda t: t.replace('"description": "', '"description": "caf\u00e9 ', 1).encode("latin-1"),
     r"not UTF-8 text \(byte 0xe9"),
    ("UTF-16 with BOM", lambda t: t.encode("utf-16"), r"UTF-16 text; save the airframe file as UTF-8"),
    ("UTF-16 big-endian BOM", lambda t: b"\xfe\xff" + t.encode("utf-16-be"), r"UTF-16 text"),
    ("NUL character", _replace('"name": "', '"name": "\x00'), r"not valid JSON \(Invalid control character"),
    ("oversized file", lambda t: b" " * (MAX_FILE_BYTES + 1), r"bytes; airframe files are at most"),
]


@pytest.mark.parametrize(("label", "transform", "message"), RAW_CASES, ids=[c[0] for c in RAW_CASES])
def test_malformed_files_name_file_and_defect(tmp_path, label, transform, message):
    path = tmp_path / "broken.json"
    path.write_bytes(transform(SOURCE.read_text()))
    with pytest.raises(AirframeError, match=message) as info:
        load_airframe(path)
    assert str(path) in str(info.value), label
    assert len(str(info.value).splitlines()) == 1


def test_utf8_byte_order_mark_is_accepted(tmp_path):
    """RFC 8259 lets a parser ignore a UTF-8 byte-order mark, which some editors write."""
    path = tmp_path / "bom.json"
    path.write_bytes(b"\xef\xbb\xbf" + SOURCE.read_bytes())
    assert load_airframe(path).name == "volantex_ranger"


@pytest.mark.parametrize(("make", "message"), [
    (lambda d: d.mkdir(), r"x.json: a directory, not an airframe file"),
    (lambda d: None, r"x.json: airframe file not found"),
])
def test_paths_that_are_not_files(tmp_path, make, message):
    make(tmp_path / "x.json")
    with pytest.raises(AirframeError, match=message):
        load_airframe(tmp_path / "x.json")
