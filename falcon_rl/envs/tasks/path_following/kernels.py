"""The path-following task's step, written once as Warp functions (``PathFollowingTask.fused_stepper``).

:func:`path_following_step` is the task's step for env i after the physics (the equations of the task's
module docstring): it advances the clock, computes the cross-track, course and altitude errors from
``flight_state`` (the twins of the engine's evaluation kernel), and writes the named reward terms, the
reward, the termination reason ("lost" after the shared reasons) and the clipped observation. The task's
buffers are zero-copy Warp views of its torch tensors, so ``info()`` sees the same memory. The step
draws no random numbers.

:class:`FusedPathFollowingStep` (a ``warp_common.FusedStep``) binds the views once, records the launch
(one per CPU slice of the engine) and replays it each step (the action copy and the launch). The warp
engine calls :func:`path_following_step` inside its own one-launch env step instead.

:func:`path_following_start` starts the episodes after a reset (``Task.start_episodes``): the reset
rows' buffers, then every env's errors and observation [N, 17] (written by the same
:func:`write_observation` as the step's); :func:`path_following_observe` is the observation of a given
(measured) state (``Task.observe``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import warp as wp

from ....constants import DEG
from ....physics._warp import forward_only
from ....physics.task_kernels import FlightState, SimulatorViews, flight_state, observe_kernel, task_kernels
from ..warp_common import (
    FusedStep,
    airspeed_margin_penalty_wp,
    bind_reward_terms,
    clip,
    fill_struct,
    gaussian_wp,
    termination_code,
    wrap_angle_wp,
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 5 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=5, dtype=wp.float32)

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class PathFollowingBuffers:
    """The task's per-env buffers (views of PathFollowingTask's tensors) and the actions [N] vec4."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    path_point: wp.array(dtype=wp.vec2)
    path_course: wp.array(dtype=wp.float32)
    errors: wp.array(dtype=wp.vec3)
    previous_action: wp.array(dtype=wp.vec4)
    action: wp.array(dtype=wp.vec4)


@wp.struct
class PathFollowingConstants:
    """Config and airframe constants, float32."""

    control_dt: float
    path_height: float
    lost_distance: float
    climb_rate_limit: float
    cruise_speed: float
    airspeed_sigma: float  # airspeed_scale x cruise
    angle_scale: float  # pi / 4
    air_angle_scale: float  # 20 deg
    w_cross_track: float
    sigma_cross_track: float
    w_course: float
    sigma_course: float
    w_altitude: float
    sigma_altitude: float
    w_energy: float
    safe_airspeed: float
    w_smooth: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def path_errors(f: FlightState, buf: PathFollowingBuffers, c: PathFollowingConstants, i: int) -> wp.vec3:
    """buf.errors[i] <- (e_y, chi_err, e_h) of env i against its path (the task's module docstring);
    returns them."""
    point = buf.path_point[i]
    course = buf.path_course[i]
    rel_north = f.position_ned[0] - point[0]
    rel_east = f.position_ned[1] - point[1]
    cross_track = -wp.sin(course) * rel_north + wp.cos(course) * rel_east
    v = f.velocity_ned
    course_error = wrap_angle_wp(wp.atan2(v[1], v[0]) - course)
    errors = wp.vec3(cross_track, course_error, f.height - c.path_height)
    buf.errors[i] = errors
    return errors


