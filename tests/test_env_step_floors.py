"""The env-step benchmark's TorchRL floors (``benchmarks/env_step.py``): what each one's rollout keeps;
its one-launch step and partial reset cases; the CUDA precompile's modules
(``benchmarks/precompile_cuda.py``).

The floor that hands out its preallocated tensors is TorchRL's own cost, but a rollout of it records
the last step's values at every step; the floor with new outputs keeps every step, as a usable env must.
"""

from __future__ import annotations

from dataclasses import asdict

import pytest
import torch
from tensordict import TensorDict


def _counting_rollout(bench, new_outputs: bool) -> torch.Tensor:
    """Observations [T] of a 4-step rollout of a floor (``benchmarks/env_step.py``'s) whose observation
    counts the steps."""
    env = bench.TrivialEnv(1, 3, 2, "cpu", new_outputs=new_outputs)
    step = env._step

    def counting(td: TensorDict) -> TensorDict:
        env._out["observation"] += 1.0
        return step(td)

    env._step = counting
    return env.rollout(4)["next", "observation"][0, :, 0]


def test_the_preallocated_floor_aliases_its_steps_and_the_new_outputs_floor_keeps_them(benchmark_script):
    bench = benchmark_script("env_step")
    assert _counting_rollout(bench, new_outputs=False).tolist() == [4.0, 4.0, 4.0, 4.0]
    assert _counting_rollout(bench, new_outputs=True).tolist() == [1.0, 2.0, 3.0, 4.0]


def test_ratios_to_both_floors_are_in_the_table(benchmark_script):
    bench = benchmark_script("env_step")
    cases = {label: bench.EnvStepCase("env", "warp", "cpu", 1, 10, 1, label=label)
             for label in ("physics", "torchrl floor", "torchrl floor (new outputs)", "env lean")}
    for case, seconds in zip(cases.values(), (1e-5, 4e-5, 5e-5, 7e-5), strict=True):
        case.finish([seconds * 10])
    bench._set_ratios(cases)
    lean = cases["env lean"]
    assert abs(lean.ratio_to_torchrl - 7 / 4) < 1e-12 and abs(lean.ratio_to_torchrl_new - 7 / 5) < 1e-12
    table = bench.format_table({"cases": [asdict(c) for c in cases.values()]})
    row = "| env lean | 1 | 0.070 | 0.070-0.070 | 14,286 | 7.00 (7.00) | 1.75 (1.75) | 1.40 (1.40) |"
    assert row in table


def test_the_one_launch_step_case_steps_the_env_and_the_graph_case_needs_cuda(benchmark_script):
    bench = benchmark_script("env_step")
    from falcon_rl import make_env

    env = make_env("altitude", "volantex_ranger", num_envs=2, backend="warp", seed=0, lean=True)
    step = bench.fused_stepper(env)
    step()
    step()
    assert env.episode_step.tolist() == [2, 2]  # two env steps, no TorchRL, no reset
    with pytest.raises(ValueError, match="a CUDA graph needs a CUDA device"):
        bench.fused_stepper(env, graph=True)  # a CPU env
    unfused = make_env("altitude", "volantex_ranger", num_envs=2, backend="torch", seed=0, lean=True)
    with pytest.raises(ValueError, match="no one-launch env step"):
        bench.fused_stepper(unfused)


def test_the_partial_reset_case_resets_one_env_per_call(benchmark_script):
    bench = benchmark_script("env_step")
    from falcon_rl import make_env

    env = make_env("altitude", "volantex_ranger", num_envs=3, backend="warp", seed=0, lean=True)
    reset = bench.partial_resetter(env)
    for _ in range(2):
        env.step_tensors(torch.zeros(3, env.task.action_dim))
    reset()
    assert env.episode_step.tolist() == [2, 0, 2]  # env 1 reset, the others untouched
    reset()
    assert env.episode_step.tolist() == [2, 0, 0]


def test_the_cuda_precompile_finds_the_modules_an_env_launches(benchmark_script):
    names = [m.name for m in benchmark_script("precompile_cuda").task_modules("altitude", "volantex_ranger")]
    assert names[0] == "falcon_rl.physics.warp_kernels" and "falcon_rl.envs.tasks.altitude.kernels" in names
    assert len(names) == 3 and any("env_step" in name for name in names)
