"""Fly one controller through the paper's robustness grid and plot its metric against severity.

Four disturbance families, one at a time, at the grid's severities (falcon_rl.transforms.presets):
sensor noise floors, observation latency (20/50/80 ms), command latency (20/60/100 ms) and Dryden
turbulence (sigma_u / V_a = 0.05/0.10/0.15). The controller is the gain-scheduled attitude LQRI
(falcon_rl.baselines) on the attitude task with a random bank / climb-rate / airspeed command stream;
it reads the state the sensors report, ("measured", ...), whenever a transform provides one. The
metric is the bank RMSE over the envs' alive steps and the survival rate, both from the true state.

    python examples/robustness_sweep.py                       # navion, 32 envs, 5 s: about 1.5 min of CPU
    python examples/robustness_sweep.py --airframe volantex_ranger --envs 128 --seconds 30
"""

from __future__ import annotations

import argparse
import json
import math

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from falcon_rl import load_airframe, make_env
from falcon_rl.envs.layout import flat_scalars
from falcon_rl.transforms import flight_env
from falcon_rl.transforms.presets import GRID, grid_turbulence, nominal_height

FAMILIES = ("sensors", "obs_delay", "action_delay", "turbulence")


class MeasuredView(TensorDictModuleBase):
    """Runs a policy that reads ("state", ...) on ("measured", ...) when the env publishes it."""

    def __init__(self, policy: TensorDictModuleBase):
        super().__init__()
        self.policy = policy
        self.in_keys = [("measured", *k[1:]) if k[0] == "state" else k for k in policy.in_keys]
        self.out_keys = list(policy.out_keys)

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        measured = td.get("measured", None)
        view = td.clone(False)
        if measured is not None:
            view.set("state", measured)
        td.set("action", self.policy(view).get("action"))
        return td


def trim_hold_policy(env) -> TensorDictModuleBase:
    """Fallback controller: hold the trim command (used when the LQR baselines are unavailable)."""
    trim = flight_env(env, "trim_action").trim_action()  # [A]

    class TrimHold(TensorDictModuleBase):
        in_keys, out_keys = [], ["action"]

        def forward(self, td: TensorDictBase) -> TensorDictBase:
            td.set("action", trim.expand(td.batch_size[0], -1).clone())
            return td

    return TrimHold()


def make_policy(airframe_name: str, dt: float):
    try:
        from falcon_rl.baselines.lqr import AttitudeLQR
    except ImportError:
        return None
    return MeasuredView(AttitudeLQR(load_airframe(airframe_name), dt))


def run_cell(family: str, level: str, args: argparse.Namespace, policy) -> dict[str, float]:
    """Bank RMSE (deg) and survival of one (family, severity) cell."""
    # The paper's 10 ms control step: the grid's 20 ms delays are whole steps (at 20 Hz they round to 0).
    options: dict = {"maneuver": "random", "episode_seconds": args.seconds, "decimation": 1}
    if level != "nominal":
        if family == "sensors":
            options["sensors"] = level
        elif family == "obs_delay":
            options["obs_delay_ms"] = level
        elif family == "action_delay":
            options["action_delay_ms"] = level
        else:
            airframe = load_airframe(args.airframe)
            from falcon_rl.envs.tasks.attitude import AttitudeConfig

            options["turbulence"] = grid_turbulence(level, airframe.envelope.cruise_speed,
                                                    nominal_height(AttitudeConfig()))
    env = make_env("attitude", args.airframe, num_envs=args.envs, seed=args.seed, **options)
    actor = policy if policy is not None else trim_hold_policy(env)
    if hasattr(actor, "policy"):
        actor.policy.integral = None
    steps = round(args.seconds / env.control_dt)
    with torch.no_grad():
        td = flat_scalars(env.rollout(steps, policy=actor, break_when_any_done=False))  # [N, T] series
    done = td["next", "done"].squeeze(-1)  # [N, T]
    alive = torch.cumprod((~done).float(), dim=-1)
    alive = torch.cat([torch.ones_like(alive[:, :1]), alive[:, :-1]], dim=-1)  # include the last step
    error = td["next", "task", "bank_error"]
    rmse = math.degrees(math.sqrt(float((alive * error**2).sum() / alive.sum())))
    survival = float((~td["next", "terminated"].squeeze(-1).any(-1)).float().mean())
    return {"bank_rmse_deg": rmse, "survival": survival}


def plot(results: dict, path: str, airframe: str) -> None:
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
    ax.set_title(f"Attitude LQRI robustness, {airframe}")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--airframe", default="navion")
    parser.add_argument("--envs", type=int, default=32)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="robustness_sweep.png")
    args = parser.parse_args()
    torch.manual_seed(args.seed)
    if args.envs <= 512:
        torch.set_num_threads(1)  # small batches: per-op overhead dominates, threads only add sync cost
    policy = make_policy(args.airframe, 0.01)
    nominal = run_cell("sensors", "nominal", args, policy)
    results = {family: {"nominal": nominal} for family in FAMILIES}
    for family in FAMILIES:
        for level in GRID[1:]:
            results[family][level] = run_cell(family, level, args, policy)
            print(f"{family:13s} {level:8s} {json.dumps(results[family][level])}", flush=True)
    plot(results, args.out, args.airframe)
    print(json.dumps({"figure": args.out, "results": results}))


if __name__ == "__main__":
    main()
