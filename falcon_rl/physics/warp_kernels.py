"""Fused Warp kernels: one launch advances every env by one step (all integrator stages and the
projection inside), calling the ``@wp.func`` twins that live beside each torch subsystem.

The state is read from and written back to the simulator's [N, S] float32 tensor (zero-copy view);
inside the kernel one env's row is a padded :data:`StateVec`. Importing this module imports Warp but
compiles nothing: Warp builds the module on the first launch and caches the binary on disk.

A reset is :func:`reset_kernel` (the masked write of the initial rows, projected, and the derived state
of the batch in one launch), or masked torch writes into the same memory on the other engines.
The Dryden turbulence update (``wind.dryden_step_wp``) runs at the start of the step kernel, once per
step, so the gusts it writes act over the whole step. Over a sea the surface under the aircraft is
sampled after each step (``surface.sample_surface_wp``), and that sample is held over the next.
"""

from __future__ import annotations

import warp as wp

from ._warp import forward_only
from .actuators import hold_ideal_wp
from .derived import DERIVED_OFFSET, MAX_MOTORS
from .dynamics import derivative_wp, evaluate_wp, project_wp
from .params import WarpParams
from .propulsion import motor_thrust_wp
from .rotations import quaternion_to_euler_wp, rotation_matrix_wp
from .sea import SeaFieldWp
from .state import (
    ANGULAR_RATE_START,
    DOWN_INDEX,
    MAX_RESET_POSITION,
    MAX_RESET_RATE,
    MAX_RESET_SPEED,
    MIN_QUATERNION_NORM,
    QUATERNION_START,
    THROTTLE_START,
    VELOCITY_START,
    StateVec,
)
from .surface import (
    CLEARANCE,
    ELEVATION,
    OVER_WATER,
    TIP_CLEARANCE,
    WAVE_VELOCITY,
    SurfaceVec,
    load_surface,
    sample_surface_wp,
    store_surface,
)
from .wind import NUM_FILTER_STATES, NUM_NOISE, Vec6, Vec8, dryden_step_wp

forward_only(__name__)

# Denormal floats (|x| < 1.2e-38) take a slow microcode path on x86 CPUs. Trimmed, symmetric states
# make them (powers of near-zero sideslip and lateral deflections in the aero table), and they cost a
# third of a CPU step. Each CPU kernel sets flush-to-zero and denormals-are-zero for its own work and
# restores the caller's MXCSR: the physics changes by less than 1e-38, the caller's thread not at all.
# On CUDA (and non-x86 CPUs) these are no-ops.
_FLUSH_BEGIN = """
#if !defined(__CUDA_ARCH__) && (defined(__x86_64__) || defined(__i386__))
unsigned int saved = __builtin_ia32_stmxcsr();
__builtin_ia32_ldmxcsr(saved | 0x8040u);
return (int)saved;
#else
return 0;
#endif
"""
_FLUSH_END = """
#if !defined(__CUDA_ARCH__) && (defined(__x86_64__) || defined(__i386__))
__builtin_ia32_ldmxcsr((unsigned int)saved);
#endif
"""


@wp.func_native(_FLUSH_BEGIN)
def flush_denormals_begin() -> int:
    """Turn on flush-to-zero on this CPU thread; returns the previous MXCSR for the matching end."""
    ...


@wp.func_native(_FLUSH_END)
def flush_denormals_end(saved: int):
    """Restore the MXCSR that :func:`flush_denormals_begin` returned."""
    ...


