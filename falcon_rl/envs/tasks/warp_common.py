"""What the tasks' Warp kernels share (``Task.fused_stepper`` on an engine that runs task kernels).

- The derived state a task reads (``physics.task_kernels.flight_state``) and the kernels around a task's
  functions (``physics.task_kernels.task_kernels``) come with the engine contract.
- Twins of the torch functions of ``base`` with torch's semantics (``torch.clamp`` keeps a NaN,
  ``torch.sign`` is 0 at 0, ``torch.remainder``): :func:`clamp_keep_nan`, :func:`torch_sign`,
  :func:`taper_wp`, :func:`gaussian_wp`, :func:`airspeed_margin_penalty_wp`, :func:`wrap_angle_wp`.
- :func:`termination_code`: the reasons of ``Task.termination_checks`` in the priority order of
  ``base.TERMINATION_REASONS`` (ground or water contact, alpha stall, speed stall, lost).
- :class:`FusedStep`: binds zero-copy Warp views of the simulator's and the task's tensors, records
  the task kernel's launch (and its start kernel's) per slice of the engine (``Engine.kernel_slices``),
  replays them with the engine's ``replayer`` and binds again when a simulator tensor it reads has
  moved; :func:`fused_stepper` is the shared ``fused_stepper``.

A task kernel has the signature ``(sim: SimulatorViews, buf: <Buffers>, c: <Constants>, observation
[N, D], reward [N], reason [N] int64, offset: int)`` and handles env i = offset + tid. A task's start
kernel (``FusedStep.start_kernel``: ``after_reset`` and ``observe`` after the physics reset, for
``Task.start_episodes``) has ``(sim, buf, c, observation [N, D], mask [N] bool, offset)``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar

import torch
import warp as wp

from ...physics.task_kernels import WARP_VECTORS, FlightState, measured_views, simulator_views
from .base import TERMINATION_CODE

if TYPE_CHECKING:
    from .base import Task

GROUND_CONTACT = wp.constant(TERMINATION_CODE["ground_contact"])
WATER_CONTACT = wp.constant(TERMINATION_CODE["water_contact"])
ALPHA_STALL = wp.constant(TERMINATION_CODE["alpha_stall"])
SPEED_STALL = wp.constant(TERMINATION_CODE["speed_stall"])
LOST = wp.constant(TERMINATION_CODE["lost"])
PI = wp.constant(math.pi)
TWO_PI = wp.constant(2.0 * math.pi)

#: Outputs of a fused step: observation [N, D], reward [N], termination reason [N] long.
StepOutputs = tuple[torch.Tensor, torch.Tensor, torch.Tensor]


@wp.func
def termination_code(f: FlightState, stall_alpha: float, stall_speed: float, lost: bool) -> wp.int64:
    """The first reason that applies (contact of the CG or the lower wing tip with the surface under them:
    the ground, or the water over a sea; |alpha| beyond ``stall_alpha``, airspeed below ``stall_speed``,
    ``lost``), 0 while flying."""
    if f.clearance <= 0.0 or f.lowest_tip <= 0.0:
        if f.over_water:
            return wp.int64(WATER_CONTACT)
        return wp.int64(GROUND_CONTACT)
    if wp.abs(f.alpha) > stall_alpha:
        return wp.int64(ALPHA_STALL)
    if f.airspeed < stall_speed:
        return wp.int64(SPEED_STALL)
    if lost:
        return wp.int64(LOST)
    return wp.int64(0)


@wp.func
def clamp_keep_nan(v: float, lo: float, hi: float) -> float:
    """``torch.clamp``: v in [lo, hi], a NaN stays NaN."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


@wp.func
def clamp_min_keep_nan(v: float, lo: float) -> float:
    """``torch.clamp_min``: max(v, lo), a NaN stays NaN."""
    if v < lo:
        return lo
    return v


@wp.func
def clamp_max_keep_nan(v: float, hi: float) -> float:
    """``torch.clamp(max=)``: min(v, hi), a NaN stays NaN."""
    if v > hi:
        return hi
    return v


@wp.func
def torch_sign(v: float) -> float:
    """``torch.sign``: -1, 0 or 1 (``wp.sign`` gives 1 at 0)."""
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@wp.func
def taper_wp(error: float, band: float) -> float:
    """max(0, 1 - |e| / band) (twin of ``base.taper``)."""
    return clamp_min_keep_nan(1.0 - wp.abs(error) / band, 0.0)


