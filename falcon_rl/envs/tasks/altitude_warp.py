"""The altitude task's step in one Warp kernel (``AltitudeTask.fused_step`` on the warp backend).

:func:`altitude_step_kernel` does for env i what ``AltitudeTask.step(sim.state, action)`` does: it
computes the few derived quantities the task reads (height, lowest wing-tip height, airspeed, alpha,
clamped elevator, pitch, down velocity) from the state row, wind and gusts with the same ``@wp.func``
twins as the engine's evaluation kernel (no aerodynamics, no propulsion), then advances the clock and
the reference ramp, releases the next target (``target_sequence``), updates the filters, and writes
the reward, the termination reason and the clipped observation. The task's buffers are zero-copy
Warp views of its torch tensors, so ``info()``, ``after_reset`` and the torch ``step`` see the same
memory. Clamps keep torch's semantics (a NaN stays NaN), so a broken row reads the same both ways.

:class:`FusedAltitudeStep` binds the views once, records the launch (one per CPU slice of the
engine) and replays it each step; per step it runs two torch ops (the action copy and, with a target
sequence, the random shift drawn from the task's generator exactly as the torch step draws it) and
the launch: no allocation, no host synchronisation.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import torch
import warp as wp

from ...constants import DEG
from ...physics.dynamics import air_data_wp
from ...physics.rotations import quaternion_to_euler_wp, rotation_matrix_wp
from ...physics.state import (
    ANGULAR_RATE_START,
    DOWN_INDEX,
    PITCH,
    QUATERNION_START,
    SURFACE_POSITION_START,
    THROTTLE_START,
    VELOCITY_START,
)
from ...physics.warp_backend import warp_device
from ...physics.warp_kernels import flush_denormals_begin, flush_denormals_end
from .base import TERMINATION_CODE

if TYPE_CHECKING:
    from .altitude import AltitudeTask

GROUND_CONTACT = wp.constant(TERMINATION_CODE["ground_contact"])
ALPHA_STALL = wp.constant(TERMINATION_CODE["alpha_stall"])
SPEED_STALL = wp.constant(TERMINATION_CODE["speed_stall"])
PITCH_RATE = wp.constant(ANGULAR_RATE_START + PITCH)


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
class AltitudeBuffers:
    """The task's per-env buffers [N] (views of AltitudeTask's tensors), actions [N] vec2, the random
    target shift [N] int64 and the target table [T]."""

    time: wp.array(dtype=wp.float32)
    climb_rate: wp.array(dtype=wp.float32)
    target: wp.array(dtype=wp.float32)
    initial_altitude: wp.array(dtype=wp.float32)
    segment_start: wp.array(dtype=wp.float32)
    segment_time: wp.array(dtype=wp.float32)
    time_in_band: wp.array(dtype=wp.float32)
    error_integral: wp.array(dtype=wp.float32)
    previous_elevator: wp.array(dtype=wp.float32)
    elevator_rate: wp.array(dtype=wp.float32)
    reference: wp.array(dtype=wp.float32)
    reference_rate: wp.array(dtype=wp.float32)
    altitude_error: wp.array(dtype=wp.float32)
    reference_error: wp.array(dtype=wp.float32)
    previous_action: wp.array(dtype=wp.vec2)
    action: wp.array(dtype=wp.vec2)
    shift: wp.array(dtype=wp.int64)
    target_table: wp.array(dtype=wp.float32)


@wp.struct
class AltitudeConstants:
    """Config and airframe constants, each the float32 the torch step's scalar becomes."""

    env_dt: float
    target_sequence: int
    hold_seconds: float
    capture_band: float
    integral_limit: float
    trim_airspeed: float
    airspeed_sigma: float  # airspeed_scale x V_a*
    climb_rate_limit: float
    pitch_scale: float  # pi / 4
    alpha_scale: float  # 20 deg
    elevator_rate_scale: float  # 100 deg
    w_altitude: float
    sigma_altitude: float
    w_airspeed: float
    w_pitch_rate: float
    pitch_rate_cap: float
    w_smooth: float
    gate_band: float
    airspeed_band: float  # airspeed_band_fraction x V_a*
    survival_bonus: float
    w_overshoot: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


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
def reference_wp(target: float, start: float, rate: float, elapsed: float) -> wp.vec2:
    """(h_ref, hdot_ref) of the ramp from ``start`` to ``target`` at ``rate`` after ``elapsed`` s
    (twin of ``AltitudeTask._update_reference``)."""
    gap = target - start
    direction = torch_sign(gap)
    remaining = clamp_min_keep_nan(wp.abs(gap) - rate * elapsed, 0.0)
    reference_rate = 0.0
    if remaining > 0.0:
        reference_rate = direction * rate
    return wp.vec2(target - direction * remaining, reference_rate)