INTEGRATOR_CODES = {"euler": 0, "rk4": 1}
# First columns of the derived fields in :func:`evaluate_kernel`'s output row (``derived.py``).
_AIRSPEED, _ALPHA, _BETA = DERIVED_OFFSET["airspeed"], DERIVED_OFFSET["alpha"], DERIVED_OFFSET["beta"]
_HEIGHT, _WING_HEIGHT = DERIVED_OFFSET["height"], DERIVED_OFFSET["wing_height"]
_SURFACES, _THRUST = DERIVED_OFFSET["surface_position"], DERIVED_OFFSET["thrust"]
_COEFFICIENTS, _LOWEST_TIP = DERIVED_OFFSET["aero_coefficients"], DERIVED_OFFSET["lowest_tip_height"]
_VELOCITY_NED, _EULER = DERIVED_OFFSET["velocity_ned"], DERIVED_OFFSET["euler"]
_AERO_FORCE, _AERO_MOMENT = DERIVED_OFFSET["aero_force_body"], DERIVED_OFFSET["aero_moment_body"]
_MOTOR_THRUST, _H_OVER_B = DERIVED_OFFSET["motor_thrust"], DERIVED_OFFSET["ge_h_over_b"]
_GE_LIFT, _GE_DRAG = DERIVED_OFFSET["ge_lift_factor"], DERIVED_OFFSET["ge_drag_factor"]
_CLEARANCE, _TIP_CLEARANCE = DERIVED_OFFSET["surface_clearance"], DERIVED_OFFSET["lowest_tip_clearance"]
_ELEVATION, _OVER_WATER = DERIVED_OFFSET["surface_elevation"], DERIVED_OFFSET["over_water"]
_WAVES = DERIVED_OFFSET["wave_velocity_ned"]
MIN_NORM, MAX_SPEED = wp.constant(MIN_QUATERNION_NORM), wp.constant(MAX_RESET_SPEED)
MAX_POSITION, MAX_RATE = wp.constant(MAX_RESET_POSITION), wp.constant(MAX_RESET_RATE)
#: Turbulence modes of the step kernel: off, noise from the Warp streams, noise read from an array.
TURBULENCE_OFF, TURBULENCE_RANDOM, TURBULENCE_EXTERNAL = 0, 1, 2


@wp.func
def load_state(x: wp.array2d(dtype=wp.float32), i: int, size: int) -> StateVec:
    """Row ``i`` of the [N, S] state as a padded state vector."""
    s = StateVec()
    for k in range(size):
        s[k] = x[i, k]
    return s


@wp.func
def advance_turbulence(s: StateVec, wind: wp.vec3, i: int, gust_velocity_body: wp.array(dtype=wp.vec3),
                       gust_rate_body: wp.array(dtype=wp.vec3), turb_filter: wp.array2d(dtype=wp.float32),
                       turb_w20: wp.array(dtype=wp.float32), turb_noise: wp.array2d(dtype=wp.float32),
                       rng_seed: int, rng_counter: int, turb_mode: int, span: float, dt: float):
    """One Dryden step of env ``i`` at its height and mean-air airspeed (twin of
    ``TorchEngine.advance_turbulence``), noise stream (rng_seed, rng_counter): updates the filter row and
    the gust arrays in place."""
    q = wp.vec4(s[QUATERNION_START], s[QUATERNION_START + 1], s[QUATERNION_START + 2],
                s[QUATERNION_START + 3])
    vel = wp.vec3(s[VELOCITY_START], s[VELOCITY_START + 1], s[VELOCITY_START + 2])
    airspeed = wp.length(vel - wp.transpose(rotation_matrix_wp(q)) * wind)
    noise = Vec6()
    if turb_mode == TURBULENCE_EXTERNAL:
        for k in range(NUM_NOISE):
            noise[k] = turb_noise[i, k]
    else:
        stream = wp.rand_init(rng_seed, rng_counter)
        rng = wp.rand_init(wp.randi(stream), i)
        for k in range(NUM_NOISE):
            noise[k] = wp.randn(rng)
            turb_noise[i, k] = noise[k]
    filt = Vec8()
    for k in range(NUM_FILTER_STATES):
        filt[k] = turb_filter[i, k]
    out = dryden_step_wp(filt, noise, gust_velocity_body[i], turb_w20[i], -s[2], airspeed, span, dt)
    for k in range(NUM_FILTER_STATES):
        turb_filter[i, k] = out.filt[k]
    gust_velocity_body[i] = out.gust_velocity
    gust_rate_body[i] = out.gust_rate


