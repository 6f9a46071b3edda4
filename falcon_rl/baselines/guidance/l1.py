"""ArduPilot's L1 lateral guidance (Park, Deyst and How 2004, as in AP_L1_Control), batched over envs.

With period P and damping zeta, ground speed V_g and the L1 distance L1 = zeta P V_g / pi, K_L1 = 4 zeta^2:

    line A -> B:  Nu2 = atan2(v_g x AB, v_g . AB)  (the velocity's angle to the line)
                  Nu1 = asin(clamp(xtrack / L1, +-sin 45 deg)) + the cross-track integrator
                  (xtrack = (p - A) x AB, positive left of the line; the 45 deg capture limit)
                  behind A (further than L1 and beyond 135 deg): fly to A; 3 s past B: fly to B
    a = K_L1 V_g^2 / L1 sin(clamp(Nu1 + Nu2, +-pi/2))

    loiter (centre C, radius R, direction d = +1 clockwise):  capture a_cap = K_L1 V_g^2 / L1 sin(Nu) towards
    C, circle a_circ = d (omega^2 (r - R) + 2 zeta omega r_dot + v_t^2 / max(R / 2, r)) (omega = 2 pi / P,
    r_dot the radial outbound velocity, v_t the tangential one); the capture law outside the circle until the
    two cross

    bank = atan(a / (g cos theta)) within the roll limit (ArduPilot's nav_roll_cd).

Parameters carry ArduPilot's names (``NAVL1_PERIOD``, ``NAVL1_DAMPING``, ``NAVL1_XTRACK_I``) and defaults.
The cross-track integrator is the caller's state ([N] rad, :func:`l1_waypoints` returns it updated);
ArduPilot's "indecision" latch (a memory of the last turn direction when flying away from a waypoint) is
left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ...constants import DEG
from .npfg import bank_for
from .paths import cross2, unit

#: sin(45 deg): the L1 line capture angle limit.
CAPTURE_SINE = 0.7071


@dataclass
class L1Params:
    """L1 parameters by ArduPilot name (SI units, angles in rad); ArduPlane's defaults."""

    NAVL1_PERIOD: float = 17.0  # s
    NAVL1_DAMPING: float = 0.75
    NAVL1_XTRACK_I: float = 0.02  # cross-track integrator gain (0 disables it)
    ROLL_LIMIT: float = 45.0 * DEG  # rad (ArduPlane's ROLL_LIMIT_DEG)

    def ardupilot(self) -> dict[str, float]:
        """The parameters as an ArduPilot parameter file holds them (ROLL_LIMIT_DEG in degrees)."""
        return {"NAVL1_PERIOD": self.NAVL1_PERIOD, "NAVL1_DAMPING": self.NAVL1_DAMPING,
                "NAVL1_XTRACK_I": self.NAVL1_XTRACK_I, "ROLL_LIMIT_DEG": self.ROLL_LIMIT / DEG}


@dataclass
class L1Output:
    """One L1 evaluation, [N] each: ``lateral_accel`` (m/s^2, positive right), ``bank`` (rad),
    ``crosstrack_error`` (m, ArduPilot's sign: positive left of the line, outside the loiter circle),
    ``nu`` (rad, the bearing error), ``l1_distance`` (m) and ``integrator`` (rad, the updated cross-track
    integrator)."""

    lateral_accel: torch.Tensor
    bank: torch.Tensor
    crosstrack_error: torch.Tensor
    nu: torch.Tensor
    l1_distance: torch.Tensor
    integrator: torch.Tensor


def _ground_velocity(ground_velocity: torch.Tensor, yaw: torch.Tensor, minimum: float) -> tuple[torch.Tensor,
                                                                                                  torch.Tensor]:
    """(velocity [N, 2], speed [N]): below ``minimum`` m/s, or moving backwards, a ``minimum`` m/s vector
    along the heading ``yaw`` (ArduPilot's fallback)."""
    speed = ground_velocity.norm(dim=-1)
    heading = torch.stack([torch.cos(yaw), torch.sin(yaw)], dim=-1)
    forwards = (ground_velocity * heading).sum(-1) > 0.0
    slow = (speed < minimum) | ~forwards
    velocity = torch.where(slow.unsqueeze(-1), heading * minimum, ground_velocity)
    return velocity, torch.where(slow, torch.full_like(speed, minimum), speed)


