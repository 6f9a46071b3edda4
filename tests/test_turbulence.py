"""Dryden turbulence and steady wind: statistics, spectra, channel wiring, effect on the dynamics and
torch/warp parity.

Statistics run the filter on its own (``dryden_step``) at a frozen height and airspeed, many envs in
parallel started from the stationary distribution of the normalised states (so no burn-in is needed
for u, v, w, p; z_q, z_r settle within 1 s). The step cost is Python overhead, not batch size, so the
tests use many envs and few steps. Tolerances:
- standard deviations within 5% of the specification (16,384 envs; sampling error below 1%);
- Welch spectra (one-sided, 1024 envs x 1536 steps of 0.25 s, 256-point segments) within 12% of the
  analytic Dryden shapes on every frequency bin of the band where the discrete realisation is exact
  up to aliasing (u, v, w: 0.03-0.5 Hz; p, q, r: 0.03-0.25 Hz, fs = 4 Hz; scatter about 3% per bin);
- wrong-channel correlations below 0.03 at every lag up to 5 s (independent streams give ~0.005).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy import integrate, signal

from falcon_rl import Simulator
from falcon_rl.physics._warp import init_warp, warp_available, warp_cuda_available
from falcon_rl.physics.dynamics import AirInputs, evaluate
from falcon_rl.physics.rotations import ned_to_body
from falcon_rl.physics.wind import (
    KT,
    TurbulenceConfig,
    critically_damped_step,
    dryden_scales,
    dryden_step,
    roll_gust_sigma,
    severity_w20,
    w20_for_sigma_u,
)

SPAN = 10.18  # m (the Navion's), any span works


def _run_filter(num_envs: int, steps: int, height: float, airspeed: float, w20: float, dt: float,
                seed: int = 0, burn_in: int = 0) -> np.ndarray:
    """Gust history [steps, N, 6] (u, v, w, p, q, r) at frozen height and airspeed."""
    g = torch.Generator().manual_seed(seed)
    n = num_envs
    filt = torch.zeros(n, 8, dtype=torch.float64)
    filt[:, :6] = torch.randn(n, 6, generator=g, dtype=torch.float64)
    gust = torch.zeros(n, 3, dtype=torch.float64)
    args = [torch.full((n,), v, dtype=torch.float64) for v in (w20, height, airspeed, SPAN)]
    out = np.empty((steps, n, 6))
    for k in range(burn_in + steps):
        noise = torch.randn(n, 6, generator=g, dtype=torch.float64)
        filt, gust, rate = dryden_step(filt, noise, gust, *args, dt)
        if k >= burn_in:
            out[k - burn_in] = torch.cat([gust, rate], -1).numpy()
    return out


def _spectra(height: float, airspeed: float, w20: float):
    """Analytic one-sided Dryden PSDs in f (Hz), channels u, v, w, p, q, r (MIL-F-8785C)."""
    h = torch.tensor([height], dtype=torch.float64)
    length, sigma = (t[0].numpy() for t in dryden_scales(h, torch.tensor([w20], dtype=torch.float64)))
    lu, lv, lw = length
    su, sv, sw = sigma
    b = SPAN

    def dryden2(om, s, L):
        return s * s * L / math.pi * (1 + 3 * (L * om) ** 2) / (1 + (L * om) ** 2) ** 2

    phi = [
        lambda om: su * su * 2 * lu / math.pi / (1 + (lu * om) ** 2),
        lambda om: dryden2(om, sv, lv),
        lambda om: dryden2(om, sw, lw),
        lambda om: (sw * sw / lw * 0.8 * (math.pi * lw / (4 * b)) ** (1 / 3)
                    / (1 + (4 * b * om / math.pi) ** 2)),
        lambda om: om**2 / (1 + (4 * b * om / math.pi) ** 2) * dryden2(om, sw, lw),
        lambda om: om**2 / (1 + (3 * b * om / math.pi) ** 2) * dryden2(om, sv, lv),
    ]
    return [lambda f, p=p: p(2 * math.pi * f / airspeed) * 2 * math.pi / airspeed for p in phi]


def spec_sigmas(height: float, airspeed: float, w20: float) -> np.ndarray:
    """Specified standard deviations (u, v, w, p, q, r): closed forms, q and r by integrating."""
    h = torch.tensor([height], dtype=torch.float64)
    w = torch.tensor([w20], dtype=torch.float64)
    length, sigma = dryden_scales(h, w)
    sigma_p = roll_gust_sigma(sigma[:, 2], length[:, 2], torch.tensor([SPAN], dtype=torch.float64))
    psd = _spectra(height, airspeed, w20)
    var_q = integrate.quad(psd[4], 0, np.inf, limit=400)[0]
    var_r = integrate.quad(psd[5], 0, np.inf, limit=400)[0]
    return np.array([*sigma[0].tolist(), float(sigma_p[0]), math.sqrt(var_q), math.sqrt(var_r)])


# ------------------------------------------------------------------------------ specification
def test_scale_lengths_and_intensities_follow_mil_f_8785c() -> None:
    w20 = torch.tensor([severity_w20("light")] * 5, dtype=torch.float64)
    h = torch.tensor([1.0, 50.0, 1000 * 0.3048, 1500 * 0.3048, 5000.0], dtype=torch.float64)
    length, sigma = dryden_scales(h, w20)
    assert length[0].tolist() == pytest.approx([10 * 0.3048 / (0.177 + 0.00823) ** 1.2] * 2 + [3.048])
    assert length[1, 0] == pytest.approx(202.3, abs=0.1) and length[1, 2] == pytest.approx(50.0)
    assert (sigma[1, 0] / sigma[1, 2]).item() == pytest.approx(1.59, abs=0.01)
    assert sigma[1, 2].item() == pytest.approx(0.1 * 15 * KT)
    assert length[2].tolist() == pytest.approx([304.8] * 3, rel=1e-6)  # isotropic at 1000 ft
    assert length[3].tolist() == pytest.approx([(1000 + 375) * 0.3048] * 3, rel=1e-6)  # blend
    assert length[4].tolist() == pytest.approx([1750 * 0.3048] * 3)
    light_at_5km = 4.6 + (5000 / 0.3048 - 15000) / 10000 * (2.7 - 4.6)  # table, ft/s
    assert sigma[4].tolist() == pytest.approx([light_at_5km * 0.3048] * 3, rel=1e-6)
    assert [severity_w20(s) / KT for s in ("very_light", "light", "moderate", "severe")] == \
        pytest.approx([2, 15, 30, 45])
    assert TurbulenceConfig(sigma_u=1.5, reference_height=60.0).resolve_w20() == pytest.approx(
        w20_for_sigma_u(1.5, 60.0))
    assert dryden_scales(torch.tensor([60.0]), torch.tensor([w20_for_sigma_u(1.5, 60.0)]))[1][0, 0] == \
        pytest.approx(1.5, rel=1e-5)


@pytest.mark.parametrize("s", [1e-5, 3e-4, 0.01, 0.3, 2.0])
def test_closed_form_matches_van_loan(s: float) -> None:
    """Phi and Q_d of the normalised filter equal expm / Van Loan of A = [[0, 1], [-a^2, -2a]]."""
    from scipy.linalg import expm

    a = 0.7
    dt = s / a
    A = np.array([[0.0, 1.0], [-a * a, -2 * a]])
    van_loan = expm(np.block([[-A, np.diag([0.0, 1.0])], [np.zeros((2, 2)), A.T]]) * dt)
    phi = van_loan[2:, 2:].T
    q_d = phi @ van_loan[:2, 2:]
    d = np.diag([2 * a**1.5, 2 * a**0.5])
    for dtype, tol in ((torch.float64, 1e-10), (torch.float32, 1e-6)):
        phi_n, chol = critically_damped_step(torch.tensor(s, dtype=dtype))
        np.testing.assert_allclose(phi_n.double().numpy(), d @ phi @ np.linalg.inv(d), atol=tol)
        q_n = (chol @ chol.T).double().numpy()
        np.testing.assert_allclose(q_n, d @ q_d @ d.T, atol=tol * np.abs(d @ q_d @ d.T).max())


# ------------------------------------------------------------------------------ statistics
@pytest.mark.parametrize(("height", "severity"), [(30.0, "light"), (150.0, "severe"), (1000.0, "moderate")])
def test_stationary_standard_deviations_within_5_percent(height: float, severity: str) -> None:
    airspeed, w20 = 50.0, severity_w20(severity)
    gusts = _run_filter(16384, 60, height, airspeed, w20, dt=0.02, burn_in=50)
    measured = gusts.reshape(-1, 6).std(0)
    expected = spec_sigmas(height, airspeed, w20)
    np.testing.assert_allclose(measured, expected, rtol=0.05)


def test_spectra_match_dryden_shapes() -> None:
    height, airspeed, w20, dt = 50.0, 25.0, severity_w20("moderate"), 0.25
    gusts = _run_filter(1024, 1536, height, airspeed, w20, dt=dt, seed=1, burn_in=8)
    f, pxx = signal.welch(gusts, fs=1 / dt, nperseg=256, axis=0)
    pxx = pxx.mean(axis=1)  # [F, 6] averaged over envs
    for ch, analytic in enumerate(_spectra(height, airspeed, w20)):
        band = (f >= 0.03) & (f <= (0.5 if ch < 3 else 0.25))
        ratio = pxx[band, ch] / analytic(f[band])
        assert np.abs(ratio - 1).max() < 0.12, (ch, ratio.min(), ratio.max())


def _xcorr(a: np.ndarray, b: np.ndarray, max_lag: int) -> np.ndarray:
    """Normalised cross-correlation of [T, N] series at lags -max_lag..max_lag (pooled over N)."""
    a = (a - a.mean()) / a.std()
    b = (b - b.mean()) / b.std()
    t = a.shape[0]
    return np.array([(a[max(0, -k):t - max(0, k)] * b[max(0, k):t - max(0, -k)]).mean()
                     for k in range(-max_lag, max_lag + 1, 5)])


def test_angular_gusts_are_wired_to_the_right_channels() -> None:
    gusts = _run_filter(4096, 400, 50.0, 25.0, severity_w20("moderate"), dt=0.05, seed=2, burn_in=40)
    u, v, w, p, q, r = (gusts[..., k] for k in range(6))
    lag = 100  # 5 s
    assert _xcorr(q, w, 0)[0] < -0.2  # q_g = -(pi/4b)(w_g - z_q): negatively correlated with w_g
    assert _xcorr(r, v, 0)[0] > 0.2  # r_g = +(pi/3b)(v_g - z_r)
    for a, b in ((q, v), (q, u), (q, p), (r, w), (r, u), (r, p), (p, w), (p, v)):
        assert np.abs(_xcorr(a, b, lag)).max() < 0.03


# ------------------------------------------------------------------------------ effect on the dynamics
def test_gusts_change_alpha_and_forces(navion) -> None:
    sim = Simulator(navion, num_envs=2)
    x = sim.x
    gust = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 3.0]])
    calm, gusty = evaluate(x, sim.params), evaluate(x, sim.params, AirInputs(None, gust, None))
    airspeed = calm.airspeed[0]
    assert (calm.alpha[1] - gusty.alpha[1]).item() == pytest.approx(
        math.atan2(3.0, airspeed) * math.cos(calm.alpha[1]) ** 2, rel=0.05)  # updraft: alpha drops ~w/V
    assert (gusty.aero_force_body[1, 2] - calm.aero_force_body[1, 2]).item() > 0.05 * navion.mass * 9.8
    rate = evaluate(x, sim.params, AirInputs(None, None, torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.2, 0.0]])))
    assert (rate.moment_body[1, 1] - calm.moment_body[1, 1]).abs() > 10.0  # pitch damping sees q - q_g
    # In flight: the same trimmed start, with and without turbulence, separates in alpha and rates.
    calm_sim = Simulator(navion, num_envs=16)
    turb_sim = Simulator(navion, num_envs=16, turbulence="moderate", seed=3)
    cmd = calm_sim.state["command"]
    for _ in range(100):
        calm_sim.step(cmd)
        turb_sim.step(cmd)
    a, b = calm_sim.state, turb_sim.state
    assert (a["alpha"] - b["alpha"]).abs().mean() > math.radians(0.3)
    assert (a["angular_rate_body"] - b["angular_rate_body"]).abs().mean() > 0.01
    assert (b["gust_velocity_body"].abs() > 0).all() and (b["gust_rate_body"].abs() > 0).all()


def test_steady_wind_acts_on_alpha_beta_and_ground_track(navion) -> None:
    wind = torch.tensor([0.0, 6.0, 0.0])  # air moving east
    sim = Simulator(navion, num_envs=1, wind=wind)
    base = Simulator(navion, num_envs=1)
    x0 = base.x.clone()
    v_air = x0[:, 7:10]
    s0 = sim.state
    assert s0["beta"].item() == pytest.approx(math.asin(-6.0 / s0["airspeed"].item()), rel=1e-4)
    # Start trimmed relative to the air (inertial velocity = air-relative trim + wind) and fly 3 s.
    start = x0.clone()
    start[:, 7:10] = v_air + ned_to_body(x0[:, 3:7], wind[None])
    sim.reset(start)
    cmd = sim.state["command"]
    for _ in range(300):
        sim.step(cmd)
        base.step(cmd)
    s, b = sim.state, base.state
    assert s["alpha"].item() == pytest.approx(b["alpha"].item(), abs=1e-4)
    assert abs(s["beta"].item()) < 1e-4
    assert (s["position_ned"] - b["position_ned"])[0].tolist() == pytest.approx([0.0, 18.0, 0.0], abs=0.02)
    # A headwind on the untrimmed start raises the airspeed and alpha responds (not only a readout).
    head = Simulator(navion, num_envs=1, wind=[-10.0, 0.0, 0.0])
    assert head.state["airspeed"].item() == pytest.approx(base.reset()["airspeed"].item() + 10.0, rel=1e-3)
    for _ in range(100):
        head.step(cmd)
    assert head.state["velocity_body"][0, 2] < b["velocity_body"][0, 2] - 0.5 or \
        head.state["angular_rate_body"][0, 1].abs() > 0.05


def test_masked_reset_zeroes_only_reset_rows(navion) -> None:
    sim = Simulator(navion, num_envs=4, turbulence="severe")
    cmd = sim.state["command"]
    for _ in range(20):
        sim.step(cmd)
    before = sim.turbulence.filter.clone()
    mask = torch.tensor([True, False, True, False])
    sim.reset(mask=mask)
    assert (sim.turbulence.filter[mask] == 0).all() and (sim.gust_velocity_body[mask] == 0).all()
    assert torch.equal(sim.turbulence.filter[~mask], before[~mask])
    assert (sim.gust_velocity_body[~mask] != 0).all()


def test_per_env_severity_and_off_by_default(navion) -> None:
    assert Simulator(navion, num_envs=2).turbulence is None
    sim = Simulator(navion, num_envs=3, turbulence="light")
    sim.turbulence.w20[1] = 0.0
    sim.turbulence.w20[2] = severity_w20("severe")
    cmd = sim.state["command"]
    for _ in range(50):
        sim.step(cmd)
    gust = sim.state["gust_velocity_body"]
    assert (gust[1] == 0).all() and (gust[0] != 0).all() and (gust[2] != 0).all()


# ------------------------------------------------------------------------------ warp parity
needs_warp = pytest.mark.skipif(not warp_available(), reason="warp-lang is not installed")


on_cuda = pytest.param("cuda", marks=[pytest.mark.gpu, pytest.mark.skipif(
    not warp_cuda_available(), reason="needs CUDA (torch and warp)")])


@needs_warp
@pytest.mark.parametrize("device", ["cpu", on_cuda])
@pytest.mark.parametrize("severity", ["light", "severe"])
def test_torch_warp_parity_with_the_same_noise(navion, severity: str, device: str) -> None:
    n = 64
    config = TurbulenceConfig(severity=severity, external_noise=True)
    sims = [Simulator(navion, num_envs=n, backend=b, turbulence=config, device=device)
            for b in ("torch", "warp")]
    heights = torch.linspace(5.0, 900.0, n, device=device)  # low altitude, the blend and the table
    for sim in sims:
        sim.reset({"height": heights})
    g = torch.Generator(device=device).manual_seed(0)
    cmd = sims[0].state["command"]
    for _ in range(100):
        noise = torch.randn(n, 6, generator=g, device=device)
        for sim in sims:
            sim.turbulence.noise.copy_(noise)
            sim.step(cmd)
    a, b = (s.state for s in sims)
    for key, tol in (("gust_velocity_body", 2e-5), ("gust_rate_body", 2e-5), ("velocity_body", 1e-4),
                     ("position_ned", 1e-3)):
        scale = a[key].abs().max().item()
        assert (a[key] - b[key]).abs().max().item() <= tol * max(scale, 1.0), key
    assert torch.allclose(sims[0].turbulence.filter, sims[1].turbulence.filter, atol=2e-5)


@needs_warp
def test_warp_scales_match_torch_at_all_altitudes() -> None:
    wp = init_warp()
    from falcon_rl.physics.wind import dryden_scales_wp

    @wp.kernel
    def kernel(h: wp.array(dtype=float), w20: wp.array(dtype=float), out: wp.array2d(dtype=float)):
        i = wp.tid()
        sc = dryden_scales_wp(h[i], w20[i])
        for k in range(3):
            out[i, k] = sc.length[k]
            out[i, 3 + k] = sc.sigma[k]

    h = torch.cat([torch.linspace(0.0, 900.0, 50), torch.linspace(900.0, 30000.0, 50)])
    w20 = torch.linspace(0.0, 30.0, 100)
    out = torch.zeros(100, 6)
    wp.launch(kernel, dim=100, inputs=[wp.from_torch(h), wp.from_torch(w20)], outputs=[wp.from_torch(out)])
    length, sigma = dryden_scales(h, w20)
    torch.testing.assert_close(out, torch.cat([length, sigma], -1), rtol=2e-5, atol=1e-5)


@needs_warp
def test_warp_streams_are_independent_per_env_and_seeded(navion) -> None:
    def run(seed: int) -> torch.Tensor:
        sim = Simulator(navion, num_envs=512, backend="warp", turbulence="moderate", seed=seed)
        cmd = sim.state["command"]
        draws = []
        for _ in range(40):
            sim.step(cmd)
            draws.append(sim.turbulence.noise.clone())
        return torch.stack(draws)  # [T, N, 6]

    a, b = run(5), run(5)
    assert torch.equal(a, b)
    flat = a.reshape(-1, 6)
    assert flat.mean(0).abs().max() < 0.02 and (flat.std(0) - 1).abs().max() < 0.02
    per_env = a.permute(1, 0, 2).reshape(512, -1)  # rows: envs
    corr = torch.corrcoef(per_env[:64])
    assert (corr - torch.eye(64)).abs().max() < 0.25  # 240 samples each: |r| ~ 0.065 +- 0.05
    assert not torch.equal(run(6), a)
