"""JSBSim aero functions sampled into table terms (``validation/jsbsim_sampling.convert``): the shapes
JSBSim's aircraft use come across exactly."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from falcon_rl.airframe_terms import TABLE_VARIABLES
from falcon_rl.validation.jsbsim_engine import EngineMap
from falcon_rl.validation.jsbsim_functions import multilinear, parse_function
from falcon_rl.validation.jsbsim_import_build import _flight
from falcon_rl.validation.jsbsim_sampling import PropertyContext, convert

METRICS_FT = {"Sw": 174.0, "bw": 36.0, "cbarw": 4.9}
#: The c182's pitching moment due to alpha: qbar S c alpha T(alpha), T linear from -0.613 at alpha 0 to
#: -0.650 at 0.0943 rad and clamped: C_m = alpha T(alpha) is quadratic between the breakpoints.
CM_ALPHA = """<function><product>
  <property>aero/qbar-psf</property><property>metrics/Sw-sqft</property><property>metrics/cbarw-ft</property>
  <property>aero/alpha-rad</property>
  <table><independentVar>aero/alpha-rad</independentVar><tableData>0.0 -0.613
  0.0943 -0.650</tableData></table></product></function>"""
#: A plain table of alpha (no product with alpha): a piecewise-linear coefficient.
CL_ALPHA = """<function><product>
  <property>aero/qbar-psf</property><property>metrics/Sw-sqft</property>
  <table><independentVar>aero/alpha-rad</independentVar><tableData>-0.1 -0.4
  0.0 0.3 0.2 1.5</tableData></table></product></function>"""


def _convert(xml: str, axis: str):
    engine = EngineMap(np.array([10.0, 50.0, 95.0]), np.array([0.0, 1.0]), np.array([1.0, 1.225]),
                       np.zeros((3, 2, 2)), np.zeros((3, 2, 2)))
    flight = _flight({"elevator": (-0.4, 0.4), "aileron": (-0.3, 0.3), "rudder": (-0.3, 0.3)}, 50.0, engine)
    context = PropertyContext(METRICS_FT, {}, None, {}, set())
    node = parse_function(ET.fromstring(xml))
    return convert("term", axis, node, context, flight, np.random.default_rng(0))


def test_a_table_times_its_own_variable_is_exact():
    """C = alpha T(alpha) becomes multiplier alpha x table T on alpha: exact, where a table of C alone
    left a chord error of 0.392 (0.05 rad)^2 / 4 = 2.45e-4 between the default grid's nodes."""
    term, row = _convert(CM_ALPHA, "PITCH")
    assert row["axes"] == ["alpha"] and row["multiply"] == ["alpha"]
    assert row["max_error"] < 1e-9 * row["rms_coefficient"]
    alpha = np.array([-0.2, -0.01, 0.0, 0.0318, 0.07, 0.0943, 0.3])
    table = np.interp(alpha, [0.0, 0.0943], [-0.613, -0.650])
    approx = alpha * multilinear(term.breakpoints, term.values, [alpha])
    np.testing.assert_allclose(approx, alpha * table, rtol=0, atol=1e-12)
    # the node at alpha = 0 holds T's limit there, not 0 / 0
    zero = int(np.flatnonzero(np.abs(term.breakpoints[0]) < 1e-12)[0])
    assert term.values[zero] == pytest.approx(-0.613, abs=1e-9)


def test_a_plain_table_stays_a_table():
    term, row = _convert(CL_ALPHA, "LIFT")
    assert row["axes"] == ["alpha"] and row["multiply"] == []
    assert term.multiply == (0,) * len(TABLE_VARIABLES)
    assert row["max_error"] < 1e-12
