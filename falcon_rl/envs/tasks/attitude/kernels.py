"""The attitude task's step, written once as Warp functions (``AttitudeTask.fused_stepper``).

:func:`attitude_step` is the task's step for env i after the physics (the equations of the task's
module docstring): it advances the clock and the command stream (a row of the maneuver table, or one
step of the random stream, :func:`random_stream_step`: timer, target redraw on expiry, slew-limited
command), computes the bank, climb-rate and airspeed errors from ``flight_state`` (the twins of the
engine's evaluation kernel), and writes the named reward terms, the reward, the termination reason and
the clipped observation. The task's buffers and the random stream's state (command, target, timer) are
zero-copy Warp views of their torch tensors, so ``info()`` and the stream's reset see the same memory.

:class:`FusedAttitudeStep` (a ``warp_common.FusedStep``) binds the views once, records the launch (one
per CPU slice of the engine) and replays it each step; per step it runs the action copy, with the random
stream the draw of its float32 uniforms [N, 4] (every env's, whether or not its target expires) from the
stream's generator, and the launch. The warp engine calls :func:`attitude_step` inside its own one-launch
env step instead.

:func:`attitude_start` starts the episodes after a reset (``Task.start_episodes``): the reset rows'
buffers, then every env's errors and observation [N, 15] (written by the same :func:`write_observation`
as the step's); :func:`attitude_observe` is the observation of a given (measured) state
(``Task.observe``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import torch
import warp as wp

from ....constants import DEG
from ....physics._warp import forward_only
from ....physics.task_kernels import FlightState, SimulatorViews, flight_state, observe_kernel, task_kernels
from ..warp_common import (
    FusedStep,
    airspeed_margin_penalty_wp,
    bind_reward_terms,
    clamp_keep_nan,
    clip,
    fill_struct,
    gaussian_wp,
    termination_code,
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 5 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=5, dtype=wp.float32)

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class AttitudeBuffers:
    """The task's per-env buffers (views of AttitudeTask's tensors and of its random stream's), the
    actions [N] vec4, the step's uniforms [N] vec4 and the maneuver table [T] vec3."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    step_index: wp.array(dtype=wp.int64)
    commanded: wp.array(dtype=wp.vec3)
    errors: wp.array(dtype=wp.vec3)
    previous_action: wp.array(dtype=wp.vec4)
    action: wp.array(dtype=wp.vec4)
    stream_command: wp.array(dtype=wp.vec3)
    stream_target: wp.array(dtype=wp.vec3)
    stream_timer: wp.array(dtype=wp.float32)
    draws: wp.array(dtype=wp.vec4)
    table: wp.array(dtype=wp.vec3)


@wp.struct
class AttitudeConstants:
    """Config, stream and airframe constants, float32."""

    control_dt: float
    random: int  # 1: RandomCommandStream, 0: maneuver table
    table_last: wp.int64
    stream_dt: float
    target_low: wp.vec3
    target_span: wp.vec3  # high - low
    slew_min: wp.vec3  # -rate x dt
    slew_max: wp.vec3  # rate x dt
    hold_low: float
    hold_span: float
    error_scale: wp.vec3
    angle_scale: float  # pi / 4
    air_angle_scale: float  # 20 deg
    climb_scale: float
    w_bank: float
    sigma_bank: float
    w_climb: float
    sigma_climb: float
    w_airspeed: float
    sigma_airspeed: float
    w_energy: float
    safe_airspeed: float
    w_smooth: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def clamp_vec3_keep_nan(v: wp.vec3, lo: wp.vec3, hi: wp.vec3) -> wp.vec3:
    """``torch.clamp`` with tensor bounds, per component."""
    return wp.vec3(clamp_keep_nan(v[0], lo[0], hi[0]), clamp_keep_nan(v[1], lo[1], hi[1]),
                   clamp_keep_nan(v[2], lo[2], hi[2]))


@wp.func
def random_stream_step(buf: AttitudeBuffers, c: AttitudeConstants, i: int) -> wp.vec3:
    """One step of env i's random command stream: its timer runs down by the stream's dt; on expiry a
    new target in [low, high] and a new hold time come from the step's uniforms ``buf.draws[i]``; the
    command slews toward the target by at most rate x dt per component. Returns the new command
    (phi*, hdot*, V_a*)."""
    timer = buf.stream_timer[i] - c.stream_dt
    target = buf.stream_target[i]
    if timer <= 0.0:
        u = buf.draws[i]
        target = c.target_low + wp.cw_mul(c.target_span, wp.vec3(u[0], u[1], u[2]))
        timer = c.hold_low + c.hold_span * u[3]
    buf.stream_timer[i] = timer
    buf.stream_target[i] = target
    command = buf.stream_command[i]
    command = command + clamp_vec3_keep_nan(target - command, c.slew_min, c.slew_max)
    buf.stream_command[i] = command
    return command


