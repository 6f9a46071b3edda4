"""What the tasks' fused Warp steps share (``Task.fused_step`` on the warp backend).

- :class:`SimulatorViews` and :func:`flight_state`: the derived state a task reads (position, NED
  velocity, Euler angles, body rates, clamped surfaces, mean throttle, airspeed, alpha, beta, height,
  lower wing-tip height) computed for one env from the state row, wind and gusts with the same
  ``@wp.func`` twins and expressions as the engine's evaluation kernel (no aerodynamics, no propulsion).
- Twins of the torch functions of ``base`` with torch's semantics (``torch.clamp`` keeps a NaN,
  ``torch.sign`` is 0 at 0, ``torch.remainder``): :func:`clamp_keep_nan`, :func:`torch_sign`,
  :func:`taper_wp`, :func:`gaussian_wp`, :func:`airspeed_margin_penalty_wp`, :func:`wrap_angle_wp`.
- :func:`termination_code`: the reasons of ``Task.termination_checks`` in the priority order of
  ``base.TERMINATION_REASONS`` (ground contact, alpha stall, speed stall, lost).
- :class:`FusedStep`: binds zero-copy Warp views of the simulator's and the task's tensors, records
  the task kernel's launch (and its start kernel's) per CPU slice of the engine, replays it with
  ``sim.engine.run`` and binds again when a simulator tensor it reads has moved; :func:`fused_stepper`
  is the shared ``fused_stepper``.

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

from ...physics.dynamics import air_data_wp
from ...physics.rotations import quaternion_to_euler_wp, rotation_matrix_wp
from ...physics.state import (
    ANGULAR_RATE_START,
    DOWN_INDEX,
    QUATERNION_START,
    SURFACE_POSITION_START,
    THROTTLE_START,
    VELOCITY_START,
)
from ...physics.warp_backend import warp_device
from .base import TERMINATION_CODE

if TYPE_CHECKING:
    from .base import Task

GROUND_CONTACT = wp.constant(TERMINATION_CODE["ground_contact"])
ALPHA_STALL = wp.constant(TERMINATION_CODE["alpha_stall"])
SPEED_STALL = wp.constant(TERMINATION_CODE["speed_stall"])
LOST = wp.constant(TERMINATION_CODE["lost"])
POSITION_START = wp.constant(DOWN_INDEX - 2)
PI = wp.constant(math.pi)
TWO_PI = wp.constant(2.0 * math.pi)

#: Outputs of a fused step: observation [N, D], reward [N], termination reason [N] long.
StepOutputs = tuple[torch.Tensor, torch.Tensor, torch.Tensor]


@wp.struct
class SimulatorViews:
    """The simulator's buffers the task reads: state [N, S], air motion [N] vec3, geometry [N]."""

    x: wp.array2d(dtype=wp.float32)
    wind_ned: wp.array(dtype=wp.vec3)
    gust_velocity_body: wp.array(dtype=wp.vec3)
    span: wp.array(dtype=wp.float32)
    wing_quarter_chord: wp.array(dtype=wp.vec3)
    surface_min: wp.array(dtype=wp.vec3)
    surface_max: wp.array(dtype=wp.vec3)


@wp.struct
class FlightState:
    """The fields of ``Simulator.state`` a task reads, for one env (SI units, rad)."""

    position_ned: wp.vec3
    velocity_ned: wp.vec3
    euler: wp.vec3  # roll, pitch, yaw
    angular_rate: wp.vec3  # p, q, r
    surfaces: wp.vec3  # clamped to the actuator limits
    surface_min: wp.vec3
    surface_max: wp.vec3
    throttle: float  # mean over the motors
    airspeed: float
    alpha: float
    beta: float
    height: float
    lowest_tip: float  # height of the lower wing tip


@wp.func
def state_vec3(x: wp.array2d(dtype=wp.float32), i: int, start: int) -> wp.vec3:
    """x[i, start:start + 3]."""
    return wp.vec3(x[i, start], x[i, start + 1], x[i, start + 2])


