"""Train PPO as an attitude executor (bank, climb-rate, airspeed commands) on the Volantex Ranger.

    python examples/train_ppo_attitude.py --frames 500000

Writes its files under runs/examples/ppo_attitude and prints bank / climb-rate / airspeed RMSE per
maneuver of the attitude protocol.
"""

from __future__ import annotations

import argparse

from falcon_rl.objectives import ppo


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=None)
    parser.add_argument("--envs", type=int, default=None)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    cfg = ppo.make_config("attitude", airframe="volantex_ranger", frames=args.frames, num_envs=args.envs,
                          seed=args.seed, out="runs/examples/ppo_attitude", final_eval_episodes=4)
    summary = ppo.train(cfg)
    print(f"{summary['frames']:,} frames in {summary['wall_seconds']:.0f} s "
          f"({summary['env_steps_per_s']:,.0f} env-steps/s incl. learning)")
    for key, value in sorted(summary["eval"].items()):
        print(f"  {key}: {value:.3g}")


if __name__ == "__main__":
    main()
