"""PX4's nonlinear path-following guidance (NPFG, Stastny & Siegwart), batched over envs.

From the path frame at the closest point (``paths.PathFrame``: unit tangent t, signed track error e, curvature
kappa), the ground velocity v_g and the wind w ([N, 2] north-east), with period P and damping zeta:

    k = 4 pi zeta / P (p gain),  T = P zeta (time constant),  e_b = V_g T (track-error bound; for V_g < 1
    m/s 0.5 T (V_g^2 + 1))
    e_n = clamp(|e| / e_b, 0, 1),  look-ahead angle lambda = (pi / 2) (e_n - 1)^2
    bearing  b = cos(lambda) (-sign(e) n) + sin(lambda) t,   n = t rotated 90 deg clockwise
    v_ref = the air velocity that makes good b through the wind at the nominal airspeed (wind triangle;
            raised towards the maximum airspeed to keep a minimum ground speed, or the excess-wind
            mitigation when b cannot be flown)
    a = k (v_air x v_ref) / |v_ref|   (k |v_air| sign(...) beyond 90 deg of heading error)
      + feas x sin^2(lambda) x V_a (1 + w.t / sqrt(V_a^2 - (w x t)^2)) kappa_e max(v_g.t, 0)

with kappa_e = kappa / max(1 - kappa e, kappa r_min) the curvature at the aircraft's distance from the path
and feas in [0, 1] the bearing's feasibility in the wind. The period is bounded below by pi tau_roll / zeta
(for curved paths in wind 4 pi tau_roll zeta, blended by the feasibility) times a safety factor, and above
by 4 pi zeta / (|kappa| V_a f_w feas) when that bound is enabled. The bank that gives a is atan(a / (g cos
theta)) within the roll limit.

Parameters carry PX4's names (``NPFG_PERIOD``, ``NPFG_DAMPING``, ...), units and defaults, so a tuned set
exports to a PX4 autopilot as is (:meth:`NPFGParams.px4`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import torch

from ...constants import DEG, G0
from .paths import PathFrame, cross2

#: Below this a speed or turn rate counts as zero (PX4's EPSILON).
EPSILON = 1.0e-4
#: Smallest loiter radius (m, PX4's MIN_RADIUS).
MIN_RADIUS = 0.5


@dataclass
class NPFGParams:
    """NPFG parameters by PX4 name (SI units, angles in rad); PX4's defaults."""

    NPFG_PERIOD: float = 10.0  # s, the guidance period P
    NPFG_DAMPING: float = 0.7  # the damping ratio zeta
    NPFG_LB_PERIOD: bool = True  # bound the period below for stability with the roll time constant
    NPFG_UB_PERIOD: bool = True  # bound it above for track keeping on curved paths
    NPFG_ROLL_TC: float = 0.5  # s, the roll loop's time constant tau_roll
    NPFG_PERIOD_SF: float = 1.5  # safety factor on the lower bound
    NPFG_ASPD_BUF: float = 1.5  # m/s, airspeed buffer of the bearing feasibility
    NPFG_TRACK_KEEP: bool = True  # keep a minimum ground speed towards the track in excess wind
    NPFG_GSP_MAX_TK: float = 5.0  # m/s, its largest ground speed
    NPFG_EN_MIN_GSP: bool = True  # keep FW_GND_SPD_MIN
    NPFG_WIND_REG: bool = True  # raise the airspeed reference (up to FW_AIRSPD_MAX) in excess wind
    FW_GND_SPD_MIN: float = 5.0  # m/s
    FW_R_LIM: float = 50.0 * DEG  # rad, the roll limit

    def px4(self) -> dict[str, float]:
        """The parameters as a PX4 parameter file would hold them (angles in deg, switches as 0/1)."""
        out: dict[str, float] = {}
        for name, value in asdict(self).items():
            out[name] = float(value) / DEG if name == "FW_R_LIM" else float(value)
        return out


@dataclass
class NPFGOutput:
    """One NPFG evaluation, [N] each: ``lateral_accel`` (m/s^2, positive right), ``bank`` (rad, within
    FW_R_LIM), ``airspeed_ref`` (m/s), ``bearing`` [N, 2] (unit), ``track_error_bound`` (m),
    ``feasibility`` (the bearing's, x that on track), ``period`` (s, adapted) and ``track_proximity``."""

    lateral_accel: torch.Tensor
    bank: torch.Tensor
    airspeed_ref: torch.Tensor
    bearing: torch.Tensor
    track_error_bound: torch.Tensor
    feasibility: torch.Tensor
    period: torch.Tensor
    track_proximity: torch.Tensor


