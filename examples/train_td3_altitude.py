"""Train TD3 on altitude acquisition and hold (Volantex Ranger) from Python, then score it.

    python examples/train_td3_altitude.py                 # the recipe's default frames
    python examples/train_td3_altitude.py --frames 200000 # a quick look

Writes checkpoint.pt, policy.pt, policy.ts and CSV logs under runs/examples/td3_altitude, and prints
the altitude protocol's survival, acquisition and RMSE of the trained policy.
"""

from __future__ import annotations

import argparse

from falcon_rl.objectives import td3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=None)
    parser.add_argument("--envs", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    cfg = td3.make_config("altitude", airframe="volantex_ranger", frames=args.frames, num_envs=args.envs,
                         seed=args.seed, out="runs/examples/td3_altitude", final_eval_episodes=20)
    summary = td3.train(cfg)
    print(f"{summary['frames']:,} frames in {summary['wall_seconds']:.0f} s "
          f"({summary['env_steps_per_s']:,.0f} env-steps/s incl. learning)")
    print("altitude protocol:", {k: round(v, 3) for k, v in summary["eval"].items()})
    print("policy:", summary["policy"])


if __name__ == "__main__":
    main()
