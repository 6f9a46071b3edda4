"""CUDA checks (skipped cleanly without a GPU): the env and torch.compile on the device. The
turbulence and trajectory parity tests run on CUDA too, in their own files. Tolerances are those of
the CPU parity tests (tests/test_warp_parity.py explains them); CUDA contracts multiply-adds
differently, which those margins were chosen to absorb."""

from __future__ import annotations

import pytest
import torch
from torchrl.envs.utils import check_env_specs

from falcon_rl import Simulator
from falcon_rl.envs import make_env
from falcon_rl.physics._warp import warp_cuda_available

pytestmark = [pytest.mark.gpu,
              pytest.mark.skipif(not warp_cuda_available(), reason="needs CUDA (torch and warp)")]


@pytest.mark.parametrize("backend", ["torch", "warp"])
@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_env_specs_and_rollout_on_cuda(task: str, backend: str) -> None:
    env = make_env(task, "volantex_ranger", num_envs=256, backend=backend, device="cuda", seed=1)
    check_env_specs(env, break_when_any_done="both")
    rollout = env.rollout(200, break_when_any_done=False)
    assert rollout.device.type == "cuda"
    assert torch.isfinite(rollout["next", "observation"]).all()


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