def track_error_bound(ground_speed: torch.Tensor, time_constant: torch.Tensor | float) -> torch.Tensor:
    """e_b = V_g T, or 0.5 T (V_g^2 + 1) below 1 m/s (m)."""
    return torch.where(ground_speed > 1.0, ground_speed * time_constant,
                       0.5 * time_constant * (ground_speed**2 + 1.0))


def look_ahead_angle(normalized_error: torch.Tensor) -> torch.Tensor:
    """lambda = (pi / 2) (e_n - 1)^2 (rad)."""
    return 0.5 * math.pi * (normalized_error - 1.0) ** 2


def bearing_vector(tangent: torch.Tensor, look_ahead: torch.Tensor, track_error: torch.Tensor
                   ) -> torch.Tensor:
    """b = cos(lambda) (-sign(e) n) + sin(lambda) t, n the tangent turned 90 deg clockwise ([N, 2])."""
    normal = torch.stack([-tangent[..., 1], tangent[..., 0]], dim=-1)
    sign = torch.where(track_error < 0.0, -1.0, 1.0).unsqueeze(-1)
    cos, sin = torch.cos(look_ahead).unsqueeze(-1), torch.sin(look_ahead).unsqueeze(-1)
    return cos * (-sign * normal) + sin * tangent


def bearing_feasibility(wind_cross: torch.Tensor, wind_dot: torch.Tensor, airspeed: torch.Tensor | float,
                        wind_speed: torch.Tensor, buffer: float) -> torch.Tensor:
    """sin^2((pi / 2) clamp((V_a - |w x b|) / buffer, 0, 1)), with |w x b| the wind speed when the wind has a
    component against the bearing (w.b < 0)."""
    cross = torch.where(wind_dot < 0.0, wind_speed, wind_cross.abs())
    return torch.sin(0.5 * math.pi * ((airspeed - cross) / buffer).clamp(0.0, 1.0)) ** 2


def _feasible(wind_cross: torch.Tensor, wind_dot: torch.Tensor, airspeed: torch.Tensor | float,
              wind_speed: torch.Tensor) -> torch.Tensor:
    """Whether the bearing can be flown at ``airspeed`` in the wind (PX4's bearingIsFeasible)."""
    return (wind_cross.abs() < airspeed) & ((wind_dot > 0.0) | (wind_speed < airspeed))


def _along(airspeed: torch.Tensor | float, wind_cross: torch.Tensor) -> torch.Tensor:
    """The air velocity's component along the bearing that cancels the cross wind: sqrt(V^2 - (w x b)^2)."""
    return (torch.as_tensor(airspeed, dtype=wind_cross.dtype, device=wind_cross.device) ** 2
            - wind_cross**2).clamp_min(0.0).sqrt()


def _triangle(wind_cross: torch.Tensor, along: torch.Tensor, bearing: torch.Tensor) -> torch.Tensor:
    """The air velocity [N, 2] with ``along`` on the bearing and the cross wind cancelled."""
    return torch.stack([along * bearing[..., 0] - wind_cross * bearing[..., 1],
                        wind_cross * bearing[..., 0] + along * bearing[..., 1]], dim=-1)


def _infeasible(wind: torch.Tensor, bearing: torch.Tensor, wind_speed: torch.Tensor,
                airspeed: torch.Tensor | float) -> torch.Tensor:
    """PX4's mitigation air velocity [N, 2] of magnitude ``airspeed`` when the bearing cannot be flown."""
    excess = (wind_speed**2 - torch.as_tensor(airspeed, dtype=wind.dtype) ** 2).clamp_min(0.0).sqrt()
    vector = excess.unsqueeze(-1) * bearing - wind
    return vector / vector.norm(dim=-1, keepdim=True).clamp_min(EPSILON) * airspeed


