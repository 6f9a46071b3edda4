"""Fused Warp kernels: one launch advances every env by one step (all integrator stages and the
projection inside), calling the ``@wp.func`` twins that live beside each torch subsystem.

The state is read from and written back to the simulator's [N, S] float32 tensor (zero-copy view);
inside the kernel one env's row is a padded :data:`StateVec`. Importing this module imports Warp but
compiles nothing: Warp builds the module on the first launch and caches the binary on disk.

There is no reset kernel: resets are masked writes that the Simulator makes to the same memory.
"""

from __future__ import annotations

import warp as wp

from .dynamics import derivative_wp, project_wp
from .params import WarpParams
from .state import StateVec

INTEGRATOR_CODES = {"euler": 0, "rk4": 1}


@wp.func
def load_state(x: wp.array2d(dtype=wp.float32), i: int, size: int) -> StateVec:
    """Row ``i`` of the [N, S] state as a padded state vector."""
    s = StateVec()
    for k in range(size):
        s[k] = x[i, k]
    return s


@wp.kernel
def step_kernel(
    x: wp.array2d(dtype=wp.float32),
    command: wp.array(dtype=wp.vec4),
    wind_ned: wp.array(dtype=wp.vec3),
    gust_velocity_body: wp.array(dtype=wp.vec3),
    gust_rate_body: wp.array(dtype=wp.vec3),
    p: WarpParams,
    dt: float,
    integrator: int,
):
    """x[i] <- project(integrate(x[i], dt)) for env i = tid, command held over the step.

    x: [N, S] state (in place). command: [N] normalised commands. wind_ned, gust_*: [N] air motion.
    integrator: 0 Euler, 1 classic RK4 (same stage arithmetic as ``integrators.rk4_step``).
    """
    i = wp.tid()
    size = x.shape[1]
    s = load_state(x, i, size)
    u = command[i]
    wind = wind_ned[i]
    gv = gust_velocity_body[i]
    gw = gust_rate_body[i]
    k1 = derivative_wp(s, u, wind, gv, gw, p, i)
    y = StateVec()
    if integrator == 0:
        y = s + dt * k1
    else:
        k2 = derivative_wp(s + (0.5 * dt) * k1, u, wind, gv, gw, p, i)
        k3 = derivative_wp(s + (0.5 * dt) * k2, u, wind, gv, gw, p, i)
        k4 = derivative_wp(s + dt * k3, u, wind, gv, gw, p, i)
        y = s + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    y = project_wp(y, p, i)
    for k in range(size):
        x[i, k] = y[k]


@wp.kernel
def derivative_kernel(
    x: wp.array2d(dtype=wp.float32),
    command: wp.array(dtype=wp.vec4),
    wind_ned: wp.array(dtype=wp.vec3),
    gust_velocity_body: wp.array(dtype=wp.vec3),
    gust_rate_body: wp.array(dtype=wp.vec3),
    p: WarpParams,
    out: wp.array2d(dtype=wp.float32),
):
    """out[i] <- f(x[i], command[i]) (twin of ``dynamics.derivative``), for checks and tools."""
    i = wp.tid()
    size = x.shape[1]
    d = derivative_wp(load_state(x, i, size), command[i], wind_ned[i], gust_velocity_body[i],
                      gust_rate_body[i], p, i)
    for k in range(size):
        out[i, k] = d[k]
