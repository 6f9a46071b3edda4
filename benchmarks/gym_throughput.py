"""Gymnasium env-steps/s against the physics' own cost: one aircraft (``CoreAircraftEnv``, raw and
through ``gymnasium.make``) and one batch of N (``FalconVectorEnv``, ``FalconSB3VecEnv``), each on its
fast path (the env's tensor core) and on TorchRL's path, against ``Simulator.step(cmd, substeps=5)``
alone (the floor: 5 physics steps of 10 ms per 20 Hz env step) and JSBSim's c172p stepped from Python
at the same control rate, all in one run.

    python benchmarks/gym_throughput.py --envs 1024 --repeats 15 [--json out.json]

Method: every case is built and warmed up, and its block size is set so that one block takes about
``--seconds``; then ``--repeats`` rounds time one block of every case in turn, so that load drifting on
a shared machine spreads over all cases. The env cases step uniform random actions in [-1, 1] (one
fixed stream) and reset the finished episodes as a Gymnasium user does (the single env by ``reset()``,
the vector envs by their SAME_STEP autoreset), so resets and their infos are in the figures. The
physics case steps the trim command, the env-core case ``FixedWingEnv.step_tensors`` (no resets,
no host arrays). JSBSim runs ``FGFDMExec.run()`` once per 10 ms physics step (``falcon_rl.evaluation.bench``'s
baseline) and counts ``decimation`` runs as one env step. Reported per case: env-steps/s median and
min-max over the rounds, and its ratios to the physics floor at the same N, to JSBSim and to the
TorchRL path of the same env, each the median over the rounds of the ratio within a round (on a
loaded machine the paired ratios are steadier than the rates).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import gymnasium as gym
import numpy as np
import torch

from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.envs import make_env
from falcon_rl.envs.gym import GYM_IDS, CoreAircraftEnv, register_gym_envs
from falcon_rl.envs.gym.vector import FalconVectorEnv
from falcon_rl.evaluation.bench import BenchConfig, time_jsbsim

#: A block runs ``steps`` env steps.
Block = Callable[[int], None]


@dataclass
class Case:
    """One timed configuration: label, env count, its group (which floor and TorchRL path it is
    compared with), block size and per-round env-steps/s."""

    label: str
    num_envs: int
    kind: str  # "physics", "core", "fast", "torchrl", "jsbsim"
    steps: int = 0
    rates: list[float] = field(default_factory=list)

    @property
    def median(self) -> float:
        return statistics.median(self.rates)


def random_actions(space: gym.spaces.Box, count: int = 256) -> list[np.ndarray]:
    """``count`` float32 samples of ``space`` from one fixed stream (cycled by the blocks)."""
    space.seed(0)
    return [space.sample() for _ in range(count)]


def single_block(env: gym.Env) -> Block:
    """Steps of one Gymnasium env, reset when the episode ends."""
    actions = random_actions(env.action_space)
    env.reset(seed=0)

    def block(steps: int) -> None:
        for index in range(steps):
            _, _, terminated, truncated, _ = env.step(actions[index % len(actions)])
            if terminated or truncated:
                env.reset()

    return block


def vector_block(step: Callable[[np.ndarray], object], space: gym.spaces.Box) -> Block:
    """Steps of a vector env (it autoresets) through ``step``."""
    actions = random_actions(space, 64)

    def block(steps: int) -> None:
        for index in range(steps):
            step(actions[index % len(actions)])

    return block


def physics_block(task: str, num_envs: int, args: argparse.Namespace) -> tuple[Block, Block]:
    """(``Simulator.step(trim command, substeps=decimation)``, ``step_tensors(zero action)``) of the
    env the Gymnasium cases build (the same simulator and task)."""
    env = make_env(task, args.airframe, num_envs=num_envs, backend=args.backend, device=args.device, seed=0,
                   **env_options(args))
    env.reset()
    command = env.task.command(env.trim_action().expand(num_envs, -1)).clone()
    substeps, zero = env.config.decimation, torch.zeros(num_envs, env.task.action_dim)

    def physics(steps: int) -> None:
        for _ in range(steps):
            env.sim.step(command, substeps=substeps)

    def core(steps: int) -> None:
        for _ in range(steps):
            env.step_tensors(zero)

    return physics, core


def sb3_block(num_envs: int, options: dict) -> tuple[Block, gym.spaces.Box]:
    """Steps of ``FalconSB3VecEnv`` (no info keys) as SB3's rollout drives it."""
    from falcon_rl.envs.gym.sb3 import FalconSB3VecEnv

    venv = FalconSB3VecEnv.make(num_envs=num_envs, seed=0, **options)
    venv.reset()

    def step(actions: np.ndarray) -> None:
        venv.step_async(actions)
        venv.step_wait()

    return vector_block(step, venv.venv.action_space), venv.venv.action_space


def calibrate(block: Block, seconds: float) -> int:
    """Warm ``block`` up and return the steps that take about ``seconds``."""
    block(3)
    steps, elapsed = 4, 0.0
    while elapsed < 0.05:
        start = time.perf_counter()
        block(steps)
        elapsed = time.perf_counter() - start
        if elapsed < 0.05:
            steps *= 4
    return max(1, round(steps * seconds / elapsed))


def env_options(args: argparse.Namespace) -> dict:
    """The env options every case is built with (the decimation when one is given)."""
    return {} if args.decimation is None else {"decimation": args.decimation}


