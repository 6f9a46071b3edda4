"""The throttle hold task's step, start and observation as Warp functions of one env (the task's one
body). No ``from __future__ import annotations``: Warp reads the annotations."""

from typing import Any

import warp as wp

from falcon_rl.envs.tasks.warp_common import (
    FusedStep,
    bind_reward_terms,
    clip,
    fill_struct,
    termination_code,
    write_reward_terms,
)
from falcon_rl.physics.task_kernels import (
    FlightState,
    SimulatorViews,
    flight_state,
    observe_kernel,
    task_kernels,
)

#: The reward's 2 terms of one env, in the order of ``HoldTask.reward_terms``.
HoldTerms = wp.types.vector(length=2, dtype=wp.float32)


@wp.struct
class HoldBuffers:
    """The task's per-env buffers [N] (views of its tensors), the action [N] and the reward terms [N, 2]."""

    time: wp.array(dtype=wp.float32)
    height_error: wp.array(dtype=wp.float32)
    previous_action: wp.array(dtype=wp.float32)
    action: wp.array(dtype=wp.float32)
    reward_term_values: wp.array2d(dtype=wp.float32)
    reward_term_sums: wp.array2d(dtype=wp.float32)


@wp.struct
class HoldConstants:
    """Config and airframe constants."""

    control_dt: float
    height: float
    w_height: float
    w_airspeed: float
    trim_airspeed: float
    stall_alpha: float
    stall_speed: float
    observation_clip: float


@wp.func
def hold_reward_terms(f: FlightState, c: HoldConstants) -> HoldTerms:
    """(-w e_h^2, -w_V |V_a - V*| / V*) of the flight state ``f``."""
    e_h = f.height - c.height
    airspeed_error = wp.abs(f.airspeed - c.trim_airspeed) / c.trim_airspeed
    return HoldTerms(-c.w_height * e_h * e_h, -c.w_airspeed * airspeed_error)


@wp.func
def hold_observe(f: FlightState, buf: HoldBuffers, c: HoldConstants,
                 observation: wp.array2d(dtype=wp.float32), i: int):
    """observation[i] <- [e_h / 10, V_a / V* - 1], clipped, of the flight state ``f``."""
    observation[i, 0] = clip((f.height - c.height) / 10.0, c.observation_clip)
    observation[i, 1] = clip(f.airspeed / c.trim_airspeed - 1.0, c.observation_clip)


@wp.func
def hold_step(sim: SimulatorViews, buf: HoldBuffers, c: HoldConstants,
              observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
              reason: wp.array(dtype=wp.int64), i: int):
    """One step of env i after the physics: clock, height error, reward terms, reason, observation."""
    f = flight_state(sim, i)
    buf.time[i] = buf.time[i] + c.control_dt
    buf.height_error[i] = f.height - c.height
    reward[i] = write_reward_terms(buf.reward_term_values, buf.reward_term_sums, i, hold_reward_terms(f, c))
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, False)
    buf.previous_action[i] = buf.action[i]
    hold_observe(f, buf, c, observation, i)


@wp.func
def hold_start(sim: SimulatorViews, buf: HoldBuffers, c: HoldConstants,
               observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]`` (clock and previous action zeroed), then, every env,
    its height error and observation."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = 0.0
    buf.height_error[i] = f.height - c.height
    hold_observe(f, buf, c, observation, i)


hold_step_kernel, hold_start_kernel = task_kernels("user_hold", hold_step, hold_start, HoldBuffers,
                                                   HoldConstants, __name__)
hold_observe_kernel = observe_kernel("user_hold", hold_observe, HoldBuffers, HoldConstants, __name__)


class FusedHoldStep(FusedStep):
    """The throttle hold task's Warp step."""

    kernel = hold_step_kernel
    kernel_func = hold_step
    start_kernel = hold_start_kernel
    observe_kernel = hold_observe_kernel
    buffers = HoldBuffers
    constants = HoldConstants

    def __init__(self, task: Any):
        super().__init__(task)
        self.bind()

    def task_inputs(self) -> list[Any]:
        task, cfg = self.task, self.task.config
        buf = fill_struct(HoldBuffers(), {"time": task.time, "height_error": task.height_error,
                                          "previous_action": task.previous_action.view(-1),
                                          "action": self.action.view(-1)})
        constants = fill_struct(HoldConstants(), {
            "control_dt": task.control_dt, "height": cfg.height, "w_height": cfg.w_height,
            "w_airspeed": cfg.w_airspeed, "trim_airspeed": task.trim_airspeed,
            "stall_alpha": task.stall_alpha, "stall_speed": task.stall_speed,
            "observation_clip": task.observation_clip})
        return [bind_reward_terms(buf, task), constants]
