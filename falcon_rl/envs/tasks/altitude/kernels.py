"""The altitude task's step, written once as Warp functions (``AltitudeTask.fused_stepper``).

:func:`altitude_step` is the task's step for env i after the physics (the equations of the task's
module docstring): it computes the derived state the task reads with ``flight_state`` (the twins of
the engine's evaluation kernel), then advances the clock and the reference ramp, releases the next
target (``target_sequence``), updates the filters, and writes the named reward terms, the reward, the
termination reason and the clipped observation. The task's buffers are zero-copy Warp views of its
float32 torch tensors, so ``info()`` and ``sample_initial`` see the same memory. Clamps keep torch's
semantics (a NaN stays NaN), so a broken row is caught by the env's non-finite guard.

:class:`FusedAltitudeStep` (a ``warp_common.FusedStep``) binds the views once, records the launch (one
per CPU slice of the engine) and replays it each step; per step it runs two torch ops (the action copy
and, with a target sequence, the random shift drawn from the task's generator) and the launch: no
allocation, no host synchronisation. The warp engine calls :func:`altitude_step` inside its own
one-launch env step instead.

:func:`altitude_start` starts the episodes after a reset (``Task.start_episodes``): the reset rows'
buffers, then every env's reference, errors and observation (written by the same
:func:`write_observation` as the step's); :func:`altitude_observe` is the observation of a given
(measured) state (``Task.observe``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import torch
import warp as wp

from ....constants import DEG, G0
from ....physics._warp import forward_only
from ....physics.task_kernels import (
    FlightState,
    SimulatorViews,
    flight_state,
    normalised_surface,
    observe_kernel,
    task_kernels,
)
from ..warp_common import (
    FusedStep,
    bind_reward_terms,
    clamp_keep_nan,
    clamp_max_keep_nan,
    clamp_min_keep_nan,
    clip,
    fill_struct,
    gaussian_wp,
    taper_wp,
    termination_code,
    torch_sign,
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 8 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=8, dtype=wp.float32)

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class AltitudeBuffers:
    """The task's per-env buffers [N] (views of AltitudeTask's tensors), actions [N] vec2, the random
    target shift [N] int64 and the target table [T]."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    climb_rate: wp.array(dtype=wp.float32)
    target: wp.array(dtype=wp.float32)
    initial_altitude: wp.array(dtype=wp.float32)
    segment_start: wp.array(dtype=wp.float32)
    segment_time: wp.array(dtype=wp.float32)
    time_in_band: wp.array(dtype=wp.float32)
    error_integral: wp.array(dtype=wp.float32)
    previous_elevator: wp.array(dtype=wp.float32)
    elevator_rate: wp.array(dtype=wp.float32)
    previous_airspeed: wp.array(dtype=wp.float32)
    airspeed_rate: wp.array(dtype=wp.float32)
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
    """Config and airframe constants, float32."""

    control_dt: float
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
    w_energy_rate: float
    energy_rate_cap: float
    gravity: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def reference_wp(target: float, start: float, rate: float, elapsed: float) -> wp.vec2:
    """(h_ref, hdot_ref) of the ramp from ``start`` to ``target`` at ``rate`` after ``elapsed`` s:
    h_ref = h* - sgn(h* - h_0) max(|h* - h_0| - r t, 0), hdot_ref = sgn(h* - h_0) r while it runs."""
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


