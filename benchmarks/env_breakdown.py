"""Where one TorchRL env step spends its time: the physics steps, ``Simulator.state``, the task's
observation/reward/termination, the output TensorDict, and TorchRL's own ``step_and_maybe_reset``.

    python benchmarks/env_breakdown.py --envs 1,4096 --backend warp [--device cuda] [--profile]

Each part is timed alone (median of 5 blocks, CUDA synchronised after each block). ``--profile``
adds a torch profiler table of the whole step (top operators by self CPU time, and the number of
host-device synchronisations), which shows whether the step is bound by kernel launches.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import torch

from falcon_rl import make_env
from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.evaluation.bench import env_stepper


def _time(fn: Callable[[], object], device: str, calls: int = 200, blocks: int = 5) -> float:
    """Median seconds per call over ``blocks`` blocks of ``calls`` calls (after a warm-up block)."""
    sync = torch.cuda.synchronize if device == "cuda" else (lambda: None)
    for _ in range(calls // 4):
        fn()
    sync()
    samples = []
    for _ in range(blocks):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        sync()
        samples.append((time.perf_counter() - start) / calls)
    return statistics.median(samples)


def breakdown(task: str, airframe: str, num_envs: int, backend: str, device: str) -> dict[str, float]:
    """Seconds per call of each part of one env step."""
    env = make_env(task, airframe, num_envs=num_envs, backend=backend, device=device, seed=0)
    env_step = env_stepper(env)
    sim, task_obj = env.sim, env.task  # internals on purpose: their parts are what is timed
    state = sim.state
    action = env.action_spec.zero()
    observation = env.observe(state)
    flags = torch.zeros(num_envs, 1, dtype=torch.bool, device=env.device)
    reason = torch.zeros(num_envs, dtype=torch.long, device=env.device)
    reward = torch.zeros(num_envs, 1, device=env.device)
    decimation = env.config.decimation
    parts = {
        "env.step_and_maybe_reset": env_step,
        f"Simulator.step x{decimation}": lambda: sim.step(sim.command, substeps=decimation),
        "Simulator.state": lambda: sim.state,
        "task.step (observe, reward, done)": lambda: task_obj.step(state, action),
        "env._output (TensorDict)": lambda: env._output(observation, state, reason, flags, reward=reward),
    }
    return {name: _time(fn, device) for name, fn in parts.items()}


def profile_step(task: str, airframe: str, num_envs: int, backend: str, device: str) -> str:
    """Torch profiler table of 50 env steps (top 25 operators by self CPU time)."""
    from torch.profiler import ProfilerActivity, profile

    env_step = env_stepper(make_env(task, airframe, num_envs=num_envs, backend=backend, device=device))
    for _ in range(20):
        env_step()
    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if device == "cuda" else [])
    with profile(activities=activities) as prof:
        for _ in range(50):
            env_step()
        if device == "cuda":
            torch.cuda.synchronize()
    return prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=25)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--envs", default="1,4096", help="comma list of env counts")
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    for n in (int(v) for v in args.envs.split(",")):
        print(f"\n{args.task} on {args.airframe}, {n} envs, {args.backend} on {args.device}")
        for name, seconds in breakdown(args.task, args.airframe, n, args.backend, args.device).items():
            print(f"  {name:<36} {seconds * 1e3:9.3f} ms")
        if args.profile:
            print(profile_step(args.task, args.airframe, n, args.backend, args.device))


if __name__ == "__main__":
    main()
