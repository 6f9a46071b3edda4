"""Stopping a run when it is solved (``stop_when``): the conditions' syntax and one-line errors, case
averaging and NaN, a run that stops at the first validation meeting them (PPO and an off-policy
recipe), its summary and checkpoint, a resumed solved run that only finishes, and a run whose
conditions are never met training all its frames."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import pytest

from falcon_rl.cli import main
from falcon_rl.recipes import ppo
from falcon_rl.recipes.checkpoint import load_checkpoint
from falcon_rl.recipes.checks import check_config
from falcon_rl.recipes.selection import StopCondition, conditions_met, parse_stop_when

sys.path.insert(0, str(Path(__file__).parent))
from test_training_reproducible import train_argv

ALTITUDE = ("survival", "acquisition", "rmse_m", "settling_time_s", "overshoot_m")
#: Validation on one 1 s episode per maneuver of the attitude protocol every 64 frames.
VALIDATE = ("--task", "attitude", "--eval-every", "64", "--set", "eval_episodes=1", "--set",
            "eval_seconds=1.0")


def test_conditions_parse_and_name_what_is_wrong():
    conditions = parse_stop_when(" survival>=1, acquisition >= 0.95,rmse_m<=0.5 ", ALTITUDE)
    assert conditions == (StopCondition("survival", ">=", 1.0), StopCondition("acquisition", ">=", 0.95),
                          StopCondition("rmse_m", "<=", 0.5))
    assert [str(c) for c in conditions] == ["survival>=1", "acquisition>=0.95", "rmse_m<=0.5"]
    assert parse_stop_when("", ALTITUDE) == ()
    for text, message in [("rmse_m<0.5", "is not METRIC>=NUMBER"), ("rmse_m", "is not METRIC"),
                          ("bank_rmse_deg<=1", "unknown metric 'bank_rmse_deg'"),
                          ("rmse_m<=nan", "must be a finite number"), ("rmse_m<=inf", "finite"),
                          ("rmse_m<=half", "finite"), (" , ", "no condition")]:
        with pytest.raises(ValueError, match=message) as error:
            parse_stop_when(text, ALTITUDE)
        assert "\n" not in str(error.value)


def test_conditions_average_cases_and_nan_never_meets():
    bank = parse_stop_when("bank_rmse_deg<=1.0,survival>=1", ["bank_rmse_deg", "survival"])
    cases = {"circle/bank_rmse_deg": 0.5, "helix/bank_rmse_deg": 1.4, "circle/survival": 1.0,
             "helix/survival": 1.0}
    assert conditions_met(cases, bank)  # mean 0.95 deg
    assert not conditions_met({**cases, "helix/bank_rmse_deg": 1.6}, bank)  # mean 1.05 deg
    rmse = parse_stop_when("rmse_m<=0.5", ALTITUDE)
    assert not conditions_met({"rmse_m": math.nan}, rmse)  # never acquired
    assert not conditions_met({"survival": 1.0}, rmse)  # not reported
    assert not conditions_met({"rmse_m": 0.1}, ())  # no condition: never solved


def test_stop_when_is_checked_before_a_run():
    with pytest.raises(ValueError, match="stop_when needs eval_every > 0"):
        check_config(ppo.make_config("altitude", stop_when="rmse_m<=0.5", eval_every=0))
    with pytest.raises(ValueError, match="unknown metric 'rmse'"):
        check_config(ppo.make_config("altitude", stop_when="rmse<=0.5"))
    check_config(ppo.make_config("attitude", stop_when="bank_rmse_deg<=1", eval_every=1000))
    assert main(["train", "ppo", "--stop-when", "rmse_m<0.5", "--no-progress"]) == 2
    assert main(["train", "ppo", "--task", "attitude", "--stop-when", "rmse_m<=0.5", "--no-progress"]) == 2


@pytest.mark.parametrize("name", ["ppo", "sac"])
def test_a_run_stops_at_the_first_validation_that_meets_the_conditions(tmp_path: Path, name: str, capsys):
    out = tmp_path / "run"
    assert main(train_argv(name, out, 512, *VALIDATE, "--stop-when", "survival>=0")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 64  # the first validation, after one 64-frame batch
    assert summary["solved"]["frames"] == 64 and summary["solved"]["wall_seconds"] > 0
    split = summary["time_split"]  # the loop's wall clock: collecting, validating and learning
    assert split["collect_s"] > 0 and split["validate_s"] > 0 and split["learn_s"] >= 0
    assert split["collect_s"] + split["validate_s"] <= split["loop_s"] <= summary["wall_seconds"]
    assert 0 < split["collect_fraction"] < 1
    assert "stop_when met at 64 frames" in capsys.readouterr().out
    checkpoint = load_checkpoint(out / "checkpoint.pt")
    assert checkpoint["counters"]["frames"] == 64 and checkpoint["extra"]["solved"] == summary["solved"]


def test_a_resumed_solved_run_only_finishes_and_unmet_conditions_train_every_frame(tmp_path: Path):
    out = tmp_path / "run"
    assert main(train_argv("ppo", out, 256, *VALIDATE, "--stop-when", "survival>=0")) == 0
    solved = load_checkpoint(out / "checkpoint.pt")["extra"]["solved"]
    assert main(train_argv("ppo", out, 256, *VALIDATE, "--stop-when", "survival>=0", "--resume")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 64 and summary["solved"] == solved
    # Other conditions, not met by the saved validation: the resumed run trains on to the end.
    assert main(train_argv("ppo", out, 256, *VALIDATE, "--stop-when", "survival>=2", "--resume")) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 256 and summary["solved"] is None


def test_demo_train_stops_when_the_altitude_protocol_is_solved(tmp_path: Path):
    from falcon_rl.cli import build_parser
    from falcon_rl.commands.demo import training_config
    from falcon_rl.envs.tasks.altitude import ALTITUDE_SOLVED

    args = build_parser().parse_args(["demo", "--train", "--frames", "2000000", "--out", str(tmp_path)])
    cfg = training_config(args, tmp_path)
    check_config(cfg)
    assert cfg.stop_when == ALTITUDE_SOLVED and cfg.frames == 2_000_000 and cfg.eval_every > 0
    assert parse_stop_when(ALTITUDE_SOLVED, ALTITUDE) == (
        StopCondition("survival", ">=", 1.0), StopCondition("acquisition", ">=", 0.95),
        StopCondition("rmse_m", "<=", 0.5))