@wp.func
def write_observation(f: FlightState, c: AltitudeConstants, e_h: float, elevator_rate: float, integral: float,
                      reference_rate: float, observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [11] of env i (the task's module docstring) from its
    flight state, e_h = h - h_ref, the elevator rate (rad/s), int(e_h) and hdot_ref."""
    lim = c.observation_clip
    observation[i, 0] = clip(e_h / 25.0, lim)
    observation[i, 1] = clip(f.angular_rate[1] / 2.0, lim)
    observation[i, 2] = clip((f.airspeed - c.trim_airspeed) / c.airspeed_sigma, lim)
    observation[i, 3] = clip(f.euler[1] / c.pitch_scale, lim)
    observation[i, 4] = clip(f.velocity_ned[2] / c.climb_rate_limit, lim)
    observation[i, 5] = clip(f.alpha / c.alpha_scale, lim)
    observation[i, 6] = clip(normalised_surface(f, 0), lim)
    observation[i, 7] = clip(elevator_rate / c.elevator_rate_scale, lim)
    observation[i, 8] = clip(2.0 * f.throttle - 1.0, lim)
    observation[i, 9] = clip(integral / 10.0, lim)
    observation[i, 10] = clip(reference_rate / 5.0, lim)


@wp.func
def altitude_step(sim: SimulatorViews, buf: AltitudeBuffers, c: AltitudeConstants,
                  observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                  reason: wp.array(dtype=wp.int64), i: int):
    """One altitude-task step of env i after the physics: updates the buffers in place
    and writes observation [N, 11], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    height = f.height
    airspeed = f.airspeed
    elevator = f.surfaces[0]
    pitch_rate = f.angular_rate[1]
    # advance: clock, segment time, reference ramp
    dt = c.control_dt
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
    airspeed_rate = (airspeed - buf.previous_airspeed[i]) / dt
    buf.airspeed_rate[i] = airspeed_rate
    buf.previous_airspeed[i] = airspeed
    integral = clamp_keep_nan(buf.error_integral[i] + e_h * dt, -c.integral_limit, c.integral_limit)
    buf.error_integral[i] = integral
    # reward
    e_v = airspeed - c.trim_airspeed
    action = buf.action[i]
    action_rate = wp.length(action - buf.previous_action[i])
    past_target = clamp_min_keep_nan(torch_sign(target - initial) * (height - target), 0.0)
    energy_rate = -f.velocity_ned[2] + airspeed * airspeed_rate / c.gravity
    energy_error = (energy_rate - ref[1]) / c.climb_rate_limit
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_altitude * gaussian_wp(e_h, c.sigma_altitude),
        -(c.w_airspeed * wp.abs(e_v) / c.trim_airspeed),
        -(c.w_pitch_rate * clamp_max_keep_nan(pitch_rate * pitch_rate, c.pitch_rate_cap)),
        -(c.w_smooth * action_rate * taper_wp(e_h, c.gate_band)),
        c.w_altitude * taper_wp(e_h, c.capture_band) * taper_wp(e_v, c.airspeed_band),
        c.survival_bonus,
        -(c.w_overshoot * past_target),
        -(c.w_energy_rate * clamp_max_keep_nan(wp.abs(energy_error), c.energy_rate_cap))))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, False)
    buf.previous_action[i] = action
    write_observation(f, c, e_h, elevator_rate, integral, ref[1], observation, i)


@wp.func
def altitude_start(sim: SimulatorViews, buf: AltitudeBuffers, c: AltitudeConstants,
                   observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]``, its physics reset already written (clock, ramp
    time, filters and previous action zeroed, elevator and airspeed remembered), then, every env, the
    reference ramp, the errors and the observation [N, 11]."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec2(0.0, 0.0)
        buf.segment_time[i] = 0.0
        buf.time_in_band[i] = 0.0
        buf.error_integral[i] = 0.0
        buf.previous_elevator[i] = f.surfaces[0]
        buf.elevator_rate[i] = 0.0
        buf.previous_airspeed[i] = f.airspeed
        buf.airspeed_rate[i] = 0.0
    target = buf.target[i]
    ref = reference_wp(target, buf.segment_start[i], buf.climb_rate[i], buf.segment_time[i])
    buf.reference[i] = ref[0]
    buf.reference_rate[i] = ref[1]
    e_h = f.height - ref[0]
    buf.altitude_error[i] = f.height - target
    buf.reference_error[i] = e_h
    write_observation(f, c, e_h, buf.elevator_rate[i], buf.error_integral[i], ref[1], observation, i)


@wp.func
def altitude_observe(f: FlightState, buf: AltitudeBuffers, c: AltitudeConstants,
                     observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, D] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, f.height - buf.reference[i], buf.elevator_rate[i], buf.error_integral[i],
                      buf.reference_rate[i], observation, i)


