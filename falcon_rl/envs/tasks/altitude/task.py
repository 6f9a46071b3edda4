"""Altitude acquisition and hold (the paper's altitude-keeping task).

Episode: trimmed level flight at V_a* (cruise) and h_0 = h* + Delta, with the commanded altitude
h* drawn from ``target_altitudes`` (20, 40, 60, 80, 100 m) and Delta = +-U(12, 18) m. The reference
is a sub-target that ramps from h_0 to h* at the airframe's climb-rate limit r and then holds:

    h_ref(t)    = h* - sgn(h* - h_0) max(|h* - h_0| - r t, 0)
    hdot_ref(t) = sgn(h* - h_0) r   while the ramp runs, else 0

With ``target_sequence`` a new h* (another of ``target_altitudes``) is released once |h - h*| has
stayed within ``capture_band`` for ``hold_seconds``; the ramp then starts again from the old target.

Observation (11, clipped to [-3, 3]); e_h = h - h_ref, e_Va = V_a - V_a*:

    o = [e_h/25, q/2, e_Va/sigma_V, theta/(pi/4), v_z/sigma_v, alpha/20deg, delta_e, ddelta_e/100,
         delta_t, int(e_h)/10, hdot_ref/5]

sigma_V = ``airspeed_scale`` V_a*, sigma_v = the climb-rate limit, v_z the NED (down) velocity,
delta_e and delta_t the elevator and throttle states on the command's [-1, 1] scale, ddelta_e the
elevator rate in deg/s (finite difference over the env step), int(e_h) in m s (clamped to
+-``integral_limit``).

Action [delta_e, delta_t] in [-1, 1]^2; aileron and rudder are held at trim.

Reward:

    r = w_h exp(-e_h^2 / 2 sigma_h^2) - w_V |e_Va| / V_a* - w_q min(q^2, q_max)
        - w_s ||a_t - a_{t-1}|| rho(e_h) + w_h kappa_h kappa_V + b_surv - w_o phi - w_E min(|e_E|, 4)

    rho(e_h)  = max(0, 1 - |e_h| / gate_band)             action-rate gate, 1 on the reference
    kappa_h   = max(0, 1 - |e_h| / capture_band)         kappa_V = max(0, 1 - |e_Va| / airspeed_band)
    phi       = max(0, sgn(h* - h_0) (h - h*))           excursion past the commanded altitude
    e_E       = (hdot + V_a dV_a/dt / g - hdot_ref) / r  specific energy-rate error (TECS)

The energy-rate term (``w_energy_rate``, 0 in the paper's reward) is what throttle alone controls: a
pitch-up trades airspeed for height at constant total energy, so only thrust can meet a climb's energy
rate. dV_a/dt is the airspeed's finite difference over the env step (0 on an episode's first step).

Termination: ground contact, |alpha| > 1.5 alpha_stall or V_a < V_stall; truncation at the horizon.
Published under ("task", ...): target_altitude h*, reference_altitude h_ref, reference_climb_rate,
initial_altitude h_0, altitude_error h - h* (the error the metrics score) and reference_error
h - h_ref.

The step, the start of episodes and the observation are written once, as Warp functions
(``altitude.kernels``): every engine runs them (the warp engine inside its one-launch env step, the
torch engine after its torch physics); the episode draws (``sample_initial``) are torch, from the env's
generator.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch

from ....physics import Simulator
from ....physics import state as S
from ..base import Task, TaskConfig

if TYPE_CHECKING:
    from ..warp_common import FusedStep


@dataclass
class AltitudeConfig(TaskConfig):
    """Altitude task parameters (SI units)."""

    episode_seconds: float = 30.0
    target_altitudes: tuple[float, ...] = (20.0, 40.0, 60.0, 80.0, 100.0)
    #: |h_0 - h*| ~ U(offset_min, offset_max), sign random.
    offset_min: float = 12.0
    offset_max: float = 18.0
    #: Reference climb/sink rate; None means the airframe's climb-rate limit.
    climb_rate: float | None = None
    #: Release a new target once the current one has been held (the paper's sequence figure).
    target_sequence: bool = False
    hold_seconds: float = 3.0
    capture_band: float = 1.0
    airspeed_scale: float = 0.1
    integral_limit: float = 30.0
    w_altitude: float = 1.0
    sigma_altitude: float = 3.0
    w_airspeed: float = 0.5
    w_pitch_rate: float = 0.1
    pitch_rate_cap: float = 1.0
    w_smooth: float = 0.05
    gate_band: float = 5.0
    airspeed_band_fraction: float = 0.05
    survival_bonus: float = 0.1
    w_overshoot: float = 0.1
    #: Weight of the specific energy-rate error (module docstring; 0: the paper's reward).
    w_energy_rate: float = 0.0

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "target_altitudes", "climb_rate", "capture_band", "airspeed_scale",
        "integral_limit", "sigma_altitude", "pitch_rate_cap", "gate_band", "airspeed_band_fraction")
    non_negative: ClassVar[tuple[str, ...]] = ("offset_min", "hold_seconds")
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (("offset_min", "offset_max"),)


class AltitudeTask(Task):
    """Altitude acquisition and hold; see the module docstring for the equations."""

    name = "altitude"
    observation_dim = 11
    action_dim = 2
    observation_clip = 3.0
    action_channels = (S.ELEVATOR, S.THROTTLE)
    #: Cap on |e_E| in the energy-rate penalty (a stall recovery's dV/dt would otherwise swamp the reward).
    energy_rate_cap = 4.0
    reward_terms = ("altitude", "airspeed", "pitch_rate", "smoothness", "capture", "survival", "overshoot",
                    "energy_rate")
    config: AltitudeConfig

    def __init__(self, config: AltitudeConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        #: Reference climb/sink rate per env, m/s. [N]
        self.default_climb_rate = float(config.climb_rate or self.airframe.envelope.climb_rate_limit)
        self.climb_rate = torch.full((n,), self.default_climb_rate, **kw)
        self.target = torch.zeros(n, **kw)
        self.target_table = torch.tensor(config.target_altitudes, **kw)
        self.initial_altitude = torch.zeros(n, **kw)
        self.segment_start = torch.zeros(n, **kw)  # altitude the current ramp starts from
        self.segment_time = torch.zeros(n, **kw)  # s since the current ramp started
        self.time_in_band = torch.zeros(n, **kw)
        self.error_integral = torch.zeros(n, **kw)
        self.previous_elevator = torch.zeros(n, **kw)
        self.elevator_rate = torch.zeros(n, **kw)  # rad/s
        self.previous_airspeed = torch.zeros(n, **kw)
        self.airspeed_rate = torch.zeros(n, **kw)  # m/s^2
        self.reference = torch.zeros(n, **kw)
        self.reference_rate = torch.zeros(n, **kw)
        self.altitude_error = torch.zeros(n, **kw)  # h - h*
        self.reference_error = torch.zeros(n, **kw)  # h - h_ref
        self._fused: FusedStep | None = None  # bound on the first fused step

    # ------------------------------------------------------------------ episode start
    def sample_targets_and_offsets(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(h* [N], h_0 [N]) for fresh episodes."""
        cfg = self.config
        target = self.choice(cfg.target_altitudes)
        offset = self.random_sign() * self.uniform(cfg.offset_min, cfg.offset_max)
        return target, target + offset

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        target, start = self.sample_targets_and_offsets()
        for buffer, value in ((self.target, target), (self.initial_altitude, start),
                              (self.segment_start, start)):
            buffer.copy_(torch.where(mask, value, buffer))
        return {**self.trim_initial(), "height": self.initial_altitude.to(self.dtype, copy=True)}

    # ------------------------------------------------------------------ step
    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``altitude.kernels``, :class:`FusedAltitudeStep`):
        (observation [N, 11], reward [N], reason [N] long), buffers overwritten by the next call. With
        ``target_sequence`` the random target shift is drawn from the task's generator before the launch."""
        from ..warp_common import fused_stepper
        from .kernels import FusedAltitudeStep

        return fused_stepper(self, FusedAltitudeStep)

    def info_views(self) -> dict[str, torch.Tensor]:
        return {
            "target_altitude": self.target,
            "reference_altitude": self.reference,
            "reference_climb_rate": self.reference_rate,
            "initial_altitude": self.initial_altitude,
            "altitude_error": self.altitude_error,
            "reference_error": self.reference_error,
        }