@wp.struct
class EngineViews:
    """Zero-copy views of an engine's buffers (the ``engine.py`` contract) that a step reads and writes."""

    x: wp.array2d(dtype=wp.float32)  # [N, S] state
    time: wp.array(dtype=wp.float32)  # [N] s
    command: wp.array(dtype=wp.vec4)  # [N] normalised commands held over the step
    wind_ned: wp.array(dtype=wp.vec3)  # [N] m/s
    gust_velocity_body: wp.array(dtype=wp.vec3)  # [N] m/s
    gust_rate_body: wp.array(dtype=wp.vec3)  # [N] rad/s
    crashed: wp.array(dtype=wp.bool)  # [N] stopped at the ground since the reset
    turb_filter: wp.array2d(dtype=wp.float32)  # [N, 8] Dryden filter state
    turb_w20: wp.array(dtype=wp.float32)  # [N] wind speed at 20 ft
    turb_noise: wp.array2d(dtype=wp.float32)  # [N, 6] the step's white noise
    turb_rng: wp.array(dtype=wp.int32)  # [2] (seed, step counter) of the noise streams
    surface: wp.array2d(dtype=wp.float32)  # [N, SURFACE_WIDTH] the surface under each aircraft
    sea: SeaFieldWp  # [N, K] the wave fields ([1, 1] calm placeholders before a sea is drawn)


@wp.struct
class StepSettings:
    """The fixed scalars of an engine's steps: dt (s), integrator (0 Euler, 1 RK4) and turbulence mode
    (0 off, 1 noise from the streams, 2 noise read from ``turb_noise``)."""

    dt: float
    integrator: int
    turb_mode: int


@wp.func
def surface_sample(e: EngineViews, p: WarpParams, s: StateVec, time: float, i: int) -> SurfaceVec:
    """Env i's surface sample at state s and ``time`` over its sea (a calm sea where none was drawn);
    zeros over the ground."""
    out = SurfaceVec()
    if p.sea_surface[i] != 0:
        q = wp.vec4(s[QUATERNION_START], s[QUATERNION_START + 1], s[QUATERNION_START + 2],
                    s[QUATERNION_START + 3])
        row = wp.min(i, e.sea.amplitude.shape[0] - 1)  # the calm [1, 1] placeholder where no sea was drawn
        out = sample_surface_wp(e.sea, s, rotation_matrix_wp(q), p.span[i], p.wing_quarter_chord[i], time,
                                row)
    return out


@wp.func
def surface_at_stop(sample: SurfaceVec, rise: float) -> SurfaceVec:
    """``sample`` moved to an aircraft stopped on the water under its CG, ``rise`` m above where it was
    sampled (the stations' horizontal positions unchanged): CG clearance 0, lower tip clearance + rise."""
    out = sample
    out[CLEARANCE] = 0.0
    out[TIP_CLEARANCE] = sample[TIP_CLEARANCE] + rise
    return out