#: The step kernel (:func:`altitude_step` of env i = offset + tid), the start kernel
#: (:func:`altitude_start`) and the observe kernel (:func:`altitude_observe`), in this module.
altitude_step_kernel, altitude_start_kernel = task_kernels(
    "altitude", altitude_step, altitude_start, AltitudeBuffers, AltitudeConstants, __name__)
altitude_observe_kernel = observe_kernel("altitude", altitude_observe, AltitudeBuffers, AltitudeConstants,
                                         __name__)


def altitude_constants(task: Task) -> Any:
    """:class:`AltitudeConstants` of ``task``'s config and airframe (Python products first, then
    float32)."""
    cfg = task.config
    return fill_struct(AltitudeConstants(), {
        "control_dt": task.control_dt, "hold_seconds": cfg.hold_seconds, "capture_band": cfg.capture_band,
        "integral_limit": cfg.integral_limit, "trim_airspeed": task.trim_airspeed,
        "airspeed_sigma": cfg.airspeed_scale * task.trim_airspeed,
        "climb_rate_limit": task.airframe.envelope.climb_rate_limit, "pitch_scale": math.pi / 4,
        "alpha_scale": 20.0 * DEG, "elevator_rate_scale": 100.0 * DEG,
        "w_altitude": cfg.w_altitude, "sigma_altitude": cfg.sigma_altitude, "w_airspeed": cfg.w_airspeed,
        "w_pitch_rate": cfg.w_pitch_rate, "pitch_rate_cap": cfg.pitch_rate_cap, "w_smooth": cfg.w_smooth,
        "gate_band": cfg.gate_band, "airspeed_band": cfg.airspeed_band_fraction * task.trim_airspeed,
        "survival_bonus": cfg.survival_bonus, "w_overshoot": cfg.w_overshoot,
        "w_energy_rate": cfg.w_energy_rate, "energy_rate_cap": task.energy_rate_cap, "gravity": G0,
        "stall_alpha": task.stall_alpha, "stall_speed": task.stall_speed,
        "observation_clip": task.observation_clip, "target_sequence": int(bool(cfg.target_sequence)),
    })


class FusedAltitudeStep(FusedStep):
    """The recorded launch of :func:`altitude_step_kernel` for one altitude task: observation [N, 11],
    reward [N], reason [N] long, and the random target shift [N] long drawn before each launch."""

    kernel = altitude_step_kernel
    kernel_func = altitude_step
    buffers = AltitudeBuffers
    constants = AltitudeConstants
    start_kernel = altitude_start_kernel
    observe_kernel = altitude_observe_kernel
    task: Task

    def __init__(self, task: Task):
        super().__init__(task)
        self.shift = torch.zeros(task.num_envs, device=task.device, dtype=torch.long)
        self.shift_high = max(len(task.target_table), 2)
        self.bind()

    def task_inputs(self) -> list[Any]:
        task = self.task
        buf = fill_struct(AltitudeBuffers(), {
            name: getattr(task, name)
            for name in ("time", "climb_rate", "target", "initial_altitude", "segment_start", "segment_time",
                         "time_in_band", "error_integral", "previous_elevator", "elevator_rate",
                         "previous_airspeed", "airspeed_rate", "reference", "reference_rate",
                         "altitude_error", "reference_error", "target_table", "previous_action")})
        fill_struct(buf, {"action": self.action, "shift": self.shift})
        bind_reward_terms(buf, task)
        return [buf, altitude_constants(task)]

    def draw(self) -> None:
        """With a target sequence: the random target shift [N] in [1, T) (a different target of the
        table's T), from the task's generator."""
        task = self.task
        if task.config.target_sequence:
            torch.randint(1, self.shift_high, (task.num_envs,), generator=task.generator, device=task.device,
                          out=self.shift)

    def generators(self) -> tuple[torch.Generator, ...]:
        return (self.task.generator,) if self.task.config.target_sequence else ()
