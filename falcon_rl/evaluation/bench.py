"""Throughput benchmark: env-steps per second of ``Simulator.step`` (and of the TorchRL env's
``step`` when available) per backend and env count, optionally against JSBSim's c172p.

Method: each case builds a simulator, runs ``warmup`` steps (kernel compilation, caches, allocator),
then times ``trials`` (>= 5) blocks of ``steps`` calls with ``time.perf_counter``; on CUDA the device
is synchronised before and after each block. A step is one Python call advancing all N envs by dt
with a fixed command (input checks off: they cost a host sync and are not part of the model). The
figure reported is the median block time per step; the spread is the min-max range over trials.
JSBSim runs one aircraft per ``FGFDMExec.run()`` call from Python at the same dt.
"""

from __future__ import annotations

import contextlib
import os
import statistics
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch

from ..defaults import BATCH_BACKENDS, DEFAULT_AIRFRAME
from ..physics.backends import runs_batches
from ..physics.simulator import Simulator

JSBSIM_MODEL = "c172p"


@dataclass
class BenchCase:
    """One timed configuration and its result (times in seconds per step call)."""

    target: str  # "simulator", "env" or "jsbsim"
    backend: str
    device: str
    num_envs: int
    steps: int
    trials: int
    median_s: float = float("nan")
    min_s: float = float("nan")
    max_s: float = float("nan")
    env_steps_per_s: float = float("nan")
    ratio_to_jsbsim: float | None = None
    warmup_s: float = float("nan")  # untimed warm-up (kernel load, torch.compile), seconds
    error: str | None = None

    def finish(self, block_times: list[float], warmup_s: float = float("nan")) -> BenchCase:
        self.warmup_s = warmup_s
        per_step = [t / self.steps for t in block_times]
        self.median_s = statistics.median(per_step)
        self.min_s, self.max_s = min(per_step), max(per_step)
        self.env_steps_per_s = self.num_envs / self.median_s
        return self


@dataclass
class BenchConfig:
    """What to time. ``backends``: registered backends, and ``<backend>-compile`` for a backend stepping
    through ``torch.compile`` (one whose engine takes the ``compile`` option); ``baseline`` None or
    "jsbsim";
    ``warp_cpu_threads`` None (one per core) or the threads of a warp batch on the CPU."""

    backends: list[str]
    env_counts: list[int]
    steps: int = 100
    trials: int = 5
    warmup: int = 10
    device: str = "cpu"
    airframe: str = DEFAULT_AIRFRAME
    dt: float = 0.01
    integrator: str = "rk4"
    baseline: str | None = None
    include_env: bool = True
    progress: bool = True
    warp_cpu_threads: int | None = None
    cases: list[BenchCase] = field(default_factory=list)


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def _time_blocks(step: Callable[[], Any], steps: int, trials: int, warmup: int, device: str
                 ) -> tuple[list[float], float]:
    """(block times of the trials, warm-up time), seconds."""
    start = time.perf_counter()
    for _ in range(warmup):
        step()
    _sync(device)
    warmup_s = time.perf_counter() - start
    blocks = []
    for _ in range(trials):
        _sync(device)
        start = time.perf_counter()
        for _ in range(steps):
            step()
        _sync(device)
        blocks.append(time.perf_counter() - start)
    return blocks, warmup_s


def step_contents(sim: Simulator) -> str:
    """One line describing what a single ``Simulator.step`` computes."""
    stages = {"rk4": 4, "euler": 1}.get(sim.integrator, 0)
    integ = f"{sim.integrator} ({stages} derivative evaluations)" if stages else "solve_ivp RK45"
    ge = {0: "off", 1: "induced-drag form", 2: "paper form", 3: "JSBSim tables"}[
        int(sim.params.ground_effect_mode[0])]
    af = sim.airframe
    aero = (f"tabulated aero ({len(af.tables.terms)} table terms)" if af.aero.kind == "tabulated" else
            f"monomial aero ({sim.params.aero_exponents.shape[0]} terms, rates)")
    thrust = "thrust-map" if any(m.model == "thrust_map" for m in af.motors) else "momentum-theory"
    return (f"6DoF rigid body + ISA atmosphere + {aero} + Phillips-Hunsaker ground effect ({ge}) + "
            f"{af.num_motors} motor(s) {thrust} thrust + 2nd/1st-order actuators; {integ}, "
            f"dt = {sim.dt:g} s, "
            f"quaternion renormalisation and actuator saturation; airframe {sim.airframe.name}")


