"""The ground-effect table: theory column equals the Phillips-Hunsaker prediction, thrust falls
near the ground, the far field is unchanged, and the paper's whole-drag form saves more."""

from __future__ import annotations

import pytest
import torch

from falcon_rl.evaluation.ground_effect_trim import ground_effect_table
from falcon_rl.physics.ground_effect import phillips_hunsaker


@pytest.mark.parametrize("name", ["navion", "volantex_ranger"])
def test_ge_table_physics(request, name):
    airframe = request.getfixturevalue("navion" if name == "navion" else "ranger")
    rows = ground_effect_table(airframe)
    g = airframe.geometry
    for r in rows:
        _, kd = phillips_hunsaker(torch.tensor(r.wing_h_over_b, dtype=torch.float64),
                                  torch.tensor(g.aspect_ratio, dtype=torch.float64),
                                  torch.tensor(g.taper_ratio, dtype=torch.float64),
                                  torch.tensor(r.cl_oge, dtype=torch.float64))
        assert r.theory_percent == pytest.approx(100 * (float(kd) - 1) * r.cdi_oge / r.cd_oge, abs=1e-9)
        # Induced-only correction at trim: the measured change follows the theory closely.
        assert r.delta_percent == pytest.approx(r.theory_percent, abs=1.5)
    assert rows[0].delta_percent < rows[1].delta_percent < rows[2].delta_percent < 0
    assert abs(rows[-1].delta_percent) < 0.5
    paper = ground_effect_table(airframe, model="paper")
    assert paper[0].delta_percent < rows[0].delta_percent
