"""What a task's Warp kernels read of an engine, and the kernels made around a task's functions.

Part of the engine contract for engines that run task kernels (``Engine.RUNS_TASK_KERNELS``): a task
writes its step as ``@wp.func`` functions of one env (``i``) and this module gives them

- :class:`SimulatorViews` (the engine's state [N, S], air motion [N] vec3 and geometry [N] as zero-copy
  views, bound by :func:`simulator_views`) and :func:`flight_state`, the derived state a task reads
  (position, NED velocity, Euler angles, body rates, clamped surfaces, mean throttle, airspeed, alpha,
  beta, height, the lower wing tip's and the CG's clearance above the surface under them, over water or
  not) computed for one env with the same ``@wp.func`` twins and
  expressions as the engine's evaluation kernel (no aerodynamics, no propulsion);
- :class:`MeasuredViews` and :func:`measured_flight_state`: the same flight state read from a given
  (e.g. measured) state TensorDict, for :func:`observe_kernel`, a task's observation of it;
- :func:`task_kernels`: the step and start kernels around a task's functions, in the task's own Warp
  module, each env i = offset + tid (``offset``: the first env of a slice, ``Engine.kernel_slices``) with
  denormals flushed as the physics' kernels do.

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations, which name the
task's struct types through the closure.
"""

from typing import Any, Protocol

import torch
import warp as wp

from ._warp import init_warp
from .dynamics import air_data_wp
from .rotations import quaternion_to_euler_wp, rotation_matrix_wp
from .state import (
    ANGULAR_RATE_START,
    DOWN_INDEX,
    QUATERNION_START,
    SURFACE_POSITION_START,
    THROTTLE_START,
    VELOCITY_START,
)
from .surface import CLEARANCE, ELEVATION, OVER_WATER, TIP_CLEARANCE
from .warp_kernels import flush_denormals_begin, flush_denormals_end

POSITION_START = wp.constant(DOWN_INDEX - 2)
#: The Warp vector type of a trailing width (a [N, k] float32 tensor viewed as an array of vec k).
WARP_VECTORS = {2: wp.vec2, 3: wp.vec3, 4: wp.vec4}


class TaskStep(Protocol):
    """A task's fused step (``envs.tasks.warp_common.FusedStep``): called with the checked action [N, A]
    right after the physics, it returns (observation [N, D], reward [N], reason [N] long), its buffers;
    :meth:`start` starts the episodes of a reset (given a ``start_kernel``). The engine's one-launch env
    step (``Engine.fuse``) calls its ``@wp.func`` (``kernel_func``) inside its own kernel, with the
    structs of its ``buf`` and ``c`` arguments (``buffers``, ``constants``) and its bound inputs."""

    kernel_func: Any
    start_kernel: Any
    observe_kernel: Any
    buffers: type
    constants: type
    action: torch.Tensor
    observation: torch.Tensor
    reward: torch.Tensor
    reason: torch.Tensor

    def __call__(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]: ...

    def start(self, mask: torch.Tensor) -> torch.Tensor:
        """Start the episodes of the rows in ``mask`` [N] bool after their physics reset; returns every
        env's observation [N, D] (a buffer the next call overwrites)."""
        ...

    def observe(self, state: Any) -> torch.Tensor:
        """[N, D] the observation of a given (measured) state with the current buffers (given an
        ``observe_kernel``)."""
        ...

    def ensure_bound(self) -> None: ...

    def kernel_inputs(self) -> list[Any]: ...

    def draw(self) -> None: ...

    def generators(self) -> tuple[torch.Generator, ...]: ...


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
    surface: wp.array2d(dtype=wp.float32)  # [N, SURFACE_WIDTH] the surface under each aircraft


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
    height: float  # above the flat ground / the sea's mean level
    lowest_tip: float  # the lower wing tip's height above the surface under it (ground or water)
    clearance: float  # the CG's height above the surface under it (a radar altimeter's reading)
    surface_elevation: float  # the surface's elevation under the CG (0 over the ground)
    over_water: bool  # the env flies over its sea (contact is "water_contact")


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
    f.clearance = f.height
    f.surface_elevation = 0.0
    f.over_water = sim.surface[i, OVER_WATER] != 0.0
    if f.over_water:
        f.lowest_tip = sim.surface[i, TIP_CLEARANCE]
        f.clearance = sim.surface[i, CLEARANCE]
        f.surface_elevation = sim.surface[i, ELEVATION]
    return f