@wp.func
def flight_state(sim: SimulatorViews, i: int) -> FlightState:
    """The derived state of env i (the expressions of ``evaluate_wp`` and ``evaluate_kernel``)."""
    x = sim.x
    q = wp.vec4(x[i, QUATERNION_START], x[i, QUATERNION_START + 1], x[i, QUATERNION_START + 2],
                x[i, QUATERNION_START + 3])
    rot = rotation_matrix_wp(q)
    vel = state_vec3(x, i, VELOCITY_START)
    air = air_data_wp(vel - wp.transpose(rot) * sim.wind_ned[i] - sim.gust_velocity_body[i])
    f = FlightState()
    f.position_ned = state_vec3(x, i, POSITION_START)
    f.velocity_ned = rot * vel
    f.euler = quaternion_to_euler_wp(q)
    f.angular_rate = state_vec3(x, i, ANGULAR_RATE_START)
    lo = sim.surface_min[i]
    hi = sim.surface_max[i]
    f.surfaces = wp.min(wp.max(state_vec3(x, i, SURFACE_POSITION_START), lo), hi)
    f.surface_min = lo
    f.surface_max = hi
    motors = x.shape[1] - THROTTLE_START
    throttle = wp.float32(0.0)
    for k in range(motors):
        throttle += x[i, THROTTLE_START + k]
    f.throttle = throttle / float(motors)
    f.airspeed = air[0]
    f.alpha = air[1]
    f.beta = air[2]
    f.height = -x[i, DOWN_INDEX]
    wing_height = f.height - wp.dot(wp.vec3(rot[2, 0], rot[2, 1], rot[2, 2]), sim.wing_quarter_chord[i])
    f.lowest_tip = wing_height - 0.5 * sim.span[i] * wp.abs(rot[2, 1])
    return f


@wp.func
def normalised_surface(f: FlightState, k: int) -> float:
    """Surface k on the command's [-1, 1] scale (twin of ``base.normalised_surfaces``)."""
    lo = f.surface_min[k]
    return 2.0 * (f.surfaces[k] - lo) / (f.surface_max[k] - lo) - 1.0


@wp.func
def termination_code(f: FlightState, stall_alpha: float, stall_speed: float, lost: bool) -> wp.int64:
    """The first reason that applies (ground contact of the CG or the lower wing tip, |alpha| beyond
    ``stall_alpha``, airspeed below ``stall_speed``, ``lost``), 0 while flying."""
    if f.height <= 0.0 or f.lowest_tip <= 0.0:
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
def clip(v: float, limit: float) -> float:
    """v clamped to +-limit (the observation clip), a NaN stays NaN."""
    return clamp_keep_nan(v, -limit, limit)


_VECTOR = {2: wp.vec2, 3: wp.vec3, 4: wp.vec4}


def warp_view(tensor: torch.Tensor) -> Any:
    """Zero-copy Warp view of a task tensor: [N] float32 or int64 as is, [N, k] (k = 2, 3, 4) float32 as
    an array of vec k."""
    if tensor.dtype == torch.long:
        return wp.from_torch(tensor, dtype=wp.int64)
    if tensor.dim() == 2:
        return wp.from_torch(tensor, dtype=_VECTOR[tensor.shape[1]])
    return wp.from_torch(tensor)