@wp.func
def next_target(target: float, shift: wp.int64, table: wp.array(dtype=wp.float32)) -> float:
    """The table entry ``shift`` places after the one nearest ``target`` (first on ties, as argmin)."""
    size = table.shape[0]
    current = wp.int32(0)
    best = wp.abs(target - table[0])
    for k in range(1, size):
        d = wp.abs(target - table[k])
        if d < best:
            best = d
            current = k
    return table[(current + int(shift)) % size]


@wp.kernel
def altitude_step_kernel(sim: SimulatorViews, buf: AltitudeBuffers, c: AltitudeConstants,
                         observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                         reason: wp.array(dtype=wp.int64), offset: int):
    """One altitude-task step of env i = offset + tid after the physics: updates the buffers in place
    and writes observation [N, 11], reward [N] and the termination reason [N] (0: flying)."""
    i = wp.tid() + offset
    saved = flush_denormals_begin()
    x = sim.x
    # The derived state the task reads (the expressions of evaluate_wp and evaluate_kernel).
    q = wp.vec4(x[i, QUATERNION_START], x[i, QUATERNION_START + 1], x[i, QUATERNION_START + 2],
                x[i, QUATERNION_START + 3])
    rot = rotation_matrix_wp(q)
    vel = wp.vec3(x[i, VELOCITY_START], x[i, VELOCITY_START + 1], x[i, VELOCITY_START + 2])
    air = air_data_wp(vel - wp.transpose(rot) * sim.wind_ned[i] - sim.gust_velocity_body[i])
    airspeed = air[0]
    alpha = air[1]
    height = -x[i, DOWN_INDEX]
    wing_height = height - wp.dot(wp.vec3(rot[2, 0], rot[2, 1], rot[2, 2]), sim.wing_quarter_chord[i])
    lowest_tip = wing_height - 0.5 * sim.span[i] * wp.abs(rot[2, 1])
    lo = sim.surface_min[i][0]
    hi = sim.surface_max[i][0]
    elevator = wp.min(wp.max(x[i, SURFACE_POSITION_START], lo), hi)
    pitch = quaternion_to_euler_wp(q)[1]
    velocity_down = (rot * vel)[2]
    motors = x.shape[1] - THROTTLE_START
    throttle = wp.float32(0.0)
    for k in range(motors):
        throttle += x[i, THROTTLE_START + k]
    throttle = throttle / float(motors)
    pitch_rate = x[i, PITCH_RATE]
    # advance: clock, segment time, reference ramp
    dt = c.env_dt
    buf.time[i] = buf.time[i] + dt
    elapsed = buf.segment_time[i] + dt
    target = buf.target[i]
    start = buf.segment_start[i]
    initial = buf.initial_altitude[i]
    ref = reference_wp(target, start, buf.climb_rate[i], elapsed)
    # update: target release, errors, elevator rate, error integral
    if c.target_sequence != 0:
        in_band = wp.float32(0.0)
        if wp.abs(height - target) <= c.capture_band:
            in_band = buf.time_in_band[i] + dt
        if in_band >= c.hold_seconds:
            start = target
            initial = target
            target = next_target(target, buf.shift[i], buf.target_table)
            elapsed = 0.0
            in_band = 0.0
            buf.segment_start[i] = start
            buf.initial_altitude[i] = initial
            buf.target[i] = target
            ref = reference_wp(target, start, buf.climb_rate[i], elapsed)
        buf.time_in_band[i] = in_band
    buf.segment_time[i] = elapsed
    buf.reference[i] = ref[0]
    buf.reference_rate[i] = ref[1]
    e_h = height - ref[0]
    buf.altitude_error[i] = height - target
    buf.reference_error[i] = e_h
    elevator_rate = (elevator - buf.previous_elevator[i]) / dt
    buf.elevator_rate[i] = elevator_rate
    buf.previous_elevator[i] = elevator
    integral = clamp_keep_nan(buf.error_integral[i] + e_h * dt, -c.integral_limit, c.integral_limit)
    buf.error_integral[i] = integral
    # reward
    e_v = airspeed - c.trim_airspeed
    action = buf.action[i]
    action_rate = wp.length(action - buf.previous_action[i])
    ratio = e_h / c.sigma_altitude
    past_target = clamp_min_keep_nan(torch_sign(target - initial) * (height - target), 0.0)
    reward[i] = (c.w_altitude * wp.exp(-0.5 * (ratio * ratio))
                 - c.w_airspeed * wp.abs(e_v) / c.trim_airspeed
                 - c.w_pitch_rate * clamp_max_keep_nan(pitch_rate * pitch_rate, c.pitch_rate_cap)
                 - c.w_smooth * action_rate * taper_wp(e_h, c.gate_band)
                 + c.w_altitude * taper_wp(e_h, c.capture_band) * taper_wp(e_v, c.airspeed_band)
                 + c.survival_bonus
                 - c.w_overshoot * past_target)
    # termination reason: the first of ground contact (CG or lower wing tip), alpha stall, speed stall
    code = wp.int64(0)
    if height <= 0.0 or lowest_tip <= 0.0:
        code = wp.int64(GROUND_CONTACT)
    elif wp.abs(alpha) > c.stall_alpha:
        code = wp.int64(ALPHA_STALL)
    elif airspeed < c.stall_speed:
        code = wp.int64(SPEED_STALL)
    reason[i] = code
    buf.previous_action[i] = action
    # observation, clipped
    clip = c.observation_clip
    observation[i, 0] = clamp_keep_nan(e_h / 25.0, -clip, clip)
    observation[i, 1] = clamp_keep_nan(pitch_rate / 2.0, -clip, clip)
    observation[i, 2] = clamp_keep_nan(e_v / c.airspeed_sigma, -clip, clip)
    observation[i, 3] = clamp_keep_nan(pitch / c.pitch_scale, -clip, clip)
    observation[i, 4] = clamp_keep_nan(velocity_down / c.climb_rate_limit, -clip, clip)
    observation[i, 5] = clamp_keep_nan(alpha / c.alpha_scale, -clip, clip)
    observation[i, 6] = clamp_keep_nan(2.0 * (elevator - lo) / (hi - lo) - 1.0, -clip, clip)
    observation[i, 7] = clamp_keep_nan(elevator_rate / c.elevator_rate_scale, -clip, clip)
    observation[i, 8] = clamp_keep_nan(2.0 * throttle - 1.0, -clip, clip)
    observation[i, 9] = clamp_keep_nan(integral / 10.0, -clip, clip)
    observation[i, 10] = clamp_keep_nan(ref[1] / 5.0, -clip, clip)
    flush_denormals_end(saved)


