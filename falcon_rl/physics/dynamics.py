"""Six-degree-of-freedom rigid-body dynamics: f(state, command, params, air) -> state derivative.

    p_dot  = R(q) v                                (NED position)
    q_dot  = 1/2 q (x) (0, omega)                  (unit quaternion, renormalised after each step)
    v_dot  = (F_aero + F_prop) / m + R(q)^T g - omega x v
    w_dot  = J^-1 (M_aero + M_prop - omega x J omega)

The aero model sees the air-relative velocity V_a = v - R^T (w_ned + w_waves) - w_gust and the rates
omega - omega_gust, so wind, the air's flow over the waves and turbulence act on alpha, beta and dynamic
pressure. Over a sea (``surface.py``) the ground-effect argument is the wing's clearance above the mean
surface under it, h/b = (h_wing - eta_bar) / b, and the surface's span asymmetry A adds the rolling and
yawing moments of ``aero.apply_ground_effect``. An airframe with
alpha-dot table terms has them solved from v_dot in closed form (``alpha_dot.py``) inside
:func:`evaluate`, so F_aero already holds them.

Model switches (``switches.ModelSwitches``) act per env inside the components; ideal actuators
and throttle also need :func:`hold_command` before each step (state set to the command).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from . import state as S
from ._warp import warp_func, warp_struct, wp
from .actuators import (
    actuator_derivative,
    actuator_derivative_wp,
    hold_ideal,
    saturate,
    saturate_wp,
)
from .aero import aero_forces, aero_forces_throttle_wp
from .alpha_dot import solve_alpha_dot_hat, solve_alpha_dot_hat_wp, with_alpha_dot, with_alpha_dot_wp
from .atmosphere import model_density, model_density_wp
from .derived import MAX_MOTORS, pack_derived
from .params import ModelParams, Vec6, WarpParams
from .propulsion import propulsion_forces, propulsion_forces_wp
from .rotations import (
    normalize_quaternion,
    normalize_quaternion_wp,
    quaternion_derivative,
    quaternion_derivative_wp,
    quaternion_to_euler,
    rotation_matrix,
    rotation_matrix_wp,
)
from .state import ANGULAR_RATE_START, QUATERNION_START, SURFACE_POSITION_START, VELOCITY_START, StateVec
from .surface import (
    ELEVATION,
    WAVE_VELOCITY,
    SurfaceVec,
    flat_clearances,
    held_surface,
    held_surface_wp,
)


@dataclass
class AirInputs:
    """Air-mass motion seen by each env (None fields mean still air)."""

    wind_ned: torch.Tensor | None = None  # [N, 3] m/s, steady wind in NED
    gust_velocity_body: torch.Tensor | None = None  # [N, 3] m/s
    gust_rate_body: torch.Tensor | None = None  # [N, 3] rad/s
    #: [N, SURFACE_WIDTH] the surface samples held over the step (``surface.py``; None: the flat ground)
    surface: torch.Tensor | None = None


@dataclass
class Evaluation:
    """Everything the derivative computes on the way, for diagnostics and trim."""

    force_body: torch.Tensor  # [N, 3] total non-gravity force
    moment_body: torch.Tensor  # [N, 3]
    aero_force_body: torch.Tensor  # [N, 3]
    aero_moment_body: torch.Tensor  # [N, 3]
    thrust: torch.Tensor  # [N, M]
    coefficients: torch.Tensor  # [N, 6]
    induced_drag_coefficient: torch.Tensor  # [N]
    kappa_lift: torch.Tensor  # [N]
    kappa_drag: torch.Tensor  # [N]
    airspeed: torch.Tensor  # [N]
    alpha: torch.Tensor  # [N]
    beta: torch.Tensor  # [N]
    density: torch.Tensor  # [N]
    height: torch.Tensor  # [N] CG height above ground
    wing_height: torch.Tensor  # [N] height of the wing quarter chord
    wing_clearance: torch.Tensor  # [N] its height above the mean surface under the wing (eta_bar)
    rotation: torch.Tensor  # [N, 3, 3] body -> NED
    surfaces: torch.Tensor  # [N, 3] clamped deflections, rad


def air_data(v_air_body: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(airspeed, alpha, beta), each [N], from air-relative body velocity [N, 3]."""
    u, v, w = v_air_body.unbind(-1)
    airspeed = torch.sqrt(u * u + v * v + w * w + 1e-12)
    alpha = torch.atan2(w, u)
    beta = torch.asin(torch.clamp(v / airspeed, -1.0, 1.0))
    return airspeed, alpha, beta


