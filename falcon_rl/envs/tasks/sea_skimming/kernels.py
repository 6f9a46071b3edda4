"""The sea-skimming task's step, written once as Warp functions (``SeaSkimmingTask.fused_stepper``).

:func:`sea_skimming_step` is the task's step for env i after the physics (the equations of the task's
module docstring): it reads the flight state (``flight_state``: the clearance is the surface sample the
engine took after its last physics step), advances the clock, takes the altimeter's rate, and writes the
named reward terms, the reward, the termination reason and the clipped observation. The task's buffers are
zero-copy Warp views of its float32 torch tensors. :func:`sea_skimming_start` starts the episodes after a
reset; :func:`sea_skimming_observe` observes a given (measured) state: its ``clearance`` is the measured
altimeter.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import TYPE_CHECKING, Any

import torch
import warp as wp

from ....constants import DEG
from ....physics._warp import forward_only
from ....physics.sea import SeaFieldWp, SeaSurface, sea_elevation_wp, sea_field_views
from ....physics.task_kernels import (
    FlightState,
    SimulatorViews,
    flight_state,
    observe_kernel,
    task_kernels,
)
from ..warp_common import (
    FusedStep,
    bind_reward_terms,
    clamp_max_keep_nan,
    clamp_min_keep_nan,
    clip,
    fill_struct,
    gaussian_wp,
    termination_code,
    write_reward_terms,
)

forward_only(__name__)

#: The reward's 7 terms of one env, in the order of the task's ``reward_terms``.
RewardTerms = wp.types.vector(length=7, dtype=wp.float32)

if TYPE_CHECKING:
    from ..base import Task


@wp.struct
class SeaSkimmingBuffers:
    """The task's per-env buffers [N] (views of SeaSkimmingTask's tensors) and actions [N] vec4."""

    time: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)  # [N, K] the step's reward terms
    reward_term_sums: wp.array2d(dtype=wp.float32)  # [N, K] their sums since the last read
    commanded_clearance: wp.array(dtype=wp.float32)
    clearance: wp.array(dtype=wp.float32)
    clearance_error: wp.array(dtype=wp.float32)
    clearance_rate: wp.array(dtype=wp.float32)
    surface_rate: wp.array(dtype=wp.float32)
    lowest_tip_clearance: wp.array(dtype=wp.float32)
    surface_elevation: wp.array(dtype=wp.float32)
    reference_altitude: wp.array(dtype=wp.float32)
    previous_action: wp.array(dtype=wp.vec4)
    action: wp.array(dtype=wp.vec4)
    sim_time: wp.array(dtype=wp.float32)  # [N] the simulator's clock (s), the waves' time
    sea: SeaFieldWp  # [N, K] the wave fields the forward-looking altimeter reads
    preview_seconds: wp.array(dtype=wp.float32)  # [max(P, 1)] its look-ahead times (s)


@wp.struct
class SeaSkimmingConstants:
    """Config and airframe constants, float32."""

    control_dt: float
    span: float
    trim_airspeed: float
    airspeed_sigma: float  # airspeed_scale x V_a*
    climb_rate_limit: float
    angle_scale: float  # pi / 4
    alpha_scale: float  # 20 deg
    ceiling: float  # m
    w_clearance: float
    sigma_clearance: float  # m
    w_airspeed: float
    w_bank: float
    w_tip: float
    tip_margin: float  # m
    w_smooth: float
    w_power: float
    survival_bonus: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float
    preview_count: int  # P, the forward-looking altimeter's readings (observations 15..15+P-1)


@wp.func
def write_observation(f: FlightState, c: SeaSkimmingConstants, commanded: float, clearance_rate: float,
                      previous_action: wp.vec4, observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- the clipped observation [15] of env i (the task's module docstring) from its
    flight state, the commanded clearance c* (m), the altimeter's rate (m/s) and a_{t-1}."""
    lim = c.observation_clip
    observation[i, 0] = clip((f.clearance - commanded) / (0.25 * c.span), lim)
    observation[i, 1] = clip(clearance_rate / c.climb_rate_limit, lim)
    observation[i, 2] = clip((f.airspeed - c.trim_airspeed) / c.airspeed_sigma, lim)
    observation[i, 3] = clip(f.euler[0] / c.angle_scale, lim)
    observation[i, 4] = clip(f.euler[1] / c.angle_scale, lim)
    for k in range(3):
        observation[i, 5 + k] = clip(f.angular_rate[k] / 2.0, lim)
    observation[i, 8] = clip(f.alpha / c.alpha_scale, lim)
    observation[i, 9] = clip(f.velocity_ned[2] / c.climb_rate_limit, lim)
    observation[i, 10] = clip(commanded / c.span, lim)
    for k in range(4):
        observation[i, 11 + k] = clip(previous_action[k], lim)


