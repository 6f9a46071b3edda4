"""``falcon-rl bench``: env-steps per second per backend and env count (optionally vs JSBSim)."""

from __future__ import annotations

import argparse

from ..defaults import BATCH_BACKENDS, DEFAULT_AIRFRAME
from ._common import (
    UsageError,
    bounded_float,
    bounded_int,
    check_device,
    comma_list,
    emit,
    nonnegative_int,
    output_dir,
    positive_int,
)

NAME = "bench"
HELP = "time Simulator.step (and the TorchRL env) per backend and env count, optionally vs JSBSim"

#: Most envs of one case (a batch beyond it is a typo that would exhaust memory, not a benchmark).
MAX_ENVS = 1 << 20
_env_count = bounded_int(1, MAX_ENVS)


def bench_backends() -> tuple[str, ...]:
    """The registered engines (``physics.backends.ENGINES``) plus ``<name>-compile`` for each engine that
    steps through ``torch.compile`` (its ``compile`` option)."""
    from ..evaluation.bench import COMPILED_SUFFIX
    from ..physics.backends import ENGINES, engine_class

    compiled = (name + COMPILED_SUFFIX for name in ENGINES if "compile" in engine_class(name).OPTIONS)
    return (*ENGINES, *compiled)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--backend", default=",".join(BATCH_BACKENDS),
                        help="comma list of registered backends (torch, warp, scipy, ...) and torch-compile "
                             "(torch through torch.compile)")
    parser.add_argument("--envs", default="1,64,1024,4096",
                        help=f"comma list of env counts (1 to {MAX_ENVS})")
    parser.add_argument("--steps", type=positive_int, default=100, help="steps per timed trial")
    parser.add_argument("--trials", type=bounded_int(5, 10**6), default=5,
                        help="timed trials per case (>= 5)")
    parser.add_argument("--warmup", type=nonnegative_int, default=10, help="untimed steps before the trials")
    parser.add_argument("--device", default="cpu", help="cpu or cuda")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--integrator", default="rk4", choices=("rk4", "euler"))
    parser.add_argument("--dt", type=bounded_float(0.0, 0.1, "s"), default=0.01, help="s (default 0.01)")
    parser.add_argument("--baseline", choices=("jsbsim",), default=None,
                        help="also time JSBSim's c172p at the same dt and print ratios to it")
    parser.add_argument("--threads", type=bounded_int(1, 4096), default=None,
                        help="torch CPU threads (default: torch's)")
    parser.add_argument("--warp-threads", type=bounded_int(1, 4096), default=None,
                        help="CPU threads stepping a warp batch (default: one per core, >= 512 envs each)")
    parser.add_argument("--no-env", action="store_true", help="time Simulator.step only")
    parser.add_argument("--out", default=None, help="write bench.json and bench.png here")


def _parse(args: argparse.Namespace) -> tuple[list[str], list[int]]:
    """(backends, env counts) of the flags; UsageError for a bad one (checked before anything is timed)."""
    backends = comma_list(args.backend, "--backend", bench_backends())
    try:
        envs = [_env_count(n) for n in comma_list(args.envs, "--envs")]
    except argparse.ArgumentTypeError as exc:
        raise UsageError(f"--envs must be a comma list of env counts: {exc}") from None
    check_device(args.device)
    if args.baseline == "jsbsim":
        try:
            import jsbsim  # noqa: F401
        except ImportError:
            raise UsageError("--baseline jsbsim needs the jsbsim package (pip install jsbsim)") from None
    return backends, envs


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..evaluation.bench import BenchConfig, format_table, plot, run_bench

    backends, envs = _parse(args)
    load_airframe(args.airframe)  # fail early on a bad name
    out = None if args.out is None else output_dir(args.out)
    if args.threads is not None:
        import torch

        torch.set_num_threads(args.threads)
    cfg = BenchConfig(backends=backends, env_counts=envs, steps=args.steps, trials=args.trials,
                      warmup=args.warmup, device=args.device, airframe=args.airframe, dt=args.dt,
                      integrator=args.integrator, baseline=args.baseline, include_env=not args.no_env,
                      warp_cpu_threads=args.warp_threads)
    doc = run_bench(cfg)
    text = format_table(doc)
    if out is not None:
        import json

        (out / "bench.json").write_text(json.dumps(doc, indent=2))
        doc["figure"] = str(plot(doc, out / "bench.png"))
        text += f"\n\nwrote {out / 'bench.json'} and {doc['figure']}"
    emit(args, doc, text)
    return 0
