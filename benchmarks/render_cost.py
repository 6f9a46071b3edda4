"""What rendering costs a Gymnasium env, and that an unrendered env pays nothing for it: one aircraft
(``gymnasium.make`` of the attitude task) stepped with no render mode, with ``render_mode="rgb_array"``
(the view observes each step, no frame drawn) and with a frame drawn at every step, against the env's
tensor core stepped directly (``TensorCore.step``, the floor under the Gymnasium wrapper), in one run.

    python benchmarks/render_cost.py --repeats 11 [--json out.json]

Method: as benchmarks/gym_throughput.py: every case is built, warmed up and given a block size of about
``--seconds``; ``--repeats`` rounds time one block of every case in turn; reported per case: steps/s
median and min-max, and its ratio to the unrendered env (median over rounds of the ratio within a
round). "unrendered / core" near 1 is what "an unrendered env is not slower" means: the render hooks
are one ``is None`` test per step.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable

import gymnasium as gym
import numpy as np

import falcon_rl  # noqa: F401 (registers the Gymnasium ids)
from falcon_rl.envs.gym import action_tensor

ACTION = np.array([0.0, 0.2, 0.0, 0.6], np.float32)


def env_block(env: gym.Env, draw: bool) -> Callable[[int], None]:
    """Step ``env`` ``steps`` times (resetting finished episodes), drawing a frame each step if ``draw``."""
    env.reset(seed=0)

    def block(steps: int) -> None:
        for _ in range(steps):
            _, _, terminated, truncated, _ = env.step(ACTION)
            if draw:
                env.render()
            if terminated or truncated:
                env.reset()
    return block


def core_block(env: gym.Env) -> Callable[[int], None]:
    """The env's tensor core stepped directly (no Gymnasium wrapper, no info dict, no render hook)."""
    core = env.unwrapped.core
    core.reset()
    action = action_tensor(ACTION[None], 1, 4)

    def block(steps: int) -> None:
        for _ in range(steps):
            step = core.step(action)
            if step.done[0]:
                core.reset()
    return block


def calibrate(block: Callable[[int], None], seconds: float) -> int:
    block(20)
    start = time.perf_counter()
    block(50)
    return max(10, round(50 * seconds / (time.perf_counter() - start)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=11)
    parser.add_argument("--seconds", type=float, default=0.5)
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    make = dict(airframe="volantex_ranger", backend=args.backend, seed=0)
    cases = {
        "core (floor)": core_block(gym.make("falcon_rl/Attitude-v0", **make)),
        "unrendered": env_block(gym.make("falcon_rl/Attitude-v0", **make), draw=False),
        "rgb_array, not drawn": env_block(gym.make("falcon_rl/Attitude-v0", render_mode="rgb_array", **make),
                                          draw=False),
        "rgb_array, drawn each step": env_block(
            gym.make("falcon_rl/Attitude-v0", render_mode="rgb_array", **make), draw=True),
    }
    steps = {name: calibrate(block, args.seconds) for name, block in cases.items()}
    rates: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(args.repeats):
        for name, block in cases.items():
            start = time.perf_counter()
            block(steps[name])
            rates[name].append(steps[name] / (time.perf_counter() - start))
    reference = rates["unrendered"]
    rows = []
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"load {os.getloadavg()[0]:.1f}; backend {args.backend}; {args.repeats} rounds")
    print(f"{'case':<28} {'steps/s':>9} {'min-max':>17} {'/ unrendered':>13}")
    for name, values in rates.items():
        ratio = statistics.median(a / b for a, b in zip(values, reference, strict=True))
        rows.append({"case": name, "median": statistics.median(values), "min": min(values),
                     "max": max(values), "ratio_to_unrendered": ratio})
        print(f"{name:<28} {statistics.median(values):>9.0f} {min(values):>8.0f}-{max(values):<8.0f} "
              f"{ratio:>13.3f}")
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"rows": rows, "repeats": args.repeats, "backend": args.backend}, handle, indent=2)


if __name__ == "__main__":
    main()
