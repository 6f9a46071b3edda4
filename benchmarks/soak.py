"""Soak test: a long run of the TorchRL env with every robustness option on and hostile random
actions, checking that no NaN or Inf ever leaves the env, that memory stays flat over the
auto-resets, and counting the terminations by reason.

    python benchmarks/soak.py --env-steps 1e8 --envs 4096 --backend warp --out benchmarks/results/soak

Env: the altitude task on the Volantex Ranger, sensors "severe", observation delay 0-80 ms and
action delay 0-100 ms drawn per episode, domain randomisation, "moderate" Dryden turbulence and a
steady wind. Actions: uniform in [-1.2, 1.2] with, per element and step, probability ``--bad`` each
of NaN, +-inf and +-1e30. The loop is TorchRL's ``step_and_maybe_reset`` (auto-reset of done envs).
Every ``--check-every`` steps it checks every float leaving the env for non-finite numbers and
samples the process RSS. Writes ``soak.json`` and ``soak.png`` (RSS over env-steps; terminations by
reason) to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import time
from pathlib import Path

import torch
from tensordict import TensorDictBase
from tqdm import tqdm

from falcon_rl import make_env
from falcon_rl.envs.tasks import TERMINATION_REASONS


def rss_mib() -> float:
    """Resident set size of this process now, MiB (Linux /proc; ru_maxrss elsewhere)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def hostile_actions(shape: torch.Size, bad: float, generator: torch.Generator) -> torch.Tensor:
    """Uniform actions in [-1.2, 1.2] with NaN, +-inf and +-1e30 elements, each with probability
    ``bad`` per element."""
    action = torch.rand(shape, generator=generator) * 2.4 - 1.2
    pick = torch.rand(shape, generator=generator)
    sign = torch.where(torch.rand(shape, generator=generator) < 0.5, -1.0, 1.0)
    action = torch.where(pick < bad, torch.full_like(action, math.nan), action)
    action = torch.where((pick >= bad) & (pick < 2 * bad), sign * math.inf, action)
    return torch.where((pick >= 2 * bad) & (pick < 3 * bad), sign * 1e30, action)


def non_finite_count(td: TensorDictBase) -> int:
    """Number of NaN or Inf numbers among the floats of ``td`` (the action entry excluded: it is the
    input)."""
    total = 0
    for key in td.keys(True, True):
        if key == "action" or (isinstance(key, tuple) and key[-1] == "action"):
            continue
        value = td.get(key)
        if isinstance(value, torch.Tensor) and value.is_floating_point():
            total += int((~torch.isfinite(value)).sum())
    return total


def soak(env_steps: float, num_envs: int, backend: str, seed: int, bad: float, check_every: int) -> dict:
    env = make_env("altitude", "volantex_ranger", num_envs=num_envs, backend=backend, seed=seed,
                   sensors="severe", obs_delay_ms=(0.0, 80.0), action_delay_ms=(0.0, 100.0), randomize=True,
                   turbulence="moderate", wind=(3.0, -2.0, 0.0))
    generator = torch.Generator().manual_seed(seed)
    steps = max(1, math.ceil(env_steps / num_envs))
    reasons = torch.zeros(len(TERMINATION_REASONS), dtype=torch.long)
    truncations, non_finite_out = 0, 0
    rss_trace: list[tuple[int, float]] = []
    td = env.reset()
    rss_start = rss_mib()
    start = time.perf_counter()
    for step in tqdm(range(steps), desc=f"soak {num_envs} envs", unit="step", mininterval=5.0):
        td["action"] = hostile_actions(env.action_spec.shape, bad, generator)
        out, td = env.step_and_maybe_reset(td)
        nxt = out["next"]
        code = nxt["termination_reason"][:, 0]
        reasons += torch.bincount(code, minlength=len(TERMINATION_REASONS))
        truncations += int(nxt["truncated"].sum())
        if step % check_every == 0 or step == steps - 1:
            non_finite_out += non_finite_count(out) + non_finite_count(td)
            rss_trace.append(((step + 1) * num_envs, rss_mib()))
    wall = time.perf_counter() - start
    reasons[0] = 0  # "none" counts the env-steps that did not terminate; not a termination
    return {
        "env_steps": steps * num_envs, "envs": num_envs, "backend": backend, "seed": seed,
        "bad_probability": bad, "wall_s": wall, "env_steps_per_s": steps * num_envs / wall,
        "rss_start_mib": rss_start, "rss_end_mib": rss_trace[-1][1],
        "rss_max_mib": max(r for _, r in rss_trace), "rss_trace": rss_trace,
        "non_finite_out": non_finite_out, "checks": len(rss_trace), "truncations": truncations,
        "terminations": {name: int(reasons[i]) for i, name in enumerate(TERMINATION_REASONS) if i > 0},
    }


def plot(result: dict, path: Path) -> Path:
    """RSS over env-steps and terminations by reason, side by side."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.8))
    steps, rss = zip(*result["rss_trace"], strict=True)
    left.plot([s / 1e6 for s in steps], rss, lw=1.2)
    left.set_xlabel("env-steps (M)")
    left.set_ylabel("RSS (MiB)")
    left.set_ylim(0, max(rss) * 1.2)
    left.set_title(f"memory: {result['rss_start_mib']:.0f} -> {result['rss_end_mib']:.0f} MiB")
    names = list(result["terminations"])
    right.barh(names, [max(result["terminations"][n], 0) for n in names])
    right.set_xscale("symlog")
    right.set_xlabel("terminations")
    right.set_title(f"{result['env_steps'] / 1e6:.0f} M env-steps, {result['non_finite_out']} non-finite out")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env-steps", type=float, default=1e8)
    parser.add_argument("--envs", type=int, default=4096)
    parser.add_argument("--backend", default="warp")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--bad", type=float, default=1e-4, help="probability of each hostile value")
    parser.add_argument("--check-every", type=int, default=100, help="steps between NaN checks and RSS")
    parser.add_argument("--threads", type=int, default=1, help="torch intra-op threads")
    parser.add_argument("--out", default="benchmarks/results/soak")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    result = soak(args.env_steps, args.envs, args.backend, args.seed, args.bad, args.check_every)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "soak.json").write_text(json.dumps(result, indent=2))
    plot(result, out / "soak.png")
    summary = {k: v for k, v in result.items() if k != "rss_trace"}
    print(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
