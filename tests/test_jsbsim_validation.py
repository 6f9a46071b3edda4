"""JSBSim export and cross-validation: the exported aircraft reproduces our model term by term,
and (slow) trajectories agree with r >= 0.999 with ground effect off."""

from __future__ import annotations

import dataclasses
import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import torch

pytest.importorskip("jsbsim")

from falcon_rl.cli import main
from falcon_rl.constants import FT, LBF, SLUG, SLUG_FT2
from falcon_rl.physics.actuators import normalised_command
from falcon_rl.physics.dynamics import derivative, evaluate
from falcon_rl.physics.params import build_params
from falcon_rl.physics.rotations import euler_to_quaternion
from falcon_rl.validation.jsbsim_compare import HEADLINE, Doublet, validate_jsbsim
from falcon_rl.validation.jsbsim_export import COEFFICIENT, export_aircraft
from falcon_rl.validation.jsbsim_fly import initialise_jsbsim, make_fdm

# (height m, euler rad, velocity as fractions of cruise, rates rad/s, surfaces rad, throttle)
STATES = [
    (100.0, (0.0, 0.03, 0.0), (1.0, 0.0, 0.04), (0.0, 0.0, 0.0), (0.01, 0.0, 0.0), 0.5),
    (1.2, (0.1, 0.05, 0.2), (0.99, 0.03, 0.06), (0.1, -0.2, 0.05), (0.05, -0.03, 0.02), 0.6),
    (3.0, (-0.2, -0.1, 1.0), (1.1, -0.05, 0.5), (-0.3, 0.4, -0.1), (-0.3, 0.2, -0.2), 0.9),  # alpha clamped
]


def _state(airframe, height, euler, vel, rates, surfaces, throttle) -> torch.Tensor:
    x = torch.zeros(1, 19 + airframe.num_motors, dtype=torch.float64)
    x[0, 2] = -height
    x[0, 3:7] = euler_to_quaternion(torch.tensor([euler], dtype=torch.float64))[0]
    x[0, 7:10] = torch.tensor(vel, dtype=torch.float64) * airframe.envelope.cruise_speed
    x[0, 10:13] = torch.tensor(rates, dtype=torch.float64)
    x[0, 13:16] = torch.tensor(surfaces, dtype=torch.float64)
    x[0, 19:] = throttle
    return x


@pytest.fixture(scope="module")
def exported(tmp_path_factory, navion, ranger):
    root = tmp_path_factory.mktemp("jsbsim")
    return root, {a.name: (a, export_aircraft(a, root)) for a in (navion, ranger)}


def test_export_writes_valid_xml_in_jsbsim_units(exported):
    _, aircraft = exported
    airframe, path = aircraft["navion"]
    assert path.name == "navion.xml" and path.parent.parent.name == "aircraft"
    root = ET.parse(path).getroot()
    assert root.tag == "fdm_config"
    assert float(root.find("metrics/wingspan").text) == pytest.approx(airframe.geometry.span / FT)
    assert root.find("metrics/wingarea").get("unit") == "FT2"
    assert float(root.find("mass_balance/iyy").text) == pytest.approx(airframe.inertia[1, 1] / SLUG_FT2)
    axes = {a.get("name") for a in root.findall("aerodynamics/axis")}
    assert axes == {"X", "Y", "Z", "ROLL", "PITCH", "YAW"}
    assert root.find("external_reactions/force").get("frame") == "BODY"