@wp.func
def write_preview(f: FlightState, buf: SeaSkimmingBuffers, c: SeaSkimmingConstants, commanded: float,
                  observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i, 15 + k] <- the forward-looking altimeter's clearance error tau_k ahead, (h - eta(p +
    V_g tau_k, t) - c*)/(b/4) clipped, for the P look-ahead times (nothing when P = 0)."""
    row = wp.min(i, buf.sea.amplitude.shape[0] - 1)
    for k in range(c.preview_count):
        tau = buf.preview_seconds[k]
        north = f.position_ned[0] + f.velocity_ned[0] * tau
        east = f.position_ned[1] + f.velocity_ned[1] * tau
        water = sea_elevation_wp(buf.sea, row, north, east, buf.sim_time[i])
        observation[i, 15 + k] = clip((f.height - water - commanded) / (0.25 * c.span), c.observation_clip)


@wp.func
def publish(f: FlightState, buf: SeaSkimmingBuffers, clearance_rate: float, i: int) -> float:
    """Write env i's clearance, its error and rates, the tip's clearance, the water's elevation and the
    reference altitude into the buffers; returns e_c."""
    error = f.clearance - buf.commanded_clearance[i]
    buf.clearance[i] = f.clearance
    buf.clearance_error[i] = error
    buf.clearance_rate[i] = clearance_rate
    buf.surface_rate[i] = -f.velocity_ned[2] - clearance_rate
    buf.lowest_tip_clearance[i] = f.lowest_tip
    buf.surface_elevation[i] = f.surface_elevation
    buf.reference_altitude[i] = f.height - error
    return error


@wp.func
def sea_skimming_step(sim: SimulatorViews, buf: SeaSkimmingBuffers, c: SeaSkimmingConstants,
                      observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                      reason: wp.array(dtype=wp.int64), i: int):
    """One sea-skimming step of env i after the physics: updates the buffers in place and writes
    observation [N, 15], reward [N] and the termination reason [N] (0: flying)."""
    f = flight_state(sim, i)
    buf.time[i] = buf.time[i] + c.control_dt
    clearance_rate = (f.clearance - buf.clearance[i]) / c.control_dt
    error = publish(f, buf, clearance_rate, i)
    action = buf.action[i]
    action_change = action - buf.previous_action[i]
    bank = f.euler[0] / c.angle_scale
    tip_gap = clamp_min_keep_nan(1.0 - f.lowest_tip / c.tip_margin, 0.0)
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, RewardTerms(
        c.w_clearance * gaussian_wp(error, c.sigma_clearance),
        -(c.w_airspeed * wp.abs(f.airspeed - c.trim_airspeed) / c.trim_airspeed),
        -(c.w_bank * clamp_max_keep_nan(bank * bank, 1.0)),
        -(c.w_tip * tip_gap),
        -(c.w_smooth * wp.dot(action_change, action_change)),
        -(c.w_power * f.throttle),
        c.survival_bonus))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, f.clearance > c.ceiling)
    buf.previous_action[i] = action
    write_observation(f, c, buf.commanded_clearance[i], clearance_rate, action, observation, i)
    write_preview(f, buf, c, buf.commanded_clearance[i], observation, i)


@wp.func
def sea_skimming_start(sim: SimulatorViews, buf: SeaSkimmingBuffers, c: SeaSkimmingConstants,
                       observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]`` (clock, altimeter rate and previous action zeroed),
    its physics reset already written; then, every env, the published errors and the observation."""
    f = flight_state(sim, i)
    rate = buf.clearance_rate[i]
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = wp.vec4(0.0)
        rate = 0.0
    publish(f, buf, rate, i)
    write_observation(f, c, buf.commanded_clearance[i], rate, buf.previous_action[i], observation, i)
    write_preview(f, buf, c, buf.commanded_clearance[i], observation, i)


