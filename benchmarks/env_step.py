"""Env step against its floors: the TorchRL env step beside the physics it runs and TorchRL's own cost.

    python benchmarks/env_step.py --envs 1,64,1024,4096 --trials 5 [--device cuda] [--profile]

Cases, per env count N (all built first, then timed in interleaved rounds so that load drift on a
shared machine hits every case alike):

- ``physics``: ``Simulator.step(command, substeps=d)`` of the env's own simulator (a dedicated env,
  input checks off as in ``falcon-rl bench``), d = the env's decimation: the physics floor;
- ``physics checked``: the same with the input checks on, as the env builds its simulator;
- ``torchrl floor``: a trivial TorchRL ``EnvBase`` with the lean env's keys and widths (observation,
  termination_reason, action, reward and done flags) whose ``_step`` returns preallocated tensors in
  an unchecked TensorDict: what TorchRL itself costs. A rollout of it records the last step's values
  at every step (the same tensors each time), so no env that a rollout can keep does this;
- ``torchrl floor (new outputs)``: the same trivial env whose ``_step`` returns new tensors (copies of
  its preallocated ones), as every env whose steps a rollout or a replay buffer keeps must: the floor
  of a usable env;
- ``fused step``: the lean env's one-launch step (``FixedWingEnv.step_tensors(action, with_state=False,
  copy=False)``: physics sub-steps, task, guard and flags in one Warp launch) without TorchRL around it
  and without resets: what the TorchRL env adds is the rest;
- ``fused step (CUDA graph)``: the same step captured once in a CUDA graph and replayed (CUDA only): the
  step's device time without its host-side launch work;
- ``partial reset``: ``FixedWingEnv.reset_tensors(mask, with_state=False)`` of the lean env with one env
  in the mask (a different one each call), what a rollout's auto-reset runs for the envs that finished
  (the task's draws, the reset checks, the physics' reset launch, the start of the task's episodes);
- ``env``, ``env lean``, ``env unfused``, ``env lean unfused``: the task env
  (``make_env(task, airframe, num_envs=N, backend, seed=0, decimation=d, lean=, fused=)``; unfused: the
  engine's step, then the task's Warp step as a launch of its own).

Every env (the floor too) is stepped by ``falcon_rl.evaluation.bench.env_stepper``:
``step_and_maybe_reset`` with a
zero action, as a rollout does. Each case gets ``--warmup`` untimed steps, then one timed block per
round (``--trials`` rounds, the case order rotated each round); a block is ``--steps`` steps or more,
enough to last ``--block-s``. Reported: median ms per env step, min-max over the blocks, env-steps/s,
and the ratios to the physics floor and to the two TorchRL floors (of the medians; in brackets of the fastest
blocks, the least disturbed on a loaded machine). ``--profile`` prints the
top-20 functions by cumulative time (cProfile) of the 1-env ``env`` step.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import math
import os
import pstats
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase
from tqdm import tqdm

from falcon_rl import make_env
from falcon_rl.defaults import DEFAULT_AIRFRAME
from falcon_rl.envs.tasks import TERMINATION_REASONS
from falcon_rl.evaluation.bench import BenchCase, _cpu_name, _time_blocks, env_stepper, plot

#: Case label -> (kind, make_env options); kind in "physics", "physics checked", "torchrl", "torchrl new",
#: "fused", "fused graph", "reset", "env".
CASES: dict[str, tuple[str, dict[str, bool]]] = {
    "physics": ("physics", {}),
    "physics checked": ("physics checked", {}),
    "torchrl floor": ("torchrl", {}),
    "torchrl floor (new outputs)": ("torchrl new", {}),
    "fused step": ("fused", {"lean": True, "fused": True}),
    "fused step (CUDA graph)": ("fused graph", {"lean": True, "fused": True}),
    "partial reset": ("reset", {"lean": True, "fused": True}),
    "env": ("env", {"lean": False, "fused": True}),
    "env lean": ("env", {"lean": True, "fused": True}),
    "env unfused": ("env", {"lean": False, "fused": False}),
    "env lean unfused": ("env", {"lean": True, "fused": False}),
}


@dataclass
class EnvStepCase(BenchCase):
    """One case at one env count; ratios are of the median times, ``*_min`` of the fastest blocks (the
    least disturbed on a loaded machine); >= 1: slower than the floor."""

    label: str = ""
    decimation: int = 0
    ratio_to_physics: float | None = None
    ratio_to_physics_min: float | None = None
    ratio_to_torchrl: float | None = None
    ratio_to_torchrl_min: float | None = None
    ratio_to_torchrl_new: float | None = None
    ratio_to_torchrl_new_min: float | None = None


class TrivialEnv(EnvBase):
    """Batch [N] env with the lean task env's keys: an [N, D] observation, an [N, 1] long
    termination_reason, [N, A] action in [-1, 1], [N, 1] reward and done flags, whose ``_step`` and
    ``_reset`` return preallocated tensors (no per-step work of its own), or with ``new_outputs`` new
    copies of them at every step (what a rollout can keep)."""

    def __init__(self, num_envs: int, obs_dim: int, action_dim: int, device: str,
                 new_outputs: bool = False) -> None:
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.new_outputs = new_outputs
        n = num_envs
        self.observation_spec = Composite(
            observation=Unbounded(shape=(n, obs_dim), device=device),
            termination_reason=Categorical(len(TERMINATION_REASONS), shape=(n, 1), dtype=torch.long,
                                           device=device),
            shape=(n,), device=device)
        self.action_spec = Bounded(-1.0, 1.0, shape=(n, action_dim), device=device)
        self.reward_spec = Unbounded(shape=(n, 1), device=device)
        flags = ("done", "terminated", "truncated")
        self.done_spec = Composite({k: Categorical(2, shape=(n, 1), dtype=torch.bool, device=device)
                                    for k in flags}, shape=(n,), device=device)
        self._out = {"observation": torch.zeros(n, obs_dim, device=device),
                     "termination_reason": torch.zeros(n, 1, dtype=torch.long, device=device),
                     "reward": torch.zeros(n, 1, device=device),
                     **{k: torch.zeros(n, 1, dtype=torch.bool, device=device) for k in flags}}

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs: Any) -> TensorDictBase:
        fields = {k: v for k, v in self._out.items() if k != "reward"}
        return TensorDict(fields, batch_size=self.batch_size, device=self.device)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        # Unchecked, as TorchRL's own Gym-like envs and the lean FixedWingEnv build their outputs.
        out = {k: v.clone() for k, v in self._out.items()} if self.new_outputs else dict(self._out)
        return TensorDict._new_unsafe(out, batch_size=self.batch_size, device=self.device)

    def _set_seed(self, seed: int | None) -> None:
        """Nothing to seed."""


def fused_stepper(env: Any, graph: bool = False) -> Callable[[], None]:
    """A call that runs ``env``'s one-launch step with a zero action (no TorchRL, no reset, no copy),
    with ``graph`` as a replay of the step captured in a CUDA graph (``FusedEnvStep.cuda_graph``);
    raises when the env has none (not the warp backend, or a task without a fused step) or, with
    ``graph``, is not on CUDA."""
    stepper = env.env_stepper()
    if stepper is None:
        raise ValueError("no one-launch env step (needs the warp backend and a task with a fused step)")
    env.reset()
    action = env.action_spec.zero()
    if graph:
        stepper.raw_action.copy_(action)
        for _ in range(3):  # load the CUDA kernels before the capture records them
            stepper.launch()
        return stepper.cuda_graph()

    def step() -> None:
        env.step_tensors(action, with_state=False, copy=False)

    return step


def partial_resetter(env: Any) -> Callable[[], None]:
    """A call that resets one env of ``env`` (``reset_tensors`` with a one-row mask, as the lean env's
    TorchRL reset calls it; the row moves on by one each call), after a full reset."""
    env.reset()
    n = env.config.num_envs
    state = {"row": 0}

    def reset() -> None:
        state["row"] = (state["row"] + 1) % n
        mask = torch.zeros(n, dtype=torch.bool, device=env.device)
        mask[state["row"]] = True
        env.reset_tensors(mask, with_state=False)

    return reset


def build_steppers(args: argparse.Namespace, n: int) -> tuple[dict[str, Callable[[], None] | str], int]:
    """Case label -> step call (or an error line), and the decimation the env resolved."""
    common = {"num_envs": n, "backend": args.backend, "device": args.device, "seed": 0,
              "decimation": args.decimation, "warp_cpu_threads": args.warp_threads}
    base = make_env(args.task, args.airframe, **common)
    decimation = int(base.config.decimation)
    steppers: dict[str, Callable[[], None] | str] = {}
    for label, (kind, options) in CASES.items():
        if args.cases and label not in args.cases:
            continue
        try:
            if kind.startswith("physics"):  # the base env's simulator, stepped alone (or a second one)
                sim = (base if kind == "physics" else make_env(args.task, args.airframe, **common)).sim
                sim.check_inputs = kind == "physics checked"
                command = sim.command.clone()
                steppers[label] = lambda sim=sim, command=command: sim.step(command, substeps=decimation)
            elif kind.startswith("torchrl"):
                floor = TrivialEnv(n, base.observation_spec["observation"].shape[-1],
                                   base.action_spec.shape[-1], args.device, new_outputs=kind == "torchrl new")
                steppers[label] = env_stepper(floor)
            elif kind == "reset":
                steppers[label] = partial_resetter(make_env(args.task, args.airframe, **common, **options))
            elif kind.startswith("fused"):
                env = make_env(args.task, args.airframe, **common, **options)
                steppers[label] = fused_stepper(env, graph=kind == "fused graph")
            else:
                steppers[label] = env_stepper(make_env(args.task, args.airframe, **common, **options))
        except Exception as exc:  # an option the env does not have yet: report, keep the others
            steppers[label] = f"{type(exc).__name__}: {exc}".splitlines()[0][:200]
    return steppers, decimation


def _new_case(args: argparse.Namespace, label: str, n: int, decimation: int) -> EnvStepCase:
    """An untimed case: target "simulator", "torchrl" or "env"; the floor's backend is the trivial env."""
    kind = CASES[label][0]
    target = "simulator" if kind.startswith("physics") else kind.split()[0]
    backend = "trivial EnvBase" if kind.startswith("torchrl") else args.backend
    return EnvStepCase(target, backend, args.device, n, 0, args.trials, label=label, decimation=decimation)


