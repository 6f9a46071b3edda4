"""The sea surface (``physics.sea``) and its Warp twins: sea-state heights, the spectra's published
properties (the Pierson-Moskowitz Hs and Tp of a wind, the JONSWAP normalisation), the sampled wave
fields' statistics (Hs = 4 sqrt(m0) of long records at a point within 2 %, the record's Welch spectrum
against the target), deep-water dispersion, the spreading, seeding, the orbital flow's decay and the
Warp twins' parity."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
import warp as wp
from scipy.signal import welch

from falcon_rl.constants import G0
from falcon_rl.physics._warp import init_warp
from falcon_rl.physics.sea import (
    SEA_STATE_HS,
    SeaFieldWp,
    SeaState,
    fully_developed_period,
    jonswap,
    pierson_moskowitz_wind,
    sample_sea,
    sea_air_velocity_wp,
    sea_elevation_rate_wp,
    sea_elevation_wp,
    sea_field_views,
    sea_state_height,
)

OMEGA = torch.linspace(0.02, 20.0, 200_001, dtype=torch.float64)


def moment0(spectrum: torch.Tensor) -> float:
    return float(torch.trapezoid(spectrum, OMEGA))


def generator(seed: int = 0) -> torch.Generator:
    return torch.Generator().manual_seed(seed)


def test_sea_state_codes_give_the_wmo_heights():
    assert [sea_state_height(code) for code in range(7)] == [0.0, 0.05, 0.3, 0.875, 1.875, 3.25, 5.0]
    assert SEA_STATE_HS[4] == (1.25, 2.5)
    for bad in (-1, 7, 2.0, True, "3"):
        with pytest.raises(ValueError, match="sea state must be an int code 0-6"):
            sea_state_height(bad)
    with pytest.raises(ValueError, match="significant_height >= 0"):
        SeaState(-1.0, 5.0)


def test_a_fully_developed_pierson_moskowitz_sea_has_hs_021_u2_over_g_and_tp_5_sqrt_hs():
    for wind in (8.0, 12.0, 20.0):
        spectrum = pierson_moskowitz_wind(OMEGA, wind)
        hs = 4.0 * math.sqrt(moment0(spectrum))
        assert hs == pytest.approx(0.2092 * wind**2 / G0, rel=2e-3)
        tp = 2.0 * math.pi / float(OMEGA[spectrum.argmax()])
        assert tp / math.sqrt(hs) == pytest.approx(5.0, rel=1e-2)
        assert fully_developed_period(hs) == pytest.approx(tp, rel=1e-2)
        # the Hs-Tp form (gamma 1) is the same spectrum
        torch.testing.assert_close(jonswap(OMEGA, hs, tp, gamma=1.0), spectrum, rtol=2e-2, atol=1e-6)


@pytest.mark.parametrize("gamma", [1.0, 2.0, 3.3, 5.0])
def test_jonswap_holds_its_hs_and_peaks_at_tp(gamma):
    spectrum = jonswap(OMEGA, 2.0, 8.0, gamma)
    assert 4.0 * math.sqrt(moment0(spectrum)) == pytest.approx(2.0, rel=1.5e-2)  # A_gamma is DNV's fit
    assert 2.0 * math.pi / float(OMEGA[spectrum.argmax()]) == pytest.approx(8.0, rel=5e-3)
    if gamma > 1.0:
        peak = torch.tensor([2.0 * math.pi / 8.0], dtype=torch.float64)
        assert float(jonswap(peak, 2.0, 8.0, gamma) / jonswap(peak, 2.0, 8.0, 1.0)) == pytest.approx(
            (1.0 - 0.287 * math.log(gamma)) * gamma, rel=1e-9)


def point_record(surface, seconds: float, dt: float) -> torch.Tensor:
    """[N, T] the elevation at the origin every ``dt`` for ``seconds`` (one point per time)."""
    time = torch.arange(0.0, seconds, dt, dtype=torch.float64).expand(surface.phase.shape[0], -1)
    return surface.elevation(torch.zeros_like(time), torch.zeros_like(time), time)


@pytest.mark.parametrize("code", [2, 3, 5])
def test_a_long_record_at_a_point_has_the_sea_states_hs(code):
    sea = SeaState.from_code(code)
    m0 = moment0(sea.spectrum(OMEGA))
    surface = sample_sea(sea, 4, generator(code), dtype=torch.float64)
    expected = torch.full((4,), 4.0 * math.sqrt(m0), dtype=torch.float64)
    torch.testing.assert_close(4.0 * surface.variance.sqrt(), expected, rtol=2e-2, atol=0)
    eta = point_record(surface, 3 * 3600.0, sea.peak_period / 8)  # three hours
    assert torch.allclose(4.0 * eta.std(-1), torch.tensor(4.0 * math.sqrt(m0), dtype=torch.float64),
                          rtol=2e-2)


def test_the_records_welch_spectrum_is_the_target_spectrum():
    sea = SeaState(2.0, 7.0, spreading=None)
    dt = 0.25
    eta = point_record(sample_sea(sea, 4, generator(5), dtype=torch.float64), 4 * 3600.0, dt).numpy()
    frequency, psd = welch(eta, fs=1.0 / dt, nperseg=1024, axis=-1)
    omega = torch.tensor(2.0 * math.pi * frequency)
    measured = torch.tensor(psd.mean(0)) / (2.0 * math.pi)  # per Hz -> per rad/s
    # the energy below each frequency, measured against the target's (a line spectrum of 128 components
    # read through Welch's bins: the cumulative spectra are compared, not the bins' wiggles)
    step = float(omega[1] - omega[0])
    measured_cdf = torch.cumsum(measured, 0) * step
    cumulative = torch.cat([torch.zeros(1, dtype=torch.float64),
                            torch.cumulative_trapezoid(sea.spectrum(OMEGA), OMEGA)])
    target_cdf = torch.tensor(np.interp((omega + step / 2).numpy(), OMEGA.numpy(), cumulative.numpy()))
    m0 = float(cumulative[-1])
    assert float((measured_cdf - target_cdf).abs().max()) < 0.03 * m0
    peak = float(omega[measured.argmax()])
    assert abs(peak - sea.peak_frequency) <= step, (peak, sea.peak_frequency)


def test_components_obey_deep_water_dispersion_and_the_spreading():
    sea = SeaState(1.0, 5.0, direction=0.6, spreading=2.0)
    surface = sample_sea(sea, 64, generator(3), dtype=torch.float64)
    torch.testing.assert_close(surface.wavenumber, surface.frequency**2 / G0)
    theta = torch.atan2(surface.direction_sin, surface.direction_cos)
    assert (theta - 0.6).abs().max() < math.pi / 2
    # cos^2 spreading: E[cos^2(theta - theta0)] = 3/4, mean direction theta0
    assert float(torch.cos(theta - 0.6).pow(2).mean()) == pytest.approx(0.75, abs=0.01)
    mean = torch.atan2(torch.sin(theta).mean(), torch.cos(theta).mean())
    assert float(mean) == pytest.approx(0.6, abs=0.01)
    crested = sample_sea(SeaState(1.0, 5.0, direction=0.6, spreading=None), 4, generator(3))
    torch.testing.assert_close(torch.atan2(crested.direction_sin, crested.direction_cos),
                               torch.full((4, 128), 0.6))


def test_a_long_crested_field_travels_at_the_phase_speed():
    """A single-frequency reading: eta(x + c t, t) of each component equals eta(x, 0); for the whole field,
    eta at (x, t) equals eta at (x - c_k t, 0) only per component, so check the one-component identity."""
    surface = sample_sea(SeaState(1.0, 6.0, spreading=None), 1, generator(1), dtype=torch.float64)
    k = 40
    one = type(surface)(**{name: getattr(surface, name)[:, k:k + 1] for name in (
        "amplitude", "wavenumber", "frequency", "direction_cos", "direction_sin", "phase")})
    speed = float(one.frequency / one.wavenumber)
    t = torch.tensor([13.7], dtype=torch.float64)
    x = torch.tensor([[5.0]], dtype=torch.float64)
    torch.testing.assert_close(one.elevation(x + speed * t, x * 0, t), one.elevation(x, x * 0, 0.0))


def test_elevation_rate_and_orbital_flow():
    surface = sample_sea(SeaState.from_code(4, direction=1.0), 3, generator(2), dtype=torch.float64)
    north = torch.tensor([0.0, 30.0, -12.0], dtype=torch.float64)
    east = torch.tensor([5.0, -8.0, 100.0], dtype=torch.float64)
    t, h = torch.tensor([3.0, 7.0, 11.0], dtype=torch.float64), 1e-4
    numeric = (surface.elevation(north, east, t + h) - surface.elevation(north, east, t - h)) / (2 * h)
    torch.testing.assert_close(surface.elevation_rate(north, east, t), numeric, rtol=1e-6, atol=1e-8)
    # at the mean level the vertical flow is the surface's rise (NED: down = -d(eta)/dt), and it decays
    at_level = surface.air_velocity(north, east, torch.zeros(3, dtype=torch.float64), t)
    torch.testing.assert_close(-at_level[:, 2], surface.elevation_rate(north, east, t))
    far = surface.air_velocity(north, east, torch.full((3,), 200.0, dtype=torch.float64), t)
    assert far.abs().max() < 1e-3 * at_level.abs().max()


def test_fields_are_seeded_per_env_and_a_flat_sea_is_flat():
    sea = SeaState.from_code(3)
    a, b = sample_sea(sea, 4, generator(9)), sample_sea(sea, 4, generator(9))
    assert torch.equal(a.phase, b.phase) and torch.equal(a.amplitude, b.amplitude)
    assert not torch.equal(a.phase[0], a.phase[1])
    flat = sample_sea(SeaState.from_code(0), 4, generator(9))
    assert flat.amplitude.abs().max() == 0
    assert flat.elevation(torch.zeros(4), torch.zeros(4), 5.0).abs().max() == 0
    with pytest.raises(ValueError, match="at least 64 components"):
        sample_sea(sea, 4, generator(9), components=32)


@wp.kernel(module="unique")
def evaluate_sea(sea: SeaFieldWp, points: wp.array(dtype=wp.vec4), out: wp.array2d(dtype=wp.float32)):
    """out[i] <- (eta, d(eta)/dt, orbital velocity [3]) of env i at points[i] = (north, east, height, t)."""
    i = wp.tid()
    p = points[i]
    out[i, 0] = sea_elevation_wp(sea, i, p[0], p[1], p[3])
    out[i, 1] = sea_elevation_rate_wp(sea, i, p[0], p[1], p[3])
    flow = sea_air_velocity_wp(sea, i, p[0], p[1], p[2], p[3])
    out[i, 2] = flow[0]
    out[i, 3] = flow[1]
    out[i, 4] = flow[2]


def test_the_warp_twins_evaluate_the_same_field():
    init_warp()
    n = 16
    surface = sample_sea(SeaState.from_code(4, direction=0.4), n, generator(7))
    points = torch.rand(n, 4, generator=generator(8)) * torch.tensor([200.0, 200.0, 3.0, 60.0])
    out = torch.zeros(n, 5)
    wp.launch(evaluate_sea, dim=n, inputs=[sea_field_views(surface), wp.from_torch(points, dtype=wp.vec4),
                                           wp.from_torch(out)], device="cpu")
    north, east, height, time = points.unbind(-1)
    expected = torch.cat([surface.elevation(north, east, time)[:, None],
                          surface.elevation_rate(north, east, time)[:, None],
                          surface.air_velocity(north, east, height, time)], -1)
    torch.testing.assert_close(out, expected, rtol=1e-4, atol=2e-4)
    assert expected[:, 0].abs().max() > 0.5  # a real sea state 4 field, not zeros
    with pytest.raises(ValueError, match="contiguous float32"):
        sea_field_views(sample_sea(SeaState.from_code(4), 2, generator(7), dtype=torch.float64))
