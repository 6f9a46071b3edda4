"""Propeller thrust by momentum theory, discharge-velocity form, for several motors.

    V_d = V_ax + d_t (k_m - V_ax),  T = 1/2 rho S_p C_p V_d (V_d - V_ax),  T >= 0
    Q   = -spin k_tp (k_omega d_t)^2 about the thrust axis (reaction on the airframe)

V_ax is the air-relative velocity along the thrust axis. Zero throttle gives zero thrust, and the
thrust is clamped at zero above the discharge speed (a windmilling propeller gives no thrust here).
A motor whose ``motor_model`` is 1 (airframe ``model`` "thrust_map") instead reads T and Q from the
airframe's table terms of outputs "thrust" and "torque" (``tables.py``), at its axial inflow speed
V_ax (the "airspeed" variable), its throttle and the density: a map sampled in steady state from
another simulator's engine and propeller (e.g. an imported JSBSim aircraft), T >= 0 again.

Each motor adds F = T a and M = r x F + Q a; the model switch ``no_propeller_torque``
(``switches.ModelSwitches(propeller_torque=False)``) drops Q per env. A thrust-map motor also adds
(:func:`propeller_moments`)

    M_gyro = (h a) x omega                         h: the map's "angular_momentum" output, N m s
    M_p    = -spin P T angle v_t / |v_t|,  angle = atan2(|v_t|, V_ax + v_i)

the gyroscopic moment of its spinning propeller (omega: the body rates) and JSBSim's p-factor: the
thrust line shifts sideways by P (``motor_p_factor``, m/rad) per rad of inflow angle, v_t = V_a - V_ax a
the in-plane inflow, v_i = (-V_ax + sqrt(V_ax |V_ax| + 2 T / (rho S_p))) / 2 the momentum-theory induced
velocity (S_p the motor's ``disk_area``), so an aircraft at positive alpha with a clockwise (spin +1)
propeller yaws left. Momentum-theory motors have neither (nor is the in-plane inflow the rotation adds
at the propeller, omega x r, in V_a).
"""

from __future__ import annotations

import torch

from ._warp import warp_func, warp_struct, wp
from .interpolated_terms import (
    AIRSPEED,
    ANGULAR_MOMENTUM_OUTPUT,
    DENSITY,
    NUM_VARIABLES,
    THROTTLE,
    THRUST_OUTPUT,
    TORQUE_OUTPUT,
    TableVars,
    has_terms,
    table_output_wp,
    table_outputs,
)
from .params import ModelParams, WarpParams
from .state import ANGULAR_RATE_START, THROTTLE_START, StateVec

#: ``motor_model`` code of a thrust-map motor.
THRUST_MAP = 1
#: In-plane inflow (m/s) below which the p-factor is zero (its direction is undefined), as in JSBSim.
MIN_IN_PLANE_SPEED = 1e-4