def time_cases(args: argparse.Namespace, n: int, bar: tqdm) -> list[EnvStepCase]:
    """Build every case at ``n`` envs and time them in interleaved rounds."""
    steppers, decimation = build_steppers(args, n)
    cases = {label: _new_case(args, label, n, decimation) for label in steppers}
    blocks: dict[str, list[float]] = {label: [] for label in steppers}
    warmup_s: dict[str, float] = {}
    for label, step in steppers.items():  # warm-up, then the block length from a short probe
        bar.set_postfix_str(f"{n} envs, {label} (warm-up)")
        if isinstance(step, str):
            cases[label].error = step
            bar.update(args.trials)
            continue
        warmup_s[label] = _time_blocks(step, 0, 0, args.warmup, args.device)[1]
        probe = _time_blocks(step, 5, 1, 0, args.device)[0][0] / 5
        cases[label].steps = max(args.steps, math.ceil(args.block_s / max(probe, 1e-9)))
    labels = [label for label in steppers if label in warmup_s]
    for round_ in range(args.trials):
        shift = round_ % max(len(labels), 1)
        for label in labels[shift:] + labels[:shift]:
            bar.set_postfix_str(f"{n} envs, {label}, round {round_ + 1}")
            blocks[label] += _time_blocks(steppers[label], cases[label].steps, 1, 0, args.device)[0]
            bar.update()
    for label in labels:
        cases[label].finish(blocks[label], warmup_s[label])
    _set_ratios(cases)
    return list(cases.values())


