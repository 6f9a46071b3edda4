"""``falcon-rl experiment <study>``: a small sweep writes its report, LaTeX tables, results.json and
figure; a second run reads every cell from the cache; a learned row without a policy stays empty."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from falcon_rl.cli import main


def run(*args: str) -> dict:
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(["experiment", *args, "--json"]) == 0
    return json.loads(printed.getvalue())


def test_altitude_study_writes_its_outputs_and_resumes(tmp_path: Path) -> None:
    args = ("altitude", "--airframes", "navion", "--controllers", "lqr,td3",
            "--episodes", "2", "--out", str(tmp_path))
    doc = run(*args)
    study = doc["studies"]["altitude"]
    assert study["cells"] == 2 and study["finished"] == 2
    report = Path(study["report"]).read_text()
    assert "| navion | lqr |" in report and "no policy" in report  # no Navion TD3 altitude policy ships
    assert "\\toprule" in Path(study["tables"]).read_text()
    results = json.loads(Path(study["results"]).read_text())
    assert results["format"] == "falcon-rl-experiment/1"
    lqr = next(c for c in results["cells"] if c["controller"] == "lqr" and c["airframe"] == "navion")
    assert lqr["summary"]["survival"] == 1.0 and lqr["summary"]["rmse_m"] < 0.5
    td3 = next(a for a in results["aggregates"] if a["controller"] == "td3")
    assert td3["metrics"] == {}  # an empty entry, as the paper leaves it
    assert [Path(f).name for f in study["figures"]] == ["altitude.png"]
    cache = sorted((tmp_path / "cells").glob("*.json"))
    stamps = [p.stat().st_mtime_ns for p in cache]
    again = run(*args)  # every cell from the cache: nothing rewritten, the same numbers
    assert [p.stat().st_mtime_ns for p in cache] == stamps
    assert json.loads(Path(again["studies"]["altitude"]["results"]).read_text())["cells"] == results["cells"]


@pytest.mark.parametrize(("args", "message"), [
    (("altitude", "--controllers", "pid"), "--controllers: unknown ['pid']"),
    (("altitude", "--controllers", ""), "--controllers must be a comma list"),
    (("altitude", "--airframes", "nope"), "nope"),
])
def test_bad_study_options_exit_2(args: tuple[str, ...], message: str, capsys, tmp_path: Path) -> None:
    assert main(["experiment", *args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


@pytest.mark.slow
def test_every_study_at_a_tiny_scale(tmp_path: Path) -> None:
    doc = run("all", "--airframes", "volantex_ranger", "--controllers", "lqr", "--episodes", "1",
              "--seconds", "3", "--out", str(tmp_path))
    assert set(doc["studies"]) == {"altitude", "maneuvers", "ground-effect", "robustness"}
    for name, study in doc["studies"].items():
        assert study["finished"] == study["cells"], name
        assert study["figures"], name


def test_sea_state_study_scores_each_sea_state(tmp_path: Path) -> None:
    doc = run("sea-state", "--airframes", "airship_v7", "--controllers", "lqr", "--episodes", "2",
              "--seconds", "6", "--out", str(tmp_path))
    study = doc["studies"]["sea-state"]
    assert study["finished"] == study["cells"] == 1
    report = Path(study["report"]).read_text()
    assert "| SS0 | SS1 | SS2 | SS3 | SS4 | SS5 |" in report and "| airship_v7 | lqr |" in report
    results = json.loads(Path(study["results"]).read_text())
    summary = results["cells"][0]["summary"]
    assert summary["0/water_contact_rate"] == 0.0 and summary["0/survival"] == 1.0
    assert summary["0/clearance_rmse_span"] < summary["3/clearance_rmse_span"]  # waves are harder to skim
    assert 0.1 < summary["0/power_saved"] < 0.25  # the V7 saves ~16 % at 0.25 b (the trim table's 16.1 %)
    assert [Path(f).name for f in study["figures"]] == ["sea_state.png"]


@pytest.mark.slow  # ~50 s: two ground-effect designs and two 10 ms landings (the protocol: test_landing.py)
def test_landing_study_flies_the_same_starts_with_and_without_ground_effect(tmp_path: Path) -> None:
    doc = run("landing", "--airframes", "airship_v7", "--episodes", "1", "--out", str(tmp_path))
    study = doc["studies"]["landing"]
    assert study["finished"] == study["cells"] == 1
    report = Path(study["report"]).read_text()
    assert "| In limits GE | In limits no GE |" in report and "| airship_v7 | tecs-flare |" in report
    summary = json.loads(Path(study["results"]).read_text())["cells"][0]["summary"]
    assert summary["ge/landed_within_limits"] == summary["no_ge/landed_within_limits"] == 1.0
    assert summary["ge/sink_rate_mps"] < summary["no_ge/sink_rate_mps"]  # the cushion softens the touchdown
    assert [Path(f).name for f in study["figures"]] == ["landing.png"]
