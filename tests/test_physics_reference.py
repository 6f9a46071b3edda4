"""Published values: ISA table, Phillips-Hunsaker factors (physics.md section 1.1 and 3)."""

from __future__ import annotations

import pytest
import torch

from falcon_rl.physics.atmosphere import isa
from falcon_rl.physics.ground_effect import H_OVER_B_MIN, phillips_hunsaker, taper_corrections

# US Standard Atmosphere 1976 check values (physics.md section 3): H m, T K, p Pa, rho, a m/s.
ISA_TABLE = [
    (0.0, 288.15, 101325.0, 1.22500, 340.29),
    (500.0, 284.90, 95461.0, 1.16727, 338.37),
    (1000.0, 281.65, 89875.0, 1.11164, 336.43),
    (2000.0, 275.15, 79495.0, 1.00649, 332.53),
    (11000.0, 216.65, 22632.0, 0.36392, 295.07),
]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_isa_matches_standard_table(dtype):
    """Tolerance: the table is printed to 5 significant digits (1e-4 relative); the table's H is
    geopotential, so geometric altitude z = r0 H / (r0 - H) is fed in."""
    r0 = 6_356_766.0
    for h_geo, t, p, rho, a in ISA_TABLE:
        z = torch.tensor([r0 * h_geo / (r0 - h_geo)], dtype=dtype)
        tt, pp, rr, aa = isa(z)
        assert tt.item() == pytest.approx(t, rel=1e-5)
        assert pp.item() == pytest.approx(p, rel=1e-4)
        assert rr.item() == pytest.approx(rho, rel=2e-4)
        assert aa.item() == pytest.approx(a, rel=1e-4)


def test_isa_stratosphere_is_isothermal():
    t, p, _, _ = isa(torch.tensor([12000.0, 15000.0], dtype=torch.float64))
    assert torch.allclose(t, torch.full_like(t, 216.65), atol=1e-9)
    assert p[1] < p[0]


# physics.md table (R_A = 8, R_T = 1): h/b, kappa_D, kappa_L, kappa_D(C_L=0.8), kappa_L(C_L=0.8).
PH_TABLE = [
    (0.05, 0.409, 1.124, 0.497, 1.115),
    (0.10, 0.565, 1.089, 0.607, 1.085),
    (0.15, 0.667, 1.067, 0.694, 1.064),
    (0.20, 0.739, 1.051, 0.759, 1.050),
    (0.30, 0.831, 1.033, 0.843, 1.032),
    (0.50, 0.915, 1.016, 0.921, 1.015),
    (1.00, 0.972, 1.004, 0.974, 1.004),
]


def test_phillips_hunsaker_matches_published_table():
    """The table is rounded to 3 decimals: tolerance 1.5e-3 absolute."""
    hb = torch.tensor([r[0] for r in PH_TABLE], dtype=torch.float64)
    ar, tr = torch.tensor(8.0, dtype=torch.float64), torch.tensor(1.0, dtype=torch.float64)
    kl, kd = phillips_hunsaker(hb, ar, tr)
    kl_hl, kd_hl = phillips_hunsaker(hb, ar, tr, torch.full_like(hb, 0.8))
    expected = torch.tensor([r[1:] for r in PH_TABLE], dtype=torch.float64)
    got = torch.stack([kd, kl, kd_hl, kl_hl], dim=-1)
    assert torch.allclose(got, expected, atol=1.5e-3), (got - expected).abs().max()


def test_taper_corrections_match_published_numbers():
    ar = torch.tensor([8.0, 8.0, 7.5], dtype=torch.float64)
    tr = torch.tensor([1.0, 0.4, 0.4], dtype=torch.float64)
    dd, dl = taper_corrections(ar, tr)
    assert torch.allclose(dd, torch.tensor([0.891, 0.979, 0.981], dtype=torch.float64), atol=1e-3)
    assert torch.allclose(dl, torch.tensor([0.878, 0.980, 0.980], dtype=torch.float64), atol=1e-3)


def test_ground_effect_clamp_and_far_field():
    ar, tr = torch.tensor(8.0), torch.tensor(1.0)
    kl0, kd0 = phillips_hunsaker(torch.tensor([0.0, -1.0, H_OVER_B_MIN]), ar, tr, torch.tensor(0.5))
    assert torch.isfinite(kl0).all() and torch.isfinite(kd0).all()
    assert torch.allclose(kl0, kl0[2].expand(3)) and torch.allclose(kd0, kd0[2].expand(3))
    kl, kd = phillips_hunsaker(torch.tensor([6.0, 20.0]), ar, tr, torch.tensor(0.5))
    assert torch.allclose(kl, torch.ones(2), atol=5e-4) and torch.allclose(kd, torch.ones(2), atol=5e-4)
    # Negative lift coefficient gives the same factors as its magnitude (no NaN).
    kl_n, kd_n = phillips_hunsaker(torch.tensor([0.2]), ar, tr, torch.tensor([-0.5]))
    kl_p, kd_p = phillips_hunsaker(torch.tensor([0.2]), ar, tr, torch.tensor([0.5]))
    assert torch.allclose(kl_n, kl_p) and torch.allclose(kd_n, kd_p)