def altitude_constants(task: AltitudeTask) -> Any:
    """:class:`AltitudeConstants` of ``task``'s config and airframe (scalars as the torch step forms
    them: Python products first, then float32)."""
    cfg = task.config
    c = AltitudeConstants()
    values = {
        "env_dt": task.env_dt, "hold_seconds": cfg.hold_seconds, "capture_band": cfg.capture_band,
        "integral_limit": cfg.integral_limit, "trim_airspeed": task.trim_airspeed,
        "airspeed_sigma": cfg.airspeed_scale * task.trim_airspeed,
        "climb_rate_limit": task.airframe.envelope.climb_rate_limit, "pitch_scale": math.pi / 4,
        "alpha_scale": 20.0 * DEG, "elevator_rate_scale": 100.0 * DEG,
        "w_altitude": cfg.w_altitude, "sigma_altitude": cfg.sigma_altitude, "w_airspeed": cfg.w_airspeed,
        "w_pitch_rate": cfg.w_pitch_rate, "pitch_rate_cap": cfg.pitch_rate_cap, "w_smooth": cfg.w_smooth,
        "gate_band": cfg.gate_band, "airspeed_band": cfg.airspeed_band_fraction * task.trim_airspeed,
        "survival_bonus": cfg.survival_bonus, "w_overshoot": cfg.w_overshoot,
        "stall_alpha": task.stall_alpha, "stall_speed": task.stall_speed,
        "observation_clip": task.observation_clip,
    }
    for name, value in values.items():
        setattr(c, name, float(value))
    c.target_sequence = int(bool(cfg.target_sequence))
    return c


