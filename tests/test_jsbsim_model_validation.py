"""An imported airframe flown against the JSBSim aircraft it came from (``validate jsbsim
--jsbsim-model``): a short elevator doublet by default, the full table (slow) on demand."""

from __future__ import annotations

import json

import numpy as np
import pytest

from falcon_rl import load_airframe

pytest.importorskip("jsbsim")

from falcon_rl.validation.jsbsim_model_compare import ModelDoublet, validate_model


def test_doublet_is_plus_then_minus():
    t = np.array([0.9, 1.0, 1.49, 1.5, 1.99, 2.0])
    np.testing.assert_allclose(ModelDoublet(0.1, 1.0, 0.5).offset(t), [0, 0.1, 0.1, -0.1, -0.1, 0])


def test_c172p_elevator_doublet_agrees_with_jsbsim(tmp_path):
    """4 s from trim at 50 m/s, 300 m: the short-period response (pitch rate) and the airspeed agree."""
    results, skipped = validate_model(load_airframe("jsbsim_c172p"), "c172p", tmp_path, (50.0,), (300.0,),
                                      ("elevator",), duration=4.0)
    assert not skipped and len(results) == 1
    m = results[0].metrics
    assert m["pitch_rate"]["r"] > 0.995
    assert m["airspeed"]["rmse"] < 0.05 and m["altitude"]["rmse"] < 0.1
    # the surfaces really moved: both simulators saw the same physical doublet
    assert np.ptp(results[0].falcon.channels["pitch_rate"]) > 0.05


def test_cli_refuses_an_unknown_jsbsim_model(tmp_path, capsys):
    from falcon_rl.cli import main

    code = main(["validate", "jsbsim", "--jsbsim-model", "no_such", "--out", str(tmp_path)])
    assert code != 0 and "unknown JSBSim aircraft 'no_such'" in capsys.readouterr().err


#: Pitch-rate r floor on the elevator doublet at dt = 0.01 s: 0.999 (the issue's target), the pa28's
#: 0.998 (measured 0.9986: JSBSim's alpha-dot lags one frame; 0.9999 at dt = 0.0025 s, see
#: docs/jsbsim_import.md).
PITCH_RATE_FLOOR = {"c172p": 0.999, "pa28": 0.998, "c182": 0.999}


@pytest.mark.slow
@pytest.mark.parametrize("model", ["c172p", "pa28", "c182"])
def test_imported_aircraft_track_jsbsim_over_20_s(model, tmp_path):
    """20 s from trim at 50 m/s, 10 and 300 m (measured in docs/jsbsim_import.md). Elevator doublet:
    altitude and airspeed r >= 0.999, raw and as the response (run minus own free flight), pitch rate
    at its floor, roll rate and bank >= 0.99. Aileron doublet: roll rate and bank >= 0.999, and the
    barely excited altitude response >= 0.999."""
    results, skipped = validate_model(load_airframe(f"jsbsim_{model}"), model, tmp_path, (50.0,),
                                      (10.0, 300.0), ("trim", "elevator", "aileron"), duration=20.0)
    assert not skipped
    for r in results:
        m, response = r.metrics, r.response
        if r.case.excitation.startswith("trim"):
            assert response is None
        elif r.case.excitation.startswith("elevator"):
            for channel in ("altitude", "airspeed"):
                assert min(m[channel]["r"], response[channel]["r"]) >= 0.999, json.dumps(r.row())
            assert m["pitch_rate"]["r"] >= PITCH_RATE_FLOOR[model], json.dumps(r.row())
            assert m["roll_rate"]["r"] >= 0.99 and m["phi"]["r"] >= 0.99, json.dumps(r.row())
        else:
            assert m["roll_rate"]["r"] >= 0.999 and m["phi"]["r"] >= 0.999, json.dumps(r.row())
            assert response["altitude"]["r"] >= 0.999, json.dumps(r.row())


def test_cli_validate_jsbsim_model_json(capsys, tmp_path):
    """1.6 s of each excitation at one condition and a 20 ms step: a row per case, the doublets' responses
    (run minus free flight), plots written, targets listed."""
    from falcon_rl.cli import main

    code = main(["validate", "jsbsim", "--jsbsim-model", "c172p", "--airspeeds", "50", "--heights", "300",
                 "--duration", "1.6", "--dt", "0.02", "--out", str(tmp_path), "--json"])
    out, _ = capsys.readouterr()
    assert code == 0
    doc = json.loads(out)
    assert doc["airframe"] == "jsbsim_c172p" and not doc["skipped"] and doc["dt_s"] == 0.02
    assert [r["excitation"] for r in doc["rows"]] == ["trim 50 m/s", "elevator 50 m/s", "aileron 50 m/s"]
    assert set(doc["rows"][0]["channels"]["phi"]) == {"unit", "r", "rmse"}
    assert "response_channels" not in doc["rows"][0]
    for row in doc["rows"][1:]:  # the doublet starts at 1 s: both responses are 0 before it, then move
        assert row["duration_s"] == pytest.approx(1.6)
        excited = {"elevator": "pitch_rate", "aileron": "roll_rate"}[row["excitation"].split()[0]]
        assert row["response_channels"][excited]["r"] > 0.99
    assert all((tmp_path / p.split("/")[-1]).exists() for p in doc["plots"])