@wp.func
def write_observation(f: FlightState, c: AttitudeConstants, errors: wp.vec3, previous_action: wp.vec4,
                      observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [15] of env i (the task's module docstring) from its
    flight state, tracking errors (e_phi, e_hdot, e_Va) and previous action."""
    lim = c.observation_clip
    for k in range(3):
        observation[i, k] = clip(errors[k] / c.error_scale[k], lim)
        observation[i, 5 + k] = clip(f.angular_rate[k] / 2.0, lim)
    observation[i, 3] = clip(f.euler[0] / c.angle_scale, lim)
    observation[i, 4] = clip(f.euler[1] / c.angle_scale, lim)
    observation[i, 8] = clip(f.alpha / c.air_angle_scale, lim)
    observation[i, 9] = clip(f.beta / c.air_angle_scale, lim)
    observation[i, 10] = clip(f.velocity_ned[2] / c.climb_scale, lim)
    for k in range(4):
        observation[i, 11 + k] = clip(previous_action[k], lim)


@wp.func
def tracking_errors(f: FlightState, commanded: wp.vec3) -> wp.vec3:
    """(e_phi, e_hdot, e_Va) = (phi, hdot, V_a) - (phi*, hdot*, V_a*) of the flight state against the
    command, hdot = -v_z."""
    return wp.vec3(f.euler[0], -f.velocity_ned[2], f.airspeed) - commanded


@wp.func
def attitude_step(sim: SimulatorViews, buf: AttitudeBuffers, c: AttitudeConstants,
                  observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                  reason: wp.array(dtype=wp.int64), i: int):
    """One attitude-task step of env i after the physics: updates the buffers in place
    and writes observation [N, 15], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    # advance: clock, command stream
    buf.time[i] = buf.time[i] + c.control_dt
    index = buf.step_index[i] + wp.int64(1)
    buf.step_index[i] = index
    commanded = wp.vec3(0.0)
    if c.random != 0:
        commanded = random_stream_step(buf, c, i)
    else:
        commanded = buf.table[int(wp.min(index, c.table_last))]
    buf.commanded[i] = commanded
    # update: tracking errors (e_phi, e_hdot, e_Va)
    errors = tracking_errors(f, commanded)
    buf.errors[i] = errors
    # reward
    action = buf.action[i]
    action_rate = wp.length_sq(action - buf.previous_action[i])
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_bank * gaussian_wp(errors[0], c.sigma_bank),
        c.w_climb * gaussian_wp(errors[1], c.sigma_climb),
        c.w_airspeed * gaussian_wp(errors[2], c.sigma_airspeed),
        -(c.w_energy * airspeed_margin_penalty_wp(f.airspeed, c.safe_airspeed)),
        -(c.w_smooth * action_rate)))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, False)
    buf.previous_action[i] = action
    write_observation(f, c, errors, action, observation, i)


@wp.func
def attitude_start(sim: SimulatorViews, buf: AttitudeBuffers, c: AttitudeConstants,
                   observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]``, its physics reset and its stream's reset already
    written (clock and previous action zeroed, the command set to the stream's or the table's current
    one), then, every env, the tracking errors and the observation [N, 15]."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec4(0.0)
        if c.random != 0:
            buf.commanded[i] = buf.stream_command[i]
        else:
            buf.commanded[i] = buf.table[int(wp.min(buf.step_index[i], c.table_last))]
    errors = tracking_errors(f, buf.commanded[i])
    buf.errors[i] = errors
    write_observation(f, c, errors, buf.previous_action[i], observation, i)


@wp.func
def attitude_observe(f: FlightState, buf: AttitudeBuffers, c: AttitudeConstants,
                     observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, D] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, tracking_errors(f, buf.commanded[i]), buf.previous_action[i], observation, i)


#: The step kernel (:func:`attitude_step` of env i = offset + tid), the start kernel
#: (:func:`attitude_start`) and the observe kernel (:func:`attitude_observe`), in this module.
attitude_step_kernel, attitude_start_kernel = task_kernels(
    "attitude", attitude_step, attitude_start, AttitudeBuffers, AttitudeConstants, __name__)
