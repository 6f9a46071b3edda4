"""The robustness study as a library function: cells in physical units, shared seeds, true-state metrics."""

from __future__ import annotations

import copy
import math

import pytest
import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModuleBase

from falcon_rl.evaluation.controllers import make_controller
from falcon_rl.evaluation.metrics import first_episode_mask
from falcon_rl.evaluation.robustness import (
    FAMILIES,
    MeasuredView,
    RobustnessCell,
    reads_state,
    robustness_grid,
    run_cell,
    severity,
)
from falcon_rl.policies import available

AIRFRAME = "volantex_ranger"
SMALL = {"episodes": 2, "seconds": 2.0, "maneuvers": ("random",), "seed": 0, "progress": False}
LEVELS = ("nominal", "severe")


@pytest.fixture(scope="module", autouse=True)
def one_thread():
    """Two envs per cell: per-op overhead dominates, a second thread only adds sync cost."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


_LQR: dict[str, TensorDictModuleBase] = {}


def _lqr(env) -> TensorDictModuleBase:
    """The attitude LQR, its gain schedule solved once (every cell has the same airframe and step); a
    fresh copy per cell, so no integrator state crosses cells."""
    if AIRFRAME not in _LQR:
        _LQR[AIRFRAME] = make_controller("lqr", env)
    return copy.deepcopy(_LQR[AIRFRAME])


@pytest.fixture(scope="module")
def lqr_grid():
    return robustness_grid(AIRFRAME, "lqr", _lqr, levels=LEVELS, **SMALL)


def test_every_cell_in_physical_units(lqr_grid) -> None:
    assert set(lqr_grid.cells) == {(f, lv) for f in FAMILIES for lv in LEVELS}
    expected = {"sensors": (5.0, "x noise floor"), "obs_delay": (80.0, "ms"), "action_delay": (100.0, "ms"),
                "turbulence": (0.15, "sigma_u/V_a")}
    for family, (value, unit) in expected.items():
        severe, nominal = lqr_grid.cell(family, "severe"), lqr_grid.cell(family, "nominal")
        assert (severe.severity, severe.unit) == (value, unit)
        assert (nominal.severity, nominal.unit) == (0.0, unit)
    for cell in lqr_grid.cells.values():
        assert cell.episodes == 2 and cell.alive_steps > 0
        assert 0.0 <= cell.survival <= 1.0
        for value in (cell.bank_rmse_deg, cell.climb_rate_rmse_mps, cell.airspeed_rmse_mps):
            assert math.isfinite(value) and value >= 0.0
    rows = lqr_grid.to_rows()
    assert len(rows) == 8 and {r["family"] for r in rows} == set(FAMILIES)
    assert {"airframe", "controller", "severity", "unit", "survival", "bank_rmse_deg", "climb_rate_rmse_mps",
            "airspeed_rmse_mps", "episodes"} <= set(rows[0])
    assert lqr_grid.as_nested()["obs_delay"]["severe"]["bank_rmse_deg"] == lqr_grid.cell(
        "obs_delay", "severe").bank_rmse_deg
    assert severity("obs_delay", "medium") == 50.0 and severity("turbulence", "mild") == 0.05


def test_nominal_column_is_the_same_flight_in_every_family(lqr_grid) -> None:
    metrics = ("survival", "bank_rmse_deg", "climb_rate_rmse_mps", "airspeed_rmse_mps", "alive_steps")
    nominal = [tuple(getattr(lqr_grid.cell(f, "nominal"), m) for m in metrics) for f in FAMILIES]
    assert len(set(nominal)) == 1
    # flown again on its own (another family, a fresh env with the same seed): the same numbers
    alone = robustness_grid(AIRFRAME, "lqr", _lqr, families=("turbulence",), levels=("nominal",), **SMALL)
    assert tuple(getattr(alone.cell("turbulence", "nominal"), m) for m in metrics) == nominal[0]
    # and the disturbed cells are not the nominal flight
    for family in FAMILIES:
        assert lqr_grid.cell(family, "severe").bank_rmse_deg != nominal[0][1], family


def test_severity_hurts_the_lqr_where_it_robustly_does(lqr_grid) -> None:
    # Command latency and turbulence raise the LQR's bank error; observation latency need not (the LQR
    # reacts to a stale bank against a current command, which acts as lead on these streams).
    for family in ("action_delay", "turbulence"):
        assert lqr_grid.cell(family, "severe").bank_rmse_deg > lqr_grid.cell(family, "nominal").bank_rmse_deg
    turbulence = lqr_grid.cell("turbulence", "severe")
    assert turbulence.airspeed_rmse_mps > lqr_grid.cell("turbulence", "nominal").airspeed_rmse_mps
    assert turbulence.climb_rate_rmse_mps > lqr_grid.cell("turbulence", "nominal").climb_rate_rmse_mps


def test_metrics_come_from_the_true_state_not_the_measured_one(lqr_grid) -> None:
    cell, rollouts = run_cell(AIRFRAME, _lqr, "sensors", "severe", ("random",), episodes=2, seconds=2.0,
                              keep_rollouts=True)
    assert cell == lqr_grid.cell("sensors", "severe")  # same seed, same flight
    nxt = rollouts[0]["next"]
    alive = first_episode_mask(nxt["done"])
    command = nxt["task", "bank_command"].reshape(alive.shape)

    def rmse_deg(euler: torch.Tensor) -> float:
        error = (euler[..., 0] - command).double()
        return math.degrees(math.sqrt(float(error[alive].pow(2).mean())))

    true, measured = rmse_deg(nxt["state", "euler"]), rmse_deg(nxt["measured", "euler"])
    assert cell.bank_rmse_deg == pytest.approx(true, rel=1e-9)
    assert cell.seen_bank_rmse_deg == pytest.approx(measured, rel=1e-9)
    assert abs(true - measured) > 0.05  # 5x noise floors: the sensors do not report the truth
    # without a sensor transform the controller is shown the truth
    nominal = lqr_grid.cell("sensors", "nominal")
    assert nominal.seen_bank_rmse_deg == nominal.bank_rmse_deg


def test_state_readers_read_the_measured_state() -> None:
    class Echo(TensorDictModuleBase):
        in_keys, out_keys = [("state", "euler")], ["action"]

        def forward(self, td):
            td.set("action", td["state", "euler"].clone())
            return td

    td = TensorDict({"state": {"euler": torch.zeros(2, 3)}, "measured": {"euler": torch.ones(2, 3)}},
                    batch_size=[2])
    view = MeasuredView(Echo())
    assert view.in_keys == [("measured", "euler")]
    assert torch.equal(view(td)["action"], torch.ones(2, 3))
    assert torch.equal(td["state", "euler"], torch.zeros(2, 3))  # the true state is left alone
    del td["measured"]
    assert torch.equal(view(td)["action"], torch.zeros(2, 3))  # no sensors: the truth
    assert reads_state(Echo())


@pytest.mark.skipif(f"ppo_attitude_{AIRFRAME}" not in available(), reason="no shipped attitude policy")
def test_shipped_ppo_attitude_policy_flies_the_grid() -> None:
    grid = robustness_grid(AIRFRAME, "ppo", families=("obs_delay", "action_delay"), levels=LEVELS, **SMALL)
    assert grid.controller == "ppo" and set(grid.cells) == {(f, lv) for f in ("obs_delay", "action_delay")
                                                           for lv in LEVELS}
    nominal = grid.cell("obs_delay", "nominal")
    assert nominal == RobustnessCell(**{**vars(grid.cell("action_delay", "nominal")), "family": "obs_delay"})
    assert nominal.survival == 1.0 and nominal.bank_rmse_deg < 5.0
    for family in ("obs_delay", "action_delay"):  # the learned executor pays for latency
        assert grid.cell(family, "severe").bank_rmse_deg > grid.cell(family, "nominal").bank_rmse_deg


def test_bad_arguments_are_one_line_value_errors() -> None:
    bad = [{"families": ("gusts",)}, {"levels": ("extreme",)}, {"maneuvers": ("loop",)}, {"episodes": 0},
           {"seconds": -1.0}, {"families": ()}]
    for kwargs in bad:
        with pytest.raises(ValueError) as info:
            robustness_grid(AIRFRAME, "lqr", _lqr, progress=False, **kwargs)
        assert "\n" not in str(info.value)
    with pytest.raises(ValueError):
        severity("sensors", "extreme")
