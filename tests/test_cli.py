"""CLI: JSON shapes on stdout, exit code 2 with a one-line reason on stderr for bad input."""

from __future__ import annotations

import json

import pytest

from falcon_rl.cli import main


def run_json(capsys, *argv):
    code = main([*argv, "--json"])
    out, err = capsys.readouterr()
    return code, json.loads(out), err


def test_airframes_json(capsys):
    code, doc, _ = run_json(capsys, "airframes")
    assert code == 0
    names = {row["name"] for row in doc["airframes"]}
    assert {"navion", "volantex_ranger"} <= names
    row = doc["airframes"][0]
    for key in ("span_m", "wing_area_m2", "aspect_ratio", "taper_ratio", "mass_kg", "cruise_speed_mps"):
        assert isinstance(row[key], float)


def test_trim_json_navion_reference_condition(capsys, navion):
    """Nelson's reference condition (sea level, 176 ft/s): C_L within 2% of W/(qS). The derived
    Navion is referred to its fuselage datum, not to Nelson's stability axes at this trim, so alpha
    is the datum attitude in cruise (wing at +2 deg incidence: a small nose-down attitude) and the
    elevator is a few degrees at most (stabilizer incidence set for cruise)."""
    code, doc, _ = run_json(capsys, "trim", "--airframe", "navion", "--airspeed", "53.64",
                            "--height", "30", "--ground-effect", "off")
    assert code == 0
    import torch

    from falcon_rl.physics.atmosphere import isa_density

    rho = float(isa_density(torch.tensor(30.0)))
    cl_weight = navion.weight / (0.5 * rho * 53.64**2 * navion.geometry.wing_area)
    assert doc["lift_coefficient"] == pytest.approx(cl_weight, rel=0.02)
    assert abs(doc["alpha_deg"]) < 3.0 and abs(doc["elevator_deg"]) < 5.0
    for key in ("alpha_deg", "elevator_deg", "throttle", "thrust_n", "drag_n", "lift_coefficient",
                "drag_coefficient", "induced_drag_coefficient"):
        assert key in doc


def test_trim_ranger_cruise_thrust(capsys):
    code, doc, _ = run_json(capsys, "trim", "--airframe", "volantex_ranger")
    assert code == 0
    assert doc["thrust_n"] == pytest.approx(0.9, rel=0.1)


def test_ge_table_json_and_plot(capsys, tmp_path, ranger):
    code, doc, _ = run_json(capsys, "ge-table", "--airframe", "volantex_ranger", "--out", str(tmp_path))
    assert code == 0
    rows = doc["rows"]
    assert [r["h_over_b"] for r in rows] == [0.25, 0.5, 1.0, 2.0, 3.0, 6.0]
    deltas = [r["delta_percent"] for r in rows]
    assert deltas[0] < deltas[1] < deltas[2] < 0  # thrust falls nearer the ground
    assert abs(deltas[-1]) < 0.5
    assert (tmp_path / "volantex_ranger.png").stat().st_size > 10_000


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["trim", "--airframe", "nope"], "unknown airframe"),
        (["trim", "--airframe", "navion", "--airspeed", "-3"], "--airspeed: '-3' must be in (0, 340] m/s"),
        (["trim", "--airframe", "navion", "--airspeed", "15"], "for navion at 15.00 m/s"),
        (["trim", "--airframe", "navion", "--airspeed", "abc"], "argument --airspeed: 'abc' is not a number"),
        (["ge-table"], "required: --airframe"),
        (["hover"], "invalid choice"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, argv, needle):
    code = main(argv)  # argparse errors too return 2 (main does not raise SystemExit)
    out, err = capsys.readouterr()
    assert code == 2
    assert needle in err
    assert len(err.strip().splitlines()) == 1
    assert out == ""


def test_eval_climb_descend_trim_json(capsys, tmp_path):
    code, doc, _ = run_json(capsys, "eval", "--task", "climb_descend", "--controller", "trim",
                            "--episodes", "2", "--seconds", "1", "--backend", "warp", "--out", str(tmp_path))
    assert code == 0
    assert doc["task"] == "climb_descend" and doc["controller"] == "trim" and doc["survival"] == 1.0
    for key in ("climb_rate_rmse_mps", "ramp_rmse_m", "level_off", "level_off_time_s", "overshoot_m"):
        assert key in doc
    assert doc["settings"]["episodes"] == 2 and doc["settings"]["episode_seconds"] == 1.0
    assert "## Climb and descend" in (tmp_path / "report.md").read_text()
    assert (tmp_path / "climb_descend_volantex_ranger_trim.png").stat().st_size > 10_000


def test_eval_flies_on_the_torch_threads_it_is_given(capsys, tmp_path):
    """One thread by default (small networks and batches), any count on request."""
    import torch

    before = torch.get_num_threads()
    try:
        for argv, threads in (([], 1), (["--threads", "2"], 2)):
            code, _, _ = run_json(capsys, "eval", "--controller", "trim", "--episodes", "1",
                                  "--seconds", "0.1", "--out", str(tmp_path / str(threads)), *argv)
            assert code == 0 and torch.get_num_threads() == threads
    finally:
        torch.set_num_threads(before)


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--task", "path_following", "--controller", "lqr"],
         "controller 'lqr' does not apply to task 'path_following'; its controllers: ['guided-l1-lqr', "
         "'guided-l1-ppo', 'guided-lqr', 'guided-ppo', 'trim']"),
        (["--task", "trajectory", "--controller", "mppi"], "'guided-ppo', 'trim']"),
        (["--task", "altitude", "--controller", "trim", "--maneuvers", "circle"],
         "--maneuvers does not apply to the altitude protocol"),
        (["--task", "attitude", "--controller", "trim", "--maneuvers", "loop"],
         "--maneuvers: unknown ['loop']"),
        (["--task", "hover", "--controller", "trim"], "invalid choice: 'hover'"),
        (["--task", "altitude", "--controller", "no_such_policy.pt"], "nor a policy file"),
        (["--task", "altitude", "--controller", "ppo", "--policy-seed", "7"],
         "no shipped ppo policy of seed 7 for task 'altitude'"),
        (["--task", "altitude", "--controller", "td3", "--airframe", "navion"], "no shipped td3 policy"),
        (["--task", "altitude", "--controller", "lqr", "--policy-seed", "1"],
         "--policy-seed picks a shipped ppo/sac/td3 policy; it does not apply to --controller lqr"),
        (["--task", "altitude", "--controller", "ppo", "--policy-seed", "-1"], "--policy-seed"),
        (["--task", "altitude", "--controller", "trim", "--threads", "0"], "--threads"),
    ],
)
def test_eval_bad_input_exits_2_with_one_line(capsys, tmp_path, argv, needle):
    code = main(["eval", *argv, "--episodes", "1", "--seconds", "0.1", "--out", str(tmp_path)])
    _, err = capsys.readouterr()
    assert code == 2
    assert needle in err
    assert len(err.strip().splitlines()) == 1


def test_shipped_policies_are_named_by_algorithm_task_airframe_and_seed():
    from falcon_rl.policies import shipped_name, shipped_policy

    assert shipped_name("altitude", "volantex_ranger") == "ppo_altitude_volantex_ranger.pt"
    name = shipped_name("attitude", "airframes/airship_v7.json", "sac", 2)
    assert name == "sac_attitude_airship_v7_seed2.pt"
    assert shipped_policy("altitude", "volantex_ranger", "ppo", 0).name == "ppo_altitude_volantex_ranger.pt"