def evaluate(x: torch.Tensor, p: ModelParams, air: AirInputs | None = None) -> Evaluation:
    """Forces, moments and air data at state x [N, S]. The surfaces sit where the actuator
    states put them (clamped to their limits), so the command is not needed here."""
    q = x[:, S.QUATERNION]
    vel = x[:, S.VELOCITY]
    omega = x[:, S.ANGULAR_RATE]
    rot = rotation_matrix(q)
    v_air = vel
    omega_air = omega
    surface_height, asymmetry = None, None
    if air is not None:
        wind = air.wind_ned
        if air.surface is not None:
            surface_height, asymmetry = held_surface(x, air.surface)
            waves = air.surface[:, WAVE_VELOCITY:WAVE_VELOCITY + 3]
            wind = waves if wind is None else wind + waves
        if wind is not None:
            v_air = v_air - (rot * wind.unsqueeze(-1)).sum(dim=-2)  # R^T w
        if air.gust_velocity_body is not None:
            v_air = v_air - air.gust_velocity_body
        if air.gust_rate_body is not None:
            omega_air = omega - air.gust_rate_body
    airspeed, alpha, beta = air_data(v_air)
    height = S.height(x)
    wing_height = height - (rot[:, 2, :] * p.wing_quarter_chord).sum(-1)
    density = model_density(height, p.constant_density)
    surfaces = torch.minimum(torch.maximum(x[:, S.SURFACE_POSITION], p.surface_min), p.surface_max)
    throttle = x[:, S.THROTTLE_START:]
    first_throttle = throttle[:, 0] if throttle.shape[1] else torch.zeros_like(height)
    clearance = wing_height if surface_height is None else wing_height - surface_height
    aero = aero_forces(airspeed, alpha, beta, omega_air, surfaces, density,
                       clearance / p.span, p, first_throttle, asymmetry)
    f_prop, m_prop, thrust = propulsion_forces(v_air, throttle, density, p, omega)
    if aero.alpha_dot_force is not None:
        steady = translational_acceleration(aero.force_body + f_prop, rot, omega, vel, p)
        per_unit = aero.alpha_dot_force / p.mass[:, None]
        aero = with_alpha_dot(aero, solve_alpha_dot_hat(v_air, steady, per_unit, airspeed, p))
    return Evaluation(
        force_body=aero.force_body + f_prop,
        moment_body=aero.moment_body + m_prop,
        aero_force_body=aero.force_body,
        aero_moment_body=aero.moment_body,
        thrust=thrust,
        coefficients=aero.coefficients,
        induced_drag_coefficient=aero.induced_drag_coefficient,
        kappa_lift=aero.kappa_lift,
        kappa_drag=aero.kappa_drag,
        airspeed=airspeed,
        alpha=alpha,
        beta=beta,
        density=density,
        height=height,
        wing_height=wing_height,
        wing_clearance=clearance,
        rotation=rot,
        surfaces=surfaces,
    )


