"""The CPU speed targets of the env step, in one run: each measured against its reference in the same
process, side by side, with a table and a figure of measured / target.

    python benchmarks/speed_targets.py --trials 9 [--train] [--out benchmarks/results/speed_targets]

Targets (the altitude task on the Volantex Ranger, warp backend):

- ``env step / physics, 4,096 envs``: the TorchRL env's ``step_and_maybe_reset`` at 4,096 envs (the
  task's control step: ``decimation`` RK4 steps of 10 ms) against ``Simulator.step`` of the same
  sub-steps, rate ratio >= 0.8 (``env_step.py``'s ``env`` and ``physics`` cases);
- ``TorchRL env / trivial EnvBase, 1 env``: the lean env against a trivial TorchRL ``EnvBase`` with its
  keys, rate ratio >= 0.7: against the floor that hands out new tensors at every step (what every env
  whose steps a rollout keeps must do), and, reported beside it, the floor that returns preallocated
  tensors (``env_step.py``'s floors);
- ``Gymnasium single env``: ``gymnasium.make("falcon_rl/Altitude-v0")`` with its wrappers, random
  actions and resets, >= 20,000 steps/s and >= 0.2x JSBSim's c172p stepped from Python for the same
  simulated time in the same rounds (``gym_throughput.py``'s cases);
- ``Gymnasium vector env, 1,024 envs``: ``FalconVectorEnv`` on its fast path, >= 500,000 env-steps/s;
- with ``--train``: ``falcon-rl train ppo --task altitude --airframe volantex_ranger --stop-when
  "survival>=1,acquisition>=0.95,rmse_m<=0.5"`` from scratch, start to exit (its 100-episode test
  included) in <= 300 s, the test meeting the same conditions (its ``summary.json`` is kept as
  ``train_summary.json``; its checkpoint and policy are not).

The Gymnasium cases run at ``--gym-decimation`` (default 1: the paper's 100 Hz control, where the
vector target is set; at the task's 20 Hz the physics of 1,024 envs alone is below it on two cores),
the env-step cases at the task's decimation (5). Every ratio is measured in the same rounds as its
reference; ``--trials`` rounds, medians and min-max reported.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).parent))
import env_step  # the sibling benchmarks
import gym_throughput

from falcon_rl.envs import task_spec
from falcon_rl.envs.tasks.altitude import ALTITUDE_SOLVED
from falcon_rl.evaluation.bench import _cpu_name
from falcon_rl.recipes.selection import conditions_met, parse_stop_when


@dataclass
class Target:
    """One criterion: its measured value (a median), the spread over the rounds (text), the target and
    its unit; met when the median reaches the target."""

    name: str
    measured: float
    spread: str
    target: float
    unit: str
    note: str = ""

    @property
    def met(self) -> bool:
        return self.measured >= self.target


def _rate_ratio(case: env_step.EnvStepCase, floor: str) -> tuple[float, str]:
    """(the median rate ratio of ``case`` to ``floor``, "fastest blocks R") from its time ratios."""
    median, fastest = getattr(case, f"ratio_to_{floor}"), getattr(case, f"ratio_to_{floor}_min")
    return 1 / median, f"fastest blocks {1 / fastest:.2f}"


def env_step_targets(args: argparse.Namespace) -> list[Target]:
    """The env step at ``args.envs`` envs against the physics, and the lean env at 1 env against the
    two TorchRL floors (``env_step.py``'s cases, interleaved rounds per env count)."""
    options = ["--task", "altitude", "--airframe", "volantex_ranger", "--trials", str(args.trials)]
    bar = tqdm(total=args.trials * 5, desc="env step", disable=args.no_progress, file=sys.stderr)
    big = {c.label: c for c in env_step.time_cases(env_step.parse_args(
        [*options, "--cases", "physics,env"]), args.envs, bar)}
    one = {c.label: c for c in env_step.time_cases(env_step.parse_args(
        [*options, "--cases", "torchrl floor,torchrl floor (new outputs),env lean"]), 1, bar)}
    bar.close()
    for case in (*big.values(), *one.values()):
        if case.error:
            raise RuntimeError(f"{case.label}: {case.error}")
    env, lean = big["env"], one["env lean"]
    return [
        Target(f"TorchRL env step / Simulator.step, {args.envs:,} envs", *_rate_ratio(env, "physics"), 0.8,
               "x", f"{env.env_steps_per_s:,.0f} against {big['physics'].env_steps_per_s:,.0f} env-steps/s"),
        Target("TorchRL env (lean) / trivial EnvBase handing out new tensors, 1 env",
               *_rate_ratio(lean, "torchrl_new"), 0.7, "x",
               f"{lean.env_steps_per_s:,.0f} against "
               f"{one['torchrl floor (new outputs)'].env_steps_per_s:,.0f} steps/s"),
        Target("TorchRL env (lean) / trivial EnvBase handing out preallocated tensors, 1 env",
               *_rate_ratio(lean, "torchrl"), 0.7, "x",
               f"against {one['torchrl floor'].env_steps_per_s:,.0f} steps/s (a rollout of it keeps "
               "no step)"),
    ]


def gym_targets(args: argparse.Namespace) -> list[Target]:
    """The Gymnasium single env against JSBSim in the same rounds, and the vector env at 1,024 envs
    (``gym_throughput.py``'s cases, every case and JSBSim timed once per round)."""
    gym_args = argparse.Namespace(task="altitude", airframe="volantex_ranger", envs=args.vector_envs,
                                  backend="warp", device="cpu", seconds=0.25, jsbsim_runs=10000,
                                  decimation=args.gym_decimation)
    built = gym_throughput.build(gym_args, args.gym_decimation)
    cases = {f"{case.label} {case.num_envs}": case for case, _ in built}
    single = cases["gymnasium.make (wrappers) fast path 1"]
    vector = cases[f"FalconVectorEnv fast path {args.vector_envs}"]
    floor = cases[f"physics: Simulator.step(substeps={args.gym_decimation}) {args.vector_envs}"]
    jsbsim = gym_throughput.Case("JSBSim c172p", 1, "jsbsim")
    for _ in tqdm(range(args.trials), desc="gymnasium", disable=args.no_progress, file=sys.stderr):
        gym_throughput.time_round(built, jsbsim, gym_args, args.gym_decimation)

    def spread(case: gym_throughput.Case) -> str:
        return f"{min(case.rates):,.0f}-{max(case.rates):,.0f}"

    hz = f"{100 / args.gym_decimation:g} Hz control"
    versus = [a / b for a, b in zip(single.rates, jsbsim.rates, strict=True)]
    return [
        Target(f"gymnasium.make single env ({hz})", single.median, spread(single), 20_000, "steps/s"),
        Target("gymnasium.make single env / JSBSim c172p (same simulated time, same rounds)",
               statistics.median(versus), f"{min(versus):.2f}-{max(versus):.2f}", 0.2, "x",
               f"JSBSim {jsbsim.median:,.0f} steps/s ({spread(jsbsim)})"),
        Target(f"FalconVectorEnv, {args.vector_envs:,} envs ({hz})", vector.median, spread(vector), 500_000,
               "env-steps/s", f"physics alone {floor.median:,.0f} ({spread(floor)}); random actions, "
               "with Gymnasium's autoreset of the envs that end"),
    ]


def train_target(args: argparse.Namespace) -> list[Target]:
    """``falcon-rl train ppo`` on the Ranger's altitude task from scratch until solved: the wall clock of
    the whole command (its 100-episode test included) and the test's RMSE."""
    with tempfile.TemporaryDirectory() as folder:  # the run's checkpoint and policy are not kept
        command = [sys.executable, "-m", "falcon_rl.cli", "train", "ppo", "--task", "altitude", "--airframe",
                   "volantex_ranger", "--seed", str(args.seed), "--stop-when", ALTITUDE_SOLVED, "--out",
                   folder, "--logger", "none", "--no-progress"]
        print("training:", " ".join(command[2:]), flush=True)
        start = time.perf_counter()
        subprocess.run(command, check=True)
        wall = time.perf_counter() - start
        summary = json.loads((Path(folder) / "summary.json").read_text())
    kept = {k: v for k, v in summary.items() if k not in ("checkpoint", "policy", "torchscript")}  # gone
    (args.out / "train_summary.json").write_text(json.dumps(kept, indent=1) + "\n")
    test, solved = summary["eval"], summary["solved"] or {}
    met = conditions_met(test, parse_stop_when(ALTITUDE_SOLVED, task_spec("altitude").metric_keys))
    note = (f"solved on validation at {solved.get('frames', 0):,} frames, "
            f"{solved.get('wall_seconds', 0):.0f} s; "
            f"100-episode test: survival {test['survival']:.2f}, acquisition {test['acquisition']:.2f}, "
            f"RMSE {test['rmse_m']:.3f} m" + ("" if met else " (test misses the conditions)"))
    # Expressed as a rate so that "met" reads the same way: 300 s / wall >= 1, and 0 when the test missed.
    return [Target(f"PPO altitude, Ranger, seed {args.seed}: 300 s / wall clock of the command", 300 / wall
                   if met else 0.0, f"{wall:.0f} s", 1.0, "x", note)]


def figure(targets: list[Target], title: str, path: Path) -> Path:
    """Horizontal bars of measured / target per criterion (>= 1: met), the target as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 0.55 * len(targets) + 1.4))
    ratios = [t.measured / t.target for t in targets]
    colours = ["tab:green" if t.met else "tab:red" for t in targets]
    ax.barh(range(len(targets)), ratios, color=colours)
    ax.axvline(1.0, color="black", lw=1)
    ax.set_yticks(range(len(targets)), [t.name for t in targets], fontsize=7)
    ax.invert_yaxis()
    ax.set_xlabel("measured / target (>= 1: met)")
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=9, help="timed rounds")
    parser.add_argument("--envs", type=int, default=4096, help="env count of the env-step target")
    parser.add_argument("--vector-envs", type=int, default=1024, help="env count of the vector env target")
    parser.add_argument("--gym-decimation", type=int, default=1,
                        help="physics steps per Gymnasium env step (default 1: 100 Hz control)")
    parser.add_argument("--train", action="store_true", help="also train PPO altitude until solved")
    parser.add_argument("--seed", type=int, default=0, help="seed of the --train run")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/speed_targets"))
    parser.add_argument("--no-progress", action="store_true")
    args = parser.parse_args(argv)
    if args.trials < 1 or args.envs < 1 or args.vector_envs < 1 or args.gym_decimation < 1:
        parser.error("--trials, --envs, --vector-envs and --gym-decimation must be >= 1")
    return args


def main(argv: list[str] | None = None) -> int:
    """Measure every target, print the table, write ``speed_targets.json`` and ``speed_targets.png``."""
    args = parse_args(argv)
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    load = [os.getloadavg()[0]]
    targets = env_step_targets(args) + gym_targets(args)
    if args.train:
        targets += train_target(args)
    load.append(os.getloadavg()[0])
    title = (f"{_cpu_name()}, torch 1 thread, warp; {args.trials} rounds; 1-min load average "
             f"{load[0]:.1f} -> {load[1]:.1f}")
    lines = [title, "", "| target | measured | spread | target | met | note |", "|---|---:|---|---:|---|---|"]
    for t in targets:
        value = f"{t.measured:,.0f}" if t.measured >= 100 else f"{t.measured:.2f}"
        lines.append(f"| {t.name} | {value} {t.unit} | {t.spread} | {t.target:,g} {t.unit} | "
                     f"{'yes' if t.met else 'no'} | {t.note} |")
    print("\n".join(lines))
    doc = {"cpu": _cpu_name(), "load_average_1min": load, "args": {k: str(v) for k, v in vars(args).items()},
           "versions": env_step._versions(), "targets": [{**asdict(t), "met": t.met} for t in targets]}
    (args.out / "speed_targets.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(f"\nwrote {args.out / 'speed_targets.json'} and "
          f"{figure(targets, title, args.out / 'speed_targets.png')}")
    return 0 if all(t.met for t in targets) else 1


if __name__ == "__main__":
    raise SystemExit(main())
