"""The trajectory task's step, written once as Warp functions (``TrajectoryTask.fused_stepper``).

:func:`trajectory_step` is the task's step for env i after the physics (the equations of the task's
module docstring): it advances the clock and the reference point along its helix arc (closed form),
rotates the position and velocity errors into the heading frame using ``flight_state`` (the twins of
the engine's evaluation kernel), and writes the named reward terms, the reward, the termination reason
("lost" after the shared reasons) and the clipped observation. The task's buffers are zero-copy Warp
views of its torch tensors, so ``info()`` sees the same memory. The step draws no random numbers.

:class:`FusedTrajectoryStep` (a ``warp_common.FusedStep``) binds the views once, records the launch
(one per CPU slice of the engine) and replays it each step (the action copy and the launch). The warp
engine calls :func:`trajectory_step` inside its own one-launch env step instead.

:func:`trajectory_start` starts the episodes after a reset (``Task.start_episodes``): the reset rows'
buffers, then every env's reference point, errors and observation [N, 17] (written by the same
:func:`write_observation` as the step's); :func:`trajectory_observe` is the observation of a given
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
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 4 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=4, dtype=wp.float32)

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class TrajectoryBuffers:
    """The task's per-env buffers (views of TrajectoryTask's tensors) and the actions [N] vec4."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    start: wp.array(dtype=wp.vec3)
    radius: wp.array(dtype=wp.float32)
    turn: wp.array(dtype=wp.float32)
    climb: wp.array(dtype=wp.float32)
    reference_position: wp.array(dtype=wp.vec3)
    reference_velocity: wp.array(dtype=wp.vec3)
    position_error: wp.array(dtype=wp.vec3)
    velocity_error: wp.array(dtype=wp.vec3)
    position_error_ned: wp.array(dtype=wp.vec3)
    previous_action: wp.array(dtype=wp.vec4)
    action: wp.array(dtype=wp.vec4)


@wp.struct
class TrajectoryConstants:
    """Config and airframe constants, float32."""

    control_dt: float
    speed: float  # cruise speed V of the reference
    lost_distance: float
    velocity_scale: float  # airspeed_scale x V
    angle_scale: float  # pi / 4
    air_angle_scale: float  # 20 deg
    w_position: float
    sigma_position: float
    w_velocity: float
    sigma_velocity: float  # sigma_velocity_fraction x V
    w_energy: float
    safe_airspeed: float
    w_smooth: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def heading_frame(e: wp.vec3, sin_yaw: float, cos_yaw: float) -> wp.vec3:
    """NED vector ``e`` in the heading frame (forward, right, down) of yaw psi."""
    return wp.vec3(cos_yaw * e[0] + sin_yaw * e[1], -sin_yaw * e[0] + cos_yaw * e[1], e[2])


@wp.func
def reference_point(buf: TrajectoryBuffers, c: TrajectoryConstants, time: float, i: int):
    """buf.reference_position[i], buf.reference_velocity[i] <- p_ref and v_ref of env i at ``time``
    (the helix arc of the task's module docstring, closed form)."""
    radius = buf.radius[i]
    turn = buf.turn[i]
    climb = buf.climb[i]
    angle = c.speed / radius * time
    s = wp.sin(angle)
    co = wp.cos(angle)
    buf.reference_position[i] = buf.start[i] + wp.vec3(radius * s, turn * radius * (1.0 - co), -climb * time)
    buf.reference_velocity[i] = wp.vec3(c.speed * co, turn * c.speed * s, -climb)


@wp.func
def update_errors(f: FlightState, buf: TrajectoryBuffers, i: int):
    """The errors of env i into its buffers: e_p = p - p_ref (NED, ``position_error_ned``), and e_p and
    e_v = v - v_ref rotated into the heading frame (``position_error``, ``velocity_error``)."""
    yaw = f.euler[2]
    sin_yaw = wp.sin(yaw)
    cos_yaw = wp.cos(yaw)
    e_p = f.position_ned - buf.reference_position[i]
    buf.position_error_ned[i] = e_p
    buf.position_error[i] = heading_frame(e_p, sin_yaw, cos_yaw)
    buf.velocity_error[i] = heading_frame(f.velocity_ned - buf.reference_velocity[i], sin_yaw, cos_yaw)


