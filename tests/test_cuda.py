"""CUDA checks (skipped cleanly without a GPU): the env, turbulence and the speed options on the
device, against the same computations on the CPU or the torch backend. Tolerances are those of the
CPU parity tests (tests/test_warp_parity.py explains them); CUDA contracts multiply-adds
differently, which those margins were chosen to absorb."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from falcon_rl import Simulator
from falcon_rl.envs import make_env
from falcon_rl.physics._warp import init_warp, warp_available
from falcon_rl.physics.wind import TurbulenceConfig


def _cuda_ready() -> bool:
    if not (warp_available() and torch.cuda.is_available()):
        return False
    return init_warp().get_cuda_device_count() > 0


pytestmark = [pytest.mark.gpu, pytest.mark.skipif(not _cuda_ready(), reason="needs CUDA (torch and warp)")]


@pytest.mark.parametrize("backend", ["torch", "warp"])
@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_env_specs_and_rollout_on_cuda(task: str, backend: str) -> None:
    env = make_env(task, "volantex_ranger", num_envs=256, backend=backend, device="cuda", seed=1)
    check_env_specs(env, break_when_any_done="both")
    rollout = env.rollout(200, break_when_any_done=False)
    assert rollout.device.type == "cuda"
    assert torch.isfinite(rollout["next", "observation"]).all()


@pytest.mark.parametrize("severity", ["light", "severe"])
def test_turbulence_parity_on_cuda(severity: str) -> None:
    n = 256
    config = TurbulenceConfig(severity=severity, external_noise=True)
    sims = [Simulator("navion", num_envs=n, backend=b, device="cuda", turbulence=config)
            for b in ("torch", "warp")]
    for sim in sims:
        sim.reset({"height": torch.linspace(5.0, 900.0, n, device="cuda")})
    gen = torch.Generator(device="cuda").manual_seed(0)
    command = sims[0].state["command"]
    for _ in range(100):
        noise = torch.randn(n, 6, generator=gen, device="cuda")
        for sim in sims:
            sim.turbulence.noise.copy_(noise)
            sim.step(command)
    a, b = (s.state for s in sims)
    for key, tol in (("gust_velocity_body", 2e-5), ("gust_rate_body", 2e-5), ("velocity_body", 1e-4),
                     ("position_ned", 1e-3)):
        scale = a[key].abs().max().item()
        assert (a[key] - b[key]).abs().max().item() <= tol * max(scale, 1.0), key


def test_compiled_torch_step_on_cuda_matches_eager() -> None:
    sims = [Simulator("navion", num_envs=1024, backend="torch", device="cuda", compile=c)
            for c in (False, True)]
    command = sims[0].command.clone()
    for _ in range(100):
        for sim in sims:
            sim.step(command)
    eager, compiled = (s.x for s in sims)
    assert torch.allclose(compiled[:, :3], eager[:, :3], atol=1e-3)
    assert torch.allclose(compiled[:, 3:], eager[:, 3:], atol=1e-4)