@wp.func
def write_observation(f: FlightState, c: PathFollowingConstants, errors: wp.vec3, previous_action: wp.vec4,
                      observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [17] of env i (the task's module docstring) from its
    flight state, path errors (e_y, chi_err, e_h) and previous action."""
    lim = c.observation_clip
    observation[i, 0] = clip(errors[0] / 50.0, lim)
    observation[i, 1] = clip(wp.sin(errors[1]), lim)
    observation[i, 2] = clip(wp.cos(errors[1]), lim)
    observation[i, 3] = clip(errors[2] / 25.0, lim)
    observation[i, 4] = clip(f.velocity_ned[2] / c.climb_rate_limit, lim)
    observation[i, 5] = clip((f.airspeed - c.cruise_speed) / c.airspeed_sigma, lim)
    observation[i, 6] = clip(f.euler[0] / c.angle_scale, lim)
    observation[i, 7] = clip(f.euler[1] / c.angle_scale, lim)
    observation[i, 8] = clip(f.alpha / c.air_angle_scale, lim)
    observation[i, 9] = clip(f.beta / c.air_angle_scale, lim)
    for k in range(3):
        observation[i, 10 + k] = clip(f.angular_rate[k] / 2.0, lim)
    for k in range(4):
        observation[i, 13 + k] = clip(previous_action[k], lim)


@wp.func
def path_following_step(sim: SimulatorViews, buf: PathFollowingBuffers, c: PathFollowingConstants,
                        observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                        reason: wp.array(dtype=wp.int64), i: int):
    """One path-following step of env i after the physics: updates the buffers in place
    and writes observation [N, 17], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    buf.time[i] = buf.time[i] + c.control_dt
    errors = path_errors(f, buf, c, i)
    cross_track = errors[0]
    course_error = errors[1]
    altitude_error = errors[2]
    # reward
    action = buf.action[i]
    action_rate = wp.length_sq(action - buf.previous_action[i])
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_cross_track * gaussian_wp(cross_track, c.sigma_cross_track),
        c.w_course * gaussian_wp(course_error, c.sigma_course),
        c.w_altitude * gaussian_wp(altitude_error, c.sigma_altitude),
        -(c.w_energy * airspeed_margin_penalty_wp(f.airspeed, c.safe_airspeed)),
        -(c.w_smooth * action_rate)))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, wp.abs(cross_track) > c.lost_distance)
    buf.previous_action[i] = action
    write_observation(f, c, errors, action, observation, i)


@wp.func
def path_following_start(sim: SimulatorViews, buf: PathFollowingBuffers, c: PathFollowingConstants,
                         observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]``, its physics reset already written (clock and
    previous action zeroed), then, every env, the path errors and the observation [N, 17]."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec4(0.0)
    write_observation(f, c, path_errors(f, buf, c, i), buf.previous_action[i], observation, i)


@wp.func
def path_following_observe(f: FlightState, buf: PathFollowingBuffers, c: PathFollowingConstants,
                           observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, D] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, buf.errors[i], buf.previous_action[i], observation, i)


#: The step kernel (:func:`path_following_step` of env i = offset + tid), the start kernel
#: (:func:`path_following_start`) and the observe kernel (:func:`path_following_observe`), in this module.
path_following_step_kernel, path_following_start_kernel = task_kernels(
    "path_following", path_following_step, path_following_start, PathFollowingBuffers,
    PathFollowingConstants, __name__)
path_following_observe_kernel = observe_kernel("path_following", path_following_observe, PathFollowingBuffers,
                                               PathFollowingConstants, __name__)


class FusedPathFollowingStep(FusedStep):
    """The recorded launch of :func:`path_following_step_kernel` for one path-following task:
    observation [N, 17], reward [N], reason [N] long."""

    kernel = path_following_step_kernel
    kernel_func = path_following_step
    buffers = PathFollowingBuffers
    constants = PathFollowingConstants
    start_kernel = path_following_start_kernel
    observe_kernel = path_following_observe_kernel
    task: Task

    def __init__(self, task: Task):
        super().__init__(task)
        self.bind()

    def task_inputs(self) -> list[Any]:
        task = self.task
        cfg = task.config
        env = task.airframe.envelope
        buf = fill_struct(PathFollowingBuffers(), {
            "time": task.time, "path_point": task.path_point, "path_course": task.path_course,
            "errors": task.errors, "previous_action": task.previous_action, "action": self.action})
        bind_reward_terms(buf, task)
        constants = fill_struct(PathFollowingConstants(), {
            "control_dt": task.control_dt, "path_height": cfg.initial_height,
            "lost_distance": cfg.lost_distance,
            "climb_rate_limit": env.climb_rate_limit, "cruise_speed": env.cruise_speed,
            "airspeed_sigma": cfg.airspeed_scale * env.cruise_speed, "angle_scale": math.pi / 4,
            "air_angle_scale": 20.0 * DEG, "w_cross_track": cfg.w_cross_track,
            "sigma_cross_track": cfg.sigma_cross_track, "w_course": cfg.w_course,
            "sigma_course": cfg.sigma_course, "w_altitude": cfg.w_altitude,
            "sigma_altitude": cfg.sigma_altitude, "w_energy": cfg.w_energy,
            "safe_airspeed": task.safe_airspeed, "w_smooth": cfg.w_smooth, "stall_alpha": task.stall_alpha,
            "stall_speed": task.stall_speed, "observation_clip": task.observation_clip})
        return [buf, constants]