class FusedAltitudeStep:
    """The recorded launch of :func:`altitude_step_kernel` for one task, with its output buffers:
    observation [N, 11], reward [N] and reason [N] long, overwritten by each call. It binds again when
    a simulator tensor it reads has moved (e.g. ``sim.params`` replaced); the task's own buffers and
    config are bound once (they are written in place)."""

    def __init__(self, task: AltitudeTask):
        self.task = task
        n, device = task.num_envs, task.device
        self.observation = torch.zeros(n, task.observation_dim, device=device, dtype=torch.float32)
        self.reward = torch.zeros(n, device=device, dtype=torch.float32)
        self.reason = torch.zeros(n, device=device, dtype=torch.long)
        #: The action of the step [N, A] (copied in) and the random target shift [N] long.
        self.action = torch.zeros(n, task.action_dim, device=device, dtype=torch.float32)
        self.shift = torch.zeros(n, device=device, dtype=torch.long)
        self.shift_high = max(len(task.target_table), 2)
        self.device = warp_device(device)
        self._launches: list[Any] = []
        self._key: tuple[int, ...] = ()
        self.bind()

    def _simulator_tensors(self) -> tuple[torch.Tensor, ...]:
        sim = self.task.sim
        p = sim.params
        return (sim.x, sim.wind_ned, sim.gust_velocity_body, p.span, p.wing_quarter_chord, p.surface_min,
                p.surface_max)

    def _binding_key(self) -> tuple[int, ...]:
        return tuple(t.data_ptr() for t in self._simulator_tensors())

    def bind(self) -> None:
        """Bind zero-copy views of the simulator's and the task's tensors and record the launches."""
        task = self.task
        views = SimulatorViews()
        for name, tensor in zip(("x", "wind_ned", "gust_velocity_body", "span", "wing_quarter_chord",
                                 "surface_min", "surface_max"), self._simulator_tensors(), strict=True):
            dtype = wp.vec3 if tensor.dim() == 2 and name != "x" else None
            setattr(views, name, wp.from_torch(tensor, dtype=dtype))
        buf = AltitudeBuffers()
        for name in ("time", "climb_rate", "target", "initial_altitude", "segment_start", "segment_time",
                     "time_in_band", "error_integral", "previous_elevator", "elevator_rate", "reference",
                     "reference_rate", "altitude_error", "reference_error", "target_table"):
            setattr(buf, name, wp.from_torch(getattr(task, name)))
        buf.previous_action = wp.from_torch(task.previous_action, dtype=wp.vec2)
        buf.action = wp.from_torch(self.action, dtype=wp.vec2)
        buf.shift = wp.from_torch(self.shift, dtype=wp.int64)
        outputs = [wp.from_torch(self.observation), wp.from_torch(self.reward),
                   wp.from_torch(self.reason, dtype=wp.int64)]
        inputs = [views, buf, altitude_constants(task), *outputs]
        self._launches = [wp.launch(altitude_step_kernel, dim=count, inputs=[*inputs, offset],
                                    device=self.device, record_cmd=True)
                          for offset, count in task.sim.engine.slices]
        self._key = self._binding_key()

    def __call__(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(observation [N, D], reward [N], reason [N] long) of the step that applied ``action`` [N, A]."""
        if self._binding_key() != self._key:
            self.bind()
        self.action.copy_(action)
        task = self.task
        if task.config.target_sequence:
            torch.randint(1, self.shift_high, (task.num_envs,), generator=task.generator, device=task.device,
                          out=self.shift)
        # The engine replays them as its own: on torch's current CUDA stream, or the CPU slices on its
        # threads.
        task.sim.engine.run(self._launches)
        return self.observation, self.reward, self.reason