def l1_waypoints(position: torch.Tensor, start: torch.Tensor, end: torch.Tensor,
                 ground_velocity: torch.Tensor, yaw: torch.Tensor, dt: float,
                 integrator: torch.Tensor | None = None, pitch: torch.Tensor | None = None,
                 p: L1Params | None = None, min_distance: float = 0.0) -> L1Output:
    """L1 along the segments ``start`` -> ``end`` ([N, 2] north-east, m) at ``position`` [N, 2] with
    ``ground_velocity`` [N, 2], heading ``yaw`` [N] and pitch [N] (rad); ``dt`` (s) the update interval
    of the cross-track integrator ``integrator`` [N] (zeros when None)."""
    p = p or L1Params()
    zeta = p.NAVL1_DAMPING
    gain = 4.0 * zeta * zeta
    velocity, speed = _ground_velocity(ground_velocity, yaw, 0.1)
    distance = (zeta * p.NAVL1_PERIOD * speed / math.pi).clamp_min(min_distance)
    segment = end - start
    length = segment.norm(dim=-1)
    to_end = end - position
    heading = torch.stack([torch.cos(yaw), torch.sin(yaw)], dim=-1)
    direction = unit(segment, fallback=unit(to_end, fallback=heading))
    from_start = position - start
    crosstrack = cross2(from_start, direction)
    start_distance = from_start.norm(dim=-1)
    along = (from_start * direction).sum(-1)
    if integrator is None:
        integrator = torch.zeros_like(crosstrack)

    def towards(point: torch.Tensor) -> torch.Tensor:
        inbound = -unit(position - point, fallback=direction)
        return torch.atan2(cross2(velocity, inbound), (velocity * inbound).sum(-1))

    behind_start = (start_distance > distance) & (along / start_distance.clamp_min(1.0) < -CAPTURE_SINE)
    past_end = along > length + 3.0 * speed
    nu2 = torch.atan2(cross2(velocity, direction), (velocity * direction).sum(-1))
    nu1 = torch.asin((crosstrack / distance.clamp_min(0.1)).clamp(-CAPTURE_SINE, CAPTURE_SINE))
    if p.NAVL1_XTRACK_I > 0.0:
        near = nu1.abs() < 5.0 * DEG
        stepped = (integrator + nu1 * p.NAVL1_XTRACK_I * dt).clamp(-0.1, 0.1)
        integrator = torch.where(near, stepped, integrator)
    else:
        integrator = torch.zeros_like(integrator)
    on_line = nu1 + integrator + nu2
    nu = torch.where(behind_start, towards(start), torch.where(past_end, towards(end), on_line))
    nu = nu.clamp(-0.5 * math.pi, 0.5 * math.pi)
    accel = gain * speed**2 / distance * torch.sin(nu)
    return L1Output(accel, bank_for(accel, pitch, p.ROLL_LIMIT), crosstrack, nu, distance, integrator)


def l1_loiter(position: torch.Tensor, center: torch.Tensor, radius: torch.Tensor, direction: torch.Tensor,
              ground_velocity: torch.Tensor, yaw: torch.Tensor, pitch: torch.Tensor | None = None,
              p: L1Params | None = None) -> L1Output:
    """L1 loiter about ``center`` [N, 2] at ``radius`` [N] (m), ``direction`` [N] +1 clockwise / -1
    counter-clockwise, from ``position``, ``ground_velocity`` [N, 2] and heading ``yaw`` [N] (rad)."""
    p = p or L1Params()
    zeta = p.NAVL1_DAMPING
    omega = 2.0 * math.pi / p.NAVL1_PERIOD
    gain = 4.0 * zeta * zeta
    speed = ground_velocity.norm(dim=-1).clamp_min(1.0)
    velocity = ground_velocity
    distance = zeta * p.NAVL1_PERIOD * speed / math.pi
    offset = position - center
    heading = torch.stack([torch.cos(yaw), torch.sin(yaw)], dim=-1)
    radial = unit(offset, fallback=unit(velocity, fallback=heading, eps=0.1), eps=0.1)
    cross_velocity = cross2(radial, velocity)  # across the inbound radial
    inbound_velocity = -(velocity * radial).sum(-1)
    nu = torch.atan2(cross_velocity, inbound_velocity).clamp(-0.5 * math.pi, 0.5 * math.pi)
    capture = gain * speed**2 / distance * torch.sin(nu)
    outbound = -inbound_velocity
    error = offset.norm(dim=-1) - radius
    pd = error * omega**2 + outbound * 2.0 * zeta * omega
    tangential = cross_velocity * direction
    pd = torch.where((inbound_velocity < 0.0) & (tangential < 0.0), pd.clamp_min(0.0), pd)
    centripetal = tangential**2 / torch.maximum(0.5 * radius, radius + error)
    circle = direction * (pd + centripetal)
    use_capture = (error > 0.0) & (direction * capture < direction * circle)
    accel = torch.where(use_capture, capture, circle)
    nu = torch.where(use_capture, nu, torch.zeros_like(nu))
    return L1Output(accel, bank_for(accel, pitch, p.ROLL_LIMIT), error, nu, distance, torch.zeros_like(error))


__all__ = ["CAPTURE_SINE", "L1Output", "L1Params", "l1_loiter", "l1_waypoints"]