@wp.func
def write_observation(f: FlightState, c: TrajectoryConstants, position_error: wp.vec3,
                      velocity_error: wp.vec3, previous_action: wp.vec4,
                      observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [17] of env i (the task's module docstring) from its
    flight state, heading-frame errors and previous action."""
    lim = c.observation_clip
    for k in range(3):
        observation[i, k] = clip(position_error[k] / 25.0, lim)
        observation[i, 3 + k] = clip(velocity_error[k] / c.velocity_scale, lim)
        observation[i, 8 + k] = clip(f.angular_rate[k] / 2.0, lim)
    observation[i, 6] = clip(f.euler[0] / c.angle_scale, lim)
    observation[i, 7] = clip(f.euler[1] / c.angle_scale, lim)
    observation[i, 11] = clip(f.alpha / c.air_angle_scale, lim)
    observation[i, 12] = clip(f.beta / c.air_angle_scale, lim)
    for k in range(4):
        observation[i, 13 + k] = clip(previous_action[k], lim)


@wp.func
def trajectory_step(sim: SimulatorViews, buf: TrajectoryBuffers, c: TrajectoryConstants,
                    observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                    reason: wp.array(dtype=wp.int64), i: int):
    """One trajectory-task step of env i after the physics: updates the buffers in place
    and writes observation [N, 17], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    time = buf.time[i] + c.control_dt
    buf.time[i] = time
    reference_point(buf, c, time, i)
    update_errors(f, buf, i)
    position_error = buf.position_error[i]
    velocity_error = buf.velocity_error[i]
    # reward
    distance = wp.length(position_error)
    action = buf.action[i]
    action_rate = wp.length_sq(action - buf.previous_action[i])
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_position * gaussian_wp(distance, c.sigma_position),
        c.w_velocity * gaussian_wp(wp.length(velocity_error), c.sigma_velocity),
        -(c.w_energy * airspeed_margin_penalty_wp(f.airspeed, c.safe_airspeed)),
        -(c.w_smooth * action_rate)))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, distance > c.lost_distance)
    buf.previous_action[i] = action
    write_observation(f, c, position_error, velocity_error, action, observation, i)


@wp.func
def trajectory_start(sim: SimulatorViews, buf: TrajectoryBuffers, c: TrajectoryConstants,
                     observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]``, its physics reset already written (clock and
    previous action zeroed), then, every env, the reference point at its clock, the errors and the
    observation [N, 17]."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec4(0.0)
    reference_point(buf, c, buf.time[i], i)
    update_errors(f, buf, i)
    write_observation(f, c, buf.position_error[i], buf.velocity_error[i], buf.previous_action[i],
                      observation, i)


@wp.func
def trajectory_observe(f: FlightState, buf: TrajectoryBuffers, c: TrajectoryConstants,
                       observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, D] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, buf.position_error[i], buf.velocity_error[i], buf.previous_action[i],
                      observation, i)


#: The step kernel (:func:`trajectory_step` of env i = offset + tid), the start kernel
#: (:func:`trajectory_start`) and the observe kernel (:func:`trajectory_observe`), in this module.
trajectory_step_kernel, trajectory_start_kernel = task_kernels(
    "trajectory", trajectory_step, trajectory_start, TrajectoryBuffers, TrajectoryConstants, __name__)
trajectory_observe_kernel = observe_kernel("trajectory", trajectory_observe, TrajectoryBuffers,
                                           TrajectoryConstants, __name__)


class FusedTrajectoryStep(FusedStep):
    """The recorded launch of :func:`trajectory_step_kernel` for one trajectory task: observation
    [N, 17], reward [N], reason [N] long."""

    kernel = trajectory_step_kernel
    kernel_func = trajectory_step
    buffers = TrajectoryBuffers
    constants = TrajectoryConstants
    start_kernel = trajectory_start_kernel
    observe_kernel = trajectory_observe_kernel
    task: Task

    def __init__(self, task: Task):
        super().__init__(task)
        self.bind()

    def task_inputs(self) -> list[Any]:
        task = self.task
        cfg = task.config
        buf = fill_struct(TrajectoryBuffers(), {
            name: getattr(task, name)
            for name in ("time", "start", "radius", "turn", "climb", "reference_position",
                         "reference_velocity", "position_error", "velocity_error", "position_error_ned",
                         "previous_action")})
        fill_struct(buf, {"action": self.action})
        bind_reward_terms(buf, task)
        constants = fill_struct(TrajectoryConstants(), {
            "control_dt": task.control_dt, "speed": task.speed, "lost_distance": cfg.lost_distance,
            "velocity_scale": cfg.airspeed_scale * task.speed, "angle_scale": math.pi / 4,
            "air_angle_scale": 20.0 * DEG, "w_position": cfg.w_position, "sigma_position": cfg.sigma_position,
            "w_velocity": cfg.w_velocity, "sigma_velocity": cfg.sigma_velocity_fraction * task.speed,
            "w_energy": cfg.w_energy, "safe_airspeed": task.safe_airspeed, "w_smooth": cfg.w_smooth,
            "stall_alpha": task.stall_alpha, "stall_speed": task.stall_speed,
            "observation_clip": task.observation_clip})
        return [buf, constants]
