"""Train PPO, SAC or TD3 on a falcon-rl task from Python, then score it on the task's protocol.

    python examples/train.py                                   # PPO, altitude, Volantex Ranger
    python examples/train.py --algorithm sac --frames 200000   # a quick look at SAC
    python examples/train.py --algorithm ppo --task attitude

Each recipe (falcon_rl/recipes/{ppo,sac,td3}.py) has the same two calls: ``make_config(task,
**overrides)`` fills the task's defaults, ``train(cfg)`` runs it. Writes checkpoint.pt, policy.pt,
policy.ts and CSV logs under runs/examples/<algorithm>_<task>.
"""

from __future__ import annotations

import argparse

from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.envs.tasks import task_names
from falcon_rl.recipes import ppo, sac, td3

RECIPES = {"ppo": ppo, "sac": sac, "td3": td3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--algorithm", choices=sorted(RECIPES), default="ppo")
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--frames", type=int, default=None, help="default: the recipe's")
    parser.add_argument("--envs", type=int, default=None, help="default: the recipe's")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eval-episodes", type=int, default=20,
                        help="episodes of the final evaluation (per maneuver on the attitude protocol)")
    args = parser.parse_args()
    recipe = RECIPES[args.algorithm]
    cfg = recipe.make_config(args.task, airframe=args.airframe, frames=args.frames, num_envs=args.envs,
                             seed=args.seed, out=f"runs/examples/{args.algorithm}_{args.task}",
                             final_eval_episodes=args.eval_episodes)
    summary = recipe.train(cfg)
    print(f"{summary['frames']:,} frames in {summary['wall_seconds']:.0f} s "
          f"({summary['env_steps_per_s']:,.0f} env-steps/s incl. learning)")
    print("protocol:", {k: round(v, 3) for k, v in (summary.get("eval") or {}).items()})
    print("policy:", summary["policy"])


if __name__ == "__main__":
    main()
