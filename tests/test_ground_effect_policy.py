"""The ground-effect study's policy column: thrust under a controller with the correction on and off."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from falcon_rl.evaluation.ground_effect_policy import (
    STATUSES,
    GroundEffectPolicyResult,
    band_heights,
    ground_effect_policy_column,
    trim_wing_offset,
)

AIRFRAME = "volantex_ranger"
SPAN = 1.62  # m, the Ranger's span
BANDS = (0.25, 1.0, 6.0)
#: Short episodes at a 20 ms control step (decimation 2) keep the file under a minute.
SHORT = {"episodes": 1, "seconds": 2.0, "settle_seconds": 1.0, "progress": False, "decimation": 2}


@pytest.fixture(scope="module")
def lqr_column() -> GroundEffectPolicyResult:
    return ground_effect_policy_column(AIRFRAME, "lqr", bands_h_over_b=BANDS, **SHORT)


class FullDeflection(TensorDictModuleBase):
    """Elevator hard over, throttle idle: no controller, it cannot hold any band."""

    def __init__(self) -> None:
        super().__init__()
        self.in_keys, self.out_keys = ["observation"], ["action"]

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        td.set("action", torch.tensor([1.0, -1.0]).expand(*td.batch_size, 2).clone())
        return td


def test_lqr_holds_every_band_with_and_without_ground_effect(lqr_column: GroundEffectPolicyResult) -> None:
    assert [r.h_over_b for r in lqr_column.rows] == list(BANDS)
    for row in lqr_column.rows:
        assert row.status == row.status_ge == row.status_no_ge == "held"
        assert row.survival_ge == row.survival_no_ge == 1.0
        assert row.height_m == pytest.approx(row.h_over_b * SPAN, rel=1e-3)
        assert row.mean_abs_error_ge_m <= row.tolerance_m and row.rmse_no_ge_m <= row.tolerance_m
        assert row.no_ge.drag_factor == row.no_ge.lift_factor == 1.0  # the correction is off
    assert lqr_column.rows[0].ge.drag_factor < 0.9 < 1.0 < lqr_column.rows[0].ge.lift_factor
    # the Ranger's wing sits above the CG: the correction sees a larger h/b than the row's
    assert lqr_column.rows[0].wing_h_over_b > BANDS[0]


def test_ground_effect_lowers_thrust_and_fades_with_height(lqr_column: GroundEffectPolicyResult) -> None:
    low, mid, high = lqr_column.rows
    assert low.thrust_ge_n < low.thrust_no_ge_n
    assert low.delta_percent < -0.5  # induced drag falls near the ground
    assert low.delta_percent < mid.delta_percent < 0.0  # and less so higher up
    assert abs(high.delta_percent) < 0.05  # ~0 at h/b = 6
    for row in lqr_column.rows:  # the delta is the thrusts' relative difference
        assert row.delta_percent == pytest.approx(100 * (row.thrust_ge_n / row.thrust_no_ge_n - 1), rel=1e-9)


def test_policy_column_agrees_with_the_trim_table(lqr_column: GroundEffectPolicyResult) -> None:
    for row in lqr_column.rows[:2]:
        assert math.copysign(1.0, row.delta_percent) == math.copysign(1.0, row.trim_delta_percent) == -1.0
        assert row.delta_percent == pytest.approx(row.trim_delta_percent, rel=0.5)
    assert abs(lqr_column.rows[2].trim_delta_percent) < 0.05


def test_rows_and_settings(lqr_column: GroundEffectPolicyResult) -> None:
    rows = lqr_column.to_rows()
    assert len(rows) == len(BANDS) and rows[0]["status"] in STATUSES
    assert {"thrust_ge_n", "thrust_no_ge_n", "delta_percent", "survival_ge", "ge", "no_ge"} <= set(rows[0])
    assert lqr_column.settings["seconds"] == 2.0 and lqr_column.settings["seed"] == 0
    assert len(lqr_column.held()) == len(BANDS)
    assert "| 0.25 |" in lqr_column.format()


def test_unholdable_bands_are_reported_not_averaged() -> None:
    # a high wing: with the wing quarter chord as the reference, h/b = 0.02 puts the CG below ground
    assert trim_wing_offset(AIRFRAME) < 0.0
    result = ground_effect_policy_column(AIRFRAME, "trim", bands_h_over_b=(0.02, 0.25),
                                         height_reference="wing", **SHORT)
    in_ground, trimmed = result.rows
    assert in_ground.status == "in_ground" and in_ground.survival_ge == 0.0
    assert math.isnan(in_ground.delta_percent) and math.isnan(in_ground.trim_delta_percent)
    # open-loop trim balloons in ground effect (more lift at the out-of-ground-effect trim)
    assert trimmed.status == "not_held" and trimmed.status_ge == "not_held"
    assert trimmed.mean_abs_error_ge_m > trimmed.tolerance_m and math.isnan(trimmed.delta_percent)
    assert trimmed.ge.wing_h_over_b > 0.25  # it flew, away from the band
    assert result.held() == []


def test_a_crash_is_reported_with_its_reason() -> None:
    result = ground_effect_policy_column(AIRFRAME, "full-deflection", lambda env: FullDeflection(),
                                         bands_h_over_b=(0.25,), compare_trim=False, **SHORT)
    (row,) = result.rows
    assert row.status == "crashed" and row.survival_ge == 0.0 and row.survival_no_ge == 0.0
    assert row.ge.termination != "none" and math.isnan(row.delta_percent)


def test_wing_reference_heights() -> None:
    offset = trim_wing_offset(AIRFRAME)
    assert band_heights(AIRFRAME, (1.0,), "wing") == [pytest.approx(SPAN + offset)]
    assert band_heights(AIRFRAME, (1.0,)) == [pytest.approx(SPAN)]


@pytest.mark.parametrize("kwargs", [
    {"bands_h_over_b": ()}, {"bands_h_over_b": (0.25, -1.0)}, {"episodes": 0}, {"seconds": 0.0},
    {"settle_seconds": 2.0}, {"backend": "jax"}, {"ground_effect": False}, {"height_reference": "tip"},
    {"tolerance_m": 0.0}, {"target_altitudes": (5.0,)},
])
def test_bad_arguments_are_one_line_value_errors(kwargs: dict) -> None:
    options = {**SHORT, **kwargs}
    with pytest.raises(ValueError) as info:
        ground_effect_policy_column(AIRFRAME, "lqr", **options)
    assert "\n" not in str(info.value)
