"""Fly one controller through the paper's robustness grid and plot its metric against severity.

Four disturbance families, one at a time, at the grid's severities (falcon_rl.transforms.presets):
sensor noise floors, observation latency (20/50/80 ms), command latency (20/60/100 ms) and Dryden
turbulence (sigma_u / V_a = 0.05/0.10/0.15), flown by falcon_rl.evaluation.robustness.robustness_grid.
The controller (default: the gain-scheduled attitude LQRI of falcon_rl.baselines; --controller ppo
flies the shipped policy) tracks a random bank / climb-rate / airspeed command stream on the attitude
task; a state-reading controller reads the state the sensors report, ("measured", ...), whenever a
transform provides one, a learned policy the corrupted observation. The metric is the bank RMSE over
the envs' alive steps and the survival rate, both from the true state.

    python examples/robustness_sweep.py                       # navion, 32 envs, 5 s: about 1.5 min of CPU
    python examples/robustness_sweep.py --airframe volantex_ranger --envs 128 --seconds 30
"""

from __future__ import annotations

import argparse
import json

import torch

from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.evaluation.controllers import reused_controller
from falcon_rl.evaluation.robustness import FAMILIES, robustness_grid
from falcon_rl.transforms.presets import GRID


def plot(results: dict, path: str, airframe: str, controller: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    x = range(len(GRID))
    for family in FAMILIES:
        cells = [results[family][level] for level in GRID]
        ax.plot(x, [c["bank_rmse_deg"] for c in cells], marker="o", label=family.replace("_", " "))
        for i, c in enumerate(cells):
            if c["survival"] < 1.0:
                ax.annotate(f"{c['survival']:.2f}", (i, c["bank_rmse_deg"]), textcoords="offset points",
                            xytext=(4, 4), fontsize=8)
    ax.set_xticks(list(x), [g.capitalize() for g in GRID])
    ax.set_xlabel("severity")
    ax.set_ylabel("bank RMSE (deg)")
    ax.set_title(f"Attitude executor robustness: {controller}, {airframe}")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--controller", default="lqr", help="lqr, mppi, trim, ppo (shipped) or a policy file")
    parser.add_argument("--envs", type=int, default=32)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="robustness_sweep.png")
    args = parser.parse_args()
    torch.manual_seed(args.seed)
    if args.envs <= 512:
        torch.set_num_threads(1)  # small batches: per-op overhead dominates, threads only add sync cost
    def controller(env):  # the LQR designed once for the whole grid
        return reused_controller(args.controller, env)

    grid = robustness_grid(args.airframe, args.controller, controller, episodes=args.envs,
                           seconds=args.seconds, maneuvers=("random",), seed=args.seed)
    for row in grid.to_rows():
        cell = {k: row[k] for k in ("severity", "unit", "survival", "bank_rmse_deg")}
        print(f"{row['family']:13s} {row['level']:8s} {json.dumps(cell)}", flush=True)
    results = grid.as_nested()
    plot(results, args.out, args.airframe, args.controller)
    print(json.dumps({"figure": args.out, "results": results}))


if __name__ == "__main__":
    main()