def reference_air_velocity(wind: torch.Tensor, bearing: torch.Tensor, min_ground_speed: torch.Tensor,
                           airspeed_nom: float, airspeed_max: float, p: NPFGParams) -> torch.Tensor:
    """The air-velocity reference [N, 2] that makes good ``bearing`` through ``wind`` (PX4's
    refAirVelocity): the nominal airspeed where it suffices, more (up to ``airspeed_max``) to keep
    ``min_ground_speed`` along the bearing, the excess-wind laws otherwise."""
    wind_speed = wind.norm(dim=-1)
    wind_cross, w_dot = cross2(wind, bearing), (wind * bearing).sum(-1)
    regulate = p.NPFG_WIND_REG and (p.NPFG_EN_MIN_GSP or p.NPFG_TRACK_KEEP)
    nominal = _triangle(wind_cross, _along(airspeed_nom, wind_cross), bearing)
    # minimum ground speed branch
    needed = ((min_ground_speed - w_dot) ** 2 + wind_cross**2).sqrt()
    at_max_ok = _feasible(wind_cross, w_dot, airspeed_max, wind_speed)
    at_max = torch.where(at_max_ok.unsqueeze(-1),
                         _triangle(wind_cross, _along(airspeed_max, wind_cross), bearing),
                         _infeasible(wind, bearing, wind_speed, airspeed_max))
    at_needed = _triangle(wind_cross, _along(needed, wind_cross), bearing)
    min_speed = torch.where((needed > airspeed_max).unsqueeze(-1), at_max,
                            torch.where((needed > airspeed_nom).unsqueeze(-1), at_needed, nominal))
    # wind excess regulation / mitigation branch
    nominal_ok = _feasible(wind_cross, w_dot, airspeed_nom, wind_speed)
    if p.NPFG_WIND_REG:
        regulated = torch.where((w_dot <= 0.0).unsqueeze(-1), wind,
                                _triangle(wind_cross, torch.zeros_like(wind_cross), bearing))
        excess = torch.where(at_max_ok.unsqueeze(-1), regulated,
                             _infeasible(wind, bearing, wind_speed, airspeed_max))
    else:
        excess = _infeasible(wind, bearing, wind_speed, airspeed_nom)
    otherwise = torch.where(nominal_ok.unsqueeze(-1), nominal, excess)
    use_min_speed = (min_ground_speed > w_dot) & regulate
    return torch.where(use_min_speed.unsqueeze(-1), min_speed, otherwise)


def adapted_period(p: NPFGParams, ground_speed: torch.Tensor, airspeed: torch.Tensor,
                   wind_speed: torch.Tensor, track_error: torch.Tensor, curvature: torch.Tensor,
                   feasibility_on_track: torch.Tensor) -> torch.Tensor:
    """The period (s) after PX4's lower (roll time constant) and upper (curvature) bounds."""
    period = torch.full_like(ground_speed, p.NPFG_PERIOD)
    if not p.NPFG_LB_PERIOD:
        return period
    zeta = p.NPFG_DAMPING
    turn_rate = (curvature * airspeed).abs()
    wind_factor = torch.where((wind_speed > airspeed) | (airspeed < EPSILON), 2.0,
                              2.0 * (1.0 - (1.0 - (wind_speed / airspeed.clamp_min(EPSILON)).clamp(max=1.0))
                                     .sqrt()))
    straight = math.pi * p.NPFG_ROLL_TC / zeta
    curved = 4.0 * math.pi * p.NPFG_ROLL_TC * zeta
    calm_or_light = (turn_rate * wind_factor < EPSILON) | (zeta < 0.5)
    lower = torch.where(calm_or_light, torch.full_like(period, straight),
                        curved * feasibility_on_track + (1.0 - feasibility_on_track) * straight)
    period = torch.maximum(lower * p.NPFG_PERIOD_SF, period)
    if not p.NPFG_UB_PERIOD:
        return period
    denominator = turn_rate * wind_factor * feasibility_on_track
    upper = torch.where(turn_rate * wind_factor > EPSILON,
                        4.0 * math.pi * zeta / denominator.clamp_min(1e-12),
                        torch.full_like(period, math.inf))
    bounded = torch.maximum(lower * p.NPFG_PERIOD_SF, upper)
    # ramp the adapted period in with the track proximity at the nominal period
    bound = track_error_bound(ground_speed, period * zeta)
    proximity = torch.sin(look_ahead_angle((track_error.abs() / bound).clamp(0.0, 1.0))) ** 2
    ramped = bounded * proximity + (1.0 - proximity) * period
    return torch.where(torch.isfinite(upper) & (period > upper), ramped, period)