def _set_ratios(cases: dict[str, EnvStepCase]) -> None:
    """Each timed case's ratios to the physics floor and to the TorchRL floors (where those were timed)."""
    for name, ref_label in (("physics", "physics"), ("torchrl", "torchrl floor"),
                            ("torchrl_new", "torchrl floor (new outputs)")):
        ref = cases.get(ref_label)
        if ref is None or ref.error is not None:
            continue
        for case in cases.values():
            if case.error is None:
                setattr(case, f"ratio_to_{name}", case.median_s / ref.median_s)
                setattr(case, f"ratio_to_{name}_min", case.min_s / ref.min_s)


def format_table(doc: dict[str, Any]) -> str:
    """Markdown table of a run: one row per case and env count; ratios "median (fastest blocks)"."""
    lines = ["| case | envs | ms/step | min-max ms | env-steps/s | x physics | x TorchRL floor "
             "| x floor (new outputs) |", "|---|---:|---:|---|---:|---:|---:|---:|"]

    def ratio(c: dict[str, Any], name: str) -> str:
        median, fastest = c.get(f"ratio_to_{name}"), c.get(f"ratio_to_{name}_min")
        return "-" if median is None else f"{median:.2f} ({fastest:.2f})"

    for c in doc["cases"]:
        if c["error"]:
            lines.append(f"| {c['label']} | {c['num_envs']:,} | error: {c['error']} | | | | | |")
            continue
        ms = [c[k] * 1e3 for k in ("median_s", "min_s", "max_s")]
        lines.append(f"| {c['label']} | {c['num_envs']:,} | {ms[0]:.3f} | {ms[1]:.3f}-{ms[2]:.3f} | "
                     f"{c['env_steps_per_s']:,.0f} | {ratio(c, 'physics')} | {ratio(c, 'torchrl')} | "
                     f"{ratio(c, 'torchrl_new')} |")
    return "\n".join(lines)