def translational_acceleration(force_body: torch.Tensor, rotation: torch.Tensor, omega: torch.Tensor,
                               velocity: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """v_dot [N, 3] m/s^2 (body axes) = F / m + R^T g - omega x v from the non-gravity force [N, 3] N, the
    body -> NED rotation [N, 3, 3], body rates [N, 3] rad/s and body velocity [N, 3] m/s."""
    # 3x3 products as broadcast multiply + sum: much cheaper than batched matmul for [N, 3, 3].
    gravity_body = rotation[:, 2, :] * p.gravity[:, None]  # R^T (0, 0, g)
    return force_body / p.mass[:, None] + gravity_body - torch.linalg.cross(omega, velocity, dim=-1)


def derivative(x: torch.Tensor, command: torch.Tensor, p: ModelParams,
               air: AirInputs | None = None) -> torch.Tensor:
    """State derivative [N, S] at state x [N, S] under normalised command [N, 4]."""
    ev = evaluate(x, p, air)
    q = x[:, S.QUATERNION]
    vel = x[:, S.VELOCITY]
    omega = x[:, S.ANGULAR_RATE]
    v_dot = translational_acceleration(ev.force_body, ev.rotation, omega, vel, p)
    j_omega = (p.inertia * omega.unsqueeze(1)).sum(dim=-1)
    torque = ev.moment_body - torch.linalg.cross(omega, j_omega, dim=-1)
    w_dot = (p.inertia_inv * torque.unsqueeze(1)).sum(dim=-1)
    p_dot = (ev.rotation * vel.unsqueeze(1)).sum(dim=-1)
    q_dot = quaternion_derivative(q, omega)
    d_pos, d_rate, d_thr = actuator_derivative(
        x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE], x[:, S.THROTTLE_START:], command, p)
    return torch.cat([p_dot, q_dot, v_dot, w_dot, d_pos, d_rate, d_thr], dim=-1)


def project(x: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """After a step: renormalise the quaternion and saturate the actuator states (new tensor)."""
    pos, rate, thr = saturate(x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE],
                              x[:, S.THROTTLE_START:], p)
    return torch.cat([x[:, S.POSITION], normalize_quaternion(x[:, S.QUATERNION]),
                      x[:, S.VELOCITY], x[:, S.ANGULAR_RATE], pos, rate, thr], dim=-1)


def hold_command(x: torch.Tensor, command: torch.Tensor, p: ModelParams) -> torch.Tensor:
    """Before a step under ``command`` [N, 4]: put the actuator states of the ideal-actuator and
    ideal-throttle envs on the command (``actuators.hold_ideal``, twin ``hold_ideal_wp``; a new
    tensor [N, S])."""
    pos, rate, thr = hold_ideal(x[:, S.SURFACE_POSITION], x[:, S.SURFACE_RATE], x[:, S.THROTTLE_START:],
                                command, p)
    return torch.cat([x[:, :S.SURFACE_POSITION_START], pos, rate, thr], dim=-1)


def lowest_tip_height(ev: Evaluation, p: ModelParams) -> torch.Tensor:
    """[N] m: height of the lower wing tip. The tips sit at the quarter-chord point +-b/2 along
    body y, so their heights are wing_height -+ (b/2) R[2, 1]; the lower one is
    wing_height - (b/2) |R[2, 1]|."""
    return ev.wing_height - 0.5 * p.span * ev.rotation[:, 2, 1].abs()


def derived_columns(x: torch.Tensor, p: ModelParams, air: AirInputs | None = None) -> torch.Tensor:
    """[N, DERIVED_WIDTH] derived state of x [N, S] in the columns of ``derived.DERIVED_FIELDS``
    (the torch twin of ``warp_kernels.evaluate_kernel``)."""
    ev = evaluate(x, p, air)
    tip = lowest_tip_height(ev, p)
    sample = None if air is None else air.surface
    clearance, tip_clearance, over_water = flat_clearances(ev.height, tip, sample)
    elevation = torch.zeros_like(ev.height) if sample is None else sample[:, ELEVATION]
    waves = (torch.zeros_like(x[:, S.VELOCITY]) if sample is None
             else sample[:, WAVE_VELOCITY:WAVE_VELOCITY + 3])
    return pack_derived({
        "airspeed": ev.airspeed, "alpha": ev.alpha, "beta": ev.beta, "height": ev.height,
        "wing_height": ev.wing_height, "surface_position": ev.surfaces, "thrust": ev.thrust.sum(-1),
        "aero_coefficients": ev.coefficients, "lowest_tip_height": tip,
        "velocity_ned": (ev.rotation * x[:, S.VELOCITY].unsqueeze(1)).sum(dim=-1),
        "euler": quaternion_to_euler(x[:, S.QUATERNION]),
        "aero_force_body": ev.aero_force_body, "aero_moment_body": ev.aero_moment_body,
        "motor_thrust": torch.nn.functional.pad(ev.thrust, (0, MAX_MOTORS - ev.thrust.shape[-1])),
        "ge_h_over_b": ev.wing_clearance / p.span, "ge_lift_factor": ev.kappa_lift,
        "ge_drag_factor": ev.kappa_drag, "surface_elevation": elevation, "surface_clearance": clearance,
        "lowest_tip_clearance": tip_clearance, "over_water": over_water, "wave_velocity_ned": waves,
    })


