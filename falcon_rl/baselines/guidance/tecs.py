"""PX4's total energy control system (TECS, Lambregts; PX4's TECSControl), batched over envs.

Outer loops (what a climb-rate / airspeed executor such as the attitude LQR or a PPO attitude policy takes):

    hdot* = clamp((h_ref - h) / FW_T_ALT_TC + FW_T_HRATE_FF hdot_ref, -FW_T_SINK_MAX, FW_T_CLMB_MAX)
    Vdot* = clamp((V* - V) / FW_T_TAS_TC, 0.5 STE_min / V, 0.5 STE_max / V)

Energy loops (pitch and throttle, what a pitch executor or an autopilot takes), specific energy rates in
m^2/s^3 with STE_max = g FW_T_CLMB_MAX and STE_min = -g FW_T_SINK_MIN:

    SPE_rate = g hdot,  SKE_rate = V Vdot,  STE = SPE + SKE,  SEB = w_h SPE - w_V SKE
    (w_V = clamp(FW_T_SPDWEIGHT, 0, 1), w_h = clamp(2 - FW_T_SPDWEIGHT, 0, 1))
    pitch*    = (FW_T_PTCH_DAMP (SEB* - SEB) + FW_T_SEB_R_FF SEB*) / (V g) + I_pitch,
                I_pitch' = FW_T_I_GAIN_PIT (SEB* - SEB) / (V g)      (frozen against saturation)
    throttle* = trim + STE* (max - trim) / STE_max   (STE* >= 0; (trim - min) / STE_min below)
                + FW_T_THR_DAMP (STE* - STE_f) / (STE_max - STE_min) + I_thr,
                I_thr' = FW_T_I_GAIN_THR (STE* - STE_f) / (STE_max - STE_min)
    STE* += FW_T_RLL2THR (1 / cos(bank) - 1) (the induced drag of a turn), clamped to [STE_min, STE_max];
    STE_f is STE low-passed with FW_T_STE_R_TC; pitch* is rate limited by FW_T_VERT_ACC / V and clamped to
    the pitch limits, throttle* to its limits.

Parameters carry PX4's names and units; the defaults are PX4's except the issue's pitch damping 0.3. The
underspeed protection, the airspeed Kalman filter and the altitude reference trajectory (jerk-limited) of
PX4 are left out: the env's airspeed and its rate are used as measured, the altitude reference as given.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch

from ...constants import DEG, G0


@dataclass
class TECSParams:
    """TECS parameters by PX4 name (SI units, angles in rad)."""

    FW_T_ALT_TC: float = 5.0  # s, altitude error time constant
    FW_T_TAS_TC: float = 5.0  # s, airspeed error time constant
    FW_T_CLMB_MAX: float = 5.0  # m/s, the climb rate at full throttle (and the climb-rate command limit)
    FW_T_SINK_MAX: float = 5.0  # m/s, the largest commanded sink rate
    FW_T_SINK_MIN: float = 2.0  # m/s, the sink rate at idle (and trim airspeed)
    FW_T_HRATE_FF: float = 0.3  # feed-forward of the altitude reference's rate
    FW_T_SPDWEIGHT: float = 1.0  # 0: pitch controls height only, 2: speed only
    FW_T_PTCH_DAMP: float = 0.3  # pitch damping gain (the default; PX4 ships 0.1)
    FW_T_SEB_R_FF: float = 1.0  # feed-forward of the energy balance rate
    FW_T_I_GAIN_PIT: float = 0.1  # pitch integrator gain
    FW_T_THR_DAMP: float = 0.05  # throttle damping gain
    FW_T_I_GAIN_THR: float = 0.05  # throttle integrator gain
    FW_T_STE_R_TC: float = 0.4  # s, time constant of the total energy rate's low-pass filter
    FW_T_RLL2THR: float = 15.0  # m^2/s^3, total energy rate per unit of extra load factor
    FW_T_VERT_ACC: float = 7.0  # m/s^2, vertical acceleration limit (pitch rate limit)
    FW_P_LIM_MAX: float = 30.0 * DEG  # rad
    FW_P_LIM_MIN: float = -30.0 * DEG  # rad
    FW_THR_MIN: float = 0.0
    FW_THR_MAX: float = 1.0
    FW_THR_TRIM: float = 0.6

    def px4(self) -> dict[str, float]:
        """The parameters as a PX4 parameter file holds them (pitch limits in deg)."""
        return {name: float(value) / DEG if name.startswith("FW_P_LIM") else float(value)
                for name, value in asdict(self).items()}


@dataclass
class TECSState:
    """The per-env memory of TECS ([N] each): pitch and throttle integrators, the last pitch and throttle
    setpoints and the filtered total energy rate."""

    pitch_integrator: torch.Tensor
    throttle_integrator: torch.Tensor
    pitch: torch.Tensor
    throttle: torch.Tensor
    ste_rate: torch.Tensor

    @classmethod
    def zeros(cls, n: int, pitch: torch.Tensor | float = 0.0, throttle: torch.Tensor | float = 0.0,
              device: torch.device | str = "cpu", dtype: torch.dtype = torch.float32) -> TECSState:
        """A fresh state for ``n`` envs starting at ``pitch`` (rad) and ``throttle``."""
        zeros = torch.zeros(n, device=device, dtype=dtype)
        return cls(zeros.clone(), zeros.clone(), zeros + pitch, zeros + throttle, zeros.clone())

    def reset(self, mask: torch.Tensor, pitch: torch.Tensor, throttle: torch.Tensor, ste_rate: torch.Tensor
              ) -> None:
        """Restart the rows of ``mask`` [N] bool at ``pitch``, ``throttle`` and ``ste_rate`` [N]."""
        for name, value in (("pitch_integrator", torch.zeros_like(pitch)), ("throttle_integrator",
                            torch.zeros_like(pitch)), ("pitch", pitch), ("throttle", throttle),
                            ("ste_rate", ste_rate)):
            target = getattr(self, name)
            target.copy_(torch.where(mask, value.to(target.dtype), target))


@dataclass
class TECSOutput:
    """One TECS update, [N] each: the outer loops' ``climb_rate`` (m/s) and ``speed_rate`` (m/s^2)
    setpoints, the energy loops' ``pitch`` (rad) and ``throttle`` setpoints, and the specific energy rate
    setpoints and estimates (m^2/s^3)."""

    climb_rate: torch.Tensor
    speed_rate: torch.Tensor
    pitch: torch.Tensor
    throttle: torch.Tensor
    ste_rate_setpoint: torch.Tensor
    ste_rate: torch.Tensor
    seb_rate_setpoint: torch.Tensor
    seb_rate: torch.Tensor


def climb_rate_setpoint(height: torch.Tensor, height_ref: torch.Tensor, height_rate_ref: torch.Tensor | float,
                        p: TECSParams) -> torch.Tensor:
    """hdot* (m/s) = clamp((h_ref - h) / FW_T_ALT_TC + FW_T_HRATE_FF hdot_ref, -FW_T_SINK_MAX,
    FW_T_CLMB_MAX)."""
    rate = (height_ref - height) / p.FW_T_ALT_TC + p.FW_T_HRATE_FF * height_rate_ref
    return rate.clamp(-p.FW_T_SINK_MAX, p.FW_T_CLMB_MAX)


def speed_rate_setpoint(airspeed: torch.Tensor, airspeed_ref: torch.Tensor | float, p: TECSParams
                        ) -> torch.Tensor:
    """Vdot* (m/s^2) = (V* - V) / FW_T_TAS_TC within half the energy rate limits over V."""
    v = airspeed.clamp_min(1e-3)
    ste_max, ste_min = G0 * p.FW_T_CLMB_MAX, -G0 * p.FW_T_SINK_MIN
    rate = (airspeed_ref - airspeed) / p.FW_T_TAS_TC
    return torch.maximum(torch.minimum(rate, 0.5 * ste_max / v), 0.5 * ste_min / v)


def tecs_update(state: TECSState, dt: float, height: torch.Tensor, climb_rate: torch.Tensor,
                airspeed: torch.Tensor, airspeed_rate: torch.Tensor, height_ref: torch.Tensor,
                airspeed_ref: torch.Tensor | float, height_rate_ref: torch.Tensor | float = 0.0,
                bank: torch.Tensor | None = None, climb_rate_direct: torch.Tensor | None = None,
                p: TECSParams | None = None) -> TECSOutput:
    """One TECS step of ``dt`` s from the measured height (m), climb rate (m/s), airspeed (m/s) and its rate
    (m/s^2) to the references; updates ``state`` in place. ``climb_rate_direct`` [N] (m/s), where given,
    replaces the altitude loop (PX4's height-rate mode, e.g. a flare's sink rate)."""
    p = p or TECSParams()
    v = airspeed.clamp_min(1e-3)
    hdot_sp = climb_rate_setpoint(height, height_ref, height_rate_ref, p)
    if climb_rate_direct is not None:
        hdot_sp = climb_rate_direct
    vdot_sp = speed_rate_setpoint(airspeed, airspeed_ref, p)
    spe_sp, ske_sp = G0 * hdot_sp, v * vdot_sp
    spe, ske = G0 * climb_rate, v * airspeed_rate
    speed_weight = min(max(p.FW_T_SPDWEIGHT, 0.0), 2.0)
    w_h, w_v = min(max(2.0 - speed_weight, 0.0), 1.0), min(speed_weight, 1.0)
    seb_sp, seb = spe_sp * w_h - ske_sp * w_v, spe * w_h - ske * w_v
    # pitch: integrator frozen in the direction that deepens saturation, rate limited, clamped
    to_pitch = v * G0
    integ_in = (seb_sp - seb) * p.FW_T_I_GAIN_PIT / to_pitch
    integ_in = torch.where(state.pitch >= p.FW_P_LIM_MAX, integ_in.clamp(max=0.0), integ_in)
    integ_in = torch.where(state.pitch <= p.FW_P_LIM_MIN, integ_in.clamp(min=0.0), integ_in)
    state.pitch_integrator = state.pitch_integrator + integ_in * dt
    pitch = ((seb_sp - seb) * p.FW_T_PTCH_DAMP + p.FW_T_SEB_R_FF * seb_sp) / to_pitch + state.pitch_integrator
    pitch = pitch.clamp(p.FW_P_LIM_MIN, p.FW_P_LIM_MAX)
    step = dt * p.FW_T_VERT_ACC / v
    pitch = torch.maximum(torch.minimum(pitch, state.pitch + step), state.pitch - step)
    state.pitch = pitch.clamp(p.FW_P_LIM_MIN, p.FW_P_LIM_MAX)
    # throttle
    ste_max, ste_min = G0 * max(p.FW_T_CLMB_MAX, 1e-6), -G0 * max(p.FW_T_SINK_MIN, 1e-6)
    blend = dt / (dt + p.FW_T_STE_R_TC)
    state.ste_rate = state.ste_rate + blend * (spe + ske - state.ste_rate)
    ste_sp = spe_sp + ske_sp
    if bank is not None:
        ste_sp = ste_sp + p.FW_T_RLL2THR * (1.0 / torch.cos(bank).clamp_min(0.1) - 1.0)
    ste_sp = ste_sp.clamp(ste_min, ste_max)
    to_throttle = 1.0 / (ste_max - ste_min)
    error = ste_sp - state.ste_rate
    thr_in = error * p.FW_T_I_GAIN_THR * dt * to_throttle
    thr_in = torch.where(state.throttle >= p.FW_THR_MAX, thr_in.clamp(max=0.0), thr_in)
    thr_in = torch.where(state.throttle <= p.FW_THR_MIN, thr_in.clamp(min=0.0), thr_in)
    state.throttle_integrator = state.throttle_integrator + thr_in
    above = (p.FW_THR_MAX - p.FW_THR_TRIM) / ste_max
    below = (p.FW_THR_TRIM - p.FW_THR_MIN) / ste_min
    predicted = torch.where(ste_sp >= 1e-6, p.FW_THR_TRIM + ste_sp * above, p.FW_THR_TRIM - ste_sp * below)
    throttle = error * p.FW_T_THR_DAMP * to_throttle + predicted + state.throttle_integrator
    state.throttle = throttle.clamp(p.FW_THR_MIN, p.FW_THR_MAX)
    return TECSOutput(hdot_sp, vdot_sp, state.pitch, state.throttle, ste_sp, state.ste_rate, seb_sp, seb)


__all__ = ["TECSOutput", "TECSParams", "TECSState", "climb_rate_setpoint", "speed_rate_setpoint",
           "tecs_update"]