@wp.func
def advance_env(e: EngineViews, p: WarpParams, g: StepSettings, substeps: int, stop_at_ground: int, i: int):
    """``substeps`` times: x[i] <- project(integrate(hold_ideal(x[i]), dt)) and time[i] += dt, the
    command held, and over a sea the surface sampled at the new state; then the crash state when
    ``stop_at_ground`` != 0 (twin of ``Engine.stop_crashed``: an env already crashed keeps its state and
    surface row, one whose CG is below the ground, or the water under it, stops on it with its sample
    moved there). Integrator: 0 Euler, 1 classic RK4
    (the stage arithmetic of ``integrators.rk4_step``). With turbulence the gusts are advanced at the start
    of each sub-step (sub-step k at counter turb_rng[1] - substeps + 1 + k)."""
    size = e.x.shape[1]
    s = load_state(e.x, i, size)
    start = s
    u = e.command[i]
    wind = e.wind_ned[i]
    t = e.time[i]
    dt = g.dt
    water = p.sea_surface[i] != 0
    held = SurfaceVec()
    if water or e.surface[i, OVER_WATER] != 0.0:
        held = load_surface(e.surface, i)
    start_held = held
    for k in range(substeps):
        if g.turb_mode != TURBULENCE_OFF:
            advance_turbulence(s, wind, i, e.gust_velocity_body, e.gust_rate_body, e.turb_filter, e.turb_w20,
                               e.turb_noise, e.turb_rng[0], e.turb_rng[1] - substeps + 1 + k, g.turb_mode,
                               p.span[i], dt)
        gv = e.gust_velocity_body[i]
        gw = e.gust_rate_body[i]
        s = hold_ideal_wp(s, u, p, i)
        k1 = derivative_wp(s, u, wind, gv, gw, held, p, i)
        y = StateVec()
        if g.integrator == 0:
            y = s + dt * k1
        else:
            k2 = derivative_wp(s + (0.5 * dt) * k1, u, wind, gv, gw, held, p, i)
            k3 = derivative_wp(s + (0.5 * dt) * k2, u, wind, gv, gw, held, p, i)
            k4 = derivative_wp(s + dt * k3, u, wind, gv, gw, held, p, i)
            y = s + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        s = project_wp(y, p, i)
        t = t + dt
        if water:
            held = surface_sample(e, p, s, t, i)
    if stop_at_ground != 0:
        below = s[DOWN_INDEX] > 0.0
        stop_down = float(0.0)  # noqa: UP018 (a mutable Warp local)
        if water:
            below = held[CLEARANCE] < 0.0
            stop_down = -held[ELEVATION]
        was_crashed = e.crashed[i]
        if was_crashed:
            s = start
            held = start_held
        if below and not was_crashed:
            if water:
                held = surface_at_stop(held, s[DOWN_INDEX] - stop_down)
            s[DOWN_INDEX] = stop_down
            for k in range(VELOCITY_START, ANGULAR_RATE_START + 3):
                s[k] = 0.0
            e.crashed[i] = True
    for k in range(size):
        e.x[i, k] = s[k]
    e.time[i] = t
    if water or e.surface[i, OVER_WATER] != 0.0:
        if not water:  # switched to the ground since the last sample
            held = SurfaceVec()
        store_surface(e.surface, i, held)


@wp.kernel
def step_kernel(e: EngineViews, p: WarpParams, g: StepSettings, substeps: int, stop_at_ground: int,
                offset: int):
    """One engine step of env i = offset + tid (:func:`advance_env`): x, time, gusts, Dryden state and
    ``crashed`` in place. ``offset``: first env of this launch (a CPU batch is split into slices
    stepped by parallel threads)."""
    i = wp.tid() + offset
    saved = flush_denormals_begin()
    advance_env(e, p, g, substeps, stop_at_ground, i)
    flush_denormals_end(saved)


@wp.kernel
def derivative_kernel(
    x: wp.array2d(dtype=wp.float32),
    command: wp.array(dtype=wp.vec4),
    wind_ned: wp.array(dtype=wp.vec3),
    gust_velocity_body: wp.array(dtype=wp.vec3),
    gust_rate_body: wp.array(dtype=wp.vec3),
    surface: wp.array2d(dtype=wp.float32),
    p: WarpParams,
    out: wp.array2d(dtype=wp.float32),
):
    """out[i] <- f(x[i], command[i]) over the held surface sample[i] (twin of ``dynamics.derivative``),
    for checks and tools."""
    i = wp.tid()
    saved = flush_denormals_begin()
    size = x.shape[1]
    d = derivative_wp(load_state(x, i, size), command[i], wind_ned[i], gust_velocity_body[i],
                      gust_rate_body[i], load_surface(surface, i), p, i)
    for k in range(size):
        out[i, k] = d[k]
    flush_denormals_end(saved)