@wp.func
def gaussian_wp(error: float, sigma: float) -> float:
    """exp(-(e / sigma)^2 / 2) (twin of ``base.gaussian``)."""
    ratio = error / sigma
    return wp.exp(-0.5 * (ratio * ratio))


@wp.func
def airspeed_margin_penalty_wp(airspeed: float, safe_airspeed: float) -> float:
    """((V_safe - V_a) / V_safe)^2 below V_safe, 0 above (twin of ``base.airspeed_margin_penalty``)."""
    margin = clamp_min_keep_nan(safe_airspeed - airspeed, 0.0) / safe_airspeed
    return margin * margin


@wp.func
def wrap_angle_wp(angle: float) -> float:
    """Wrap to (-pi, pi] (twin of ``base.wrap_angle``: ``torch.remainder`` is fmod moved to the
    divisor's sign)."""
    mod = wp.mod(angle + PI, TWO_PI)
    if mod < 0.0:
        mod += TWO_PI
    return mod - PI


@wp.func
def write_reward_terms(values: wp.array2d(dtype=wp.float32), sums: wp.array2d(dtype=wp.float32), i: int,
                       terms: Any) -> float:
    """The reward of env i, the sum of ``terms`` (a vector of the task's K weighted, signed terms) in
    order, as ``Task.reward`` sums them; writes them into ``values[i]`` [K] and adds them to ``sums[i]``."""
    total = terms[0]
    for k in range(1, values.shape[1]):
        total = total + terms[k]
    for k in range(values.shape[1]):
        values[i, k] = terms[k]
        sums[i, k] = sums[i, k] + terms[k]
    return total


@wp.func
def clip(v: float, limit: float) -> float:
    """v clamped to +-limit (the observation clip), a NaN stays NaN."""
    return clamp_keep_nan(v, -limit, limit)


def warp_view(tensor: torch.Tensor) -> Any:
    """Zero-copy Warp view of a task tensor: [N] float32 or int64 as is, [N, k] (k = 2, 3, 4) float32 as
    an array of vec k."""
    if tensor.dtype == torch.long:
        return wp.from_torch(tensor, dtype=wp.int64)
    if tensor.dim() == 2:
        return wp.from_torch(tensor, dtype=WARP_VECTORS[tensor.shape[1]])
    return wp.from_torch(tensor)


def bind_reward_terms(buffers: Any, task: Task) -> Any:
    """Set a task buffers struct's ``reward_term_values`` and ``reward_term_sums`` to views of the task's
    [N, K] tensors (2D arrays, whatever K). Returns ``buffers``."""
    buffers.reward_term_values = wp.from_torch(task.reward_term_values)
    buffers.reward_term_sums = wp.from_torch(task.reward_term_sums)
    return buffers


def fill_struct(struct: Any, values: dict[str, Any]) -> Any:
    """Set the fields of a Warp struct instance: tensors as :func:`warp_view`, vectors of floats as
    the Warp vector, ints as int, other numbers as the float32 the torch step's scalar becomes
    (Python products first, then float32). Returns ``struct``."""
    for name, value in values.items():
        if isinstance(value, torch.Tensor):
            value = warp_view(value)
        elif isinstance(value, (tuple, list)):
            value = WARP_VECTORS[len(value)](*(float(v) for v in value))
        elif not isinstance(value, (bool, int)):
            value = float(value)
        setattr(struct, name, value)
    return struct


