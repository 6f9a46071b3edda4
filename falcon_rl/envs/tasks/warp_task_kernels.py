"""The two Warp kernels around a task's fused functions, made here for every task (each task's
``kernels`` module): the step kernel (``FusedStep.kernel``) and the start kernel
(``FusedStep.start_kernel``), each handling env i = offset + tid (``offset``: the first env of a CPU
slice of the engine) with denormals flushed as the physics' kernels do.

No ``from __future__ import annotations`` here: Warp reads the kernels' annotations, which name the
task's struct types through the closure.
"""

from typing import Any

import warp as wp

from ...physics.warp_kernels import flush_denormals_begin, flush_denormals_end
from .warp_common import SimulatorViews


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


__all__ = ["task_kernels"]
