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

On the warp backend the env's step runs :meth:`AltitudeTask.fused_step`: all of the above after the
physics in one Warp kernel (``altitude.kernels``) instead of ``Simulator.state`` and ~100 torch ops; a
reset starts the episodes (``after_reset`` and the observation) in one launch too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch
from tensordict import TensorDictBase

from ....constants import DEG, G0
from ....physics import Simulator
from ....physics import state as S
from ..base import Task, TaskConfig, gaussian, normalised_surfaces, taper

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
        n, kw = self.num_envs, {"device": self.device, "dtype": self.dtype}
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
        return {**self.trim_initial(), "height": self.initial_altitude.clone()}

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        for buffer in (self.segment_time, self.time_in_band, self.error_integral):
            buffer.masked_fill_(mask, 0.0)
        elevator = state["surface_position"][:, S.ELEVATOR]
        self.previous_elevator.copy_(torch.where(mask, elevator, self.previous_elevator))
        self.elevator_rate.masked_fill_(mask, 0.0)
        self.previous_airspeed.copy_(torch.where(mask, state["airspeed"], self.previous_airspeed))
        self.airspeed_rate.masked_fill_(mask, 0.0)
        self._update_reference()
        self.altitude_error.copy_(state["height"] - self.target)
        self.reference_error.copy_(state["height"] - self.reference)

    # ------------------------------------------------------------------ reference
    def _update_reference(self) -> None:
        """h_ref and hdot_ref from the ramp's start, target and elapsed time (closed form)."""
        gap = self.target - self.segment_start
        direction = torch.sign(gap)
        remaining = (gap.abs() - self.climb_rate * self.segment_time).clamp_min(0.0)
        self.reference.copy_(self.target - direction * remaining)
        self.reference_rate.copy_(torch.where(remaining > 0, direction * self.climb_rate, 0.0))

    def advance(self) -> None:
        super().advance()
        self.segment_time += self.control_dt
        self._update_reference()

    def _release_next_targets(self, height: torch.Tensor) -> None:
        """Target sequence: envs that held h* for hold_seconds get a new, different target."""
        cfg = self.config
        inside = (height - self.target).abs() <= cfg.capture_band
        self.time_in_band.copy_(torch.where(inside, self.time_in_band + self.control_dt, 0.0))
        held = self.time_in_band >= cfg.hold_seconds
        table = self.target_table
        shift = torch.randint(1, max(len(table), 2), (self.num_envs,), generator=self.generator,
                              device=self.device)
        current = (self.target[:, None] - table).abs().argmin(-1)
        new_target = table[(current + shift) % len(table)]
        self.segment_start.copy_(torch.where(held, self.target, self.segment_start))
        self.initial_altitude.copy_(torch.where(held, self.target, self.initial_altitude))
        self.target.copy_(torch.where(held, new_target, self.target))
        self.segment_time.masked_fill_(held, 0.0)
        self.time_in_band.masked_fill_(held, 0.0)
        self._update_reference()

    # ------------------------------------------------------------------ MDP
    def update(self, state: TensorDictBase) -> None:
        cfg = self.config
        height = state["height"]
        if cfg.target_sequence:
            self._release_next_targets(height)
        self.altitude_error.copy_(height - self.target)
        self.reference_error.copy_(height - self.reference)
        elevator = state["surface_position"][:, S.ELEVATOR]
        torch.div(elevator - self.previous_elevator, self.control_dt, out=self.elevator_rate)
        self.previous_elevator.copy_(elevator)
        torch.div(state["airspeed"] - self.previous_airspeed, self.control_dt, out=self.airspeed_rate)
        self.previous_airspeed.copy_(state["airspeed"])
        self.error_integral.copy_((self.error_integral + (height - self.reference) * self.control_dt)
                                  .clamp(-cfg.integral_limit, cfg.integral_limit))

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        cfg = self.config
        e_h = state["height"] - self.reference
        surfaces = normalised_surfaces(state, self.sim)
        throttle = 2.0 * state["throttle"].mean(-1) - 1.0
        obs = torch.stack([
            e_h / 25.0,
            state["angular_rate_body"][:, S.PITCH] / 2.0,
            (state["airspeed"] - self.trim_airspeed) / (cfg.airspeed_scale * self.trim_airspeed),
            state["euler"][:, S.PITCH] / (math.pi / 4),
            state["velocity_ned"][:, S.DOWN] / self.airframe.envelope.climb_rate_limit,
            state["alpha"] / (20.0 * DEG),
            surfaces[:, S.ELEVATOR],
            self.elevator_rate / (100.0 * DEG),
            throttle,
            self.error_integral / 10.0,
            self.reference_rate / 5.0,
        ], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        cfg = self.config
        e_h = state["height"] - self.reference
        e_v = state["airspeed"] - self.trim_airspeed
        q = state["angular_rate_body"][:, S.PITCH]
        action_rate = torch.linalg.vector_norm(action - self.previous_action, dim=-1)
        direction = torch.sign(self.target - self.initial_altitude)
        past_target = (direction * (state["height"] - self.target)).clamp_min(0.0)
        return (cfg.w_altitude * gaussian(e_h, cfg.sigma_altitude),
                -(cfg.w_airspeed * e_v.abs() / self.trim_airspeed),
                -(cfg.w_pitch_rate * torch.clamp(q * q, max=cfg.pitch_rate_cap)),
                -(cfg.w_smooth * action_rate * taper(e_h, cfg.gate_band)),
                cfg.w_altitude * taper(e_h, cfg.capture_band)
                * taper(e_v, cfg.airspeed_band_fraction * self.trim_airspeed),
                torch.full_like(e_h, cfg.survival_bonus),
                -(cfg.w_overshoot * past_target),
                -(cfg.w_energy_rate * self.energy_rate_error(state).abs().clamp(max=self.energy_rate_cap)))

    def energy_rate_error(self, state: TensorDictBase) -> torch.Tensor:
        """e_E [N]: (hdot + V_a dV_a/dt / g - hdot_ref) / r, r the reference climb rate limit."""
        climb = -state["velocity_ned"][:, S.DOWN]
        energy_rate = climb + state["airspeed"] * self.airspeed_rate / G0
        return (energy_rate - self.reference_rate) / self.airframe.envelope.climb_rate_limit

    # ------------------------------------------------------------------ fused step
    def fused_stepper(self) -> FusedStep | None:
        """:meth:`step` as one Warp kernel on the warp backend (``altitude.kernels``; None elsewhere, or
        when a subclass overrides a method of the step): (observation [N, 11], reward [N], reason [N]
        long), buffers overwritten by the next call. With ``target_sequence`` the random shift is drawn
        from the task's generator in torch before the launch, exactly as :meth:`step` draws it."""
        if not self.sim.engine.runs_task_kernels:
            return None
        from ..warp_common import fused_stepper
        from .kernels import FusedAltitudeStep

        return fused_stepper(self, AltitudeTask, _FUSED_METHODS, FusedAltitudeStep)

    def info(self) -> dict[str, torch.Tensor]:
        return {key: value.clone() for key, value in self.info_views().items()}

    def info_views(self) -> dict[str, torch.Tensor]:
        return {
            "target_altitude": self.target,
            "reference_altitude": self.reference,
            "reference_climb_rate": self.reference_rate,
            "initial_altitude": self.initial_altitude,
            "altitude_error": self.altitude_error,
            "reference_error": self.reference_error,
        }


#: The methods :meth:`AltitudeTask.fused_step` fuses: a subclass that overrides one falls back to ``step``.
_FUSED_METHODS: tuple[str, ...] = ("step", "advance", "update", "reward", "reward_terms_of", "observe",
                                   "termination_checks",
                                   "termination_reason", "_update_reference", "_release_next_targets")