def profile_env_step(args: argparse.Namespace, steps: int = 500, top: int = 20) -> str:
    """cProfile of ``steps`` steps of the 1-env ``env`` case (after a warm-up): the ``top`` functions
    by cumulative time."""
    step = env_stepper(make_env(args.task, args.airframe, num_envs=1, backend=args.backend,
                                device=args.device, seed=0, decimation=args.decimation,
                                warp_cpu_threads=args.warp_threads))
    for _ in range(max(args.warmup, 20)):
        step()
    profiler = cProfile.Profile()
    profiler.enable()
    for _ in range(steps):
        step()
    profiler.disable()
    text = io.StringIO()
    pstats.Stats(profiler, stream=text).strip_dirs().sort_stats("cumulative").print_stats(top)
    head = f"cProfile of {steps} steps of the 1-env env step (top {top} by cumulative time)"
    return f"{head}\n{text.getvalue()}"


def _versions() -> dict[str, str]:
    """Versions of the packages on the timed path."""
    from importlib.metadata import PackageNotFoundError, version

    found = {}
    for name in ("torch", "torchrl", "tensordict", "warp-lang"):
        try:
            found[name] = version(name)
        except PackageNotFoundError:
            found[name] = "absent"
    return found


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line options (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--envs", default=None, help="comma list of env counts (default: 1,64,1024,4096; "
                        "on cuda also 65536,1048576)")
    parser.add_argument("--decimation", type=int, default=None, help="physics steps per env step "
                        "(default: the task's)")
    parser.add_argument("--cases", default=None, help=f"comma list, default all: {', '.join(CASES)}")
    parser.add_argument("--trials", type=int, default=5, help="timed rounds (blocks per case)")
    parser.add_argument("--steps", type=int, default=20, help="fewest env steps per block")
    parser.add_argument("--block-s", type=float, default=0.3, help="seconds a block should last at least")
    parser.add_argument("--warmup", type=int, default=10)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    parser.add_argument("--warp-threads", type=int, default=None, help="warp CPU threads (default: per core)")
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results/env_step"))
    parser.add_argument("--no-progress", action="store_true")
    parser.add_argument("--profile", action="store_true", help="also print a cProfile of the 1-env env step")
    args = parser.parse_args(argv)
    default_envs = "1,64,1024,4096" + (",65536,1048576" if args.device.startswith("cuda") else "")
    args.env_counts = [int(v) for v in (args.envs or default_envs).split(",")]
    args.cases = None if args.cases is None else [c.strip() for c in args.cases.split(",")]
    unknown = set(args.cases or ()) - set(CASES)
    if unknown or args.trials < 1:
        parser.error(f"unknown cases {sorted(unknown)}" if unknown else "--trials must be >= 1")
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the cases, print the table, write ``env_step.json`` and ``env_step.png`` under ``--out``."""
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    load_before = os.getloadavg()[0]
    cases_per_n = len(args.cases or CASES)
    bar = tqdm(total=len(args.env_counts) * cases_per_n * args.trials, desc="env step",
               disable=args.no_progress, file=sys.stderr)
    results: list[EnvStepCase] = []
    for n in args.env_counts:
        results += time_cases(args, n, bar)
        if args.device.startswith("cuda"):
            torch.cuda.empty_cache()
    bar.close()
    doc = {"task": args.task, "airframe": args.airframe, "backend": args.backend, "device": args.device,
           "decimation": results[0].decimation if results else args.decimation, "dt": 0.01,
           "integrator": "rk4", "cpu": _cpu_name(), "torch_threads": torch.get_num_threads(),
           "warp_cpu_threads": args.warp_threads, "trials": args.trials, "versions": _versions(),
           "load_average_1min": [load_before, os.getloadavg()[0]],  # before and after, other processes'
           "cases": [asdict(c) for c in results]}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "env_step.json").write_text(json.dumps(doc, indent=1) + "\n")
    plot_doc = {**doc, "integrator": f"rk4 x{doc['decimation']} per env step",
                "cases": [{**c, "target": c["label"]} for c in doc["cases"]]}
    plot(plot_doc, args.out / "env_step.png")
    print(f"{args.task} on {args.airframe}, {args.backend} on {args.device} ({doc['cpu']}), "
          f"decimation {doc['decimation']}, median of {args.trials} interleaved blocks (min-max), "
          f"1-min load average {load_before:.1f} -> {doc['load_average_1min'][1]:.1f}\n")
    print(format_table(doc))
    print(f"\nwrote {args.out / 'env_step.json'} and {args.out / 'env_step.png'}")
    if args.profile:
        print("\n" + profile_env_step(args))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
