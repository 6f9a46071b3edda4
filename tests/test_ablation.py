"""The ablation study: one arm per simplified phenomenon, scored against the full model."""

from __future__ import annotations

import json
import math

from falcon_rl.cli import main
from falcon_rl.evaluation.ablation import (
    ABLATIONS,
    FULL,
    ablation_markdown,
    headline_metric,
    run_ablation,
)
from falcon_rl.evaluation.controllers import make_controller


def test_headline_metrics_come_from_the_task_records():
    assert headline_metric("altitude") == ("rmse_m", "m")
    assert headline_metric("attitude") == ("bank_rmse_deg", "deg")


def test_every_arm_is_flown_with_its_switch():
    result = run_ablation("altitude", "volantex_ranger", "trim", lambda env: make_controller("trim", env),
                          episodes=2, episode_seconds=12.0)
    assert list(result.values) == [FULL, *(label for label, _ in ABLATIONS)]
    assert result.change(FULL) == 0.0
    assert all(math.isfinite(v) for v in result.values.values())
    assert result.results["ideal actuators"].settings.get("model") == {"actuators": "ideal"}
    assert result.results["no ground effect"].settings.get("ground_effect") is False
    table = ablation_markdown([result])
    assert "| no ground effect |" in table and "rmse_m" in table


def test_cli_ablation_writes_the_report_figure_and_json(tmp_path, capsys):
    code = main(["experiment", "ablation", "--tasks", "altitude", "--controllers", "trim", "--episodes", "2",
                 "--seconds", "1", "--out", str(tmp_path), "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["results"][0]["controller"] == "trim"
    assert set(doc["results"][0]["changes"]) == {label for label, _ in ABLATIONS}
    for name in ("report.md", "results.json", "ablation.png"):
        assert (tmp_path / name).is_file()


def test_cli_rejects_a_controller_that_does_not_apply(capsys):
    assert main(["experiment", "ablation", "--tasks", "path_following", "--controllers", "lqr"]) == 2
    assert "does not apply" in capsys.readouterr().err