class FusedStep:
    """The recorded launch of a task kernel (:attr:`kernel`) for one task, with its output buffers:
    observation [N, D], reward [N] and reason [N] long, overwritten by each call, and the action [N, A]
    it copies in. It binds again when a simulator tensor it reads has moved (e.g. ``sim.params``
    replaced); the task's own buffers and config are bound once (they are written in place).

    A subclass sets :attr:`kernel` and gives :meth:`task_inputs` (the kernel's ``buf`` and ``c``
    structs); it draws the step's random numbers in :meth:`draw` (torch, the task's generator). With a
    :attr:`start_kernel` the start of episodes (``Task.start_episodes``) is one launch too."""

    kernel: ClassVar[Any]
    #: The task step's ``@wp.func`` that :attr:`kernel` wraps (the engine's fused env step calls it too,
    #: ``Engine.fuse``), and the Warp structs of its ``buf`` and ``c`` arguments.
    kernel_func: ClassVar[Any]
    buffers: ClassVar[type]
    constants: ClassVar[type]
    #: A kernel ``(sim, buf, c, observation [N, D], mask [N] bool, offset)`` that starts the episodes of
    #: the rows in ``mask`` after their physics reset (the task's ``after_reset``) and writes every
    #: env's observation (its ``observe``); None: the task starts episodes in torch.
    start_kernel: ClassVar[Any] = None
    #: A kernel ``(m: MeasuredViews, buf, c, observation [N, D], offset)`` (``physics.task_kernels.
    #: observe_kernel``): the observation of a given (measured) state with the task's current buffers,
    #: the task's ``observe``; None: the task observes a given state in torch.
    observe_kernel: ClassVar[Any] = None

    def __init__(self, task: Task):
        self.task = task
        n, device = task.num_envs, task.device
        self.observation = torch.zeros(n, task.observation_dim, device=device, dtype=torch.float32)
        self.reward = torch.zeros(n, device=device, dtype=torch.float32)
        self.reason = torch.zeros(n, device=device, dtype=torch.long)
        self.action = torch.zeros(n, task.action_dim, device=device, dtype=torch.float32)
        #: [N] bool: the rows :meth:`start` starts (staged for its launch), and its observation [N, D] (a
        #: buffer of its own: a caller may still read the step's after a reset).
        self.start_mask = torch.zeros(n, device=device, dtype=torch.bool)
        self.start_observation = torch.zeros_like(self.observation)
        self._launches: list[Any] = []
        self._replay: Callable[[], None] = lambda: None
        self._start_replay: Callable[[], None] = lambda: None
        self._inputs: list[Any] = []
        self._key: tuple[int, ...] = ()
        self._shadows: list[tuple[torch.Tensor, torch.Tensor]] = []
        self.task_tensors: tuple[torch.Tensor, ...] = ()

    #: How many of :meth:`_simulator_tensors` make the :class:`SimulatorViews` (the rest are the task's own,
    #: :meth:`task_simulator_tensors`).
    _VIEW_TENSORS: ClassVar[int] = 8

    def _simulator_tensors(self) -> tuple[torch.Tensor, ...]:
        sim = self.task.sim
        p = sim.params
        return (sim.x, sim.wind_ned, sim.gust_velocity_body, p.span, p.wing_quarter_chord, p.surface_min,
                p.surface_max, sim.surface, *self.task_simulator_tensors())

    def task_simulator_tensors(self) -> tuple[torch.Tensor, ...]:
        """Simulator tensors beyond :class:`SimulatorViews` that the task's buffers read (e.g. the clock
        and the wave fields): bound, re-bound when they move and shadowed in float32 like the views'; a
        subclass reads their float32 versions from :attr:`task_tensors` in :meth:`task_inputs`."""
        return ()

    def _kernel_tensors(self) -> tuple[torch.Tensor, ...]:
        """The simulator tensors the kernels read, in float32: the tensors themselves, or, for a float64
        simulator, float32 shadows (made at :meth:`bind`, filled by :meth:`refresh` before each launch)."""
        sources = self._simulator_tensors()
        shadows = tuple(t if t.dtype == torch.float32 and t.is_contiguous()
                        else torch.empty(t.shape, device=t.device, dtype=torch.float32) for t in sources)
        self._shadows = [(t, shadow) for t, shadow in zip(sources, shadows, strict=True) if shadow is not t]
        return shadows

    def refresh(self) -> None:
        """Copy a float64 simulator's tensors into their float32 shadows (nothing for a float32 one)."""
        for source, shadow in self._shadows:
            shadow.copy_(source)

    def binding_key(self) -> tuple[int, ...]:
        """What the launches were bound to (the addresses of the simulator tensors the kernel reads)."""
        return tuple(t.data_ptr() for t in self._simulator_tensors())

    def ensure_bound(self) -> None:
        """Bind (again) when never bound or a simulator tensor moved."""
        if not self._launches or self.binding_key() != self._key:
            self.bind()

    def kernel_inputs(self) -> list[Any]:
        """The task function's inputs before env i: (simulator views, buffers, constants, observation,
        reward, reason), as bound by the last :meth:`bind`."""
        return self._inputs

    def task_inputs(self) -> list[Any]:
        """The kernel's inputs between the simulator views and the outputs (buffers, constants)."""
        raise NotImplementedError

    def bind(self) -> None:
        """Bind zero-copy views of the simulator's and the task's tensors and record the launches."""
        tensors = self._kernel_tensors()
        views = simulator_views(*tensors[:self._VIEW_TENSORS])
        #: float32 versions of :meth:`task_simulator_tensors` (the tensors, or their shadows)
        self.task_tensors = tensors[self._VIEW_TENSORS:]
        outputs = [wp.from_torch(self.observation), wp.from_torch(self.reward), warp_view(self.reason)]
        task_inputs = self.task_inputs()
        self._inputs = [views, *task_inputs, *outputs]
        # The engine replays them as its own: on torch's current CUDA stream, the CPU slices on its
        # threads, one CPU slice as a captured graph.
        engine = self.task.sim.engine
        self._launches = [wp.launch(self.kernel, dim=count, inputs=[*self._inputs, offset],
                                    device=engine.kernel_device, record_cmd=True)
                          for offset, count in engine.kernel_slices]
        self._replay = engine.replayer(self._launches)
        if self.start_kernel is not None:
            start_inputs = [views, *task_inputs, wp.from_torch(self.start_observation),
                            wp.from_torch(self.start_mask)]
            self._start_replay = engine.replayer([
                wp.launch(self.start_kernel, dim=count, inputs=[*start_inputs, offset],
                          device=engine.kernel_device, record_cmd=True)
                for offset, count in engine.kernel_slices])
        self._key = self.binding_key()

    def observe(self, state: Any) -> torch.Tensor:
        """[N, D] float32 (a new tensor): the task's observation of ``state`` (a mapping of the state's
        entries, [N], [N, 1] or [N, k], e.g. a measured state) with its current buffers, by
        :attr:`observe_kernel`; nothing else is written."""
        if self.observe_kernel is None:
            raise RuntimeError(f"{type(self).__name__} has no observe kernel")
        self.ensure_bound()
        task, engine = self.task, self.task.sim.engine
        views, kept = measured_views(state, task.num_envs, task.sim.params.surface_min,
                                     task.sim.params.surface_max)
        out = torch.empty(task.num_envs, task.observation_dim, device=task.device, dtype=torch.float32)
        buf, constants = self._inputs[1], self._inputs[2]
        target = wp.from_torch(out)
        launches = [wp.launch(self.observe_kernel, dim=count, inputs=[views, buf, constants, target, offset],
                              device=engine.kernel_device, record_cmd=True)
                    for offset, count in engine.kernel_slices]
        engine.replayer(launches)()
        del kept  # the views' memory is needed until the launches ran
        return out

    def draw(self) -> None:
        """Draw the step's random numbers into bound buffers (none by default)."""

    def generators(self) -> tuple[torch.Generator, ...]:
        """The torch generators :meth:`draw` draws from (none by default): a CUDA graph of the step
        registers them, so that each replay draws fresh numbers."""
        return ()

    def start(self, mask: torch.Tensor) -> torch.Tensor:
        """Start the episodes of the rows in ``mask`` [N] bool, whose physics reset is written, with
        :attr:`start_kernel`; returns every env's observation [N, D] (:attr:`start_observation`, which
        the next call overwrites; the step's outputs are left as they are)."""
        if self.start_kernel is None:
            raise RuntimeError(f"{type(self).__name__} has no start kernel")
        self.ensure_bound()
        self.refresh()
        self.start_mask.copy_(mask)
        self._start_replay()
        return self.start_observation

    def __call__(self, action: torch.Tensor) -> StepOutputs:
        """(observation [N, D], reward [N], reason [N] long) of the step that applied ``action`` [N, A]."""
        self.ensure_bound()
        self.refresh()
        self.action.copy_(action)
        self.draw()
        self._replay()
        return self.observation, self.reward, self.reason


def fused_stepper(task: Task, factory: type[FusedStep]) -> FusedStep:
    """The shared body of a task's ``fused_stepper``: the task's ``factory`` step, built on the first
    call and kept in ``task._fused``."""
    fused = getattr(task, "_fused", None)
    if fused is None:
        fused = task.__dict__["_fused"] = factory(task)
    return fused