def npfg(frame: PathFrame, ground_velocity: torch.Tensor, wind: torch.Tensor, airspeed_nom: float,
         airspeed_max: float, pitch: torch.Tensor | None = None, p: NPFGParams | None = None) -> NPFGOutput:
    """NPFG's lateral acceleration and bank for ``frame`` at ground velocity and wind ([N, 2] north-east,
    m/s), the nominal and maximum airspeeds (m/s) and the pitch [N] (rad, for the bank; level when None)."""
    p = p or NPFGParams()
    zeta = p.NPFG_DAMPING
    tangent, error, curvature = frame.tangent, frame.track_error, frame.curvature
    ground_speed = ground_velocity.norm(dim=-1)
    air_velocity = ground_velocity - wind
    airspeed = air_velocity.norm(dim=-1)
    wind_speed = wind.norm(dim=-1)
    track_error = error.abs()
    wind_cross_t, wind_dot_t = cross2(wind, tangent), (wind * tangent).sum(-1)
    feas_on_track = bearing_feasibility(wind_cross_t, wind_dot_t, airspeed, wind_speed, p.NPFG_ASPD_BUF)
    # PX4 normalises the track error with the previous evaluation's time constant; this stateless
    # evaluation uses the period it adapts now (the same once the period settles).
    period = adapted_period(p, ground_speed, airspeed, wind_speed, track_error, curvature, feas_on_track)
    gain = 4.0 * math.pi * zeta / period
    bound = track_error_bound(ground_speed, period * zeta)
    normalized = (track_error / bound).clamp(0.0, 1.0)
    look_ahead = look_ahead_angle(normalized)
    bearing = bearing_vector(tangent, look_ahead, error)
    proximity = torch.sin(look_ahead) ** 2
    feas = bearing_feasibility(cross2(wind, bearing), (wind * bearing).sum(-1), airspeed, wind_speed,
                               p.NPFG_ASPD_BUF)
    combined = feas * feas_on_track
    keep = torch.zeros_like(combined)
    if p.NPFG_TRACK_KEEP and p.NPFG_WIND_REG:
        keep = (1.0 - combined) * p.NPFG_GSP_MAX_TK * normalized.clamp(0.0, 1.0)
    min_ground_speed = torch.maximum(keep, torch.full_like(keep, p.FW_GND_SPD_MIN
                                                           if p.NPFG_EN_MIN_GSP and p.NPFG_WIND_REG else 0.0))
    air_ref = reference_air_velocity(wind, bearing, min_ground_speed, airspeed_nom, airspeed_max, p)
    airspeed_ref = air_ref.norm(dim=-1)
    dot, cross = (air_velocity * air_ref).sum(-1), cross2(air_velocity, air_ref)
    feedback = torch.where(dot < 0.0, gain * torch.where(cross < 0.0, -airspeed, airspeed),
                           gain * cross / airspeed_ref.clamp_min(EPSILON))
    frame_curvature = curvature / torch.maximum(1.0 - curvature * error, curvature * MIN_RADIUS)
    frame_curvature = torch.where(curvature == 0.0, torch.zeros_like(curvature), frame_curvature)
    along_ground = (ground_velocity * tangent).sum(-1).clamp_min(0.0)
    speed_ratio = 1.0 + wind_dot_t / _along(airspeed, wind_cross_t).clamp_min(EPSILON)
    feedforward = airspeed * speed_ratio * frame_curvature * along_ground
    accel = feedback + combined * proximity * feedforward
    bank = bank_for(accel, pitch, p.FW_R_LIM)
    return NPFGOutput(accel, bank, airspeed_ref, bearing, bound, combined, period, proximity)


def bank_for(lateral_accel: torch.Tensor, pitch: torch.Tensor | None, limit: float) -> torch.Tensor:
    """The bank (rad) of a coordinated turn with ``lateral_accel`` (m/s^2) at ``pitch`` (level when None):
    atan(a / (g cos theta)), within +-``limit``."""
    cos_pitch = torch.ones_like(lateral_accel) if pitch is None else torch.cos(pitch.clamp(-1.047, 1.047))
    return torch.atan(lateral_accel / (G0 * cos_pitch)).clamp(-limit, limit)


__all__ = ["EPSILON", "MIN_RADIUS", "NPFGOutput", "NPFGParams", "adapted_period", "bank_for",
           "bearing_feasibility", "bearing_vector", "look_ahead_angle", "npfg", "reference_air_velocity",
           "track_error_bound"]
