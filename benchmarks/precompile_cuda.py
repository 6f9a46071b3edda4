"""Compile the CUDA kernels of task envs ahead of time, on any machine (no GPU needed), into Warp's kernel
cache, so that a GPU run of the same code and Warp version starts without compiling.

    python benchmarks/precompile_cuda.py --arch 90 --tasks altitude          # H100 / H200 (sm_90)
    WARP_CACHE_PATH=cache python benchmarks/precompile_cuda.py --arch 80     # A100, into ./cache

A cold CUDA compile is long: the physics module and each task's one-launch env step inline the RK4
sub-steps of the whole flight model (on a 2-core AMD EPYC host, NVRTC took 342 s for the physics module
and 301 s for the altitude env step, forward kernels only). Warp keys its cache by module contents and
options, and CUDA launches use a block of 256 threads (CPU launches one), so the modules are hashed as
a CUDA launch hashes them. Copy the cache folder to the GPU machine (``~/.cache/warp`` or the
``WARP_CACHE_PATH`` it runs with).

Per task: an env is built on the CPU to find its kernels, then the physics module, the one-launch env
step's module and the task's fused step's module are compiled for
``--arch``: CUBIN by default (what Warp loads when the driver is older than its CUDA toolkit), PTX with
``--ptx`` (what it loads otherwise).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import warp as wp
from tqdm import tqdm

from falcon_rl import make_env
from falcon_rl.defaults import DEFAULT_AIRFRAME


def task_modules(task: str, airframe: str) -> list[Any]:
    """The Warp modules an env of ``task`` launches on the warp backend: the physics, and the task's
    one-launch env step and fused task step where it has them (the kernels exist from import on)."""
    env = make_env(task, airframe, num_envs=1, backend="warp", seed=0, lean=True)
    modules = [wp.get_module("falcon_rl.physics.warp_kernels")]
    stepper = env.env_stepper()
    if stepper is not None:
        modules += [stepper.kernel.module, stepper.task_step.kernel.module]
    return modules


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--arch", type=int, required=True, help="CUDA compute capability x 10, e.g. 90")
    parser.add_argument("--tasks", default="altitude", help="comma list of tasks")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--ptx", action="store_true", help="PTX instead of CUBIN")
    args = parser.parse_args(argv)
    modules: dict[str, Any] = {}
    for task in args.tasks.split(","):
        for module in task_modules(task.strip(), args.airframe):
            modules.setdefault(module.name, module)
    bar = tqdm(list(modules.values()), desc=f"CUDA sm_{args.arch}", unit="module")
    for module in bar:
        bar.set_postfix_str(module.name[-40:])
        start = time.perf_counter()
        paths = wp.compile_aot_module(module, arch=args.arch, use_ptx=args.ptx)
        bar.write(f"{module.name}: {time.perf_counter() - start:.0f} s -> {paths[0].parent}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
