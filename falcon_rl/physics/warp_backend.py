"""Warp engine of the :class:`~falcon_rl.physics.simulator.Simulator` (``backend="warp"``).

The engine binds zero-copy Warp views of the simulator's tensors once (state, command, air motion,
parameters), records a launch of :func:`~falcon_rl.physics.warp_kernels.step_kernel` (one per CPU
slice, below) and replays it on every step: no host copies. ``Simulator.state`` replays a launch of
:func:`~falcon_rl.physics.warp_kernels.evaluate_kernel` into an engine-owned buffer. Parameters
written in place (domain randomisation through ``ModelParams.assign``) are seen by the next launch.
Replacing the whole ``ModelParams`` object, a state buffer, ``dt`` or ``integrator`` re-binds on the
next step; replacing a single parameter tensor re-binds at the next reset (or call
:meth:`WarpEngine.rebind`), which keeps that 30-tensor check off the per-step path.
On CUDA the launch is queued on torch's current stream, so no synchronisation is needed.
On the CPU a Warp kernel runs serially on one core; batches of at least ``2 * MIN_ENVS_PER_THREAD``
envs are split into contiguous chunks (``CHUNKS_PER_THREAD`` per thread), one recorded launch per
chunk, which parallel threads take from a shared queue (a CPU launch is a ctypes call, which
releases the GIL). ``Simulator(warp_cpu_threads=...)`` overrides the default of one thread per
available core.
With turbulence on, the kernel also advances the Dryden filters (``sim.turbulence``); the step
counter of its noise streams is a device tensor bumped by torch before each launch.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor
from queue import Empty, SimpleQueue
from typing import TYPE_CHECKING, Any

import torch

from ._warp import init_warp
from .params import bind_warp_params
from .state import WARP_MAX_MOTORS

if TYPE_CHECKING:
    from .simulator import Simulator


#: Smallest CPU slice worth a thread of its own (below it the thread hand-off costs more than it saves).
MIN_ENVS_PER_THREAD = 512
#: Chunks per thread: the threads take chunks from a shared queue, so a core slowed by another process
#: hands its remaining chunks to the others instead of holding back the whole step.
CHUNKS_PER_THREAD = 4

_POOL: ThreadPoolExecutor | None = None


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def cpu_thread_count(num_envs: int, threads: int | None) -> int:
    """Threads that step a CPU batch: ``threads``, or with None one per available core with at
    least :data:`MIN_ENVS_PER_THREAD` envs each (at least one, at most one per env)."""
    if threads is None:
        threads = min(available_cores(), num_envs // MIN_ENVS_PER_THREAD)
    return max(1, min(threads, num_envs))


def cpu_slices(num_envs: int, threads: int | None) -> list[tuple[int, int]]:
    """(offset, count) chunks of a CPU batch: one for a single thread, else
    :data:`CHUNKS_PER_THREAD` per thread (at most one per env), in env order."""
    count = cpu_thread_count(num_envs, threads)
    chunks = 1 if count == 1 else min(num_envs, count * CHUNKS_PER_THREAD)
    bounds = [num_envs * k // chunks for k in range(chunks + 1)]
    return [(lo, hi - lo) for lo, hi in itertools.pairwise(bounds)]


def _pool() -> ThreadPoolExecutor:
    """Process-wide worker threads for the CPU slices (created on first use)."""
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=max(1, available_cores() - 1),
                                   thread_name_prefix="falcon-warp")
    return _POOL


def warp_device(device: torch.device) -> str:
    """Warp device name of a torch device ("cpu" or "cuda:<index>")."""
    if device.type == "cpu":
        return "cpu"
    if device.type == "cuda":
        index = device.index if device.index is not None else torch.cuda.current_device()
        return f"cuda:{index}"
    raise ValueError(f"the warp backend runs on cpu or cuda devices, not {device}")


class WarpEngine:
    """Fused-kernel stepping of ``sim.x`` in place (float32, at most 8 motors)."""

    def __init__(self, sim: Simulator):
        wp = init_warp()
        if sim.dtype != torch.float32:
            raise ValueError(f"the warp backend runs in float32, got dtype={sim.dtype}")
        if sim.airframe.num_motors > WARP_MAX_MOTORS:
            raise ValueError(f"the warp backend supports at most {WARP_MAX_MOTORS} motors, "
                             f"{sim.airframe.name!r} has {sim.airframe.num_motors}")
        from . import warp_kernels

        self._wp = wp
        self._kernels = warp_kernels
        self.sim = sim
        self.device = warp_device(sim.device)
        self._is_cuda = sim.device.type == "cuda"
        self._key: tuple[Any, ...] = ()
        self._launches: list[Any] = []
        self._evaluate_launches: list[Any] = []
        self._evaluation = torch.empty(sim.num_envs, len(warp_kernels.EVALUATION_COLUMNS),
                                       device=sim.device, dtype=torch.float32)
        self._stream: Any = None
        self.threads = 1 if self._is_cuda else cpu_thread_count(sim.num_envs, sim.warp_cpu_threads)
        self.slices = [(0, sim.num_envs)] if self._is_cuda else cpu_slices(sim.num_envs, sim.warp_cpu_threads)
        self.rebind()

    def _binding_key(self) -> tuple[Any, ...]:
        sim = self.sim
        turb = sim.turbulence
        turb_key = (None if turb is None else
                    (id(turb), turb.filter.data_ptr(), turb.w20.data_ptr(), turb.noise.data_ptr(),
                     turb.external_noise))
        return (id(sim.params), sim.x.data_ptr(), sim.time.data_ptr(), sim.command.data_ptr(),
                sim.wind_ned.data_ptr(), sim.gust_velocity_body.data_ptr(), sim.gust_rate_body.data_ptr(),
                sim.dt, sim.integrator, turb_key)

    def _turbulence_inputs(self) -> list[Any]:
        """Views of the Dryden state and the mode code (placeholders and mode 0 when off)."""
        wp, sim, k = self._wp, self.sim, self._kernels
        turb = sim.turbulence
        if turb is None:
            dev = sim.device
            self._turb_placeholders = (torch.zeros(1, 8, device=dev), torch.zeros(1, device=dev),
                                       torch.zeros(1, 6, device=dev),
                                       torch.zeros(2, dtype=torch.int32, device=dev))
            tensors, mode = self._turb_placeholders, k.TURBULENCE_OFF
        else:
            self._turb_object = turb  # held so that its id cannot be reused
            tensors = (turb.filter, turb.w20, turb.noise, turb.rng)
            mode = k.TURBULENCE_EXTERNAL if turb.external_noise else k.TURBULENCE_RANDOM
        return [*(wp.from_torch(t) for t in tensors), mode]

    def rebind(self) -> None:
        """Bind fresh views of the simulator's tensors and record the launch again."""
        wp, sim = self._wp, self.sim
        for name in ("x", "time", "command", "wind_ned", "gust_velocity_body", "gust_rate_body"):
            if not getattr(sim, name).is_contiguous():
                raise ValueError(f"Simulator.{name} must be contiguous for the warp backend")
        self._params_object = sim.params  # held so that its id cannot be reused
        self._params = bind_warp_params(sim.params)
        self._params_ptrs = [t.data_ptr() for t in vars(sim.params).values()]
        inputs = [
            wp.from_torch(sim.x),
            wp.from_torch(sim.command, dtype=wp.vec4),
            wp.from_torch(sim.wind_ned, dtype=wp.vec3),
            wp.from_torch(sim.gust_velocity_body, dtype=wp.vec3),
            wp.from_torch(sim.gust_rate_body, dtype=wp.vec3),
            self._params,
            sim.dt,
            self._kernels.INTEGRATOR_CODES[sim.integrator],
            *self._turbulence_inputs(),
        ]
        step_inputs = [inputs[0], wp.from_torch(sim.time), *inputs[1:]]
        self._launches = [wp.launch(self._kernels.step_kernel, dim=count, inputs=[*step_inputs, offset],
                                    device=self.device, record_cmd=True)
                          for offset, count in self.slices]
        evaluate_inputs = [inputs[0], *inputs[2:6], wp.from_torch(self._evaluation)]
        self._evaluate_launches = [wp.launch(self._kernels.evaluate_kernel, dim=count,
                                             inputs=[*evaluate_inputs, offset], device=self.device,
                                             record_cmd=True)
                                   for offset, count in self.slices]
        if self._is_cuda:
            self._stream = wp.stream_from_torch(self.sim.device)
        self._key = self._binding_key()

    def step(self) -> None:
        """Advance ``sim.x`` and ``sim.time`` by one dt in place (one kernel launch per CPU slice)."""
        if self._binding_key() != self._key:
            self.rebind()
        turb = self.sim.turbulence
        if turb is not None and not turb.external_noise:
            turb.rng[1] += 1
        self._run(self._launches)

    def evaluate(self) -> torch.Tensor:
        """[N, len(EVALUATION_COLUMNS)] observables of the current state (engine-owned buffer,
        overwritten by the next call): one kernel launch."""
        if self._binding_key() != self._key:
            self.rebind()
        self._run(self._evaluate_launches)
        return self._evaluation

    def derived_state(self) -> dict[str, torch.Tensor]:
        """The derived fields of ``Simulator.state`` (fresh tensors), read from one evaluation launch
        by the column names of ``warp_kernels.EVALUATION_COLUMNS``."""
        e = self.evaluate()
        col = {name: k for k, name in enumerate(self._kernels.EVALUATION_COLUMNS)}

        def take(first: str, last: str | None = None) -> torch.Tensor:
            if last is None:
                return e[:, col[first]].clone()
            return e[:, col[first]:col[last] + 1].clone()

        return {
            "velocity_ned": take("velocity_n", "velocity_d"),
            "airspeed": take("airspeed"),
            "alpha": take("alpha"),
            "beta": take("beta"),
            "height": take("height"),
            "wing_height": take("wing_height"),
            "surface_position": take("surface_e", "surface_r"),
            "thrust": take("thrust"),
            "aero_coefficients": take("CL", "Cn"),
            "ground_contact": (e[:, col["height"]] <= 0.0) | (e[:, col["lowest_tip_height"]] <= 0.0),
            "euler": take("roll", "yaw"),
        }

    def _run(self, launches: list[Any]) -> None:
        """Replay one launch, or the CPU chunks' launches from a queue that ``self.threads`` threads
        (this one and pool workers) drain in parallel."""
        if len(launches) == 1:
            self._replay(launches[0])
            return
        queue: SimpleQueue[Any] = SimpleQueue()
        for launch in launches:
            queue.put(launch)

        def drain() -> None:
            while True:
                try:
                    launch = queue.get_nowait()
                except Empty:
                    return
                launch.launch()

        pending = [_pool().submit(drain) for _ in range(self.threads - 1)]
        drain()
        for future in pending:
            future.result()

    def _replay(self, launch: Any) -> None:
        if self._is_cuda:
            if torch.cuda.current_stream(self.sim.device).cuda_stream != self._stream.cuda_stream:
                self._stream = self._wp.stream_from_torch(self.sim.device)
            launch.launch(stream=self._stream)
        else:
            launch.launch()

    def _params_moved(self) -> bool:
        return any(t.data_ptr() != ptr for t, ptr in zip(vars(self.sim.params).values(),
                                                         self._params_ptrs, strict=True))

    def after_reset(self, mask: torch.Tensor | None) -> None:
        """Resets are torch writes into the bound memory; re-bind only if a tensor was replaced."""
        del mask
        if self._params_moved():
            self.rebind()
