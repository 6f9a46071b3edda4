"""``falcon-rl bench``: env-steps per second per backend and env count (optionally vs JSBSim)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import UsageError, emit

NAME = "bench"
HELP = "time Simulator.step (and the TorchRL env) per backend and env count, optionally vs JSBSim"

#: Not an engine of its own: the torch engine with ``compile=True``.
TORCH_COMPILE = "torch-compile"


def bench_backends() -> tuple[str, ...]:
    """The registered engines (``physics.backends.ENGINES``) plus torch-compile."""
    from ..physics.backends import ENGINES

    return (*ENGINES, TORCH_COMPILE)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--backend", default="torch,warp",
                        help="comma list of registered backends (torch, warp, scipy, ...) and torch-compile "
                             "(torch through torch.compile)")
    parser.add_argument("--envs", default="1,64,1024,4096", help="comma list of env counts")
    parser.add_argument("--steps", type=int, default=100, help="steps per timed trial")
    parser.add_argument("--trials", type=int, default=5, help="timed trials per case (>= 5)")
    parser.add_argument("--warmup", type=int, default=10, help="untimed steps before the trials")
    parser.add_argument("--device", default="cpu", help="cpu or cuda")
    parser.add_argument("--airframe", default="navion")
    parser.add_argument("--integrator", default="rk4", choices=("rk4", "euler"))
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--baseline", choices=("jsbsim",), default=None,
                        help="also time JSBSim's c172p at the same dt and print ratios to it")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's)")
    parser.add_argument("--warp-threads", type=int, default=None,
                        help="CPU threads stepping a warp batch (default: one per core, >= 512 envs each)")
    parser.add_argument("--no-env", action="store_true", help="time Simulator.step only")
    parser.add_argument("--out", type=Path, default=None, help="write bench.json and bench.png here")


def _parse(args: argparse.Namespace) -> tuple[list[str], list[int]]:
    backends = [b.strip() for b in args.backend.split(",") if b.strip()]
    known = bench_backends()
    bad = [b for b in backends if b not in known]
    if not backends or bad:
        raise UsageError(f"--backend must be a comma list of {', '.join(known)}; got {args.backend!r}")
    try:
        envs = [int(n) for n in args.envs.split(",") if n.strip()]
    except ValueError:
        raise UsageError(f"--envs must be a comma list of integers; got {args.envs!r}") from None
    if not envs or min(envs) < 1:
        raise UsageError(f"--envs must be positive integers; got {args.envs!r}")
    if args.steps < 1 or args.trials < 5 or args.warmup < 0 or not args.dt > 0:
        raise UsageError("need --steps >= 1, --trials >= 5, --warmup >= 0 and --dt > 0")
    if args.device not in ("cpu", "cuda") and not args.device.startswith("cuda:"):
        raise UsageError(f"--device must be cpu or cuda; got {args.device!r}")
    if args.device.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise UsageError("--device cuda requested but CUDA is not available")
    if args.threads is not None:
        if args.threads < 1:
            raise UsageError(f"--threads must be >= 1; got {args.threads}")
        import torch

        torch.set_num_threads(args.threads)
    if args.warp_threads is not None and args.warp_threads < 1:
        raise UsageError(f"--warp-threads must be >= 1; got {args.warp_threads}")
    if args.baseline == "jsbsim":
        try:
            import jsbsim  # noqa: F401
        except ImportError:
            raise UsageError("--baseline jsbsim needs the jsbsim package (pip install jsbsim)") from None
    return backends, envs


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..bench import BenchConfig, format_table, plot, run_bench

    backends, envs = _parse(args)
    load_airframe(args.airframe)  # fail early on a bad name
    cfg = BenchConfig(backends=backends, env_counts=envs, steps=args.steps, trials=args.trials,
                      warmup=args.warmup, device=args.device, airframe=args.airframe, dt=args.dt,
                      integrator=args.integrator, baseline=args.baseline, include_env=not args.no_env,
                      warp_cpu_threads=args.warp_threads)
    doc = run_bench(cfg)
    text = format_table(doc)
    if args.out is not None:
        import json

        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "bench.json").write_text(json.dumps(doc, indent=2))
        doc["figure"] = str(plot(doc, args.out / "bench.png"))
        text += f"\n\nwrote {args.out / 'bench.json'} and {doc['figure']}"
    emit(args, doc, text)
    return 0