def thrust_map(v_axial: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor, p: ModelParams
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(thrust [N, M] N, torque [N, M] N m, angular momentum [N, M] N m s) of the airframe's thrust map at
    axial inflow [N, M] m/s, throttle [N, M] and density [N] (evaluated for every motor; used where
    motor_model is 1)."""
    n, m = v_axial.shape
    x = torch.zeros(n, m, NUM_VARIABLES, dtype=v_axial.dtype, device=v_axial.device)
    x[..., AIRSPEED] = v_axial
    x[..., THROTTLE] = throttle.clamp(0.0, 1.0)
    x[..., DENSITY] = density[:, None]
    gains = p.table_gain.repeat_interleave(m, dim=0)
    out = table_outputs(x.reshape(n * m, NUM_VARIABLES), p, gains).reshape(n, m, -1)
    return torch.relu(out[..., THRUST_OUTPUT]), out[..., TORQUE_OUTPUT], out[..., ANGULAR_MOMENTUM_OUTPUT]


def motor_thrust(v_air_body: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor,
                 p: ModelParams) -> torch.Tensor:
    """Thrust per motor [N, M] N from air velocity [N, 3], throttle [N, M] in [0, 1], rho [N]."""
    v_axial = torch.einsum("nmi,ni->nm", p.motor_axis, v_air_body)
    mapped = thrust_map(v_axial, throttle, density, p)[0] if has_thrust_map(p) else None
    return axial_thrust(v_axial, throttle, density, p, mapped)


def axial_thrust(v_axial: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor, p: ModelParams,
                 mapped: torch.Tensor | None) -> torch.Tensor:
    """:func:`motor_thrust` from the axial inflow [N, M] m/s; ``mapped`` [N, M] is the thrust map's
    thrust where the airframe has one (used where motor_model is 1), else None."""
    delta = throttle.clamp(0.0, 1.0)
    v_discharge = v_axial + delta * (p.discharge_speed - v_axial)
    thrust = 0.5 * density[:, None] * p.disk_area * p.thrust_coefficient * v_discharge * (
        v_discharge - v_axial)
    if mapped is not None:
        thrust = torch.where(p.motor_model == THRUST_MAP, mapped, thrust)
    return torch.relu(thrust)


def has_thrust_map(p: ModelParams) -> bool:
    """Whether the airframe has thrust-map terms (``tables.has_terms``, cached per tensor)."""
    return bool(p.motor_model.numel()) and has_terms(p, THRUST_OUTPUT)


def propulsion_forces(v_air_body: torch.Tensor, throttle: torch.Tensor, density: torch.Tensor,
                      p: ModelParams, omega_body: torch.Tensor | None = None
                      ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(force [N, 3], moment [N, 3], thrust per motor [N, M]) in body axes about the CG, from the air
    velocity [N, 3], throttles [N, M], density [N] and the body rates [N, 3] rad/s (None: no gyroscopic
    moment). The thrust map, where there is one, is evaluated once for thrust, torque and angular
    momentum."""
    v_axial = torch.einsum("nmi,ni->nm", p.motor_axis, v_air_body)  # [N, M]
    mapped = thrust_map(v_axial, throttle, density, p) if has_thrust_map(p) else None
    thrust = axial_thrust(v_axial, throttle, density, p, None if mapped is None else mapped[0])
    force_m = thrust.unsqueeze(-1) * p.motor_axis  # [N, M, 3]
    delta = throttle.clamp(0.0, 1.0)
    torque = -p.motor_spin * p.torque_coefficient * (p.torque_speed_constant * delta) ** 2
    if mapped is not None:
        torque = torch.where(p.motor_model == THRUST_MAP, mapped[1], torque)
    torque = torque.masked_fill((p.no_propeller_torque != 0).unsqueeze(-1), 0.0)
    moment_m = torch.linalg.cross(p.motor_position, force_m, dim=-1) + torque.unsqueeze(-1) * (
        p.motor_axis)
    moment = moment_m.sum(dim=1)
    if mapped is not None:
        moment = moment + propeller_moments(v_air_body, v_axial, omega_body, thrust, mapped[2], density, p)
    return force_m.sum(dim=1), moment, thrust


def propeller_moments(v_air_body: torch.Tensor, v_axial: torch.Tensor, omega_body: torch.Tensor | None,
                      thrust: torch.Tensor, angular_momentum: torch.Tensor, density: torch.Tensor,
                      p: ModelParams) -> torch.Tensor:
    """[N, 3] N m: gyroscopic and p-factor moments of the thrust-map motors (see the module doc) from the
    air velocity [N, 3], its axial part per motor [N, M], body rates [N, 3] (None: no gyroscopic
    moment), thrust [N, M], angular momentum [N, M] and density [N]."""
    axis = p.motor_axis  # [N, M, 3]
    in_plane = v_air_body.unsqueeze(1) - v_axial.unsqueeze(-1) * axis  # [N, M, 3]
    speed = in_plane.norm(dim=-1)
    disk = 2.0 * thrust / (density[:, None] * p.disk_area)
    squared = v_axial * v_axial.abs() + disk
    induced = 0.5 * (-v_axial + torch.sign(squared) * squared.abs().sqrt())
    angle = torch.atan2(speed, v_axial + induced)
    scale = -p.motor_spin * p.motor_p_factor * thrust * angle / speed.clamp_min(MIN_IN_PLANE_SPEED)
    moment = torch.where((speed > MIN_IN_PLANE_SPEED).unsqueeze(-1), scale.unsqueeze(-1) * in_plane, 0.0)
    if omega_body is not None:
        h = angular_momentum.unsqueeze(-1) * axis
        moment = moment + torch.linalg.cross(h, omega_body.unsqueeze(1).expand_as(h), dim=-1)
    return torch.where((p.motor_model == THRUST_MAP).unsqueeze(-1), moment, 0.0).sum(dim=1)


# ---------------------------------------------------------------------------------------- warp twins
@warp_struct
class PropulsionResultWp:
    """Per-env twin of :func:`propulsion_forces`' output (thrust summed over motors)."""

    force_body: wp.vec3
    moment_body: wp.vec3
    thrust: float


@warp_func
def motor_thrust_wp(v_air_body: wp.vec3, throttle: float, density: float, p: WarpParams, i: int,
                    m: int) -> float:
    """Thrust of motor ``m`` of env ``i``, N (twin of :func:`motor_thrust`)."""
    v_axial = wp.dot(p.motor_axis[i, m], v_air_body)
    delta = wp.clamp(throttle, 0.0, 1.0)
    v_discharge = v_axial + delta * (p.discharge_speed[i, m] - v_axial)
    thrust = 0.5 * density * p.disk_area[i, m] * p.thrust_coefficient[i, m] * v_discharge * (
        v_discharge - v_axial)
    if p.motor_model[i, m] == THRUST_MAP:
        thrust = table_output_wp(map_variables_wp(v_axial, throttle, density), p, i, THRUST_OUTPUT)
    return wp.max(thrust, 0.0)


@warp_func
def map_variables_wp(v_axial: float, throttle: float, density: float) -> TableVars:
    """The thrust-map variables of one motor (twin of the rows built in :func:`thrust_map`)."""
    x = TableVars()
    x[AIRSPEED] = v_axial
    x[THROTTLE] = wp.clamp(throttle, 0.0, 1.0)
    x[DENSITY] = density
    return x


@warp_func
def propulsion_forces_wp(v_air_body: wp.vec3, x: StateVec, density: float, p: WarpParams, i: int
                         ) -> PropulsionResultWp:
    """Force and moment about the CG of all motors of env ``i``; throttles and body rates are read from
    the state vector ``x`` (twin of :func:`propulsion_forces`)."""
    out = PropulsionResultWp()
    omega_body = wp.vec3(x[ANGULAR_RATE_START], x[ANGULAR_RATE_START + 1], x[ANGULAR_RATE_START + 2])
    for m in range(p.num_motors):
        throttle = x[THROTTLE_START + m]
        thrust = motor_thrust_wp(v_air_body, throttle, density, p, i, m)
        axis = p.motor_axis[i, m]
        force = thrust * axis
        delta = wp.clamp(throttle, 0.0, 1.0)
        ks = p.torque_speed_constant[i, m] * delta
        torque = -p.motor_spin[i, m] * p.torque_coefficient[i, m] * ks * ks
        if p.motor_model[i, m] == THRUST_MAP:
            torque = table_output_wp(map_variables_wp(wp.dot(axis, v_air_body), throttle, density), p, i,
                                     TORQUE_OUTPUT)
        if p.no_propeller_torque[i] != 0:
            torque = 0.0
        out.force_body = out.force_body + force
        out.moment_body = out.moment_body + wp.cross(p.motor_position[i, m], force) + torque * axis
        if p.motor_model[i, m] == THRUST_MAP:
            out.moment_body = out.moment_body + propeller_moment_wp(v_air_body, omega_body, throttle, thrust,
                                                                    density, p, i, m)
        out.thrust = out.thrust + thrust
    return out


@warp_func
def propeller_moment_wp(v_air_body: wp.vec3, omega_body: wp.vec3, throttle: float, thrust: float,
                        density: float, p: WarpParams, i: int, m: int) -> wp.vec3:
    """Gyroscopic and p-factor moment of thrust-map motor ``m`` of env ``i`` (twin of one motor of
    :func:`propeller_moments`)."""
    axis = p.motor_axis[i, m]
    v_axial = wp.dot(axis, v_air_body)
    in_plane = v_air_body - v_axial * axis
    speed = wp.length(in_plane)
    squared = v_axial * wp.abs(v_axial) + 2.0 * thrust / (density * p.disk_area[i, m])
    induced = 0.5 * (-v_axial + wp.sign(squared) * wp.sqrt(wp.abs(squared)))
    moment = wp.vec3(0.0, 0.0, 0.0)
    if speed > MIN_IN_PLANE_SPEED:
        angle = wp.atan2(speed, v_axial + induced)
        moment = (-p.motor_spin[i, m] * p.motor_p_factor[i, m] * thrust * angle / speed) * in_plane
    h = table_output_wp(map_variables_wp(v_axial, throttle, density), p, i, ANGULAR_MOMENTUM_OUTPUT)
    return moment + wp.cross(h * axis, omega_body)
