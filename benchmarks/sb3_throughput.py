"""Stable-Baselines3 PPO throughput on one batched simulator (``FalconSB3VecEnv``) at several env
counts, against SB3 on one Gymnasium env (``DummyVecEnv`` of one ``gymnasium.make``), in one run.

    python benchmarks/sb3_throughput.py --envs 1,64,256,1024 --repeats 3 [--torchrl-path] [--json out.json]

``--torchrl-path`` adds each adapter stepping through TorchRL's ``step_and_maybe_reset`` instead of
the env's tensor core (``fast_path=False``), the path the fast one replaces.

Method: every case trains the same PPO (MlpPolicy 64x64, ``--rollout`` samples per update, i.e.
n_steps = rollout / N, ``--epochs`` epochs of minibatches of ``--batch``), so the training cost per
sample is the same in every case and the cases differ in how the samples are collected. Each case
is built and warmed up by one update (env build, Warp kernel load, allocator), then timed in
``--repeats`` rounds of ``--updates`` updates; the rounds go through every case in turn, so that load
drifting on a shared machine spreads over all cases. Reported per case: env-steps/s of the whole
``learn`` (collection and training) and of the collection phase alone (SB3's rollout: policy
forward, env step, buffer), median and min-max over the rounds, and each median as a ratio to the
baseline's median of the same run.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from dataclasses import asdict, dataclass, field

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.envs.gym import GYM_IDS, register_gym_envs
from falcon_rl.envs.gym.sb3 import FalconSB3VecEnv


class RolloutTimer(BaseCallback):
    """Adds up the wall time of SB3's rollout (collection) phases."""

    def __init__(self) -> None:
        super().__init__()
        self.seconds = 0.0
        self._start = 0.0

    def _on_rollout_start(self) -> None:
        self._start = time.perf_counter()

    def _on_rollout_end(self) -> None:
        self.seconds += time.perf_counter() - self._start

    def _on_step(self) -> bool:
        return True


@dataclass
class Case:
    """One timed configuration: its label, env count and per-round env-steps/s."""

    label: str
    num_envs: int
    learn: list[float] = field(default_factory=list)
    collect: list[float] = field(default_factory=list)


def build(label: str, venv: VecEnv, args: argparse.Namespace) -> tuple[Case, PPO]:
    """The case and its PPO, warmed up by one update."""
    model = PPO("MlpPolicy", venv, n_steps=max(1, args.rollout // venv.num_envs), batch_size=args.batch,
                n_epochs=args.epochs, seed=0, device="cpu")
    model.learn(total_timesteps=args.rollout)
    return Case(label, venv.num_envs), model


def time_round(case: Case, model: PPO, args: argparse.Namespace) -> None:
    """Time ``args.updates`` PPO updates and append the case's env-steps/s (learn, collection)."""
    timer = RolloutTimer()
    start_steps = model.num_timesteps
    start = time.perf_counter()
    model.learn(total_timesteps=args.updates * args.rollout, callback=timer, reset_num_timesteps=False)
    seconds = time.perf_counter() - start
    steps = model.num_timesteps - start_steps
    case.learn.append(steps / seconds)
    case.collect.append(steps / timer.seconds)


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):>10,.0f} {min(values):>10,.0f}-{max(values):<10,.0f}"


def report(cases: list[Case]) -> None:
    """Print the table: medians, min-max and ratios to the baseline (the first case)."""
    base_learn, base_collect = (statistics.median(values) for values in (cases[0].learn, cases[0].collect))
    width = max(len(case.label) for case in cases)
    print(f"\n{'case':<{width}} {'envs':>5} {'learn steps/s':>10} {'min-max':>21} {'x':>6}   "
          f"{'collect steps/s':>10} {'min-max':>21} {'x':>6}")
    for case in cases:
        learn, collect = statistics.median(case.learn), statistics.median(case.collect)
        print(f"{case.label:<{width}} {case.num_envs:>5} {spread(case.learn)} {learn / base_learn:>6.1f}   "
              f"{spread(case.collect)} {collect / base_collect:>6.1f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--envs", default="1,64,256,1024", help="comma list of env counts of the adapter")
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--rollout", type=int, default=4096, help="samples per PPO update (n_steps x N)")
    parser.add_argument("--batch", type=int, default=1024, help="PPO minibatch size")
    parser.add_argument("--epochs", type=int, default=4, help="PPO epochs per update")
    parser.add_argument("--updates", type=int, default=2, help="timed PPO updates per round")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds")
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (the policy)")
    parser.add_argument("--torchrl-path", action="store_true",
                        help="also time each adapter on TorchRL's step (fast_path=False)")
    parser.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    options = {"airframe": args.airframe, "backend": args.backend, "device": args.device}
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, torch {torch.__version__} "
          f"({args.threads} thread(s)); {args.task} on {args.airframe}, {args.backend} on {args.device}; "
          f"PPO {args.rollout} samples/update, batch {args.batch}, {args.epochs} epochs")
    register_gym_envs()
    gym_id = GYM_IDS[args.task]
    builders = [("SB3 DummyVecEnv(1 x gymnasium.make)",
                 lambda: DummyVecEnv([lambda: gym.make(gym_id, **options)]))]
    paths = {"": True, ", TorchRL path": False} if args.torchrl_path else {"": True}
    builders += [(f"FalconSB3VecEnv (one batch of {n}{name})",
                  lambda n=n, fast=fast: FalconSB3VecEnv.make(args.task, num_envs=n, fast_path=fast,
                                                              **options))
                 for n in (int(v) for v in args.envs.split(",")) for name, fast in paths.items()]
    runs = []
    for label, make in builders:
        print(f"building and warming up: {label}", flush=True)
        runs.append(build(label, make(), args))
    for round_index in range(args.repeats):
        for case, model in runs:
            print(f"round {round_index + 1}/{args.repeats}: {case.label}", flush=True)
            time_round(case, model, args)
    cases = [case for case, _ in runs]
    report(cases)
    if args.json:
        with open(args.json, "w") as handle:
            json.dump({"args": vars(args), "cases": [asdict(case) for case in cases]}, handle, indent=2)


if __name__ == "__main__":
    main()