@wp.func
def normalised_surface(f: FlightState, k: int) -> float:
    """Surface k on the command's [-1, 1] scale (twin of ``base.normalised_surfaces``)."""
    lo = f.surface_min[k]
    return 2.0 * (f.surfaces[k] - lo) / (f.surface_max[k] - lo) - 1.0


@wp.struct
class MeasuredViews:
    """The fields of a state TensorDict a task observes (a measured state, e.g. through the sensor
    transform), [N] or [N, 3] each, throttle [N, M], and the surface limits [N] vec3."""

    position_ned: wp.array(dtype=wp.vec3)
    velocity_ned: wp.array(dtype=wp.vec3)
    euler: wp.array(dtype=wp.vec3)
    angular_rate: wp.array(dtype=wp.vec3)
    surfaces: wp.array(dtype=wp.vec3)
    throttle: wp.array2d(dtype=wp.float32)
    airspeed: wp.array(dtype=wp.float32)
    alpha: wp.array(dtype=wp.float32)
    beta: wp.array(dtype=wp.float32)
    height: wp.array(dtype=wp.float32)
    clearance: wp.array(dtype=wp.float32)
    surface_min: wp.array(dtype=wp.vec3)
    surface_max: wp.array(dtype=wp.vec3)


@wp.func
def measured_flight_state(m: MeasuredViews, i: int) -> FlightState:
    """Env i's flight state as a state TensorDict gives it (surfaces as given, not clamped; the surface
    clearance as given, e.g. a measured altimeter; the lower wing tip at the CG's clearance and not over
    water: an observation reads neither)."""
    f = FlightState()
    f.position_ned = m.position_ned[i]
    f.velocity_ned = m.velocity_ned[i]
    f.euler = m.euler[i]
    f.angular_rate = m.angular_rate[i]
    f.surfaces = m.surfaces[i]
    f.surface_min = m.surface_min[i]
    f.surface_max = m.surface_max[i]
    motors = m.throttle.shape[1]
    throttle = wp.float32(0.0)
    for k in range(motors):
        throttle += m.throttle[i, k]
    f.throttle = throttle / float(motors)
    f.airspeed = m.airspeed[i]
    f.alpha = m.alpha[i]
    f.beta = m.beta[i]
    f.height = m.height[i]
    f.clearance = m.clearance[i]
    f.surface_elevation = m.height[i] - m.clearance[i]
    f.lowest_tip = m.clearance[i]
    f.over_water = False
    return f


#: The state entries :class:`MeasuredViews` reads, by field: (key in the state, trailing width).
MEASURED_FIELDS: dict[str, tuple[str, int]] = {
    "position_ned": ("position_ned", 3), "velocity_ned": ("velocity_ned", 3), "euler": ("euler", 3),
    "angular_rate": ("angular_rate_body", 3), "surfaces": ("surface_position", 3),
    "throttle": ("throttle", 0),
    "airspeed": ("airspeed", 1), "alpha": ("alpha", 1), "beta": ("beta", 1), "height": ("height", 1),
    "clearance": ("surface_clearance", 1)}


def measured_views(state: Any, num_envs: int, surface_min: torch.Tensor, surface_max: torch.Tensor
                   ) -> tuple[Any, list[torch.Tensor]]:
    """(:class:`MeasuredViews`, the float32 contiguous tensors it views: keep them alive until the
    launch ran) of the entries of ``state`` (a mapping of [N], [N, 1] or [N, k] tensors) and the surface
    limits [N, 3] (any float dtype)."""
    init_warp()  # an engine that is not Warp's own may run the first task kernel of the process
    views, kept = MeasuredViews(), []
    for field, (key, width) in MEASURED_FIELDS.items():
        if field == "clearance" and key not in state:
            key = "height"  # a state without the surface (e.g. a layout's subset): over the flat ground
        tensor = state[key].to(torch.float32)
        tensor = tensor.reshape(num_envs, -1) if width == 0 else tensor.reshape(num_envs, width)
        tensor = tensor.contiguous()
        kept.append(tensor)
        if width == 1:
            setattr(views, field, wp.from_torch(tensor.view(num_envs)))
        elif width == 3:
            setattr(views, field, wp.from_torch(tensor, dtype=wp.vec3))
        else:
            setattr(views, field, wp.from_torch(tensor))
    for field, limit in (("surface_min", surface_min), ("surface_max", surface_max)):
        limit = limit.to(torch.float32).contiguous()
        kept.append(limit)
        setattr(views, field, wp.from_torch(limit, dtype=wp.vec3))
    return views, kept


