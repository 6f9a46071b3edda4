"""The cost of flying over a sea: the Warp physics step and env step over sea state 3 against the same over
the flat ground, in one run, alternated round by round (the ratio is the figure; the machine is shared).

    python benchmarks/sea_speed.py --envs 4096 --rounds 7 [--out benchmarks/results/sea_speed]

Physics: ``Simulator.step(command, substeps)`` of ``--airframe`` at trimmed cruise (100 m), the flat ground
against a sea of ``--sea-state`` (64 components). Env: the lean altitude env (20 Hz control: 5 physics steps
per env step) stepping with ``step_and_maybe_reset``, flat against the same env with ``env.sim.set_sea``.
Each round times ``--steps`` calls of each case after a warm-up; the ratio is sea speed / flat speed.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path
from typing import Any

import torch

from falcon_rl import Simulator, make_env


def physics_case(airframe: str, envs: int, sea: int | None, substeps: int) -> Any:
    """A callable stepping the Warp physics of ``envs`` envs by ``substeps`` steps (over sea ``sea``)."""
    sim = Simulator(airframe, envs, backend="warp", seed=0, sea=sea)
    sim.reset()
    command = sim.default_initial()[1].expand(envs, -1).clone()

    def step() -> None:
        sim.step(command, substeps)
    return step


def env_case(envs: int, sea: int | None) -> Any:
    """A callable stepping the lean altitude env of ``envs`` envs (over sea ``sea``) with a fixed action."""
    env = make_env("altitude", "volantex_ranger", num_envs=envs, backend="warp", seed=0, lean=True)
    if sea is not None:
        env.sim.set_sea(sea)
    td = env.reset()
    action = env.trim_action().expand(envs, -1).clone()
    state = {"td": td}

    def step() -> None:
        state["td"]["action"] = action
        _, state["td"] = env.step_and_maybe_reset(state["td"])
    return step


def timed(step: Any, steps: int) -> float:
    """Seconds per call over ``steps`` calls."""
    start = time.perf_counter()
    for _ in range(steps):
        step()
    return (time.perf_counter() - start) / steps


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", type=int, default=4096)
    parser.add_argument("--airframe", default="navion")
    parser.add_argument("--sea-state", type=int, default=3)
    parser.add_argument("--substeps", type=int, default=5)
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--out", default=None, help="folder for sea_speed.json")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    cases = {"physics": (physics_case(args.airframe, args.envs, None, args.substeps),
                         physics_case(args.airframe, args.envs, args.sea_state, args.substeps)),
             "env": (env_case(args.envs, None), env_case(args.envs, args.sea_state))}
    rows: dict[str, dict[str, Any]] = {}
    for name, (flat, sea) in cases.items():
        for step in (flat, sea):
            timed(step, 3)  # warm-up: kernel load, allocator
        ratios, flat_rates, sea_rates = [], [], []
        for _ in range(args.rounds):
            flat_s, sea_s = timed(flat, args.steps), timed(sea, args.steps)
            ratios.append(flat_s / sea_s)
            per_call = args.envs * (args.substeps if name == "physics" else 1)
            flat_rates.append(per_call / flat_s)
            sea_rates.append(per_call / sea_s)
        rows[name] = {"ratio_median": statistics.median(ratios), "ratio_min": min(ratios),
                      "ratio_max": max(ratios), "flat_per_s_median": statistics.median(flat_rates),
                      "sea_per_s_median": statistics.median(sea_rates), "ratios": ratios}
        unit = "physics steps/s" if name == "physics" else "env steps/s"
        row = rows[name]
        print(f"{name}: sea/flat {row['ratio_median']:.2f}x (min {min(ratios):.2f}, max {max(ratios):.2f}); "
              f"flat {row['flat_per_s_median']:,.0f} {unit}, sea {row['sea_per_s_median']:,.0f}")
    if args.out:
        folder = Path(args.out)
        folder.mkdir(parents=True, exist_ok=True)
        document = {"settings": vars(args), "results": rows}
        (folder / "sea_speed.json").write_text(json.dumps(document, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