attitude_observe_kernel = observe_kernel("attitude", attitude_observe, AttitudeBuffers, AttitudeConstants,
                                         __name__)


def attitude_constants(task: Task) -> Any:
    """:class:`AttitudeConstants` of ``task``'s config, stream and airframe."""
    cfg = task.config
    env = task.airframe.envelope
    values: dict[str, Any] = {
        "control_dt": task.control_dt, "random": 0, "table_last": 0, "stream_dt": 0.0,
        "target_low": (0.0,) * 3,
        "target_span": (0.0,) * 3, "slew_min": (0.0,) * 3, "slew_max": (0.0,) * 3, "hold_low": 0.0,
        "hold_span": 0.0, "error_scale": tuple(task.error_scale.tolist()), "angle_scale": math.pi / 4,
        "air_angle_scale": 20.0 * DEG, "climb_scale": task.climb_scale, "w_bank": cfg.w_bank,
        "sigma_bank": cfg.sigma_bank, "w_climb": cfg.w_climb,
        "sigma_climb": cfg.sigma_climb_fraction * env.climb_rate_limit, "w_airspeed": cfg.w_airspeed,
        "sigma_airspeed": cfg.sigma_airspeed_fraction * env.cruise_speed, "w_energy": cfg.w_energy,
        "safe_airspeed": task.safe_airspeed, "w_smooth": cfg.w_smooth, "stall_alpha": task.stall_alpha,
        "stall_speed": task.stall_speed, "observation_clip": task.observation_clip,
    }
    stream = task.random_stream
    if stream is not None:
        lo, hi = stream.hold_seconds
        values.update({"random": 1, "stream_dt": stream.dt, "target_low": tuple(stream.low.tolist()),
                       "target_span": tuple((stream.high - stream.low).tolist()),
                       "slew_min": tuple((-stream.rate * stream.dt).tolist()),
                       "slew_max": tuple((stream.rate * stream.dt).tolist()), "hold_low": lo,
                       "hold_span": hi - lo})
    else:
        assert task.table is not None
        values["table_last"] = task.table.shape[0] - 1
    constants = fill_struct(AttitudeConstants(), values)
    constants.table_last = wp.int64(values["table_last"])
    return constants


class FusedAttitudeStep(FusedStep):
    """The recorded launch of :func:`attitude_step_kernel` for one attitude task: observation [N, 15],
    reward [N], reason [N] long, and the random stream's uniforms [N, 4] drawn before each launch."""

    kernel = attitude_step_kernel
    kernel_func = attitude_step
    buffers = AttitudeBuffers
    constants = AttitudeConstants
    start_kernel = attitude_start_kernel
    observe_kernel = attitude_observe_kernel
    task: Task

    def __init__(self, task: Task):
        super().__init__(task)
        n, kw = task.num_envs, {"device": task.device, "dtype": torch.float32}
        self.draws = torch.zeros(n if task.random_stream is not None else 1, 4, **kw)
        #: Placeholders for the buffers of the other command source (never read by the kernel).
        self._unused = {"vec3": torch.zeros(1, 3, **kw), "scalar": torch.zeros(1, **kw)}
        self.bind()

    def task_inputs(self) -> list[Any]:
        task = self.task
        stream = task.random_stream
        vec3, scalar = self._unused["vec3"], self._unused["scalar"]
        return [bind_reward_terms(fill_struct(AttitudeBuffers(), {
            "time": task.time, "step_index": task.step_index, "commanded": task.commanded,
            "errors": task.errors, "previous_action": task.previous_action, "action": self.action,
            "stream_command": stream.command if stream is not None else vec3,
            "stream_target": stream.target if stream is not None else vec3,
            "stream_timer": stream.timer if stream is not None else scalar, "draws": self.draws,
            "table": task.table if task.table is not None else vec3,
        }), task), attitude_constants(task)]

    def draw(self) -> None:
        """With a random stream: the step's float32 uniforms [N, 4] (every env's, whether or not its
        target expires), from the stream's generator."""
        stream = self.task.random_stream
        if stream is not None:
            torch.rand(self.draws.shape, generator=stream.generator, device=self.draws.device,
                       dtype=self.draws.dtype, out=self.draws)

    def generators(self) -> tuple[torch.Generator, ...]:
        stream = self.task.random_stream
        return (stream.generator,) if stream is not None else ()