# ---------------------------------------------------------------------------------------- warp twins
@warp_func
def air_data_wp(v_air_body: wp.vec3) -> wp.vec3:
    """(airspeed, alpha, beta) from the air-relative body velocity (twin of :func:`air_data`)."""
    u = v_air_body[0]
    v = v_air_body[1]
    w = v_air_body[2]
    airspeed = wp.sqrt(u * u + v * v + w * w + 1.0e-12)
    return wp.vec3(airspeed, wp.atan2(w, u), wp.asin(wp.clamp(v / airspeed, -1.0, 1.0)))


@warp_func
def state_vec3(x: StateVec, start: int) -> wp.vec3:
    """Three consecutive state components from ``start``."""
    return wp.vec3(x[start], x[start + 1], x[start + 2])


@warp_func
def translational_acceleration_wp(force_body: wp.vec3, rotation: wp.mat33, omega: wp.vec3, velocity: wp.vec3,
                                  p: WarpParams, i: int) -> wp.vec3:
    """v_dot of env i (twin of :func:`translational_acceleration`)."""
    gravity_body = wp.transpose(rotation) * wp.vec3(0.0, 0.0, p.gravity[i])
    return force_body / p.mass[i] + gravity_body - wp.cross(omega, velocity)


@warp_struct
class EvaluationWp:
    """Per-env twin of the parts of :class:`Evaluation` that the derivative and the state need."""

    rotation: wp.mat33
    airspeed: float
    alpha: float
    beta: float
    height: float
    wing_height: float
    wing_clearance: float
    surfaces: wp.vec3
    force_body: wp.vec3
    moment_body: wp.vec3
    thrust: float
    coefficients: Vec6
    # diagnostics (read by the evaluation kernel only)
    aero_force_body: wp.vec3
    aero_moment_body: wp.vec3
    kappa_lift: float
    kappa_drag: float
    v_air_body: wp.vec3
    density: float