@pytest.mark.parametrize("name", ["navion", "volantex_ranger"])
@pytest.mark.parametrize("ground_effect", [False, True])
@pytest.mark.parametrize("case", range(len(STATES)))
def test_exported_aero_reproduces_our_coefficients_forces_and_accelerations(exported, name, ground_effect,
                                                                             case):
    root, aircraft = exported
    airframe = aircraft[name][0]
    p = build_params(airframe, 1, dtype=torch.float64, ground_effect=ground_effect)
    x = _state(airframe, *STATES[case])
    command = normalised_command(x[:, 13:16], x[:, 19], p)
    ev, xdot = evaluate(x, p), derivative(x, command, p)
    fdm = make_fdm(root, airframe, float(-x[0, 2]))
    initialise_jsbsim(fdm, airframe, x[0], command[0].numpy(), ground_effect)
    ours = ev.coefficients[0].tolist()
    theirs = [fdm[COEFFICIENT[c]] for c in ("CL", "CD", "CY", "Cl", "Cm", "Cn")]
    # 1e-7: JSBSim resolves altitude on the 1000-Earth-radii sphere to about 1 micrometre.
    np.testing.assert_allclose(theirs, ours, rtol=1e-7, atol=1e-12)
    assert fdm["aero/falcon/kappa-L"] == pytest.approx(float(ev.kappa_lift[0]), rel=1e-7)
    assert fdm["aero/falcon/kappa-D"] == pytest.approx(float(ev.kappa_drag[0]), rel=1e-7)
    # Forces scale with density, and JSBSim's ISA density is 9e-6 (relative) above ours.
    ratio = fdm["atmosphere/rho-slugs_ft3"] * SLUG / FT**3 / float(ev.density[0])
    assert ratio == pytest.approx(1.0, abs=2e-5)
    force = [fdm[f"forces/fb{c}-total-lbs"] * LBF for c in "xyz"]
    tol = {"rtol": 1e-6, "atol": 1e-9 * airframe.weight}
    np.testing.assert_allclose(force, (ev.force_body[0] * ratio).tolist(), **tol)
    moment = [fdm[f"moments/{c}-total-lbsft"] * LBF * FT for c in "lmn"]
    np.testing.assert_allclose(moment, (ev.moment_body[0] * ratio).tolist(), **tol)
    v_dot = xdot[0, 7:10] + (ratio - 1.0) * ev.force_body[0] / airframe.mass
    accel = [fdm[f"accelerations/{c}dot-ft_sec2"] * FT for c in "uvw"]
    np.testing.assert_allclose(accel, v_dot.tolist(), rtol=1e-6, atol=1e-8)
    w_dot = xdot[0, 10:13] + (ratio - 1.0) * (p.inertia_inv[0] @ ev.moment_body[0])
    alpha_dot = [fdm[f"accelerations/{c}dot-rad_sec2"] for c in "pqr"]
    np.testing.assert_allclose(alpha_dot, w_dot.tolist(), rtol=1e-6, atol=1e-8)


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # get_J returns an np.matrix
def test_exported_inertia_products_keep_their_signs(tmp_path, ranger):
    inertia = np.array([[0.06, -0.002, -0.004], [-0.002, 0.05, 0.001], [-0.004, 0.001, 0.1]])
    airframe = dataclasses.replace(ranger, name="ranger_products", inertia=inertia)
    export_aircraft(airframe, tmp_path)
    fdm = make_fdm(tmp_path, airframe, 100.0)
    fdm["ic/h-agl-ft"] = 100.0 / FT
    fdm["ic/u-fps"] = 15.0 / FT
    assert fdm.run_ic()
    jsbsim_inertia = np.asarray(fdm.get_mass_balance().get_J()) * SLUG_FT2
    np.testing.assert_allclose(jsbsim_inertia, inertia, rtol=1e-9, atol=1e-12)


def test_short_doublet_agrees_and_ground_effect_switch_matters(tmp_path, ranger):
    results = validate_jsbsim(ranger, tmp_path, heights=(1.0,), ground_effect=("off", "on", "both"),
                              excitations=("doublet",), duration=1.5, doublet=Doublet(0.1, 0.2, 0.3))
    by_ge = {r.case.ground_effect: r for r in results}
    for setting in ("off", "both"):
        for channel in HEADLINE:
            # A short, sharp doublet weights the sub-step actuator timing most; the 10 s runs of the
            # slow test reach 0.999.
            assert by_ge[setting].metrics[channel]["r"] >= 0.995, (setting, channel)
    assert by_ge["on"].metrics["altitude"]["rmse"] > 10 * by_ge["off"].metrics["altitude"]["rmse"]
    assert by_ge["on"].kappa[0] > 1.0 and by_ge["on"].kappa[1] < 1.0


def test_doublet_commands():
    trim = np.array([0.1, 0.0, 0.0, -0.2])
    u = Doublet(amplitude=0.05, start=0.1, width=0.05).commands(trim, 30, 0.01)
    assert u.shape == (30, 4)
    np.testing.assert_allclose(u[:10, 0], 0.1)
    np.testing.assert_allclose(u[10:15, 0], 0.05)
    np.testing.assert_allclose(u[15:20, 0], 0.15)
    np.testing.assert_allclose(u[20:, 0], 0.1)
    np.testing.assert_allclose(u[:, 3], -0.2)


def test_cli_validate_jsbsim_json(capsys, tmp_path):
    code = main(["validate", "jsbsim", "--airframe", "volantex_ranger", "--heights", "50",
                 "--duration", "0.3", "--ground-effect", "off", "--out", str(tmp_path), "--json"])
    out, _ = capsys.readouterr()
    assert code == 0
    doc = json.loads(out)
    assert {(r["height_m"], r["ground_effect"], r["excitation"]) for r in doc["rows"]} == {
        (50.0, "off", "trim"), (50.0, "off", "doublet")}
    row = doc["rows"][0]
    assert set(row["channels"]["altitude"]) == {"unit", "r", "rmse"}
    assert all((tmp_path / p.split("/")[-1]).exists() for p in doc["plots"])


@pytest.mark.parametrize("argv", [["--heights", "-1"], ["--ground-effect", "sometimes"],
                                  ["--excitation", "spin"], ["--duration", "0"]])
def test_cli_validate_bad_input_exits_2(capsys, tmp_path, argv):
    code = main(["validate", "jsbsim", "--airframe", "navion", "--out", str(tmp_path), *argv])
    _, err = capsys.readouterr()
    assert code == 2 and err.count("\n") == 1


@pytest.mark.slow
@pytest.mark.parametrize("name", ["navion", "volantex_ranger"])
def test_regression_r_at_least_0999_with_ground_effect_off(tmp_path, name):
    from falcon_rl import load_airframe

    results = validate_jsbsim(load_airframe(name), tmp_path, heights=(1.0, 10.0, 100.0),
                              ground_effect=("off",), excitations=("doublet",), duration=10.0)
    assert len(results) == 3
    for r in results:
        assert r.falcon.time[-1] >= 10.0
        for channel in HEADLINE:
            assert r.metrics[channel]["r"] >= 0.999, (name, r.case, channel, r.metrics[channel])