@wp.func
def write_derived(x: wp.array2d(dtype=wp.float32), wind_ned: wp.array(dtype=wp.vec3),
                  gust_velocity_body: wp.array(dtype=wp.vec3), gust_rate_body: wp.array(dtype=wp.vec3),
                  surface: wp.array2d(dtype=wp.float32), p: WarpParams, out: wp.array2d(dtype=wp.float32),
                  i: int):
    """out[i] <- the derived state of env i in the columns of ``derived.DERIVED_FIELDS`` (twin of
    ``dynamics.derived_columns``)."""
    s = load_state(x, i, x.shape[1])
    sample = load_surface(surface, i)
    ev = evaluate_wp(s, wind_ned[i], gust_velocity_body[i], gust_rate_body[i], sample, p, i)
    rot = ev.rotation
    vel_ned = rot * wp.vec3(s[VELOCITY_START], s[VELOCITY_START + 1], s[VELOCITY_START + 2])
    euler = quaternion_to_euler_wp(wp.vec4(s[QUATERNION_START], s[QUATERNION_START + 1],
                                           s[QUATERNION_START + 2], s[QUATERNION_START + 3]))
    half_span_roll = 0.5 * p.span[i] * wp.abs(rot[2, 1])
    out[i, _AIRSPEED] = ev.airspeed
    out[i, _ALPHA] = ev.alpha
    out[i, _BETA] = ev.beta
    out[i, _HEIGHT] = ev.height
    out[i, _WING_HEIGHT] = ev.wing_height
    out[i, _THRUST] = ev.thrust
    lowest_tip = ev.wing_height - half_span_roll
    out[i, _LOWEST_TIP] = lowest_tip
    water = sample[OVER_WATER] != 0.0
    out[i, _CLEARANCE] = wp.where(water, sample[CLEARANCE], ev.height)
    out[i, _TIP_CLEARANCE] = wp.where(water, sample[TIP_CLEARANCE], lowest_tip)
    out[i, _ELEVATION] = sample[ELEVATION]
    out[i, _OVER_WATER] = sample[OVER_WATER]
    for k in range(3):
        out[i, _WAVES + k] = sample[WAVE_VELOCITY + k]
    for k in range(3):
        out[i, _SURFACES + k] = ev.surfaces[k]
        out[i, _VELOCITY_NED + k] = vel_ned[k]
        out[i, _EULER + k] = euler[k]
    for k in range(6):
        out[i, _COEFFICIENTS + k] = ev.coefficients[k]
    for k in range(3):
        out[i, _AERO_FORCE + k] = ev.aero_force_body[k]
        out[i, _AERO_MOMENT + k] = ev.aero_moment_body[k]
    for m in range(MAX_MOTORS):
        thrust = float(0.0)  # noqa: UP018 (a mutable Warp local)
        if m < p.num_motors:
            thrust = motor_thrust_wp(ev.v_air_body, s[THROTTLE_START + m], ev.density, p, i, m)
        out[i, _MOTOR_THRUST + m] = thrust
    out[i, _H_OVER_B] = ev.wing_clearance / p.span[i]
    out[i, _GE_LIFT] = ev.kappa_lift
    out[i, _GE_DRAG] = ev.kappa_drag


@wp.kernel
def evaluate_kernel(
    x: wp.array2d(dtype=wp.float32),
    wind_ned: wp.array(dtype=wp.vec3),
    gust_velocity_body: wp.array(dtype=wp.vec3),
    gust_rate_body: wp.array(dtype=wp.vec3),
    surface: wp.array2d(dtype=wp.float32),
    p: WarpParams,
    out: wp.array2d(dtype=wp.float32),
    offset: int,
):
    """out[i] <- the derived state of env i = offset + tid (:func:`write_derived`): one launch (per CPU
    slice) instead of the torch model."""
    i = wp.tid() + offset
    saved = flush_denormals_begin()
    write_derived(x, wind_ned, gust_velocity_body, gust_rate_body, surface, p, out, i)
    flush_denormals_end(saved)