@wp.func
def sea_skimming_observe(f: FlightState, buf: SeaSkimmingBuffers, c: SeaSkimmingConstants,
                         observation: wp.array2d(dtype=wp.float32), i: int):
    """The observation [N, D] of env i's flight state ``f`` (e.g. a measured one) with the task's current
    buffers, no side effect."""
    write_observation(f, c, buf.commanded_clearance[i], buf.clearance_rate[i], buf.previous_action[i],
                      observation, i)
    write_preview(f, buf, c, buf.commanded_clearance[i], observation, i)


#: The step kernel (:func:`sea_skimming_step` of env i = offset + tid), the start kernel and the observe
#: kernel, in this module.
sea_skimming_step_kernel, sea_skimming_start_kernel = task_kernels(
    "sea_skimming", sea_skimming_step, sea_skimming_start, SeaSkimmingBuffers, SeaSkimmingConstants,
    __name__)
sea_skimming_observe_kernel = observe_kernel("sea_skimming", sea_skimming_observe, SeaSkimmingBuffers,
                                             SeaSkimmingConstants, __name__)


def sea_skimming_constants(task: Task) -> Any:
    """:class:`SeaSkimmingConstants` of ``task``'s config and airframe (Python products, then float32)."""
    cfg, span = task.config, float(task.airframe.geometry.span)
    return fill_struct(SeaSkimmingConstants(), {
        "control_dt": task.control_dt, "span": span, "trim_airspeed": task.trim_airspeed,
        "airspeed_sigma": cfg.airspeed_scale * task.trim_airspeed,
        "climb_rate_limit": task.airframe.envelope.climb_rate_limit, "angle_scale": math.pi / 4,
        "alpha_scale": 20.0 * DEG, "ceiling": cfg.ceiling * span, "w_clearance": cfg.w_clearance,
        "sigma_clearance": cfg.sigma_clearance * span, "w_airspeed": cfg.w_airspeed, "w_bank": cfg.w_bank,
        "w_tip": cfg.w_tip, "tip_margin": cfg.tip_margin * span, "w_smooth": cfg.w_smooth,
        "w_power": cfg.w_power, "survival_bonus": cfg.survival_bonus, "stall_alpha": task.stall_alpha,
        "stall_speed": task.stall_speed, "observation_clip": task.observation_clip,
        "preview_count": len(cfg.preview_seconds),
    })


class FusedSeaSkimmingStep(FusedStep):
    """The recorded launch of :func:`sea_skimming_step_kernel` for one sea-skimming task: observation
    [N, 15 + P], reward [N], reason [N] long."""

    kernel = sea_skimming_step_kernel
    kernel_func = sea_skimming_step
    buffers = SeaSkimmingBuffers
    constants = SeaSkimmingConstants
    start_kernel = sea_skimming_start_kernel
    observe_kernel = sea_skimming_observe_kernel

    def __init__(self, task: Task):
        times = task.config.preview_seconds or (0.0,)
        self.preview_seconds = torch.tensor(times, device=task.device, dtype=torch.float32)
        super().__init__(task)
        self.bind()

    def task_simulator_tensors(self) -> tuple[torch.Tensor, ...]:
        """The clock [N] and the wave fields [N, K] (six) the forward-looking altimeter reads."""
        sim = self.task.sim
        sea = sim.sea if sim.sea is not None else sim.ensure_sea()
        return (sim.time, *(getattr(sea, field.name) for field in fields(SeaSurface)))

    def task_inputs(self) -> list[Any]:
        task = self.task
        buf = fill_struct(SeaSkimmingBuffers(), {
            name: getattr(task, name)
            for name in ("time", "commanded_clearance", "clearance", "clearance_error", "clearance_rate",
                         "surface_rate", "lowest_tip_clearance", "surface_elevation", "reference_altitude",
                         "previous_action")})
        fill_struct(buf, {"action": self.action, "sim_time": self.task_tensors[0],
                          "preview_seconds": self.preview_seconds})
        buf.sea = sea_field_views(SeaSurface(*self.task_tensors[1:]))
        bind_reward_terms(buf, task)
        return [buf, sea_skimming_constants(task)]
