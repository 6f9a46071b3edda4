"""The landing task's step, written once as Warp functions (``LandingTask.fused_stepper``).

:func:`landing_step` is the task's step for env i after the physics (the equations of the task's module
docstring): it advances the clock, computes the glide-path, centreline and course errors and the wheels'
height from ``flight_state``, detects the touchdown (or a wing-tip strike) and keeps its state, and writes
the named reward terms, the reward, the termination reason and the clipped observation.
:func:`landing_start` starts the episodes after a reset; :func:`landing_observe` observes a given
(measured) state. The task's buffers are zero-copy Warp views of its float32 torch tensors.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import warp as wp

from ....constants import DEG
from ....physics._warp import forward_only
from ....physics.task_kernels import FlightState, SimulatorViews, flight_state, observe_kernel, task_kernels
from ..base import TERMINATION_CODE
from ..warp_common import (
    ALPHA_STALL,
    LOST,
    SPEED_STALL,
    FusedStep,
    bind_reward_terms,
    clamp_max_keep_nan,
    clip,
    fill_struct,
    gaussian_wp,
    wrap_angle_wp,
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 6 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=6, dtype=wp.float32)
TOUCHDOWN = wp.constant(TERMINATION_CODE["touchdown"])
TIP_STRIKE = wp.constant(TERMINATION_CODE["tip_strike"])

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class LandingBuffers:
    """The task's per-env buffers [N] (views of LandingTask's tensors) and actions [N] vec4."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    errors: wp.array(dtype=wp.vec3)  # (e_h, e_y, chi_err)
    glide_path_height: wp.array(dtype=wp.float32)
    reference_climb_rate: wp.array(dtype=wp.float32)
    wheel_height: wp.array(dtype=wp.float32)
    touchdown: wp.array(dtype=wp.float32)
    touchdown_state: wp.array2d(dtype=wp.float32)  # [N, 5] (sink, pitch, bank, along, lateral)
    ground_effect_north: wp.array(dtype=wp.float32)
    previous_action: wp.array(dtype=wp.vec4)
    action: wp.array(dtype=wp.vec4)


@wp.struct
class LandingConstants:
    """Config and airframe constants, float32."""

    control_dt: float
    span: float
    gear: float  # m
    tan_glide: float
    distance_max: float
    trim_airspeed: float
    airspeed_sigma: float
    climb_rate_limit: float
    angle_scale: float  # pi / 4
    air_angle_scale: float  # 20 deg
    pitch_min: float
    pitch_max: float
    bank_max: float
    lost_lateral: float
    long_distance: float
    w_glide_path: float
    sigma_glide_path: float
    w_centerline: float
    sigma_centerline: float
    w_airspeed: float
    w_bank: float
    w_smooth: float
    w_touchdown: float
    sigma_touchdown: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def glide_height(f: FlightState, c: LandingConstants) -> float:
    """h_gp (m) at the aircraft's north position: the gear height plus tan(gamma) x the distance to go."""
    return c.gear + c.tan_glide * wp.max(-f.position_ned[0], 0.0)


@wp.func
def glide_errors(f: FlightState, c: LandingConstants) -> wp.vec3:
    """(e_h, e_y, chi_err) of a flight state against the glide path and the centreline."""
    return wp.vec3(f.height - glide_height(f, c), f.position_ned[1],
                   wrap_angle_wp(wp.atan2(f.velocity_ned[1], f.velocity_ned[0])))


@wp.func
def landing_errors(f: FlightState, buf: LandingBuffers, c: LandingConstants, i: int) -> wp.vec3:
    """Env i's glide-path reference, wheel height and errors (e_h, e_y, chi_err) into its buffers (the
    ground-effect entry noted); returns the errors."""
    north = f.position_ned[0]
    height_ref = glide_height(f, c)
    ground_speed = wp.sqrt(f.velocity_ned[0] * f.velocity_ned[0] + f.velocity_ned[1] * f.velocity_ned[1])
    rate_ref = float(0.0)  # noqa: UP018 (a mutable Warp local)
    if north < 0.0:
        rate_ref = -ground_speed * c.tan_glide
    wheels = f.clearance - c.gear
    buf.glide_path_height[i] = height_ref
    buf.reference_climb_rate[i] = rate_ref
    buf.wheel_height[i] = wheels
    if wheels < c.span:
        buf.ground_effect_north[i] = wp.min(buf.ground_effect_north[i], north)
    errors = glide_errors(f, c)
    buf.errors[i] = errors
    return errors


