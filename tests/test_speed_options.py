"""Options that only change how fast a step runs must not change what it computes: the warp CPU
batch split over threads (bit-identical: each env's arithmetic is the same, only the thread that
runs it changes) and the torch step through ``torch.compile`` (same float32 arithmetic fused by
Inductor, which may reorder it: compared at the warp-parity tolerances)."""

from __future__ import annotations

import pytest
import torch

from falcon_rl import Simulator
from falcon_rl.cli import main
from falcon_rl.physics._warp import warp_available
from falcon_rl.physics.warp_backend import (
    CHUNKS_PER_THREAD,
    MIN_ENVS_PER_THREAD,
    available_cores,
    cpu_slices,
    cpu_thread_count,
)

needs_warp = pytest.mark.skipif(not warp_available(), reason="warp-lang not installed")


def test_cpu_slices_cover_the_batch_once():
    for n, threads in [(1, None), (7, 3), (1000, 2), (4097, 4), (3, 8), (2 * MIN_ENVS_PER_THREAD, None)]:
        slices = cpu_slices(n, threads)
        assert sum(count for _, count in slices) == n
        assert [offset for offset, _ in slices] == [sum(c for _, c in slices[:k]) for k in range(len(slices))]
        assert all(count >= 1 for _, count in slices)
    assert len(cpu_slices(MIN_ENVS_PER_THREAD - 1, None)) == 1  # small batches stay on one thread
    assert len(cpu_slices(3, 8)) == 3  # at most one chunk per env
    assert len(cpu_slices(4096, 2)) == 2 * CHUNKS_PER_THREAD  # threads take chunks from a queue


def test_sub_steps_count_as_work_when_the_batch_is_split():
    """A launch of 5 physics sub-steps per env (an env step) is split at a fifth of the envs."""
    small = 2 * MIN_ENVS_PER_THREAD // 5 + 1
    assert cpu_thread_count(small, None) == 1
    assert cpu_thread_count(small, None, substeps=5) == min(available_cores(), 2)
    assert cpu_slices(small, 2, substeps=5) == cpu_slices(small, 2)  # explicit threads win


def _perturbed(sim: Simulator) -> None:
    gen = torch.Generator().manual_seed(3)
    sim.x[:, 2] -= 20.0 * torch.rand(sim.num_envs, generator=gen)  # different heights
    sim.x[:, 10:13] += 0.2 * torch.randn(sim.num_envs, 3, generator=gen)  # and body rates


@needs_warp
@pytest.mark.parametrize("turbulence", [None, "moderate"])
def test_warp_threaded_slices_are_bit_identical(turbulence):
    runs = []
    for threads in (1, 3):
        sim = Simulator("volantex_ranger", num_envs=50, backend="warp", turbulence=turbulence, seed=4,
                        warp_cpu_threads=threads)
        assert sim.engine.threads == threads
        assert len(sim.engine.slices) == (1 if threads == 1 else threads * CHUNKS_PER_THREAD)
        _perturbed(sim)
        command = torch.linspace(-0.5, 0.5, 50).unsqueeze(-1).expand(50, 4).contiguous()
        for _ in range(30):
            sim.step(command)
        runs.append((sim.x.clone(), sim.state))
    (x1, state1), (x3, state3) = runs
    assert torch.isfinite(x1).all()
    assert torch.equal(x1, x3)
    for key in sorted(state1.keys()):  # the evaluation kernel is sliced the same way
        assert torch.equal(state1[key], state3[key]), key


def test_speed_option_errors():
    with pytest.raises(ValueError, match="warp_cpu_threads"):
        Simulator("navion", backend="warp", warp_cpu_threads=0)
    with pytest.raises(ValueError, match="compile=True applies to the torch backend"):
        Simulator("navion", backend="warp", compile=True)
    assert main(["bench", "--json", "--warp-threads", "0"]) == 2


@pytest.mark.slow
def test_compiled_torch_step_matches_eager():
    sims = [Simulator("navion", num_envs=16, backend="torch", compile=c) for c in (False, True)]
    for sim in sims:
        _perturbed(sim)
    command = torch.linspace(-0.3, 0.3, 16).unsqueeze(-1).expand(16, 4).contiguous()
    for _ in range(100):
        for sim in sims:
            sim.step(command)
    eager, compiled = (s.x for s in sims)
    assert torch.allclose(compiled[:, :3], eager[:, :3], atol=1e-3)  # m, 1 s
    assert torch.allclose(compiled[:, 3:], eager[:, 3:], atol=1e-4)
