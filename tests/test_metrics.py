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
from falcon_rl.evaluation.tracking_metrics import (
    climb_descend_metrics,
    path_following_metrics,
    trajectory_metrics,
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


# ------------------------------------------------------------------ climb/descend, path, trajectory
def _synthetic(n: int, t: int, dt: float, state: dict, task: dict,
               terminated: torch.Tensor | None = None) -> TensorDict:
    """A rollout [n, t] of "next" entries with times dt, 2 dt, ... and no done unless ``terminated``."""
    time = (dt * torch.arange(1, t + 1, dtype=torch.float32)).expand(n, t)
    terminated = torch.zeros(n, t, dtype=torch.bool) if terminated is None else terminated
    return TensorDict({"next": {"state": {**state, "time": time}, "task": task,
                                "done": terminated[..., None].clone(), "terminated": terminated[..., None]}},
                      batch_size=[n, t])


def test_climb_descend_metrics_score_the_ramp_and_the_level_off() -> None:
    # dt 1 s, 40 -> 50 m at 2 m/s: the ramp runs 5 steps (h_ref 42..50), then holds
    rate = torch.tensor([[2.0] * 5 + [0.0] * 3, [2.0] * 8])  # row 1: the ramp never ends
    height = torch.tensor([[42.0, 44.0, 46.0, 48.0, 49.5, 51.2, 50.2, 50.0],
                           [42.0, 44.0, 46.0, 48.0, 50.0, 52.0, 54.0, 56.0]])
    reference = torch.tensor([[42.0, 44.0, 46.0, 48.0, 50.0, 50.0, 50.0, 50.0],
                              [42.0, 44.0, 46.0, 48.0, 50.0, 52.0, 54.0, 56.0]])
    climb = torch.tensor([[2.0, 2.0, 2.0, 2.0, 1.5, 1.3, -0.6, -0.2], [2.0] * 8])
    velocity = torch.stack([torch.zeros(2, 8), torch.zeros(2, 8), -climb], dim=-1)
    full = torch.ones(2, 8)
    rollout = _synthetic(2, 8, 1.0, {"height": height, "velocity_ned": velocity},
                         {"target_altitude": torch.stack([50.0 * full[0], 70.0 * full[1]]),
                          "initial_altitude": 40.0 * full, "reference_altitude": reference,
                          "reference_climb_rate": rate})
    m = climb_descend_metrics(rollout, band=1.0, grace_seconds=1.0)
    assert m["survival"].tolist() == [True, True]
    assert m["climb_rate_rmse_mps"][0].item() == pytest.approx(math.sqrt(0.25 / 5))  # -0.5 at the ramp's end
    assert m["climb_rate_rmse_mps"][1].item() == pytest.approx(0.0)
    assert m["ramp_rmse_m"][0].item() == pytest.approx(math.sqrt(0.25 / 5))
    assert m["level_off"].tolist() == [True, False]
    assert m["level_off_time_s"][0].item() == pytest.approx(1.0)  # ramp ends at step 5, inside for good at 6
    assert math.isnan(m["level_off_time_s"][1].item()) and math.isnan(m["level_off_rmse_m"][1].item())
    assert m["level_off_rmse_m"][0].item() == pytest.approx(math.sqrt((0.04 + 0.0) / 2), abs=1e-5)
    assert m["overshoot_m"][0].item() == pytest.approx(1.2, abs=1e-5)


def test_path_following_metrics_known_cross_track_and_course() -> None:
    # row 0: path north through the origin, aircraft weaving +-3 m east of it after t = 3 s, heading 45 deg
    # row 1: path south (course pi), aircraft 6 m east = 6 m left of it (e_y = -6), heading -170 deg
    t = 6
    north = 10.0 * torch.arange(1, t + 1, dtype=torch.float32)
    east = torch.tensor([[8.0, 4.0, 3.0, -3.0, 3.0, -3.0], [6.0] * t])
    position = torch.stack([north.expand(2, t), east, torch.full((2, t), -61.0)], dim=-1)
    heading = torch.tensor([math.radians(45.0), math.radians(-170.0)])[:, None].expand(2, t)
    velocity = torch.stack([10 * torch.cos(heading), 10 * torch.sin(heading), torch.zeros(2, t)], dim=-1)
    course = torch.tensor([0.0, math.pi])[:, None].expand(2, t)
    rollout = _synthetic(2, t, 1.0, {"position_ned": position, "velocity_ned": velocity,
                                     "height": -position[..., 2]},
                         {"path_point": torch.zeros(2, t, 2), "path_course": course,
                          "path_height": torch.full((2, t), 60.0)})
    m = path_following_metrics(rollout, band=5.0, intercept_seconds=3.0)
    assert m["cross_track_rmse_m"].tolist() == pytest.approx([3.0, 6.0], abs=1e-5)
    assert m["course_rmse_rad"].tolist() == pytest.approx([math.radians(45.0), math.radians(10.0)], abs=1e-5)
    assert m["altitude_rmse_m"].tolist() == pytest.approx([1.0, 1.0], abs=1e-5)
    assert m["completion"].tolist() == [True, False]
    assert m["capture_time_s"][0].item() == pytest.approx(2.0) and math.isnan(m["capture_time_s"][1].item())


def test_trajectory_metrics_split_the_position_error() -> None:
    # reference at the origin; after the 1 s intercept the errors are (3, 4, 0), (0, 0, -2), (3, 4, 0) m
    position = torch.tensor([[[0.0, 0.0, 12.0], [3.0, 4.0, 0.0], [0.0, 0.0, -2.0], [3.0, 4.0, 0.0]]])
    terminated = torch.tensor([[False, False, False, True]])
    # the reference flies north at 10 m/s on a right turn of 100 m (centre 100 m east of it)
    velocity = torch.tensor([10.0, 0.0, 0.0]).expand(1, 4, 3)
    rollout = _synthetic(1, 4, 0.5, {"position_ned": position},
                         {"reference_position": torch.zeros(1, 4, 3), "reference_velocity": velocity,
                          "reference_curvature": torch.full((1, 4, 1), 0.01)}, terminated)
    m = trajectory_metrics(rollout, tolerance=4.5, intercept_seconds=1.0)
    off_arc = 100.0 - math.hypot(3.0, 96.0)
    assert m["cross_track_rmse_m"].item() == pytest.approx(math.sqrt(2 * off_arc**2 / 3), abs=1e-4)
    assert m["position_rmse_m"].item() == pytest.approx(math.sqrt((25 + 4 + 25) / 3), abs=1e-5)
    assert m["horizontal_rmse_m"].item() == pytest.approx(math.sqrt(50 / 3), abs=1e-5)
    assert m["vertical_rmse_m"].item() == pytest.approx(math.sqrt(4 / 3), abs=1e-5)
    assert m["time_in_band"].item() == pytest.approx(1 / 3)
    assert not m["survival"].item()  # terminated on the last step