#: The suffix of a case that steps its backend through ``torch.compile`` (``<backend>-compile``).
COMPILED_SUFFIX = "-compile"


def compiled_variant(case: str) -> tuple[str, bool]:
    """(backend, compiled) of a bench case name: ``"<backend>-compile"`` -> (backend, True)."""
    if case.endswith(COMPILED_SUFFIX):
        return case[: -len(COMPILED_SUFFIX)], True
    return case, False


def time_simulator(cfg: BenchConfig, backend: str, num_envs: int) -> tuple[BenchCase, str]:
    """Time raw ``Simulator.step``; returns the case and the step description."""
    case = BenchCase("simulator", backend, cfg.device, num_envs, cfg.steps, cfg.trials)
    engine, compiled = compiled_variant(backend)
    sim = Simulator(cfg.airframe, num_envs=num_envs, backend=engine, device=cfg.device, dt=cfg.dt,
                    integrator=cfg.integrator, check_inputs=False, warp_cpu_threads=cfg.warp_cpu_threads,
                    compile=compiled)
    command = sim.command.clone()
    steps = cfg.steps if runs_batches(engine) else max(1, cfg.steps // 10)  # a one-env reference: slow
    case.steps = steps
    blocks, warmup_s = _time_blocks(lambda: sim.step(command), steps, cfg.trials, max(cfg.warmup, 2),
                                    cfg.device)
    return case.finish(blocks, warmup_s), step_contents(sim)


def env_stepper(env: Any) -> Callable[[], None]:
    """A call that steps a TorchRL env once with a zero action, as a rollout does
    (``step_and_maybe_reset``, the next TensorDict carried over); the env is reset first."""
    td = env.reset()
    action = env.action_spec.zero()
    td["action"] = action
    state = {"td": td}

    def step() -> None:
        _, nxt = env.step_and_maybe_reset(state["td"])
        nxt["action"] = action
        state["td"] = nxt

    return step


def time_env(cfg: BenchConfig, backend: str, num_envs: int) -> BenchCase | None:
    """Time the TorchRL "altitude" env's ``step_and_maybe_reset`` (None if envs are unavailable)."""
    try:
        from ..envs import make_env
    except (ImportError, AttributeError):
        return None
    case = BenchCase("env", backend, cfg.device, num_envs, cfg.steps, cfg.trials)
    try:
        env = make_env("altitude", cfg.airframe, num_envs=num_envs, backend=backend, device=cfg.device,
                       seed=0, decimation=1)  # one physics step per env step, as the simulator rows
        blocks, warmup_s = _time_blocks(env_stepper(env), cfg.steps, cfg.trials, cfg.warmup, cfg.device)
    except Exception as exc:  # the env is optional here: report, do not fail the bench
        case.error = f"{type(exc).__name__}: {exc}".splitlines()[0][:200]
        return case
    return case.finish(blocks, warmup_s)


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence stdout at the file-descriptor and the Python level (JSBSim prints a banner, through
    either depending on how its bindings were built) so that --json output stays one document."""
    import io
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as devnull, contextlib.redirect_stdout(io.StringIO()):
            os.dup2(devnull.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def time_jsbsim(cfg: BenchConfig, when: str = "") -> BenchCase:
    """JSBSim c172p, one aircraft, trimmed cruise at 3000 ft, ``FGFDMExec.run()`` per step;
    ``when`` tags the case (the baseline is timed before and after the other cases)."""
    import jsbsim

    backend = f"jsbsim-{JSBSIM_MODEL}" + (f" {when}" if when else "")
    case = BenchCase("jsbsim", backend, "cpu", 1, cfg.steps * 10, cfg.trials)
    with _quiet_stdout():
        fdm = jsbsim.FGFDMExec(jsbsim.get_default_root_dir())
        fdm.set_debug_level(0)
        fdm.load_model(JSBSIM_MODEL)
        fdm.set_dt(cfg.dt)
        fdm["ic/h-sl-ft"] = 3000.0
        fdm["ic/vc-kts"] = 100.0
        fdm.run_ic()
        fdm["propulsion/set-running"] = -1
        fdm["fcs/throttle-cmd-norm"] = 0.7
    blocks = []
    for _ in range(cfg.trials):
        with _quiet_stdout():
            fdm.reset_to_initial_conditions(0)
        for _ in range(cfg.warmup):
            fdm.run()
        start = time.perf_counter()
        for _ in range(case.steps):
            fdm.run()
        blocks.append(time.perf_counter() - start)
    return case.finish(blocks)


def run_bench(cfg: BenchConfig) -> dict[str, Any]:
    """Run every case of ``cfg`` and return a JSON-able document (cases in ``cfg.cases``)."""
    from tqdm import tqdm

    batches = {b: runs_batches(compiled_variant(b)[0]) for b in cfg.backends}
    plan = [(b, n) for b in cfg.backends for n in cfg.env_counts if batches[b] or n == 1]
    skipped = [f"{b}:{n}" for b in cfg.backends for n in cfg.env_counts if not (batches[b] or n == 1)]
    contents = ""
    if cfg.baseline == "jsbsim":
        cfg.cases.append(time_jsbsim(cfg, "before"))
    bar = tqdm(plan, desc="bench", disable=not cfg.progress, file=__import__("sys").stderr)
    for backend, n in bar:
        bar.set_postfix_str(f"{backend} x {n}")
        case, contents = time_simulator(cfg, backend, n)
        cfg.cases.append(case)
        if cfg.include_env and backend in BATCH_BACKENDS:
            env_case = time_env(cfg, backend, n)
            if env_case is not None:
                cfg.cases.append(env_case)
    if cfg.baseline == "jsbsim":
        # Timed again at the end: on a shared machine the load drifts over a run of minutes, and the
        # faster of the two JSBSim figures is the reference (the conservative ratio for falcon-rl).
        cfg.cases.append(time_jsbsim(cfg, "after"))
        reference = max(c.env_steps_per_s for c in cfg.cases if c.target == "jsbsim")
        for case in cfg.cases:
            if case.error is None:
                case.ratio_to_jsbsim = case.env_steps_per_s / reference
    return {
        "step_contents": contents,
        "airframe": cfg.airframe,
        "dt": cfg.dt,
        "integrator": cfg.integrator,
        "device": cfg.device,
        "torch_threads": torch.get_num_threads(),
        "warp_cpu_threads": cfg.warp_cpu_threads,
        "cpu": _cpu_name(),
        "trials": cfg.trials,
        "skipped": skipped,
        "cases": [asdict(c) for c in cfg.cases],
    }


def _cpu_name() -> str:
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return f"{line.split(':', 1)[1].strip()} ({os.cpu_count()} cores)"
    except OSError:
        pass
    return f"{platform.machine()} ({os.cpu_count()} cores)"


def format_table(doc: dict[str, Any]) -> str:
    """Human-readable table of a :func:`run_bench` document."""
    lines = [f"one step = {doc['step_contents']}",
             f"device {doc['device']}, {doc['cpu']}, torch threads {doc['torch_threads']}, "
             f"median of {doc['trials']} trials (min-max)", ""]
    head = f"{'target':10} {'backend':19} {'envs':>7} {'ms/step':>10} {'min-max ms':>17} " \
           f"{'env-steps/s':>13} {'x JSBSim':>9}"
    lines += [head, "-" * len(head)]
    for c in doc["cases"]:
        if c["error"]:
            lines.append(f"{c['target']:10} {c['backend']:19} {c['num_envs']:>7} error: {c['error']}")
            continue
        ratio = f"{c['ratio_to_jsbsim']:.2f}" if c["ratio_to_jsbsim"] is not None else "-"
        spread = f"{c['min_s'] * 1e3:.3f}-{c['max_s'] * 1e3:.3f}"
        lines.append(f"{c['target']:10} {c['backend']:19} {c['num_envs']:>7} {c['median_s'] * 1e3:>10.3f} "
                     f"{spread:>17} {c['env_steps_per_s']:>13,.0f} {ratio:>9}")
    return "\n".join(lines)


def plot(doc: dict[str, Any], path: Path) -> Path:
    """Log-log env-steps/s against env count, one line per (target, backend); JSBSim as a level."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    series: dict[str, list[tuple[int, float]]] = {}
    for c in doc["cases"]:
        if c["error"] or c["target"] == "jsbsim":
            continue
        series.setdefault(f"{c['backend']} ({c['target']})", []).append(
            (c["num_envs"], c["env_steps_per_s"]))
    for label, pts in sorted(series.items()):
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=label)
    baselines = [c["env_steps_per_s"] for c in doc["cases"] if c["target"] == "jsbsim" and not c["error"]]
    if baselines:
        ax.axhline(max(baselines), color="k", ls="--", label=f"JSBSim {JSBSIM_MODEL} (1 env, faster of 2)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("parallel envs")
    ax.set_ylabel("env-steps / s")
    ax.set_title(f"{doc['airframe']}, {doc['integrator']}, dt = {doc['dt']:g} s, {doc['device']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