@warp_func
def evaluate_wp(x: StateVec, wind_ned: wp.vec3, gust_velocity_body: wp.vec3, gust_rate_body: wp.vec3,
                surface: SurfaceVec, p: WarpParams, i: int) -> EvaluationWp:
    """Forces, moments and air data of env ``i`` at state ``x`` over its held ``surface`` sample (read
    when ``p.sea_surface[i]`` is set) (twin of :func:`evaluate`)."""
    q = wp.vec4(x[QUATERNION_START], x[QUATERNION_START + 1], x[QUATERNION_START + 2],
                x[QUATERNION_START + 3])
    rot = rotation_matrix_wp(q)
    wind = wind_ned
    held = wp.vec2(0.0, 0.0)
    if p.sea_surface[i] != 0:
        held = held_surface_wp(x, surface)
        wind = wind + wp.vec3(surface[WAVE_VELOCITY], surface[WAVE_VELOCITY + 1], surface[WAVE_VELOCITY + 2])
    v_air = state_vec3(x, VELOCITY_START) - wp.transpose(rot) * wind - gust_velocity_body
    omega_air = state_vec3(x, ANGULAR_RATE_START) - gust_rate_body
    air = air_data_wp(v_air)
    height = -x[S.DOWN_INDEX]
    wing_height = height - wp.dot(wp.vec3(rot[2, 0], rot[2, 1], rot[2, 2]), p.wing_quarter_chord[i])
    density = model_density_wp(height, p.constant_density[i])
    lo = p.surface_min[i]
    hi = p.surface_max[i]
    surfaces = wp.vec3(wp.min(wp.max(x[SURFACE_POSITION_START], lo[0]), hi[0]),
                       wp.min(wp.max(x[SURFACE_POSITION_START + 1], lo[1]), hi[1]),
                       wp.min(wp.max(x[SURFACE_POSITION_START + 2], lo[2]), hi[2]))
    clearance = wing_height - held[0]
    aero = aero_forces_throttle_wp(air[0], air[1], air[2], omega_air, surfaces, density,
                                   clearance / p.span[i], held[1], x[S.THROTTLE_START], p, i)
    prop = propulsion_forces_wp(v_air, x, density, p, i)
    if p.num_alpha_dot_terms > 0:
        omega = state_vec3(x, ANGULAR_RATE_START)
        velocity = state_vec3(x, VELOCITY_START)
        steady = translational_acceleration_wp(aero.force_body + prop.force_body, rot, omega, velocity, p, i)
        per_unit = aero.alpha_dot_force / p.mass[i]
        aero = with_alpha_dot_wp(aero, solve_alpha_dot_hat_wp(v_air, steady, per_unit, air[0], p, i))
    ev = EvaluationWp()
    ev.rotation = rot
    ev.airspeed = air[0]
    ev.alpha = air[1]
    ev.beta = air[2]
    ev.height = height
    ev.wing_height = wing_height
    ev.wing_clearance = clearance
    ev.surfaces = surfaces
    ev.force_body = aero.force_body + prop.force_body
    ev.moment_body = aero.moment_body + prop.moment_body
    ev.thrust = prop.thrust
    ev.coefficients = aero.coefficients
    ev.aero_force_body = aero.force_body
    ev.aero_moment_body = aero.moment_body
    ev.kappa_lift = aero.kappa_lift
    ev.kappa_drag = aero.kappa_drag
    ev.v_air_body = v_air
    ev.density = density
    return ev


@warp_func
def derivative_wp(x: StateVec, command: wp.vec4, wind_ned: wp.vec3, gust_velocity_body: wp.vec3,
                  gust_rate_body: wp.vec3, surface: SurfaceVec, p: WarpParams, i: int) -> StateVec:
    """State derivative of env ``i`` (twin of :func:`derivative`; padded throttle slots stay 0)."""
    ev = evaluate_wp(x, wind_ned, gust_velocity_body, gust_rate_body, surface, p, i)
    rot = ev.rotation
    q = wp.vec4(x[QUATERNION_START], x[QUATERNION_START + 1], x[QUATERNION_START + 2],
                x[QUATERNION_START + 3])
    vel = state_vec3(x, VELOCITY_START)
    omega = state_vec3(x, ANGULAR_RATE_START)
    v_dot = translational_acceleration_wp(ev.force_body, rot, omega, vel, p, i)
    w_dot = p.inertia_inv[i] * (ev.moment_body - wp.cross(omega, p.inertia[i] * omega))
    p_dot = rot * vel
    q_dot = quaternion_derivative_wp(q, omega)
    d = actuator_derivative_wp(x, command, p, i)
    for k in range(3):
        d[k] = p_dot[k]
        d[VELOCITY_START + k] = v_dot[k]
        d[ANGULAR_RATE_START + k] = w_dot[k]
    for k in range(4):
        d[QUATERNION_START + k] = q_dot[k]
    return d


@warp_func
def project_wp(x: StateVec, p: WarpParams, i: int) -> StateVec:
    """Renormalise the quaternion and saturate the actuators (twin of :func:`project`)."""
    y = saturate_wp(x, p, i)
    q = normalize_quaternion_wp(wp.vec4(x[QUATERNION_START], x[QUATERNION_START + 1],
                                        x[QUATERNION_START + 2], x[QUATERNION_START + 3]))
    for k in range(4):
        y[QUATERNION_START + k] = q[k]
    return y
