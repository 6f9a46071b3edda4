"""Analytic cases for each metric of the paper's metric table."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDict

from falcon_rl.evaluation import (
    acquisition,
    altitude_metrics,
    first_episode_mask,
    overshoot,
    rmse,
    settled_window,
    settling_index,
    settling_time,
    summarize,
    survival,
    time_in_band,
)


def test_first_episode_mask() -> None:
    done = torch.tensor([[0, 0, 1, 0, 1], [0, 0, 0, 0, 0]], dtype=torch.bool)
    expected = torch.tensor([[1, 1, 1, 0, 0], [1, 1, 1, 1, 1]], dtype=torch.bool)
    assert torch.equal(first_episode_mask(done), expected)
    assert torch.equal(first_episode_mask(done[..., None]), expected)


def test_survival_counts_only_terminations_in_the_scored_episode() -> None:
    terminated = torch.tensor([[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]], dtype=torch.bool)
    assert survival(terminated).tolist() == [True, False, False]
    valid = torch.tensor([[1, 1, 1, 1], [1, 1, 1, 1], [1, 1, 0, 0]], dtype=torch.bool)
    assert survival(terminated, valid).tolist() == [True, False, True]


def test_settling_time_linear_approach() -> None:
    # e_t = 10 - t for t <= 10, then 0: inside the 1 m band from t = 9 on
    t = torch.arange(20, dtype=torch.float32)
    error = (10.0 - t).clamp_min(0.0)[None]
    assert settling_index(error, 1.0).item() == 9
    assert settling_time(error, 1.0, dt=0.1).item() == pytest.approx(0.9)
    assert settling_time(error, 1.0, dt=0.1, start_time=0.1).item() == pytest.approx(1.0)


def test_settling_time_requires_holding_to_the_end() -> None:
    # enters the band at t = 2, leaves at t = 5, re-enters for good at t = 7
    error = torch.tensor([[5.0, 2.0, 0.5, 0.2, 0.0, 3.0, 2.0, 0.9, 0.1, 0.0]])
    assert settling_index(error, 1.0).item() == 7
    never = torch.tensor([[5.0, 0.0, 0.0, 2.0]])
    assert math.isnan(settling_time(never, 1.0, dt=1.0).item())
    assert settling_time(torch.zeros(1, 4), 1.0, dt=1.0).item() == 0.0


def test_acquisition_needs_survival_and_settling() -> None:
    error = torch.tensor([[4.0, 0.5, 0.5], [4.0, 3.0, 2.0], [4.0, 0.5, 0.5]])
    terminated = torch.tensor([[0, 0, 0], [0, 0, 0], [0, 1, 0]], dtype=torch.bool)
    assert acquisition(error, terminated, 1.0).tolist() == [True, False, False]


def test_rmse_over_the_window() -> None:
    error = torch.tensor([[3.0, -3.0, 3.0, -3.0], [10.0, 10.0, 1.0, -1.0]])
    assert rmse(error).tolist() == pytest.approx([3.0, math.sqrt(50.5)])
    window = torch.tensor([[1, 1, 1, 1], [0, 0, 1, 1]], dtype=torch.bool)
    assert rmse(error, window).tolist() == pytest.approx([3.0, 1.0])
    assert math.isnan(rmse(error, torch.zeros_like(window))[0].item())


def test_time_in_band() -> None:
    error = torch.tensor([[0.0, 0.5, 2.0, -0.9], [5.0, 5.0, 5.0, 5.0]])
    assert time_in_band(error, 1.0).tolist() == pytest.approx([0.75, 0.0])
    window = torch.tensor([[0, 0, 1, 1], [1, 1, 1, 1]], dtype=torch.bool)
    assert time_in_band(error, 1.0, window).tolist() == pytest.approx([0.5, 0.0])


def test_overshoot_is_the_excursion_past_the_target() -> None:
    # climbing from 15 m below (e_0 = -15): overshoot is the largest positive error
    climb = torch.tensor([[-15.0, -5.0, 2.0, 0.5, 0.0]])
    # descending from 15 m above: overshoot is the largest negative error, as a magnitude
    descend = torch.tensor([[15.0, 4.0, -1.5, -0.2, 0.0]])
    # never crossing the target: 0, not max |e|
    short = torch.tensor([[-15.0, -10.0, -3.0, -1.0, -0.5]])
    error = torch.cat([climb, descend, short])
    direction = torch.tensor([1.0, -1.0, 1.0])
    assert overshoot(error, direction).tolist() == pytest.approx([2.0, 1.5, 0.0])


def test_settled_window_starts_after_the_ramp() -> None:
    rate = torch.tensor([[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    window = settled_window(rate, dt=0.5, grace_seconds=1.0)
    assert window.tolist() == [[False] * 5 + [True] * 3]


def test_summarize_averages_errors_over_survivors() -> None:
    metrics = {"survival": torch.tensor([True, True, False]),
               "acquisition": torch.tensor([True, False, False]),
               "rmse": torch.tensor([1.0, 3.0, 100.0]),
               "settling_time": torch.tensor([5.0, math.nan, 1.0])}
    out = summarize(metrics, metrics["survival"])
    assert out["survival"] == pytest.approx(2 / 3) and out["acquisition"] == pytest.approx(1 / 3)
    assert out["rmse"] == pytest.approx(2.0) and out["settling_time"] == pytest.approx(5.0)
    none = summarize({"rmse": torch.tensor([1.0])}, torch.tensor([False]))
    assert math.isnan(none["rmse"])


def test_altitude_metrics_on_a_synthetic_rollout() -> None:
    # 1 episode, dt = 1 s, target 50 m from 35 m: ramp at 5 m/s for 3 s, overshoot 0.6 m, then holds
    height = torch.tensor([[40.0, 45.0, 50.6, 50.3, 50.1, 50.0, 50.0, 50.0]])
    n, t = height.shape
    ref_rate = torch.tensor([[5.0, 5.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    full = torch.full((n, t), 1.0)
    rollout = TensorDict({"next": {
        "state": {"height": height, "time": torch.arange(1.0, t + 1.0)[None]},
        "task": {"target_altitude": 50.0 * full, "initial_altitude": 35.0 * full,
                 "reference_climb_rate": ref_rate},
        "done": torch.zeros(n, t, 1, dtype=torch.bool), "terminated": torch.zeros(n, t, 1, dtype=torch.bool),
    }}, batch_size=[n, t])
    m = altitude_metrics(rollout, band=1.0, grace_seconds=2.0)
    assert m["survival"].item() and m["acquisition"].item()
    assert m["settling_time"].item() == pytest.approx(3.0)  # first sample inside for good is t = 3 s
    assert m["overshoot"].item() == pytest.approx(0.6, abs=1e-5)
    assert m["rmse"].item() == pytest.approx(math.sqrt((0.01 + 0 + 0 + 0) / 4), abs=1e-5)
    assert m["time_in_band"].item() == 1.0