@wp.kernel
def screen_kernel(initial_x: wp.array2d(dtype=wp.float32), initial_command: wp.array(dtype=wp.vec4),
                  mask: wp.array(dtype=wp.bool), codes: wp.array(dtype=wp.int32), offset: int):
    """codes[i] <- 1 when env i = offset + tid is in ``mask`` and its initial row fails a reset check of
    ``Simulator`` (a NaN or Inf, a command outside [-1, 1], a quaternion shorter than
    ``MIN_QUATERNION_NORM``, a position, speed or body rate beyond ``MAX_RESET_*``, a height below the
    ground), else 0: the device's screen before ``Simulator``'s own check, which names the rows."""
    i = wp.tid() + offset
    bad = int(0)  # noqa: UP018, RUF046 (a mutable Warp local)
    if mask[i]:
        size = initial_x.shape[1]
        for k in range(size):
            if not wp.isfinite(initial_x[i, k]):
                bad = 1
        u = initial_command[i]
        for k in range(4):
            if not wp.isfinite(u[k]) or wp.abs(u[k]) > 1.0:
                bad = 1
        s = load_state(initial_x, i, size)
        q = wp.vec4(s[QUATERNION_START], s[QUATERNION_START + 1], s[QUATERNION_START + 2],
                    s[QUATERNION_START + 3])
        velocity = wp.vec3(s[VELOCITY_START], s[VELOCITY_START + 1], s[VELOCITY_START + 2])
        if wp.length(q) < MIN_NORM or wp.length(velocity) > MAX_SPEED or s[DOWN_INDEX] > 0.0:
            bad = 1
        for k in range(3):
            if wp.abs(s[k]) > MAX_POSITION or wp.abs(s[ANGULAR_RATE_START + k]) > MAX_RATE:
                bad = 1
    codes[i] = bad


@wp.kernel
def reset_kernel(e: EngineViews, p: WarpParams, initial_x: wp.array2d(dtype=wp.float32),
                 initial_command: wp.array(dtype=wp.vec4), mask: wp.array(dtype=wp.bool),
                 out: wp.array2d(dtype=wp.float32), derive: int, offset: int):
    """Env i = offset + tid: when ``mask[i]``, x[i] <- project(hold_ideal(initial_x[i])) under
    ``initial_command[i]`` (twins of ``dynamics.hold_command`` and ``dynamics.project``), the command
    written, the clock, gusts and crash flag zeroed and the surface sampled (``Engine.reset``); then, with
    ``derive`` != 0,
    every env's out[i] <- its derived state (:func:`write_derived`): the reset and the state it
    publishes in one launch."""
    i = wp.tid() + offset
    if mask[i]:
        size = e.x.shape[1]
        u = initial_command[i]
        s = project_wp(hold_ideal_wp(load_state(initial_x, i, size), u, p, i), p, i)
        for k in range(size):
            e.x[i, k] = s[k]
        e.command[i] = u
        e.time[i] = 0.0
        e.gust_velocity_body[i] = wp.vec3(0.0, 0.0, 0.0)
        e.gust_rate_body[i] = wp.vec3(0.0, 0.0, 0.0)
        e.crashed[i] = False
        if p.sea_surface[i] != 0 or e.surface[i, OVER_WATER] != 0.0:
            store_surface(e.surface, i, surface_sample(e, p, s, 0.0, i))
    if derive != 0:
        saved = flush_denormals_begin()
        write_derived(e.x, e.wind_ned, e.gust_velocity_body, e.gust_rate_body, e.surface, p, out, i)
        flush_denormals_end(saved)
