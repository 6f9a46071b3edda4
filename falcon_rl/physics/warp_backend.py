"""Warp engine (``backend="warp"``): the model in fused Warp kernels, on the CPU or CUDA.

The engine binds zero-copy Warp views of its buffers once (state, command, air motion, parameters),
records a launch of :func:`~falcon_rl.physics.warp_kernels.step_kernel` (one per CPU slice, below)
and replays it on every step with the number of sub-steps as a launch argument: all sub-steps run
inside one launch, no host copies. :meth:`WarpEngine.derived` replays a launch of
:func:`~falcon_rl.physics.warp_kernels.evaluate_kernel` into an engine-owned buffer. Parameters
written in place (domain randomisation through ``ModelParams.assign``) are seen by the next launch.
Replacing the whole ``ModelParams`` object, ``dt`` or ``integrator`` re-binds on the next step;
replacing a single parameter tensor re-binds at the next reset (or call :meth:`WarpEngine.rebind`),
which keeps that 30-tensor check off the per-step path.
On CUDA the launch is queued on torch's current stream, so no synchronisation is needed. A pickled
engine carries only its tensors and setup; loading it binds the views and records the launches again.
On the CPU a Warp kernel runs serially on one core; batches of at least ``2 * MIN_ENVS_PER_THREAD``
envs are split into contiguous chunks (``CHUNKS_PER_THREAD`` per thread), one recorded launch per
chunk, which parallel threads take from a shared queue (a CPU launch is a ctypes call, which
releases the GIL). ``Simulator(warp_cpu_threads=...)`` overrides the default of one thread per
available core. A launch that runs as one CPU slice replays as a captured Warp CPU graph where Warp has
them (:meth:`WarpEngine.replayer`): its arguments are packed once, not on every step.
With turbulence on, the kernel also advances the Dryden filters (``Engine.turbulence``) at the start
of each sub-step; the step counter of its noise streams is a device tensor that torch bumps by the
number of sub-steps before each launch (sub-step k of the launch uses counter - substeps + 1 + k, so
one launch of n sub-steps draws what n launches of one draw).
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from queue import Empty, SimpleQueue
from typing import Any

import torch

from ._warp import capture_cpu_graph, init_warp, warp_device
from .derived import DERIVED_WIDTH
from .engine import Engine, EngineSetup
from .params import bind_warp_params
from .sea import SeaSurface, sea_field_views
from .state import WARP_MAX_MOTORS

#: Smallest CPU slice worth a thread of its own, in envs x physics sub-steps per launch (below it the thread
#: hand-off costs more than it saves).
MIN_ENVS_PER_THREAD = 512
#: Chunks per thread: the threads take chunks from a shared queue, so a core slowed by another process
#: hands its remaining chunks to the others instead of holding back the whole step.
CHUNKS_PER_THREAD = 4

#: Step replays (one per sub-step count) captured as CPU graphs between two rebinds; further counts
#: replay the recorded launch.
MAX_CAPTURED_STEPS = 32

_POOL: ThreadPoolExecutor | None = None


def available_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def cpu_thread_count(num_envs: int, threads: int | None, substeps: int = 1) -> int:
    """Threads that step a CPU batch of launches of ``substeps`` physics steps: ``threads``, or with
    None one per available core with at least :data:`MIN_ENVS_PER_THREAD` envs x sub-steps each (at
    least one, at most one per env)."""
    if threads is None:
        threads = min(available_cores(), num_envs * substeps // MIN_ENVS_PER_THREAD)
    return max(1, min(threads, num_envs))


def cpu_slices(num_envs: int, threads: int | None, substeps: int = 1) -> list[tuple[int, int]]:
    """(offset, count) chunks of a CPU batch (launches of ``substeps`` physics steps): one for a
    single thread, else :data:`CHUNKS_PER_THREAD` per thread (at most one per env), in env order."""
    count = cpu_thread_count(num_envs, threads, substeps)
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


class WarpEngine(Engine):
    """Fused-kernel stepping of the batch in place (float32, at most 8 motors). Option
    ``cpu_threads``: threads that step a CPU batch (None: one per available core, at most one per
    :data:`MIN_ENVS_PER_THREAD` envs); ignored on CUDA."""

    OPTIONS = ("cpu_threads",)
    RUNS_TASK_KERNELS = True

    #: What the engine binds to its buffers (Warp module, kernels, arrays, recorded launches, stream):
    #: left out of a pickle and bound again from the plain state on load.
    _RUNTIME = ("_wp", "_kernels", "device", "_torch_device", "_is_cuda", "_key", "_launches",
                "_evaluate_launches", "_substeps", "_evaluation", "_stream", "threads", "slices",
                "_params_object", "_params", "_params_ptrs", "_turb_placeholders", "_turb_object",
                "_stop", "generation", "_views", "_step_replay", "_step_replays", "_evaluate_replay",
                "_reset_inputs", "_reset_replays", "_screen_replay", "_calm_sea")

    @classmethod
    def placement(cls, num_envs: int, device: torch.device, dtype: torch.dtype
                  ) -> tuple[torch.device, torch.dtype]:
        if dtype != torch.float32:
            raise ValueError(f"the warp backend runs in float32, got dtype={dtype}")
        warp_device(device)
        return device, dtype

    def __init__(self, setup: EngineSetup):
        init_warp()
        if setup.airframe.num_motors > WARP_MAX_MOTORS:
            raise ValueError(f"the warp backend supports at most {WARP_MAX_MOTORS} motors, "
                             f"{setup.airframe.name!r} has {setup.airframe.num_motors}")
        threads = setup.options.get("cpu_threads")
        if threads is not None and not threads >= 1:
            raise ValueError(f"warp_cpu_threads must be None or >= 1, got {threads}")
        super().__init__(setup)
        self._bind_runtime()

    def _bind_runtime(self) -> None:
        """Set up the Warp side of the engine for its buffers: device, CPU slices, launches."""
        from . import warp_kernels

        setup = self.setup
        self._wp = init_warp()
        self._kernels = warp_kernels
        self.device = warp_device(setup.device)
        self._torch_device = setup.device
        self._is_cuda = setup.device.type == "cuda"
        self._key: tuple[Any, ...] = ()
        self._launches: list[Any] = []
        self._evaluate_launches: list[Any] = []
        self._step_replay: Callable[[], None] = lambda: None
        #: The step's replay per (sub-steps, stop at ground) used since the last rebind: a CPU graph holds
        #: the arguments it was captured with, and capturing costs ~0.5 ms, so a caller that varies the
        #: sub-step count captures each count once.
        self._step_replays: dict[tuple[int, bool], Callable[[], None]] = {}
        self._evaluate_replay: Callable[[], None] = lambda: None
        self._substeps = 1
        self._stop = False
        #: Bumped by every :meth:`rebind`: a kernel bound to :meth:`bind_views` binds again when it moves.
        self.generation = 0
        self._views: tuple[Any, Any, Any] | None = None
        self._evaluation = torch.empty(self.num_envs, DERIVED_WIDTH, device=setup.device,
                                       dtype=torch.float32)
        #: The reset's staging buffers (initial x [N, S], command [N, 4], mask [N]) and the screen's codes
        #: [N] int32: bound once, written by :meth:`start` before its recorded launches.
        self._reset_inputs = (torch.empty_like(self.x), torch.empty_like(self.command),
                              torch.empty(self.num_envs, device=setup.device, dtype=torch.bool),
                              torch.zeros(self.num_envs, device=setup.device, dtype=torch.int32))
        self._reset_replays: dict[bool, Callable[[], None]] = {}
        self._screen_replay: Callable[[], None] = lambda: None
        self._stream: Any = None
        threads = setup.options.get("cpu_threads")
        self.threads = 1 if self._is_cuda else cpu_thread_count(self.num_envs, threads)
        self.slices = [(0, self.num_envs)] if self._is_cuda else cpu_slices(self.num_envs, threads)
        self.rebind()

    def __getstate__(self) -> dict[str, Any]:
        """The plain state (setup, params, x, command, time, wind, gusts, turbulence, generator)."""
        return {key: value for key, value in self.__dict__.items() if key not in self._RUNTIME}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._bind_runtime()

    def _binding_key(self) -> tuple[Any, ...]:
        turb = self.turbulence
        turb_key = (None if turb is None else
                    (id(turb), turb.filter.data_ptr(), turb.w20.data_ptr(), turb.noise.data_ptr(),
                     turb.external_noise))
        sea_key = None if self.sea is None else (id(self.sea), self.sea.amplitude.data_ptr())
        return (id(self.params), self.dt, self.integrator, turb_key, sea_key)

    def _turbulence_inputs(self) -> tuple[list[Any], int]:
        """(views of the Dryden state: filter, W20, noise, rng; the mode code): placeholders and mode 0
        when off."""
        wp, k = self._wp, self._kernels
        turb = self.turbulence
        if turb is None:
            dev = self._torch_device
            self._turb_placeholders = (torch.zeros(1, 8, device=dev), torch.zeros(1, device=dev),
                                       torch.zeros(1, 6, device=dev),
                                       torch.zeros(2, dtype=torch.int32, device=dev))
            tensors, mode = self._turb_placeholders, k.TURBULENCE_OFF
        else:
            self._turb_object = turb  # held so that its id cannot be reused
            tensors = (turb.filter, turb.w20, turb.noise, turb.rng)
            mode = k.TURBULENCE_EXTERNAL if turb.external_noise else k.TURBULENCE_RANDOM
        return [wp.from_torch(t) for t in tensors], mode

    def bind_views(self) -> tuple[Any, Any, Any]:
        """(``EngineViews`` of the buffers, ``WarpParams`` of the parameters, ``StepSettings``): what a
        kernel that advances this engine's envs (:func:`~falcon_rl.physics.warp_kernels.advance_env`)
        takes; valid until the next :meth:`rebind`."""
        wp, k = self._wp, self._kernels
        views = k.EngineViews()
        views.x = wp.from_torch(self.x)
        views.time = wp.from_torch(self.time)
        views.command = wp.from_torch(self.command, dtype=wp.vec4)
        for name in ("wind_ned", "gust_velocity_body", "gust_rate_body"):
            setattr(views, name, wp.from_torch(getattr(self, name), dtype=wp.vec3))
        views.crashed = wp.from_torch(self.crashed, dtype=wp.bool)
        turbulence, mode = self._turbulence_inputs()
        views.turb_filter, views.turb_w20, views.turb_noise, views.turb_rng = turbulence
        views.surface = wp.from_torch(self.surface)
        views.sea = sea_field_views(self._sea_field())
        settings = k.StepSettings()
        settings.dt, settings.integrator = self.dt, k.INTEGRATOR_CODES[self.integrator]
        settings.turb_mode = mode
        return views, self._params, settings

    def _sea_field(self) -> SeaSurface:
        """The wave fields the kernels read: the drawn ones, or a calm [1, 1] placeholder (held)."""
        if self.sea is not None:
            return self.sea
        self._calm_sea = SeaSurface(*(torch.zeros(1, 1, device=self._torch_device) for _ in range(6)))
        return self._calm_sea

    def rebind(self) -> None:
        """Bind fresh views of the buffers and parameters and record the launches again."""
        wp = self._wp
        self._params_object = self.params  # held so that its id cannot be reused
        self._params = bind_warp_params(self.params)
        self._params_ptrs = [t.data_ptr() for t in vars(self.params).values()]
        views, params, settings = self._views = self.bind_views()
        self._launches = [wp.launch(self._kernels.step_kernel, dim=count,
                                    inputs=[views, params, settings, self._substeps, int(self._stop), offset],
                                    device=self.device, record_cmd=True)
                          for offset, count in self.slices]
        evaluate_inputs = [views.x, views.wind_ned, views.gust_velocity_body, views.gust_rate_body,
                           views.surface, params, wp.from_torch(self._evaluation)]
        self._evaluate_launches = [wp.launch(self._kernels.evaluate_kernel, dim=count,
                                             inputs=[*evaluate_inputs, offset], device=self.device,
                                             record_cmd=True)
                                   for offset, count in self.slices]
        initial_x, initial_command, mask, codes = self._reset_inputs
        staged = [wp.from_torch(initial_x), wp.from_torch(initial_command, dtype=wp.vec4),
                  wp.from_torch(mask, dtype=wp.bool)]
        reset_inputs = [views, params, *staged, wp.from_torch(self._evaluation)]
        reset_launches, bare_reset_launches, screen_launches = (
            [wp.launch(kernel, dim=count, inputs=[*inputs, offset], device=self.device, record_cmd=True)
             for offset, count in self.slices]
            for kernel, inputs in ((self._kernels.reset_kernel, [*reset_inputs, 1]),
                                   (self._kernels.reset_kernel, [*reset_inputs, 0]),
                                   (self._kernels.screen_kernel, [*staged, wp.from_torch(codes)])))
        self._step_replay = self.replayer(self._launches)
        self._step_replays = {(self._substeps, self._stop): self._step_replay}
        self._evaluate_replay = self.replayer(self._evaluate_launches)
        #: The reset's replays by whether they evaluate the batch's derived state.
        self._reset_replays = {True: self.replayer(reset_launches), False: self.replayer(bare_reset_launches)}
        self._screen_replay = self.replayer(screen_launches)
        if self._is_cuda:
            self._stream = wp.stream_from_torch(self._torch_device)
        self._key = self._binding_key()
        self.generation += 1

    def check_binding(self) -> None:
        """Bind again when the parameters object, dt, the integrator or the turbulence changed."""
        if self._binding_key() != self._key:
            self.rebind()

    def step(self, command: torch.Tensor, substeps: int = 1, stop_at_ground: bool = False) -> None:
        """``Engine.step`` with the crash state inside the kernel (no torch work after the launch)."""
        torch.clamp(command.detach(), -1.0, 1.0, out=self.command)
        self.advance(int(substeps), bool(stop_at_ground))

    def advance(self, substeps: int, stop_at_ground: bool = False) -> None:
        """``substeps`` steps of x and time in place, then the crash state with ``stop_at_ground``
        (``Engine.step``): one kernel launch per CPU slice."""
        self.check_binding()
        if substeps != self._substeps or stop_at_ground != self._stop:
            for launch in self._launches:
                launch.set_param_by_name("substeps", substeps)
                launch.set_param_by_name("stop_at_ground", int(stop_at_ground))
            self._substeps, self._stop = substeps, stop_at_ground
            replay = self._step_replays.get((substeps, stop_at_ground))
            if replay is None:
                captured = len(self._step_replays) < MAX_CAPTURED_STEPS
                replay = self.replayer(self._launches) if captured else partial(self.run, self._launches)
                self._step_replays[substeps, stop_at_ground] = replay
            self._step_replay = replay
        self.bump_turbulence_counter(substeps)
        self._step_replay()

    def bump_turbulence_counter(self, substeps: int) -> None:
        """Advance the step counter of the Warp noise streams by ``substeps`` before a launch of that many
        sub-steps (no-op without turbulence or with external noise)."""
        turb = self.turbulence
        if turb is not None and not turb.external_noise:
            turb.rng[1] += substeps

    def derived(self) -> torch.Tensor:
        """[N, DERIVED_WIDTH] derived state (engine-owned buffer, overwritten by the next call):
        one kernel launch per CPU slice."""
        self.check_binding()
        self._evaluate_replay()
        return self._evaluation

    def start(self, initial_x: torch.Tensor, initial_command: torch.Tensor,
              mask: torch.Tensor | None = None, check: Callable[[], None] | None = None,
              derive: bool = True) -> torch.Tensor | None:
        """``Engine.start`` in two launches per CPU slice: ``warp_kernels.screen_kernel`` screens the
        rows against the reset ranges (``check`` runs only when it finds a bad row; one host read of
        its codes), then ``warp_kernels.reset_kernel`` holds, projects and writes them and, with
        ``derive``, evaluates the derived state of every env, which it returns (the engine's buffer,
        as :meth:`derived`; None without ``derive``). The Dryden filters of the rows are zeroed in
        torch."""
        if self._params_moved():  # a parameter tensor replaced (domain randomisation): bind it first
            self.rebind()
        self.check_binding()
        staged_x, staged_command, staged_mask, codes = self._reset_inputs
        staged_x.copy_(initial_x)
        staged_command.copy_(initial_command)
        if mask is None:
            staged_mask.fill_(True)
        else:
            staged_mask.copy_(mask)
        if check is not None:
            self._screen_replay()
            if bool(codes.any()):
                check()
        if self.turbulence is not None:
            self.turbulence.reset(mask)
        self._reset_replays[derive]()
        return self._evaluation if derive else None

    @property
    def kernel_slices(self) -> list[tuple[int, int]]:
        return self.slices

    @property
    def kernel_device(self) -> str:
        return self.device

    def fuse(self, task_step: Any, env: Any) -> Any | None:
        """The env's whole step in one launch per CPU slice (:class:`~.fused_env_step.FusedEnvStep`)."""
        from .fused_env_step import FusedEnvStep

        return FusedEnvStep(env, task_step)

    def split(self, substeps: int) -> tuple[int, list[tuple[int, int]]]:
        """(threads, CPU slices) for launches of ``substeps`` physics steps each (the option
        ``cpu_threads`` kept); one slice on CUDA."""
        if self._is_cuda:
            return 1, [(0, self.num_envs)]
        threads = self.setup.options.get("cpu_threads")
        return (cpu_thread_count(self.num_envs, threads, substeps),
                cpu_slices(self.num_envs, threads, substeps))

    def replayer(self, launches: list[Any], threads: int | None = None) -> Callable[[], None]:
        """A call that replays ``launches`` as :meth:`run` does. A single CPU launch (one slice: small
        batches) replays as a captured Warp CPU graph where this Warp has them
        (:func:`~falcon_rl.physics._warp.capture_cpu_graph`), which keeps the launch's argument packing
        out of a one-env step. Make it again after changing a launch's parameters."""
        if len(launches) == 1 and not self._is_cuda:
            graph = capture_cpu_graph(launches[0])
            if graph is not None:
                return partial(self._wp.capture_launch, graph)
        return partial(self.run, launches, threads)

    def run(self, launches: list[Any], threads: int | None = None) -> None:
        """Replay one launch, or the CPU chunks' launches from a queue that ``threads`` threads (this
        one and pool workers; None: ``self.threads``) drain in parallel: the engine's own launches, or
        ones recorded per ``self.slices`` (or per :meth:`split`) by a task's fused step or an env's
        step, on torch's current CUDA stream."""
        threads = self.threads if threads is None else threads
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

        pending = [_pool().submit(drain) for _ in range(threads - 1)]
        drain()
        for future in pending:
            future.result()

    def follow_torch_stream(self) -> None:
        """Queue the next CUDA launches on torch's current stream (each launch checks this itself; a
        caller about to capture a CUDA graph on a stream calls it there first, so that the capture
        registers no new Warp stream). No-op on the CPU."""
        if not self._is_cuda:
            return
        current = torch.cuda.current_stream(self._torch_device).cuda_stream
        if self._stream is None or current != self._stream.cuda_stream:
            self._stream = self._wp.stream_from_torch(self._torch_device)

    def _replay(self, launch: Any) -> None:
        if self._is_cuda:
            self.follow_torch_stream()
            launch.launch(stream=self._stream)
        else:
            launch.launch()

    def _params_moved(self) -> bool:
        return any(t.data_ptr() != ptr for t, ptr in zip(vars(self.params).values(),
                                                         self._params_ptrs, strict=True))

    def after_reset(self) -> None:
        """Resets are torch writes into the bound memory; bind again only if a tensor was replaced."""
        if self._params_moved():
            self.rebind()

    def sample_surface(self, mask: torch.Tensor | None = None) -> None:
        """``Engine.sample_surface``, the wave fields bound again first when they were just allocated."""
        super().sample_surface(mask)
        self.check_binding()