@wp.func
def write_observation(f: FlightState, c: LandingConstants, errors: wp.vec3, wheels: float,
                      previous_action: wp.vec4, observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [19] of env i (the task's module docstring)."""
    lim = c.observation_clip
    observation[i, 0] = clip(errors[0] / 5.0, lim)
    observation[i, 1] = clip(wheels / c.span, lim)
    observation[i, 2] = clip(f.velocity_ned[2] / c.climb_rate_limit, lim)
    observation[i, 3] = clip(errors[1] / 10.0, lim)
    observation[i, 4] = clip(wp.sin(errors[2]), lim)
    observation[i, 5] = clip(wp.cos(errors[2]), lim)
    observation[i, 6] = clip((f.airspeed - c.trim_airspeed) / c.airspeed_sigma, lim)
    observation[i, 7] = clip(f.euler[0] / c.angle_scale, lim)
    observation[i, 8] = clip(f.euler[1] / c.angle_scale, lim)
    for k in range(3):
        observation[i, 9 + k] = clip(f.angular_rate[k] / 2.0, lim)
    observation[i, 12] = clip(f.alpha / c.air_angle_scale, lim)
    observation[i, 13] = clip(f.beta / c.air_angle_scale, lim)
    observation[i, 14] = clip(-f.position_ned[0] / c.distance_max, lim)
    for k in range(4):
        observation[i, 15 + k] = clip(previous_action[k], lim)


@wp.func
def landing_reason(f: FlightState, c: LandingConstants, errors: wp.vec3, wheels: float) -> wp.int64:
    """The first reason that applies: a wing-tip strike, the touchdown (wheels on the surface), stall,
    lost (off the centreline or long); 0 while flying."""
    reason = wp.int64(0)  # written from the last reason to the first: the first that applies stays
    if wp.abs(errors[1]) > c.lost_lateral or f.position_ned[0] > c.long_distance:
        reason = wp.int64(LOST)
    if f.airspeed < c.stall_speed:
        reason = wp.int64(SPEED_STALL)
    if wp.abs(f.alpha) > c.stall_alpha:
        reason = wp.int64(ALPHA_STALL)
    if wheels <= 0.0:
        reason = wp.int64(TOUCHDOWN)
    if f.lowest_tip <= 0.0:
        reason = wp.int64(TIP_STRIKE)
    return reason


@wp.func
def landing_step(sim: SimulatorViews, buf: LandingBuffers, c: LandingConstants,
                 observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                 reason: wp.array(dtype=wp.int64), i: int):
    """One landing step of env i after the physics: updates the buffers in place and writes observation
    [N, 19], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    buf.time[i] = buf.time[i] + c.control_dt
    errors = landing_errors(f, buf, c, i)
    wheels = buf.wheel_height[i]
    code = landing_reason(f, c, errors, wheels)
    # The touchdown's state; an aircraft the engine stopped on the ground (its CG went below in the step)
    # has no velocity left: its sink is the one the step started with (the last published).
    sink = f.velocity_ned[2]
    speed = wp.length(f.velocity_ned)
    if speed == 0.0:
        sink = buf.touchdown_state[i, 0]
    buf.touchdown_state[i, 0] = sink
    touchdown_term = float(0.0)  # noqa: UP018 (a mutable Warp local)
    buf.touchdown[i] = 0.0
    if code == wp.int64(TOUCHDOWN):
        buf.touchdown[i] = 1.0
        buf.touchdown_state[i, 1] = f.euler[1]
        buf.touchdown_state[i, 2] = f.euler[0]
        buf.touchdown_state[i, 3] = f.position_ned[0]
        buf.touchdown_state[i, 4] = f.position_ned[1]
        if f.euler[1] >= c.pitch_min and f.euler[1] <= c.pitch_max and wp.abs(f.euler[0]) <= c.bank_max:
            touchdown_term = c.w_touchdown * gaussian_wp(sink, c.sigma_touchdown)
    action = buf.action[i]
    action_change = action - buf.previous_action[i]
    bank = f.euler[0] / c.angle_scale
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_glide_path * gaussian_wp(errors[0], c.sigma_glide_path),
        c.w_centerline * gaussian_wp(errors[1], c.sigma_centerline),
        -(c.w_airspeed * wp.abs(f.airspeed - c.trim_airspeed) / c.trim_airspeed),
        -(c.w_bank * clamp_max_keep_nan(bank * bank, 1.0)),
        -(c.w_smooth * wp.dot(action_change, action_change)),
        touchdown_term))
    reason[i] = code
    buf.previous_action[i] = action
    write_observation(f, c, errors, wheels, action, observation, i)


@wp.func
def landing_start(sim: SimulatorViews, buf: LandingBuffers, c: LandingConstants,
                  observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]`` (clock, previous action, touchdown zeroed), its
    physics reset already written; then, every env, the errors and the observation."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec4(0.0)
        buf.touchdown[i] = 0.0
        for k in range(5):
            buf.touchdown_state[i, k] = 0.0
        buf.touchdown_state[i, 0] = f.velocity_ned[2]
    errors = landing_errors(f, buf, c, i)
    write_observation(f, c, errors, buf.wheel_height[i], buf.previous_action[i], observation, i)


@wp.func
def landing_observe(f: FlightState, buf: LandingBuffers, c: LandingConstants,
                    observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, 19] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, glide_errors(f, c), f.clearance - c.gear, buf.previous_action[i], observation, i)


landing_step_kernel, landing_start_kernel = task_kernels(
    "landing", landing_step, landing_start, LandingBuffers, LandingConstants, __name__)
landing_observe_kernel = observe_kernel("landing", landing_observe, LandingBuffers, LandingConstants,
                                        __name__)


def landing_constants(task: Task) -> Any:
    """:class:`LandingConstants` of ``task``'s config and airframe (Python products, then float32)."""
    cfg, span = task.config, float(task.airframe.geometry.span)
    return fill_struct(LandingConstants(), {
        "control_dt": task.control_dt, "span": span, "gear": cfg.gear_height * span,
        "tan_glide": math.tan(cfg.glide_slope), "distance_max": cfg.distance_max,
        "trim_airspeed": task.trim_airspeed, "airspeed_sigma": cfg.airspeed_scale * task.trim_airspeed,
        "climb_rate_limit": task.airframe.envelope.climb_rate_limit, "angle_scale": math.pi / 4,
        "air_angle_scale": 20.0 * DEG, "pitch_min": cfg.pitch_min, "pitch_max": cfg.pitch_max,
        "bank_max": cfg.bank_max, "lost_lateral": cfg.lost_lateral, "long_distance": cfg.long_distance,
        "w_glide_path": cfg.w_glide_path, "sigma_glide_path": cfg.sigma_glide_path,
        "w_centerline": cfg.w_centerline, "sigma_centerline": cfg.sigma_centerline,
        "w_airspeed": cfg.w_airspeed, "w_bank": cfg.w_bank, "w_smooth": cfg.w_smooth,
        "w_touchdown": cfg.w_touchdown, "sigma_touchdown": cfg.sigma_touchdown,
        "stall_alpha": task.stall_alpha, "stall_speed": task.stall_speed,
        "observation_clip": task.observation_clip,
    })


class FusedLandingStep(FusedStep):
    """The recorded launch of :func:`landing_step_kernel` for one landing task: observation [N, 19], reward
    [N], reason [N] long."""

    kernel = landing_step_kernel
    kernel_func = landing_step
    buffers = LandingBuffers
    constants = LandingConstants
    start_kernel = landing_start_kernel
    observe_kernel = landing_observe_kernel

    def __init__(self, task: Task):
        super().__init__(task)
        self.bind()

    def task_inputs(self) -> list[Any]:
        task = self.task
        buf = fill_struct(LandingBuffers(), {
            name: getattr(task, name)
            for name in ("time", "errors", "glide_path_height", "reference_climb_rate", "wheel_height",
                         "touchdown", "ground_effect_north", "previous_action")})
        buf.touchdown_state = wp.from_torch(task.touchdown_state)
        fill_struct(buf, {"action": self.action})
        bind_reward_terms(buf, task)
        return [buf, landing_constants(task)]