def observe_kernel(name: str, observe: Any, buffers: type, constants: type, module: str) -> Any:
    """``<name>_observe_kernel`` in the Warp module ``module`` of a task's ``@wp.func`` observe ``(f:
    FlightState, buf: buffers, c: constants, observation [N, D], i)``: the observation of a given
    (measured) state with the task's current buffers, no side effect; arguments ``(m: MeasuredViews,
    buf, c, observation, offset)``."""

    def kernel(m: MeasuredViews, buf: buffers, c: constants,  # type: ignore[valid-type]
               observation: wp.array2d(dtype=wp.float32), offset: int):
        i = wp.tid() + offset
        saved = flush_denormals_begin()
        observe(measured_flight_state(m, i), buf, c, observation, i)
        flush_denormals_end(saved)

    return wp.kernel(kernel, name=f"{name}_observe_kernel", module=module)


def simulator_views(x: torch.Tensor, wind_ned: torch.Tensor, gust_velocity_body: torch.Tensor,
                    span: torch.Tensor, wing_quarter_chord: torch.Tensor, surface_min: torch.Tensor,
                    surface_max: torch.Tensor, surface: torch.Tensor) -> Any:
    """A :class:`SimulatorViews` of an engine's float32 tensors: x [N, S], wind and gusts [N, 3], span
    [N], wing quarter chord, surface limits [N, 3], the surface samples [N, SURFACE_WIDTH] (zero-copy: the
    views follow in-place writes)."""
    init_warp()  # an engine that is not Warp's own may run the first task kernel of the process
    views = SimulatorViews()
    views.x = wp.from_torch(x)
    views.surface = wp.from_torch(surface)
    for name, tensor in (("wind_ned", wind_ned), ("gust_velocity_body", gust_velocity_body),
                         ("wing_quarter_chord", wing_quarter_chord), ("surface_min", surface_min),
                         ("surface_max", surface_max)):
        setattr(views, name, wp.from_torch(tensor, dtype=WARP_VECTORS[tensor.shape[1]]))
    views.span = wp.from_torch(span)
    return views


def task_kernels(name: str, step: Any, start: Any, buffers: type, constants: type, module: str
                 ) -> tuple[Any, Any]:
    """(``<name>_step_kernel``, ``<name>_start_kernel``) in the Warp module named ``module`` (the task's
    own) of a task's
    ``@wp.func`` step ``(sim, buf: buffers, c: constants, observation [N, D], reward [N], reason [N]
    int64, i)`` and start ``(sim, buf, c, observation [N, D], mask [N] bool, i)``; the kernels take the
    same arguments with ``offset`` in place of ``i``."""

    def step_kernel(sim: SimulatorViews, buf: buffers, c: constants,  # type: ignore[valid-type]
                    observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                    reason: wp.array(dtype=wp.int64), offset: int):
        i = wp.tid() + offset
        saved = flush_denormals_begin()
        step(sim, buf, c, observation, reward, reason, i)
        flush_denormals_end(saved)

    def start_kernel(sim: SimulatorViews, buf: buffers, c: constants,  # type: ignore[valid-type]
                     observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), offset: int):
        i = wp.tid() + offset
        saved = flush_denormals_begin()
        start(sim, buf, c, observation, mask, i)
        flush_denormals_end(saved)

    return (wp.kernel(step_kernel, name=f"{name}_step_kernel", module=module),
            wp.kernel(start_kernel, name=f"{name}_start_kernel", module=module))


__all__ = ["MEASURED_FIELDS", "WARP_VECTORS", "FlightState", "MeasuredViews", "SimulatorViews", "TaskStep",
           "flight_state", "measured_flight_state", "measured_views", "normalised_surface", "observe_kernel",
           "simulator_views", "task_kernels"]
