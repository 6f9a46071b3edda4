"""The throttle hold task's step as Warp functions of one env (its fused step): the twin of
``HoldTask.step``. No ``from __future__ import annotations``: Warp reads the annotations."""

from typing import Any

import warp as wp

from falcon_rl.envs.tasks.warp_common import FusedStep, clip, fill_struct, termination_code
from falcon_rl.physics.task_kernels import SimulatorViews, flight_state, task_kernels


@wp.struct
class HoldBuffers:
    """The task's per-env buffers [N] (views of its tensors) and the action [N]."""

    time: wp.array(dtype=wp.float32)
    height_error: wp.array(dtype=wp.float32)
    previous_action: wp.array(dtype=wp.float32)
    action: wp.array(dtype=wp.float32)


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
def hold_step(sim: SimulatorViews, buf: HoldBuffers, c: HoldConstants,
              observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
              reason: wp.array(dtype=wp.int64), i: int):
    """One step of env i after the physics (``HoldTask.step``)."""
    f = flight_state(sim, i)
    buf.time[i] = buf.time[i] + c.control_dt
    e_h = f.height - c.height
    buf.height_error[i] = e_h
    airspeed_error = wp.abs(f.airspeed - c.trim_airspeed) / c.trim_airspeed
    reward[i] = -c.w_height * e_h * e_h - c.w_airspeed * airspeed_error
    reason[i] = termination_code(f, c.stall_alpha, c.stall_speed, False)
    buf.previous_action[i] = buf.action[i]
    observation[i, 0] = clip(e_h / 10.0, c.observation_clip)
    observation[i, 1] = clip(f.airspeed / c.trim_airspeed - 1.0, c.observation_clip)


@wp.func
def hold_start(sim: SimulatorViews, buf: HoldBuffers, c: HoldConstants,
               observation: wp.array2d(dtype=wp.float32), mask: wp.array(dtype=wp.bool), i: int):
    """The start of env i's episode when ``mask[i]`` (``HoldTask.after_reset``), then its observation."""
    f = flight_state(sim, i)
    if mask[i]:
        buf.time[i] = 0.0
        buf.previous_action[i] = 0.0
    buf.height_error[i] = f.height - c.height
    observation[i, 0] = clip((f.height - c.height) / 10.0, c.observation_clip)
    observation[i, 1] = clip(f.airspeed / c.trim_airspeed - 1.0, c.observation_clip)


hold_step_kernel, hold_start_kernel = task_kernels("user_hold", hold_step, hold_start, HoldBuffers,
                                                   HoldConstants, __name__)


class FusedHoldStep(FusedStep):
    """The throttle hold task's fused step."""

    kernel = hold_step_kernel
    kernel_func = hold_step
    start_kernel = hold_start_kernel
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
        return [buf, constants]