def fill_struct(struct: Any, values: dict[str, Any]) -> Any:
    """Set the fields of a Warp struct instance: tensors as :func:`warp_view`, vectors of floats as
    the Warp vector, ints as int, other numbers as the float32 the torch step's scalar becomes
    (Python products first, then float32). Returns ``struct``."""
    for name, value in values.items():
        if isinstance(value, torch.Tensor):
            value = warp_view(value)
        elif isinstance(value, (tuple, list)):
            value = _VECTOR[len(value)](*(float(v) for v in value))
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
    #: The task step's ``@wp.func`` that :attr:`kernel` wraps (the env-step kernel calls it too).
    kernel_func: ClassVar[Any]
    #: A kernel ``(sim, buf, c, observation [N, D], mask [N] bool, offset)`` that starts the episodes of
    #: the rows in ``mask`` after their physics reset (the task's ``after_reset``) and writes every
    #: env's observation (its ``observe``); None: the task starts episodes in torch.
    start_kernel: ClassVar[Any] = None

    def __init__(self, task: Task):
        self.task = task
        n, device = task.num_envs, task.device
        self.observation = torch.zeros(n, task.observation_dim, device=device, dtype=torch.float32)
        self.reward = torch.zeros(n, device=device, dtype=torch.float32)
        self.reason = torch.zeros(n, device=device, dtype=torch.long)
        self.action = torch.zeros(n, task.action_dim, device=device, dtype=torch.float32)
        self.device = warp_device(device)
        #: [N] bool: the rows :meth:`start` starts (staged for its launch), and its observation [N, D] (a
        #: buffer of its own: a caller may still read the step's after a reset).
        self.start_mask = torch.zeros(n, device=device, dtype=torch.bool)
        self.start_observation = torch.zeros_like(self.observation)
        #: The task class whose methods the kernels twin (:func:`fused_stepper` sets it to its ``owner``).
        self.owner: type = type(task)
        self._launches: list[Any] = []
        self._replay: Callable[[], None] = lambda: None
        self._start_replay: Callable[[], None] = lambda: None
        self._inputs: list[Any] = []
        self._key: tuple[int, ...] = ()

    def _simulator_tensors(self) -> tuple[torch.Tensor, ...]:
        sim = self.task.sim
        p = sim.params
        return (sim.x, sim.wind_ned, sim.gust_velocity_body, p.span, p.wing_quarter_chord, p.surface_min,
                p.surface_max)

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
        views = SimulatorViews()
        for name, tensor in zip(("x", "wind_ned", "gust_velocity_body", "span", "wing_quarter_chord",
                                 "surface_min", "surface_max"), self._simulator_tensors(), strict=True):
            setattr(views, name, wp.from_torch(tensor) if name == "x" else warp_view(tensor))
        outputs = [wp.from_torch(self.observation), wp.from_torch(self.reward), warp_view(self.reason)]
        task_inputs = self.task_inputs()
        self._inputs = [views, *task_inputs, *outputs]
        self._launches = [wp.launch(self.kernel, dim=count, inputs=[*self._inputs, offset],
                                    device=self.device, record_cmd=True)
                          for offset, count in self.task.sim.engine.slices]
        # The engine replays them as its own: on torch's current CUDA stream, the CPU slices on its
        # threads, one CPU slice as a captured graph.
        engine = self.task.sim.engine
        self._replay = engine.replayer(self._launches)
        if self.start_kernel is not None:
            start_inputs = [views, *task_inputs, wp.from_torch(self.start_observation),
                            wp.from_torch(self.start_mask)]
            self._start_replay = engine.replayer([
                wp.launch(self.start_kernel, dim=count, inputs=[*start_inputs, offset], device=self.device,
                          record_cmd=True) for offset, count in engine.slices])
        self._key = self.binding_key()

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
        self.start_mask.copy_(mask)
        self._start_replay()
        return self.start_observation

    def __call__(self, action: torch.Tensor) -> StepOutputs:
        """(observation [N, D], reward [N], reason [N] long) of the step that applied ``action`` [N, A]."""
        self.ensure_bound()
        self.action.copy_(action)
        self.draw()
        self._replay()
        return self.observation, self.reward, self.reason


def fused_stepper(task: Task, owner: type, methods: tuple[str, ...], factory: type[FusedStep]
                  ) -> FusedStep | None:
    """The shared body of a task's ``fused_stepper``: None when a subclass of ``owner`` overrides one of
    the fused ``methods`` (it then falls back to ``step``), else the task's ``factory`` step, built on
    the first call and kept in ``task._fused`` (its ``owner`` set: ``Task.fused_starter`` checks
    ``after_reset`` against it)."""
    if task.overrides(owner, methods):
        return None
    fused = getattr(task, "_fused", None)
    if fused is None:
        fused = task.__dict__["_fused"] = factory(task)
        fused.owner = owner
    return fused