def build(args: argparse.Namespace, decimation: int) -> list[tuple[Case, Block]]:
    """Every case with its block (built, warmed up and calibrated)."""
    task, n = args.task, args.envs
    options = {"task": task, "airframe": args.airframe, "backend": args.backend, "device": args.device,
               **env_options(args)}
    physics1, core1 = physics_block(task, 1, args)
    physics_n, core_n = physics_block(task, n, args)
    fast_vec = FalconVectorEnv(n, seed=0, **options)
    slow_vec = FalconVectorEnv(n, seed=0, fast_path=False, **options)
    for envs in (fast_vec, slow_vec):
        envs.reset(seed=0)
    sb3, _ = sb3_block(n, options)
    register_gym_envs()
    made = gym.make(GYM_IDS[task], **{k: v for k, v in options.items() if k != "task"})
    blocks = [
        (Case(f"physics: Simulator.step(substeps={decimation})", 1, "physics"), physics1),
        (Case("env core: step_tensors", 1, "core"), core1),
        (Case("CoreAircraftEnv fast path", 1, "fast"), single_block(CoreAircraftEnv(seed=0, **options))),
        (Case("gymnasium.make (wrappers) fast path", 1, "fast"), single_block(made)),
        (Case("CoreAircraftEnv TorchRL path", 1, "torchrl"),
         single_block(CoreAircraftEnv(seed=0, fast_path=False, **options))),
        (Case(f"physics: Simulator.step(substeps={decimation})", n, "physics"), physics_n),
        (Case("env core: step_tensors", n, "core"), core_n),
        (Case("FalconVectorEnv fast path", n, "fast"), vector_block(fast_vec.step, fast_vec.action_space)),
        (Case("FalconSB3VecEnv fast path", n, "fast"), sb3),
        (Case("FalconVectorEnv TorchRL path", n, "torchrl"),
         vector_block(slow_vec.step, slow_vec.action_space)),
    ]
    cases = []
    for case, block in blocks:
        print(f"warming up: {case.label} (N={case.num_envs})", flush=True)
        case.steps = calibrate(block, args.seconds)
        cases.append((case, block))
    return cases


def time_jsbsim_round(args: argparse.Namespace, decimation: int) -> float:
    """JSBSim c172p env-steps/s at ``decimation`` runs per env step (one timed block)."""
    runs = max(10, round(args.jsbsim_runs / 10))  # time_jsbsim times 10 x steps runs
    bench = time_jsbsim(BenchConfig(backends=[], env_counts=[], steps=runs, trials=1, warmup=100, dt=0.01))
    return bench.env_steps_per_s / decimation


def time_round(cases: list[tuple[Case, Block]], jsbsim: Case, args: argparse.Namespace,
               decimation: int) -> None:
    """One timed round: JSBSim's block, then one block of every case, each rate appended to its case."""
    jsbsim.rates.append(time_jsbsim_round(args, decimation))
    for case, block in cases:
        start = time.perf_counter()
        block(case.steps)
        case.rates.append(case.num_envs * case.steps / (time.perf_counter() - start))


def paired(case: Case, reference: Case | None) -> str:
    """Median over the rounds of ``case``'s rate over ``reference``'s in the same round ("-" without a
    reference): load drifting between rounds cancels out."""
    if reference is None:
        return "-"
    return f"{statistics.median(a / b for a, b in zip(case.rates, reference.rates, strict=True)):.2f}"


def report(cases: list[Case], jsbsim: Case) -> str:
    """The table: median env-steps/s, min-max, and ratios (paired by round) to the physics floor at the
    same N, to JSBSim, and to the TorchRL path of the same env."""
    floor = {c.num_envs: c for c in cases if c.kind == "physics"}
    torchrl = {c.num_envs: c for c in cases if c.kind == "torchrl"}
    width = max(len(case.label) for case in [*cases, jsbsim])
    lines = [f"{'case':<{width}} {'N':>5} {'env-steps/s':>12} {'min-max':>23} {'/floor':>7} {'x JSBSim':>9} "
             f"{'x TorchRL':>9}"]
    for case in [*cases, jsbsim]:
        low, high = min(case.rates), max(case.rates)
        faster = torchrl.get(case.num_envs) if case.kind in ("fast", "core") else None
        lines.append(f"{case.label:<{width}} {case.num_envs:>5} {case.median:>12,.0f} {low:>11,.0f}-"
                     f"{high:<11,.0f} {paired(case, floor.get(case.num_envs)):>7} {paired(case, jsbsim):>9}"
                     f" {paired(case, faster):>9}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--envs", type=int, default=1024, help="env count of the vector cases")
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--repeats", type=int, default=15, help="timed rounds")
    parser.add_argument("--seconds", type=float, default=0.25, help="approximate seconds per timed block")
    parser.add_argument("--jsbsim-runs", type=int, default=10000, help="FGFDMExec.run() calls per block")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    parser.add_argument("--decimation", type=int, default=None,
                        help="physics steps per env step (default: the task's, 5 = 20 Hz control)")
    parser.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    decimation = make_env(args.task, args.airframe, backend=args.backend, seed=0,
                          **env_options(args)).config.decimation
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.1f}, torch {torch.__version__} ({args.threads} thread(s)); {args.task} on "
          f"{args.airframe}, {args.backend} on {args.device}, {100 / decimation:g} Hz control ({decimation} "
          f"physics steps of 10 ms)")
    cases = build(args, decimation)
    jsbsim = Case(f"JSBSim c172p ({decimation} FGFDMExec.run() per step)", 1, "jsbsim")
    for round_index in range(args.repeats):
        print(f"round {round_index + 1}/{args.repeats}", flush=True)
        time_round(cases, jsbsim, args, decimation)
    table = report([case for case, _ in cases], jsbsim)
    print(table)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"args": vars(args), "load_average": os.getloadavg(),
                       "cases": [asdict(case) for case, _ in cases] + [asdict(jsbsim)]}, handle, indent=2)


if __name__ == "__main__":
    main()
